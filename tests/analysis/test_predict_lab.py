"""The predictor on sweeps as a lab plans them: a fixed grid of control values, stopped early.

Reference: the Euler beam (``sim.euler_beam``, written independently of the analysis): its
``bifurcation`` gives mu* and the transition (symmetric: subcritical pitchfork at mu* = 2, with
U_A folding at mu2* = 2.0119), ``spectrum`` the exact sigma^2 and ``equilibrium`` the static
deflection at X = 1/4. Relative Gaussian noise is added to sigma^2 (std given), absolute noise
to w. The comparison is the paper's two-point rule on the same data.
"""

from __future__ import annotations

import functools
import math

import numpy as np
import pytest

from service.analysis.classify import MIN_T_RATIO, classify
from service.analysis.errors import ParameterError
from service.analysis.predict import paper_rule, predict

pytest.importorskip("sim.euler_beam")

A_OF = {"saddle-node": 0.25, "subcritical-pitchfork": 0.5, "supercritical-pitchfork": 0.5}


@functools.cache
def _exact(
    act: str, step: float, stop: float
) -> tuple[float, str, np.ndarray, np.ndarray, np.ndarray]:
    """Grid of steps ``step`` ending ``stop`` before mu* (first point >= 0), exact data."""
    from sim.euler_beam import bifurcation, equilibrium, spectrum

    b = bifurcation(act)
    last = b.mu_star - stop
    mu = last - step * np.arange(int(math.floor(last / step + 1e-9)) + 1)[::-1]
    mu[np.abs(mu) < 1e-9] = 0.0
    s2 = np.array([spectrum(act, m, "U_A", modes=1).sigma2[0] for m in mu])
    w = np.array([equilibrium(act, m, "U_A").w_quarter for m in mu])
    return b.mu_star, b.transition, mu, s2, w


def lab_sweep(act: str, step: float, stop: float, rel: float = 1e-4, seed: int = 0) -> dict:
    mu_star, kind, mu, s2, w = _exact(act, step, stop)
    rng = np.random.default_rng(seed)
    sd = rel * np.abs(s2)
    return {
        "mu": mu, "sigma2": s2 + sd * rng.standard_normal(mu.size), "sigma2_std": sd,
        "w": w + 1e-6 * rng.standard_normal(mu.size), "mu_star": mu_star, "kind": kind,
    }  # fmt: skip


@pytest.mark.parametrize("stop", [0.05, 0.01, 0.002])
def test_symmetric_fixed_grid_is_a_pitchfork_and_beats_the_rule(stop: float) -> None:
    """Steps of 0.05 stopping 0.05 / 0.01 / 0.002 before mu* = 2 (the issue's plans): a
    pitchfork, the interval covers mu*, and the error is below the paper's rule's (measured
    before the secondary-fold law: supercritical or undetermined, errors 1e-2 and 1.7e-3, the
    interval missing at stop 0.05).

    At stop 0.05 the last record lies 3.9 secondary-fold distances (0.0119) before mu*, where
    no record sees the pitchfork's own regime (x < delta), and without static data a fold law
    with as many parameters fits within 7.9 of it (likelihood ratio 51 < 1e6): the type is
    withheld (``fold_indistinct``), never a fold named; of 5 noise seeds the probabilities
    alone already left 2 undetermined (saddle-node 0.57 and 0.48). From stop 0.01 (0.8
    distances) the fold law loses by > 7000."""
    d = lab_sweep("symmetric", 0.05, stop)
    p = predict(d["mu"], d["sigma2"], sigma2_std=d["sigma2_std"])
    if stop == 0.05:
        assert p.transition == "undetermined", p.probabilities
        assert "fold_indistinct" in {f.code for f in p.flags}
    else:
        assert p.transition == "pitchfork", p.probabilities
    lo, hi = p.mu_star_interval
    assert lo <= d["mu_star"] <= hi
    rule = paper_rule(d["mu"], d["sigma2"], 0.5)
    err, rerr = abs(p.mu_star - d["mu_star"]), abs(rule.mu_star - d["mu_star"])
    assert err < 0.2 * rerr, (err, rerr)
    assert err < {0.05: 3e-3, 0.01: 3e-4, 0.002: 5e-5}[stop]


@pytest.mark.slow
@pytest.mark.parametrize("stop", [0.05, 0.01, 0.002])
def test_symmetric_fixed_grid_with_static_data_is_subcritical(stop: float) -> None:
    d = lab_sweep("symmetric", 0.05, stop)
    p = predict(d["mu"], d["sigma2"], sigma2_std=d["sigma2_std"], w_static=d["w"],
                w_static_std=1e-6)  # fmt: skip
    assert p.transition == "subcritical-pitchfork", p.probabilities
    lo, hi = p.mu_star_interval
    assert lo <= d["mu_star"] <= hi


