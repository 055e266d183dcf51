"""Lab files and campaigns: every writer's file reads back through ``service.recordings`` with
the record's samples and step, the manifest is the one ``snapwarn sweep`` reads, and a
campaign's records follow the normal form's laws (softening exponent, static deflection)."""

from __future__ import annotations

import math
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).parent))
import labfiles as F  # noqa: E402
import labgen as L  # noqa: E402

from service.recordings import manifest_columns, read_file, read_table  # noqa: E402


@pytest.mark.parametrize("style", F.STYLES)
@pytest.mark.parametrize("quantity", L.QUANTITIES)
def test_every_lab_file_reads_back_as_written(tmp_path: Path, style: str, quantity: str):
    rec = L.draw_record(4, quantity=quantity, fs=2000.0, duration=1.0)
    path = F.write_record(rec, tmp_path / f"r{F.suffix(style)}", style)
    got = read_file(str(path))
    assert got.dt * L_seconds(got.unit) == pytest.approx(rec.dt, rel=1e-9)
    np.testing.assert_allclose(got.w, rec.y, rtol=1e-6, atol=1e-7 * np.abs(rec.y).max())


def L_seconds(unit: str | None) -> float:  # noqa: N802 - the reader's time unit in seconds
    return {"s": 1.0, "ms": 1e-3, None: 1.0}[unit]


def test_a_campaign_writes_its_files_and_a_manifest_sweep_reads(tmp_path: Path):
    camp, style = F.issue_campaigns()["saddle-node"]
    truth = F.write_campaign(camp, tmp_path, controls=[0.0, 20.0, 40.0], style=style,
                             spurious={1: "bad_kick"}, dt_column=True)  # fmt: skip
    table = read_table(truth.manifest.read_bytes())
    path_col, control_col = manifest_columns(table)
    assert [r.name for r in truth.records] == ["rec_00.csv", "rec_01_bad_kick.csv", "rec_02.csv"]
    assert truth.spurious == {"rec_01_bad_kick.csv": "bad_kick"}
    assert list(table.floats(control_col)) == [0.0, 20.0, 40.0]
    assert table.find("dt") is not None
    for r in truth.records:
        assert (tmp_path / r.name).exists()


@pytest.mark.parametrize("kind", F.KINDS)
def test_campaign_laws_follow_the_normal_form(kind: str):
    camp = F.Campaign(kind, 31.0, lab=L.Lab(quantity="displacement", pretrigger=0.2))
    mus = F.controls_for(camp, 8, slowdown=4.0)
    x = camp.mu_star - mus
    s2 = np.array([camp.record(float(m), k).truth.sigma2 for k, m in enumerate(mus)])
    e = {"saddle-node": 0.5}.get(kind, 1.0)
    slope = np.polyfit(np.log(x), np.log(-s2), 1)[0]
    assert slope == pytest.approx(e, rel=1e-9)
    period = 1 / np.sqrt(-s2)
    assert period[-1] / period[0] == pytest.approx(4.0, rel=1e-9)
    # the static level: the rest before the kick (no drift, noise or hum)
    quiet = replace(camp, offset=0.0, ramp=0.0, wobble=0.0)
    rest = np.array([quiet.record(float(m), k).y[0] for k, m in enumerate(mus)])
    b = {"subcritical-pitchfork": 1.0}.get(kind, 0.5)
    slope_b = np.polyfit(np.log(x), np.log(rest - camp.static_c), 1)[0]
    assert slope_b == pytest.approx(b, rel=1e-9)


def test_a_fixed_hammer_makes_the_softer_structure_ring_larger():
    camp, _ = F.issue_campaigns()["supercritical-pitchfork"]
    quiet = replace(camp, lab=replace(camp.lab, snr_db=None, hum=0.0, pretrigger=0.0),
                    offset=0.0, ramp=0.0, wobble=0.0)  # fmt: skip
    first = quiet.record(camp.mu0, 0)
    assert np.abs(first.y - first.truth.static).max() == pytest.approx(camp.lab.peak_mm, rel=1e-9)
    late = quiet.record(30.0, 1)
    assert np.abs(late.y - late.truth.static).max() > 1.5 * camp.lab.peak_mm


def test_spurious_records_are_what_their_names_say():
    camp, _ = F.issue_campaigns()["saddle-node"]
    good = camp.record(20.0, 3)
    bad = camp.record(20.0, 3, spurious="bad_kick")
    assert bad.modes.coef[0] == 0.0 and good.modes.coef[0] == 1.0
    assert bad.modes.coef[1:] == good.modes.coef[1:]
    none = camp.record(20.0, 4, spurious="no_ringdown")
    assert np.abs(none.parts["response"]).max() < 1e-6 * np.abs(good.parts["response"]).max()
    clip = camp.record(20.0, 4, spurious="heavy_clipping")
    assert clip.clipped is not None and clip.clipped.mean() > 0.05
    with pytest.raises(ValueError, match="past mu"):
        camp.record(camp.mu_star + 1.0)
    assert math.isfinite(camp.record(41.9).truth.sigma2)


def test_a_lab_in_the_loop_records_where_and_how_it_is_told():
    """``Campaign.record`` at any control, with the advised length and step."""
    camp, _ = F.issue_campaigns()["saddle-node"]
    rec = camp.record(37.25, 5, duration=3.0, dt=1 / 2500)
    assert rec.dt == pytest.approx(1 / 2500) and rec.y.size == 7500
    assert rec.truth.sigma2 == pytest.approx(camp.modes(37.25).f0_hz[0] ** 2 * -4 * math.pi**2)
    x = (camp.mu_star - 37.25) / (camp.mu_star - camp.mu0)
    assert -rec.truth.sigma2 == pytest.approx((2 * math.pi * camp.f1_hz) ** 2 * math.sqrt(x))
    # the same control and index, the same record; another index, other draws
    assert np.array_equal(rec.y, camp.record(37.25, 5, duration=3.0, dt=1 / 2500).y)
    assert not np.array_equal(rec.y, camp.record(37.25, 6, duration=3.0, dt=1 / 2500).y)
