"""A `sweep` atlas on records written as a lab writes them: semicolon CSV with a time column in
milliseconds (its unit unnamed) rounded to 6 significant digits, NPY (t in ms, w), the control
in degrees of end rotation. The cell reads them through the service's one reader and predicts
mu* in degrees."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from service.atlas import load_spec, run_atlas

DL = 1e-2
MU_STAR_BEAM = 1.7817760411567123  # the Euler beam's fold (closed-form root, paper: 1.782)


def _write_campaign(folder: Path) -> float:
    from sim import simulate
    from sim.scene import Scene

    rows = []
    for k, mu in enumerate([0.0, 1.0, 1.4, 1.6, 1.7, 1.74, 1.76, 1.77]):
        sig = simulate(Scene(actuation="asymmetric", mu=mu, snr_db=40, seed=k, duration=60.0,
                             dt=0.02), "euler-beam")  # fmt: skip
        deg = math.degrees(mu * math.sqrt(DL))
        if k % 2:
            np.save(folder / f"run{k}.npy", np.column_stack([sig.t * 1e3, sig.w]))
            rows.append(f"data/run{k}.npy,{deg:.6f}")
        else:
            lines = [f"{t * 1e3:.6g};{w:.6g}" for t, w in zip(sig.t, sig.w)]
            # no unit on the time column: the NPY files cannot name theirs, and records that
            # name different units (ms, none) are refused, as by `snapwarn sweep`
            (folder / f"run{k}.csv").write_text("time;deflection [mm]\n" + "\n".join(lines))
            rows.append(f"data/run{k}.csv,{deg:.6f}")
    (folder.parent / "manifest.csv").write_text("path,control\n" + "\n".join(rows) + "\n")
    return math.degrees(MU_STAR_BEAM * math.sqrt(DL))


@pytest.mark.slow  # ~25 s on a loaded machine (8 simulated records, one sweep analysis)
def test_sweep_atlas_on_lab_files_in_lab_units(tmp_path: Path) -> None:
    (tmp_path / "data").mkdir()
    true_deg = _write_campaign(tmp_path / "data")
    (tmp_path / "atlas.yaml").write_text(
        "kind: sweep\ncells:\n"
        f"  - {{manifest: manifest.csv, mu_star_true: {true_deg!r}, "
        "transition_true: saddle-node}\n"
        "  - {manifest: missing.csv}\n")
    res = run_atlas(load_spec(tmp_path / "atlas.yaml"), serial=True)
    good, bad = res.rows
    assert good.status == "ok", good.error
    r = good.results
    assert r["responses"] == 8 and r["transition"] == "saddle-node" and r["transition_correct"]
    assert r["mu_star"] == pytest.approx(true_deg, rel=1e-2)  # degrees, not mu: ~10.2
    assert r["error"] == pytest.approx(r["mu_star"] - true_deg, abs=1e-12)
    assert r["mu_star_lo"] <= r["mu_star"] <= r["mu_star_hi"]
    assert r["paper_mu_star"] == pytest.approx(true_deg, rel=1e-2)
    assert bad.status == "failed" and bad.error["parameter"] == "manifest"
    assert res.summary.ok == 1 and res.summary.failed == 1


def test_the_atlas_reads_a_manifest_as_the_cli_does(tmp_path: Path) -> None:
    """One reader for manifests: the files' column may be named 'file', a record naming its
    time unit (ms) beside one naming none is refused as `snapwarn sweep` refuses it, and
    records in s and ms are brought to one unit (their steps agree)."""
    from service.analysis.errors import ParameterError
    from service.atlas.cells import _read_manifest

    t = np.arange(64) * 1e-3
    w = np.cos(40 * t)
    rows = [(float(x), float(y)) for x, y in zip(t, w, strict=True)]
    (tmp_path / "a.csv").write_text("t [ms],w\n" + "".join(f"{x * 1e3:g},{y!r}\n" for x, y in rows))
    (tmp_path / "b.csv").write_text("t [s],w\n" + "".join(f"{x:g},{y!r}\n" for x, y in rows))
    np.save(tmp_path / "c.npy", np.column_stack([t * 1e3, w]))
    (tmp_path / "m1.csv").write_text("file;control\na.csv;1\nb.csv;2\n")
    records, names = _read_manifest(str(tmp_path / "m1.csv"))
    assert names == ["a.csv", "b.csv"]
    assert records[0][1] == pytest.approx(records[1][1], rel=1e-9)  # one time base
    (tmp_path / "m2.csv").write_text("path,control\na.csv,1\nc.npy,2\n")
    with pytest.raises(ParameterError, match="time unit"):
        _read_manifest(str(tmp_path / "m2.csv"))
    (tmp_path / "m3.csv").write_text("where,control\na.csv,1\n")
    with pytest.raises(ParameterError, match="columns found"):
        _read_manifest(str(tmp_path / "m3.csv"))
