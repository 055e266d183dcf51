"""Calibration of the predictor on random lab plans (a smaller ``bench/calibration.py``).

30 plans per actuation on the Euler beam's exact spectrum (grid step 0.02-0.1, last point 1e-3
to 1e-1 before mu*, relative noise 1e-5 to 1e-3, half of them with static data). If the 95 %
interval is calibrated, the number of plans it covers is Binomial(30, 0.95) per actuation and
Binomial(90, 0.95) over all: the test accepts what such a variable reaches with probability
>= 0.999 (the band is computed below, not typed in). A confident wrong criticality (a named
transition that is wrong) never passes.
"""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import pytest
from scipy import stats

ROOT = Path(__file__).resolve().parents[2]


def _calibration():
    spec = importlib.util.spec_from_file_location("calibration", ROOT / "bench" / "calibration.py")
    assert spec is not None and spec.loader is not None
    mod = importlib.util.module_from_spec(spec)
    sys.modules["calibration"] = mod
    spec.loader.exec_module(mod)
    return mod


@pytest.mark.slow
def test_coverage_binomial_band_and_no_confident_wrong_type() -> None:
    pytest.importorskip("sim.euler_beam")
    cal = _calibration()
    plans = cal.random_plans(30, seed=7, sources=("euler-beam",))
    rows = [cal.run_plan(p) for p in plans]
    lo_one = int(stats.binom.ppf(0.001, 30, 0.95))  # 24: P(X < 24) < 0.001
    lo_all = int(stats.binom.ppf(0.001, 90, 0.95))
    hi_all = int(stats.binom.isf(0.001, 90, 0.95))
    for act in cal.ACTS:
        g = [r for r in rows if r["actuation"] == act]
        covered = sum(r["covered"] for r in g)
        assert covered >= lo_one, (act, covered, [r for r in g if not r["covered"]])
        assert not any(r["confident_wrong"] for r in g), [r for r in g if r["confident_wrong"]]
        right = sum(r["right"] for r in g)
        assert right >= 0.7 * len(g), (act, right)
    total = sum(r["covered"] for r in rows)
    assert lo_all <= total <= hi_all
