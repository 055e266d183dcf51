"""Blind trials of the labs the product had not seen (slow): a truss with joint friction, an
imperfect arch recorded by a geophone, columns whose critical mode ends overdamped, even load
steps that stop at ``T/T0 = 1.3``, a sensor whose zero jumps mid-record, a logger whose sampling
instants jitter.

Each case is a campaign of ``_blind_sweeps.campaign(family, plan, seed, **overrides)`` run
through ``snapwarn sweep MANIFEST --json`` and judged as in ``test_blind_trials.py``
(``_blind_trials.failures``): never confidently wrong, an interval that holds the truth, untrusted
records set aside by name. Passing cases guard against regressions; failing ones are strict
xfails whose reason gives what was measured and the component at fault (found with
``python tests/blind/_blind_diagnose.py FAMILY PLAN SEED DIR key=value ...``). The HTTP door
(SDK against a real ``snapwarn serve``) and a live sweep must give the CLI's answer on the new
labs whatever that answer is, with no 5xx.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).parent))

import _blind_sweeps as S  # noqa: E402
import _blind_trials as T  # noqa: E402

pytestmark = pytest.mark.slow

#: id -> (family, plan, seed, recording/damping overrides, None or the measured failure)
LAB_CASES: dict[str, tuple[str, str, int, dict, str | None]] = {
    # a two-bar truss with Coulomb friction in its joints (a linear envelope, then the apex sticks)
    "truss_friction-lab-0": ("truss_friction", "lab", 0, {}, (
        "detector (measured on 8958a8b: `pitchfork` [8.86652, 8.87489] kN for a saddle-node at "
        "8.890167, the sideband picks; session 19 reads each comb at its dominant line): "
        "saddle-node 8.87605 [8.874885, 8.878449] kN, early, flags law_misfit, interval_huge; "
        "9 of 10 controls within 2.4 of their stated errors, the last (8.8749 kN: some 6 "
        "cycles, then the apex sticks) read at a weak slower line, sigma2 -28.67 +- 3.6 for "
        "-79.91 (z +14, flag nonlinear only); predict on the exact sigma2 with the same stds "
        "covers")),
    # `pitchfork` [61.947, 66.124] for the saddle-node at 61.9059 on 8958a8b (wholly late: the
    # sideband picks, sum z^2 3.8e4); withheld, covering since session 19 (the comb read at its
    # dominant line, its error bounded by the split main lobe: sum z^2 7.9 over 10 controls)
    "truss_friction-lab-1": ("truss_friction", "lab", 1, {}, None),
    # `pitchfork` [2712.06, 2741.62] lbf for the saddle-node at 2721.18 on 8958a8b (the sideband
    # picks); passes on 03b3dcc (after the detector's and reconcile's changes of session 18)
    "truss_friction-past-0": ("truss_friction", "past", 0, {}, None),
    "truss_friction-far-0": ("truss_friction", "far", 0, {}, None),
    "truss_friction-veryfar-0": ("truss_friction", "veryfar", 0, {}, None),
    # an imperfect high arch (its fold 10.7 % below the perfect bifurcation) recorded by a geophone
    # (velocity through its own 4.5 Hz, zeta 0.7 high-pass, in V): right and covering (the
    # detector's sigma2 within its stated errors: sum z^2 14.8 over 14 controls)
    "arch_imperfect-lab-1-geophone": ("arch_imperfect", "lab", 1, {
        "sensor": "geophone", "unit": "V", "rate_hz": 2000.0, "duration_s": 1.0}, None),
    # the critical mode's damping ratio grows as 1/omega0 (0.25 at the first record): overdamped
    # at the end; passes (withheld, [0.977, 5.934] N covers 1.01655) although the detector takes
    # the stiff mode 2 in the 7 records from zeta >= 0.56 on (z -100 to -227)
    "threelink-lab-0-overdamped": ("threelink", "lab", 0, {"damping": 0.25}, None),
    # even load steps that stop at T/T0 = 1.3: the type withheld, the interval covering
    "arch_pitchfork-veryfar-0": ("arch_pitchfork", "veryfar", 0, {}, None),
    "threelink-veryfar-0": ("threelink", "veryfar", 0, {}, None),
    # the sensor's zero jumps by 30 % / 20 % of the peak mid-record
    "arch_fold-lab-0-offset-step": ("arch_fold", "lab", 0, {"offset_step": (0.5, 0.3)}, (
        "predictor/detector (passed on af10ea0; fails on 03b3dcc, not bisected: the detector's "
        "errors (c44abb5) and reconcile changed between): saddle-node 98.99052 [98.98803, "
        "98.99451] N for the fold at 98.99504, early by 0.08 of the width, no caution flag; the "
        "detector's "
        "sigma2 honest (sum z^2 16.4 over 12 controls, largest z +2.74); predict on the exact "
        "sigma2 with the same stds: [98.73996, 98.99917] covers (python "
        "tests/blind/_blind_diagnose.py arch_fold lab 0 DIR 'offset_step=(0.5, 0.3)')")),
    "threelink-lab-0-offset-step": ("threelink", "lab", 0, {"offset_step": (0.6, 0.2)}, None),
    # sampling instants jitter by 1 % of the step (500 Hz), stamped on the nominal grid
    "arch_fold-lab-0-jitter": ("arch_fold", "lab", 0, {"jitter_s": 2e-5}, None),
}


def _params() -> list:
    out = []
    for cid, (*_, why) in LAB_CASES.items():
        marks = [pytest.mark.xfail(strict=True, reason=why)] if why else []
        out.append(pytest.param(cid, marks=marks, id=cid))
    return out


def _truth(cid: str, folder: Path) -> S.Truth:
    family, plan, seed, over, _ = LAB_CASES[cid]
    return S.campaign(family, plan, seed, **over).write(folder)


@pytest.mark.parametrize("cid", _params())
def test_new_lab_through_the_cli(cid: str, tmp_path: Path):
    truth = _truth(cid, tmp_path / "c")
    ans = T.cli_sweep(truth.manifest)
    assert not T.failures(ans, truth), T.describe(truth, ans, T.judge(ans, truth))


def test_a_logger_that_stamps_its_jittered_instants(tmp_path: Path):
    """Every record's time stamps are the instants actually sampled (jitter 10 % of the step):
    the sweep refuses with the file's name and the cure (``--resample``), never a traceback; with
    ``--resample`` it answers right or withholds, covering. One such record among good ones is
    set aside by name."""
    from dataclasses import replace

    over = {"jitter_s": 1e-4, "jitter_stamped": True}
    truth = S.campaign("threelink", "lab", 0, **over).write(tmp_path / "all")
    plain = T.cli_sweep(truth.manifest)
    assert plain.ok and plain.transition is None, plain
    assert "rec00" in plain.error and "--resample" in plain.error, plain.error
    ans = T.cli_sweep(truth.manifest, "--resample")
    assert not T.failures(ans, truth), T.describe(truth, ans, T.judge(ans, truth))
    camp = replace(S.campaign("threelink", "lab", 0), spoil={3: over})
    one = camp.write(tmp_path / "one")
    ans = T.cli_sweep(one.manifest)
    assert not T.failures(ans, one), T.describe(one, ans, T.judge(ans, one))
    assert any(one.names[3].removesuffix(".csv") in m for m in ans.set_aside), ans.set_aside


#: campaigns whose critical mode is NOT the lowest line far from mu* (the detector sees it in
#: every record): the sweep's measurements must follow the mode that goes soft
FOLLOW_CASES: dict[tuple[str, str, int], str | None] = {
    # reconcile follows the line that reaches sigma^2 = 0 first (modes, 2026-11-28): pitchfork
    # 1.394312 [1.384594, 1.394380] kN, every measurement on the critical mode
    ("foundation", "lab", 0): None,
}


@pytest.mark.parametrize("family,plan,seed", [
    pytest.param(*k, marks=[pytest.mark.xfail(strict=True, reason=why)] if why else [],
                 id="-".join(map(str, k)))
    for k, why in FOLLOW_CASES.items()])  # fmt: skip
def test_the_sweep_follows_the_mode_that_goes_soft(family: str, plan: str, seed: int,
                                                   tmp_path: Path):  # fmt: skip
    truth = S.campaign(family, plan, seed).write(tmp_path / "c")
    ans = T.cli_sweep(truth.manifest)
    v = T.judge(ans, truth)
    assert ans.ok and not v.bad_records, T.describe(truth, ans, v)


@pytest.fixture(scope="module")
def server(tmp_path_factory: pytest.TempPathFactory):
    s = T.Server(tmp_path_factory.mktemp("blind-labs-serve"))
    yield s
    s.stop()


#: the doors must agree on these whatever the answer (one that fails the judge included)
DOOR_CASES = ("truss_friction-lab-0", "arch_fold-lab-0-offset-step")


@pytest.mark.parametrize("cid", DOOR_CASES)
def test_http_and_live_doors_give_the_cli_answer_on_new_labs(cid: str, server, tmp_path: Path):

    truth = _truth(cid, tmp_path / "c")
    cli = T.cli_sweep(truth.manifest)
    http = T.http_sweep(server.url, truth.manifest, truth.control_unit)
    assert cli.ok and http.ok, (cli.error, http.error)
    assert http.transition == cli.transition
    assert http.mu_star == pytest.approx(cli.mu_star, rel=1e-9)
    assert np.allclose(http.interval, cli.interval, rtol=1e-9)
    T.assert_live_gives(server.url, truth, cli, f"blind {cid}")
    assert not server.server_errors()