@pytest.mark.parametrize("stop", [0.3, 0.2, 0.125, 0.05])
def test_symmetric_early_stop_is_never_called_supercritical(stop: float) -> None:
    """A snapping strip called supercritical is the worst answer: an early stop (T/T0 from 1.7
    to 3.6) with static data is never named supercritical, nor given it with probability
    >= 0.9; below T/T0 = MIN_T_RATIO (2.75) no type is named."""
    d = lab_sweep("symmetric", 0.05, stop)
    c = classify(d["mu"], d["sigma2"], sigma2_std=d["sigma2_std"], w_static=d["w"],
                 w_static_std=1e-6)  # fmt: skip
    assert c.transition in ("subcritical-pitchfork", "pitchfork", "undetermined")
    assert c.probabilities["supercritical-pitchfork"] < 0.9
    if math.sqrt(d["sigma2"][0] / d["sigma2"][-1]) < MIN_T_RATIO:
        assert c.transition == "undetermined"
        assert "slowdown_not_reached" in {f.code for f in c.flags}


@pytest.mark.slow
@pytest.mark.parametrize("act", ["asymmetric", "antisymmetric"])
def test_other_actuations_on_fixed_grids_beat_the_rule(act: str) -> None:
    for stop in (0.05, 0.01):
        d = lab_sweep(act, 0.05, stop)
        p = predict(d["mu"], d["sigma2"], sigma2_std=d["sigma2_std"])
        assert p.transition in (d["kind"], "pitchfork" if "pitchfork" in d["kind"] else "")
        lo, hi = p.mu_star_interval
        assert lo <= d["mu_star"] <= hi
        rule = paper_rule(d["mu"], d["sigma2"], A_OF[d["kind"]])
        assert abs(p.mu_star - d["mu_star"]) < abs(rule.mu_star - d["mu_star"])


def test_prepared_sweep_gives_the_same_prediction() -> None:
    from service.analysis.classify import prepare_sweep

    d = lab_sweep("antisymmetric", 0.05, 0.01)
    sw = prepare_sweep(d["mu"], d["sigma2"], sigma2_std=d["sigma2_std"])
    p1 = predict(d["mu"], d["sigma2"], sigma2_std=d["sigma2_std"])
    p2 = predict(sw)
    assert p1.mu_star == p2.mu_star and p1.mu_star_interval == p2.mu_star_interval
    assert classify(sw).transition == p1.transition


def test_parameter_errors_carry_the_field() -> None:
    d = lab_sweep("antisymmetric", 0.05, 0.01)
    with pytest.raises(ParameterError) as e:
        predict(d["mu"], -d["sigma2"])
    assert e.value.parameter == "sigma2"
    with pytest.raises(ParameterError) as e:
        predict(d["mu"][::-1], d["sigma2"])
    assert e.value.parameter == "mu"
    with pytest.raises(ParameterError) as e:
        predict(d["mu"], d["sigma2"], level=1.5)
    assert e.value.parameter == "level" and e.value.value == 1.5


def test_noise_free_fold_gives_an_interval_not_an_error() -> None:
    """Exact sigma^2 of a fold (zero profile widths): the mixture's quantiles still exist."""
    mu = np.linspace(0.0, 1.6, 6)
    p = predict(mu, -np.sqrt(2.0 - mu))
    lo, hi = p.mu_star_interval
    assert lo <= 2.0 <= hi
    assert abs(p.mu_star - 2.0) < 1e-6


def _calibration_plan(**kw: object) -> dict:
    """One plan of bench/calibration.py run through it (its data and predict)."""
    import importlib.util
    import sys
    from pathlib import Path

    path = Path(__file__).resolve().parents[2] / "bench" / "calibration.py"
    spec = importlib.util.spec_from_file_location("calibration", path)
    assert spec is not None and spec.loader is not None
    cal = importlib.util.module_from_spec(spec)
    sys.modules["calibration"] = cal
    spec.loader.exec_module(cal)
    return cal.run_plan(cal.Plan(source="euler-beam", actuation="asymmetric", **kw))


