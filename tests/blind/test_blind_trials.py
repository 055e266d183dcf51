"""Blind trials through the product's doors (slow): campaigns from tests/blind judged against
their exact truths.

Each case is one campaign (``_blind_sweeps.campaign(family, plan, seed)``) run through
``snapwarn sweep MANIFEST --json``. A case passes when the answer is never confidently wrong:
the right type or an honest withholding (a sweep that stops at ``T/T0 = 1.6`` must withhold),
an interval that holds the true mu*, every untrusted record (snapped branch, growing) set aside
by its file's name or reported as past the transition, and every record set aside named.
The cases that pass today guard against regressions; the ones that fail are strict xfails whose
reason is what was measured (the product's answer, the truth, the component at fault), so a fix
shows up as an XPASS to be turned into a guard. The HTTP door (a real ``snapwarn serve`` on a
free port, driven by the SDK) must give the CLI's answer and never a 5xx; a record with dropped
samples must be refused with a 4xx naming it, never a 5xx.
"""

from __future__ import annotations

import json
import math
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).parent))

import _blind_sweeps as S  # noqa: E402
import _blind_trials as T  # noqa: E402

pytestmark = pytest.mark.slow

#: (family, plan, seed) -> None (passes today) or the measured failure (strict xfail)
CASES: dict[tuple[str, str, int], str | None] = {
    ("arch_fold", "lab", 0): None,
    ("arch_fold", "far", 0): None,
    ("arch_fold", "past", 0): None,
    ("arch_fold", "past", 1): None,  # passes with the causal lead-in detector (d87c840)
    # wholly late [116.907, 6264.98] N on 03b3dcc (114.207 N read as two slow terms the fit
    # made of the noise, sigma2 -16.5 +- 55); passes since the detector takes no component
    # it cannot tell from nothing as the fundamental (session 19)
    ("arch_fold", "past", 2): None,
    ("arch_pitchfork", "lab", 0): None,
    ("arch_pitchfork", "far", 0): None,
    ("arch_pitchfork", "past", 0): None,  # passes with the causal lead-in detector (d87c840)
    ("arch_crossing", "lab", 0): None,
    # undetermined [4.1989, 5.0161] kN for 5.03980 on e21e7fb (blended pair read as one line
    # after a false repeated_kick); passes on 03b3dcc (session 18's detector and reconcile)
    ("arch_crossing", "far", 0): None,
    ("arch_crossing", "past", 0): None,  # passes with the causal lead-in detector (d87c840)
    ("arch_crossing", "past", 1): None,  # passes with the causal lead-in detector (d87c840)
    # was a strict xfail (saddle-node [1149.660, 1150.137] lbf ending 0.03 below the fold at
    # 1150.164: the fold's series at its correction limit, 7 points and 4 terms, 2.65 std early
    # on the exact sigma2 too): the term the series drops is carried into the interval
    # (cusp, interval._next_term, 2026-11-28): [1149.660, 1150.219]
    ("arch_imperfect", "lab", 0): None,
    ("arch_imperfect", "far", 0): None,
    ("arch_imperfect", "past", 0): None,
    ("foundation", "lab", 0): None,
    # was a confident `none` for a buckling column (the lowest line followed): reconcile follows
    # the line that reaches sigma^2 = 0 first (modes, 2026-11-28): undetermined 5.638
    # [5.402, 51.18] N, covering, type withheld
    ("foundation", "lab", 1): None,
    ("foundation", "far", 0): None,
    # was a strict xfail (audit, session 19, on 4c04a7a): undetermined [3.5219, 12.6094] kN for
    # the buckling load 1.82684, WHOLLY LATE, the sweep following mode 1 (-854.95 at 0 kN) while
    # the detector lists the critical mode in every record. XPASS on bf8bd9b: undetermined
    # [1.369, 60.25] kN (interval_huge, ambiguous), covering; the sweep still follows mode 1
    # (reconcile's choice is left open: its interval is honest, not useful)
    ("foundation", "far", 12): None,
    ("foundation", "past", 0): None,  # the growth no longer read as a drift (a64b4c6)
    ("foundation", "past", 2): None,  # passes with the causal lead-in detector (d87c840)
    ("threelink", "lab", 0): None,
    ("threelink", "far", 0): None,
    ("threelink", "past", 0): None,
}


