"""A `sweep` atlas on records written as a lab writes them: semicolon CSV with a time column in
milliseconds rounded to 6 significant digits, NPY (t in ms, w), the control in degrees of end
rotation. The cell reads them through the service's one reader and predicts mu* in degrees."""

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
            (folder / f"run{k}.csv").write_text("time [ms];deflection [mm]\n" + "\n".join(lines))
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