def test_no_type_named_while_the_other_exponent_keeps_five_percent() -> None:
    """A fold plan (step 0.082, stop 0.035 before it, noise 1.4e-5, no static data) where the
    saddle-node wins at 0.94 and the pitchfork keeps 0.06: while the other exponent keeps
    >= 5 % the type is withheld (flag), never named wrong, and the interval covers mu*. (The
    saddle-node law also needs all three corrections there and wins by less than a likelihood
    ratio of 1e6: the classification itself withholds it, ``exponent_undecided``.)"""
    row = _calibration_plan(index=51, step=0.08172296303253954, stop=0.03471226328353402,
                            rel=1.4346494951659886e-05, with_w=False, seed=455565353)  # fmt: skip
    assert row["covered"]
    assert row["transition"] == "undetermined"
    assert {"type_withheld", "exponent_undecided"} & set(row["flags"].split())
    assert 0.9 <= row["p_true"] <= 0.95  # the fold favoured, the rival kept above 5 %


def test_coarse_noisy_fold_named_a_pitchfork_before_is_withheld() -> None:
    """A coarse, noisy asymmetric plan (step 0.085, stop 0.0057 before the fold, noise 9e-4,
    no static data) was called a pitchfork at probability 0.93: the pitchfork law's secondary
    fold is pinned at its limit (a fold in disguise), the type is withheld, the interval covers
    mu*."""
    row = _calibration_plan(index=14, step=0.08530704830552606, stop=0.005739741625910706,
                            rel=0.000906767130229382, with_w=False, seed=1266997513)  # fmt: skip
    assert row["covered"]
    assert row["transition"] == "undetermined"
    assert "fold_indistinct" in row["flags"]
    assert 0.05 <= row["p_true"] < 0.1  # the comparison alone favours the pitchfork


def test_a_fold_with_static_data_far_from_the_disguise_s_fold_is_not_named() -> None:
    """A held-out calibration plan (seed 7, plan 152: step 0.094, stop 0.0036 before the fold,
    noise 6.3e-4, static data given): the subcritical pitchfork in the conformal variable beat
    the fold by 15.4 (-2 log L + BIC penalty, probability 0.9996), its secondary fold 5.7e-4
    beyond its mu*, the last record 9.4 times that before it; named with the interval wholly
    past mu* (1.7e-3 to 5.7e-3 late). Static data do not tell them apart there: in the
    conformal variable the static law also goes as sqrt(x) far from delta (b = 0.446 +-
    0.017). Now, as without static data, only a decisive ratio names the type."""
    row = _calibration_plan(index=152, step=0.09423972626320702, stop=0.0036044233608473197,
                            rel=0.0006268611081527508, with_w=True, seed=1461281404)  # fmt: skip
    assert row["transition"] == "undetermined", row
    assert "fold_indistinct" in row["flags"]
    assert row["covered"]


def test_fold_in_disguise_is_not_called_a_pitchfork() -> None:
    """A coarse noisy fold plan (a calibration plan: step 0.095, stop 0.0058 before mu*, noise
    5.6e-4, no static data): the pitchfork law in the conformal variable fits it best by pinning
    its secondary fold at the nearest it allows -- a branch that simply ends, i.e. a fold. The
    type is then withheld (flag ``fold_indistinct``) where it was called a pitchfork at
    0.99995; the symmetric beam's true secondary fold never trips it (test above)."""
    d = lab_sweep("asymmetric", 0.09537325053274796, 0.005772852750816229,
                  rel=0.0005575226606433603, seed=201188064)  # fmt: skip
    c = classify(d["mu"], d["sigma2"], sigma2_std=d["sigma2_std"])
    assert c.probabilities["pitchfork"] > 0.99  # what the comparison alone would say
    assert c.transition == "undetermined"
    assert "fold_indistinct" in {f.code for f in c.flags}
    p = predict(d["mu"], d["sigma2"], sigma2_std=d["sigma2_std"])
    assert p.transition not in ("pitchfork", "subcritical-pitchfork", "supercritical-pitchfork")


@pytest.mark.parametrize(
    ("step", "stop"), [(0.041, 6.8e-3), (0.05, 1e-2), (0.05, 2e-3), (0.08, 3e-2), (0.03, 1e-3)]
)
@pytest.mark.parametrize("given", [True, False])
def test_noise_free_fold_on_a_fixed_grid_is_a_fold(step: float, stop: float, given: bool) -> None:
    """Exact sigma^2 of the beam's fold on lab grids (a simulation from another code: no noise),
    the std given as 1e-9 relative or not given. No law fits a coarse grid within so little
    noise; the noise is then scaled by the misfit of the nearest points (where the laws hold).
    Scaled by the misfit over half the sweep, these were called undetermined or a pitchfork
    (step 0.05, stop 0.002), mu* off by 1e-3 to 5e-3, worse than the paper's rule. Now: never a
    pitchfork, a saddle-node whenever the (tiny) noise is given, and better than the rule (by
    5x or more when the noise is given)."""
    mu_star, _, mu, s2, _ = _exact("asymmetric", step, stop)
    p = predict(mu, s2, sigma2_std=1e-9 * np.abs(s2) if given else None)
    rule = abs(paper_rule(mu, s2, 0.25).mu_star - mu_star)
    assert "pitchfork" not in p.transition
    if given:
        assert p.transition == "saddle-node", [f.code for f in p.flags]
    assert abs(p.mu_star - mu_star) < (0.2 if given else 0.5) * rule