def _params(cases: dict) -> list:
    out = []
    for key, why in cases.items():
        marks = [pytest.mark.xfail(strict=True, reason=why)] if why else []
        out.append(pytest.param(*key, marks=marks, id="-".join(map(str, key))))
    return out


@pytest.mark.parametrize("family,plan,seed", _params(CASES))
def test_blind_campaign_through_the_cli(family: str, plan: str, seed: int, tmp_path: Path):
    truth = S.campaign(family, plan, seed).write(tmp_path / "c")
    ans = T.cli_sweep(truth.manifest)
    v = T.judge(ans, truth)
    assert not T.failures(ans, truth), T.describe(truth, ans, v)


#: the predictor alone on each family's exact measurements (0.1 % noise, static levels given)
PREDICT_CASES: dict[tuple[str, str, int], str | None] = {
    **{(f, "lab", 0): None for f in S.FAMILIES},
    ("arch_imperfect", "past", 0): None,
}


@pytest.mark.parametrize("family,plan,seed", _params(PREDICT_CASES))
def test_blind_exact_measurements_through_predict(family: str, plan: str, seed: int,
                                                  tmp_path: Path):  # fmt: skip
    camp = S.campaign(family, plan, seed, duration_s=0.2, rate_hz=500.0)  # records unused
    truth = camp.write(tmp_path / "c")
    ans = T.cli_predict(truth.write_table(tmp_path / "table.csv"))
    v = T.judge(ans, truth)
    assert v.type in ("right", "withheld") and v.covered and not v.confident, \
        T.describe(truth, ans, v)


def test_a_record_with_dropped_samples_does_not_sink_the_sweep(tmp_path: Path):
    """One file with NaN gaps (a logger's dropped samples) among good ones: the sweep must
    answer from the others and name the bad file as set aside."""
    camp = replace(S.campaign("threelink", "lab", 0), spoil={4: {"nan_gaps": 2}})
    truth = camp.write(tmp_path / "c")
    ans = T.cli_sweep(truth.manifest)
    assert ans.ok, ans.error
    assert ans.transition is not None, ans.error
    assert any("rec04" in m for m in ans.set_aside), ans.set_aside


@pytest.fixture(scope="module")
def server(tmp_path_factory: pytest.TempPathFactory):
    s = T.Server(tmp_path_factory.mktemp("blind-serve"))
    yield s
    s.stop()


def test_http_door_gives_the_cli_answer_and_no_5xx(server, tmp_path: Path):
    truth = S.campaign("threelink", "lab", 0).write(tmp_path / "c")
    cli = T.cli_sweep(truth.manifest)
    http = T.http_sweep(server.url, truth.manifest, truth.control_unit)
    assert http.ok and cli.ok, (http.error, cli.error)
    assert http.transition == cli.transition
    assert http.mu_star == pytest.approx(cli.mu_star, rel=1e-9)
    assert np.allclose(http.interval, cli.interval, rtol=1e-9)
    v = T.judge(http, truth)
    assert v.type in ("right", "withheld") and v.covered, T.describe(truth, http, v)
    assert not server.server_errors()


def test_http_upload_of_a_record_with_dropped_samples_is_a_4xx_naming_it(server, tmp_path):
    from service.client import Client
    from service.client.errors import ApiError

    camp = replace(S.campaign("threelink", "lab", 0), spoil={1: {"nan_gaps": 1}})
    truth = camp.write(tmp_path / "c")
    bad = truth.manifest.parent / truth.names[1]
    with Client(server.url, timeout=120.0) as sdk:
        with pytest.raises(ApiError) as err:
            sdk.upload_file(bad, control_value=truth.controls[1], control_unit="N")
    status = getattr(err.value, "status", None) or getattr(err.value, "status_code", None)
    assert status is not None and 400 <= int(status) < 500, err.value
    assert "finite" in str(err.value) or "NaN" in str(err.value) or "w[" in str(err.value)
    assert not server.server_errors()


