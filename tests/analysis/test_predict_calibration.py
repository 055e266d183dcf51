"""Calibration of the predictor on random lab plans (a smaller ``bench/calibration.py``).

30 plans per source (Euler beam's exact spectrum, normal-form records) and actuation (grid step
0.02-0.1, last point 1e-3 to 1e-1 before mu*, relative noise 1e-5 to 1e-3, half of them with
static data). If the 95 % interval is calibrated, the number of plans it covers is
Binomial(30, 0.95) per group and Binomial(180, 0.95) over all: the test accepts what such a
variable reaches with probability >= 0.999, on both sides (the bands are computed below, not
typed in). An interval far wider than its errors covers every plan and passes a coverage band
of 30 plans, so the sharpness is tested as well: a calibrated interval with Gaussian errors puts
the error below a fifth of the half-width in 30.5 % of plans (P(|Z| < 0.392)); the old
truncation spread, which counted the noise twice and took fits with fewer terms as neighbours,
did so in most beam plans (median |error| / half-width 0.04-0.10). A confident wrong
criticality (a named transition that is wrong) never passes.
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
@pytest.mark.xfail(strict=True, reason=(
    "sharpness lost on the imperfect-pitchfork engine: 103 of 180 plans have errors below a "
    "fifth of the half-width (a calibrated interval allows 74; 100 before the fold's interval "
    "held one more correction's): the intervals that reach the earliest fold an imperfection "
    "allows are wider than the perfect plans need; imperfect columns the records cannot tell "
    "from perfect ones (softening gain < 1) are 11-560 half-widths late without it"))
def test_coverage_binomial_band_sharpness_and_no_confident_wrong_type() -> None:
    pytest.importorskip("sim.euler_beam")
    cal = _calibration()
    per = 30
    plans = cal.random_plans(per, seed=7)
    rows = [cal.run_plan(p) for p in plans]
    n = len(rows)
    lo_one = int(stats.binom.ppf(0.001, per, 0.95))  # 24: P(X < 24) < 0.001
    lo_all = int(stats.binom.ppf(0.001, n, 0.95))
    hi_all = int(stats.binom.isf(0.001, n, 0.95))
    for src in cal.SOURCES:
        for act in cal.ACTS:
            g = [r for r in rows if r["source"] == src and r["actuation"] == act]
            assert len(g) == per
            covered = sum(r["covered"] for r in g)
            assert covered >= lo_one, (src, act, covered, [r for r in g if not r["covered"]])
            wrong = [r for r in g if r["confident_wrong"]]
            assert not wrong, wrong
            if src == "euler-beam":
                right = sum(r["right"] for r in g)
                assert right >= 0.7 * len(g), (act, right)
    total = sum(r["covered"] for r in rows)
    assert lo_all <= total <= hi_all, (total, lo_all, hi_all)
    # sharpness: errors below a fifth of the half-width no more often than a calibrated
    # interval allows (Binomial(n, 0.305), upper 0.001 tail)
    p_small = float(2 * stats.norm.cdf(stats.norm.ppf(0.975) / 5) - 1)
    small = sum(cal.error_over_half_width(r) < 0.2 for r in rows)
    assert small <= int(stats.binom.isf(0.001, n, p_small)), (small, n)


@pytest.mark.parametrize(
    "step, stop, rel, seed",
    [
        (0.041014660675814496, 0.006800949391932209, 1.1012595518639363e-05, 605075501),
        (0.04343327007503956, 0.008617874565420106, 3.7402225130126494e-05, 1107617160),
    ],
)
def test_a_fold_bias_only_larger_windows_reveal_is_covered(
    step: float, stop: float, rel: float, seed: int
) -> None:
    """Two lab plans on the beam's fold (calibration seed 2026, plans 53 and 89): the chosen fit
    (2 corrections, nearest 8 points) sits 16 and 5 standard deviations below mu*, and every
    smaller window shares the points nearest mu* that set this truncation error (plan 53: -16.6
    to -15.8 standard deviations for 5-8 points), so with only smaller windows and one more term
    as neighbours the interval missed mu*; the windows one and two points larger show it."""
    pytest.importorskip("sim.euler_beam")
    cal = _calibration()
    plan = cal.Plan(0, "euler-beam", "asymmetric", step, stop, rel, False, seed)
    r = cal.run_plan(plan)
    assert r["transition"] == "saddle-node"
    assert r["covered"], r
    assert cal.error_over_half_width(r) > 0.2, r  # covered, not by a blown-up interval


@pytest.mark.parametrize(
    "step, stop, rel, seed",
    [
        (0.04820090296227639, 0.022439883978220932, 0.000774879566443594, 2100530763),
        (0.05819618512587793, 0.0027513082311421415, 0.0009962345367368255, 1595227025),
        (0.1, 0.01, 1e-3, 6017),
        (0.1, 0.001, 1e-3, 6017),
    ],
)
def test_a_fold_in_a_pitchforks_disguise_is_not_named_and_stays_covered(
    step: float, stop: float, rel: float, seed: int
) -> None:
    """Two noisy lab plans on the beam's fold without static data (calibration seed 2026, 300
    plans per group: 131 and 198) were named ``pitchfork`` at probability 0.995 and 0.989, mu*
    6e-3 and 1.3e-3 late with the interval past mu*: the pitchfork law's secondary fold sat
    6 and 9.7 of its distances before the last record, where its series in z is a fold's, and
    a fold law with as many parameters fitted within 8.4 and 5.2 of it. Two cells of the
    predictor's atlas (step 0.1, noise 1e-3, stop 0.01 and 0.001): the same, with the secondary
    fold 9.3 and 2.8 of its distances before the last record and the fold law 13.4 and 20.3
    behind (its truncated series misfits the window 0.6 wide as well). The type is withheld
    and the fold's own mu*, earlier, stays inside the interval."""
    pytest.importorskip("sim.euler_beam")
    cal = _calibration()
    r = cal.run_plan(cal.Plan(0, "euler-beam", "asymmetric", step, stop, rel, False, seed))
    assert r["transition"] == "undetermined", r
    assert "fold_indistinct" in r["flags"].split(), r
    assert r["covered"] and not r["confident_wrong"], r