@functools.cache
def _grid_from_zero(act: str, step: float) -> tuple[float, np.ndarray, np.ndarray]:
    """A lab's grid 0, step, 2 step, ... up to mu* - 0.01 with exact sigma^2."""
    from sim.euler_beam import bifurcation, spectrum

    ms = bifurcation(act).mu_star
    mu = np.arange(0.0, ms - 0.01 + 1e-12, step)
    return ms, mu, np.array([spectrum(act, float(m), "U_A", modes=1).sigma2[0] for m in mu])


def _over_seeds(act: str, step: float, rel: float, seeds: int = 20) -> tuple[float, list, int]:
    """(mu*, the predictions, how many cover mu*) of the grid from zero with relative noise
    ``rel`` (std given), one per noise seed."""
    ms, mu, s2 = _grid_from_zero(act, step)
    preds = []
    for seed in range(seeds):
        sd = rel * np.abs(s2)
        y = s2 + sd * np.random.default_rng(seed).standard_normal(mu.size)
        preds.append(predict(mu, y, sigma2_std=sd))
    covered = sum(p.mu_star_interval[0] <= ms <= p.mu_star_interval[1] for p in preds)
    return ms, preds, covered


def test_a_fold_on_a_coarse_grid_far_from_mu_star_is_covered() -> None:
    """The fold on the grid 0, 0.1, ..., 1.7 (the last record 0.082 before mu*; noise 1e-4 with
    its std, no static data): the saddle-node law needs all three corrections on its 7 points
    and is 5e-3 early (15 statistical std); its larger windows go farther below, the smaller
    ones above. The one-sided truncation spread put their allowance below and covered mu* in
    7 of 20 noise seeds; at the truncation limit it now widens both sides (18 of 20; a 95 %
    interval covers 18 or more of 20 in 92 % of draws, 19 or more in 74 %)."""
    ms, preds, covered = _over_seeds("asymmetric", 0.1, 1e-4)
    ours = [abs(p.mu_star - ms) for p in preds]
    rule = [abs(p.baseline.mu_star - ms) for p in preds]
    for p, e, r in zip(preds, ours, rule):
        if e > r:  # worse than the rule only with a flag that says why
            assert {f.code for f in p.flags} - {"no_static_data"}, p.flags
    assert covered >= 18, covered
    assert {p.transition for p in preds} <= {"saddle-node", "undetermined"}
    assert np.median(ours) < 0.3 * np.median(rule)  # 5e-3 against 2.3e-2


def test_a_fold_read_as_a_pitchfork_far_from_mu_star_is_not_named() -> None:
    """The same grid with noise 3e-4 (seed 17): the pitchfork law with three corrections on the
    nearest 7 points beats the fold's by 7.9 (-2 log L) and was named at probability 0.98 with
    mu* 0.041 late and its interval past mu*, at T/T0 = 2.77. A series at its limit far from
    mu* follows either exponent: without static data only a decisive ratio names the type."""
    ms, mu, s2 = _grid_from_zero("asymmetric", 0.1)
    sd = 3e-4 * np.abs(s2)
    y = s2 + sd * np.random.default_rng(17).standard_normal(mu.size)
    p = predict(mu, y, sigma2_std=sd)
    assert p.probabilities["pitchfork"] > 0.95  # what the comparison alone says
    assert p.transition == "undetermined"
    assert "exponent_undecided" in [f.code for f in p.flags]
    lo, hi = p.mu_star_interval
    assert lo <= ms <= hi


def test_a_fold_on_a_fine_grid_with_precise_records_is_covered() -> None:
    """The grid 0, 0.03, ..., the last record 0.012 before the fold, noise 1e-5: two corrections
    on any window of its nearest 5-10 points put mu* 1.8e-5 early (15 statistical std, the same
    on exact data: the nearest points set the truncation bias), and so does one more term; the
    second term beyond (the (n, K + 2) neighbour) reveals it. Covered in 6 of 20 noise seeds
    before it was consulted."""
    ms, preds, covered = _over_seeds("asymmetric", 0.03, 1e-5)
    for p in preds:
        assert abs(p.mu_star - ms) < 0.05 * abs(p.baseline.mu_star - ms)  # 2e-5 against 2e-3
    assert covered >= 18, covered