def test_cli_detect_json_on_blind_records_never_crashes(tmp_path: Path):
    """Every recording style of the blind lab read by ``snapwarn detect --json``: exit 0 (or a
    clear refusal for the NaN record), a JSON document, a time unit and a value unit."""
    styles = {
        "geophone_V": dict(sensor="geophone", unit="V", rate_hz=20000.0, duration_s=1.0),
        "accel_g": dict(sensor="accel", unit="g", rate_hz=5000.0, duration_s=1.0),
        "laser_in_ms": dict(unit="in", time_unit="ms", rate_hz=500.0, duration_s=2.0),
        "bounce": dict(second_hit=(0.4, 0.6), duration_s=2.0),
        "adc12": dict(adc_bits=12, duration_s=2.0),
    }
    for name, over in styles.items():
        camp = replace(S.campaign("threelink", "lab", 0, **over), adaptive_length=False)
        camp = replace(camp, controls=camp.controls[:1])
        truth = camp.write(tmp_path / name)
        exe = T.ROOT / ".venv/bin/snapwarn"
        r = subprocess.run([str(exe), "detect", str(truth.manifest.parent / truth.names[0]),
                            "--json"], capture_output=True, text=True, timeout=600)  # fmt: skip
        assert r.returncode == 0, (name, r.stderr[-500:])
        doc = json.loads(r.stdout)
        assert doc["time_unit"] in ("s", "ms"), (name, doc["time_unit"])
        fu = doc.get("fundamental")
        assert fu is None or math.isfinite(fu["sigma2"]), name


def test_live_door_gives_the_cli_answer(server, tmp_path: Path):
    """The same campaign fed record by record to a live sweep (SDK) ends on the CLI's answer."""
    truth = S.campaign("threelink", "lab", 0).write(tmp_path / "c")
    cli = T.cli_sweep(truth.manifest)
    T.assert_live_gives(server.url, truth, cli, "blind threelink lab 0")
    assert not server.server_errors()


#: detector rows (``_blind_trials.DETECTOR_ROWS``), the records tried, and None (no record is
#: silently wrong today) or the measured failure (strict xfail)
DETECTOR_CASES: dict[str, tuple[range, str | None]] = {
    "clean_45dB": (range(4), None),
    "midring_30dB": (range(4), None),
    "hum_2pct_45dB": (range(4), None),
    "hum_10pct_45dB": (range(4), None),
    "rate_500Hz": (range(4), None),
    "rate_20kHz": (range(4), None),
    "geophone": (range(4), None),
    "accel_g": (range(4), None),
    "adc_12bit": (range(4), None),
    "bounce": (range(4), None),
    # strict xfails until the detector's causal lead-in (detect/_lab._causal_envelope): the
    # pre-trigger was not recognised at 25-30 dB (3 of 4 records silently wrong each)
    "noise_30dB": (range(4), None),
    "noise_25dB": (range(4, 8), None),
    "rig_mode": (range(4), (
        "detector/reconcile: a rig mode at a fixed 0.6 Hz (a suspended sensor, half the "
        "response's peak) is the fundamental with no flag in 2 of these 4 (5 of 8)")),
}


@pytest.mark.parametrize("row", [
    pytest.param(r, marks=[pytest.mark.xfail(strict=True, reason=why)] if why else [], id=r)
    for r, (_, why) in DETECTOR_CASES.items()])  # fmt: skip
def test_blind_records_are_never_silently_wrong_in_the_detector(row: str):
    out = [T.detect_one(row, i) for i in DETECTOR_CASES[row][0]]
    bad = [o for o in out if o["outcome"] in ("silent", "error")]
    assert not bad, bad
