"""The compiled profile-likelihood kernels against a slow numpy reference.

Reference: ``-2 log L`` of a weighted linear least-squares fit by ``numpy.linalg.lstsq`` (SVD,
independent of the kernels' Householder QR), the unknown-variance form, the penalty on
corrections that exceed ``RHO`` of the leading term, and, for the conformal variable, a brute
force over a fine grid of the fold parameter.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from service.analysis.predictor._kernels.fold import nll_exponent_rows, nll_rows
from service.analysis.predictor._kernels.laws import REL_FLOOR, RHO, nll_fixed_u
from service.analysis.predictor.likelihood import _LOGU, _Comp, _pack


def ref_comp(ms: float, u: float, mu: np.ndarray, c: _Comp, x_last: float) -> float:
    x = np.maximum(ms - mu, 1e-300)
    if c.conformal and u > 0:
        delta = x_last / u
        x = 2 * x / (1 + np.sqrt(1 + x / delta))
    A = x[:, None] ** c.exps[None, :] * c.wt[:, None]
    A = A / np.linalg.norm(A, axis=0)
    b = c.y * c.wt
    coef, *_ = np.linalg.lstsq(A, b, rcond=None)
    r = b - A @ coef
    rss = float(r @ r)
    n, k = A.shape
    if c.known:
        out = rss
    else:
        floor = n * (REL_FLOOR * max(float(np.max(np.abs(b))), 1e-300)) ** 2
        out = max(n - k, 1) * math.log(max(rss, floor) / n)
    if c.lead and k > c.lead_col + 1:
        terms = A * coef[None, :]
        lead = terms[:, c.lead_col]
        corr = terms[:, c.lead_col + 1 :].sum(axis=1)
        with np.errstate(divide="ignore", invalid="ignore"):
            if c.signed:
                ratio = np.where(lead > 0, np.abs(corr) / lead, np.inf)
            else:
                ratio = np.where(lead != 0, np.abs(corr / lead), np.inf)
        out += 1e4 * min(max(float(np.max(ratio)) - RHO, 0.0), 1e3) ** 2
    return out


def ref_total(ms: float, u: float, mu_w: np.ndarray, comps: list[_Comp]) -> float:
    x_last = max(ms - float(mu_w[-1]), 1e-300)
    return sum(ref_comp(ms, u, mu_w if c.mu is None else c.mu, c, x_last) for c in comps)


def _data(seed: int, n: int = 14):
    rng = np.random.default_rng(seed)
    mu = np.sort(rng.uniform(0.0, 1.9, n))
    x = 2.0 - mu
    y = 30 * x * (1 + 0.3 * x) * (1 + 1e-3 * rng.standard_normal(n))
    w = 0.2 + 0.1 * x - 0.05 * x**2 + 1e-5 * rng.standard_normal(n)
    return mu, y, w


@pytest.mark.parametrize("seed", range(4))
@pytest.mark.parametrize("known", [True, False])
def test_plain_laws_match_the_reference(seed: int, known: bool) -> None:
    mu, y, w = _data(seed)
    comps = [
        _Comp(y, 1.0 / (1e-3 * y), np.array([1.0, 2.0, 3.0]), known, True),
        _Comp(w, np.full(w.size, 1e5), np.array([0.0, 1.0, 2.0]), known, True, 1, False, mu),
        _Comp(y, 1.0 / (1e-3 * y), np.array([0.5, 1.0, 1.7]), known, False),  # not arithmetic
    ]
    ms = mu[-1] + np.geomspace(1e-4, 3.0, 9)
    got = nll_fixed_u(ms, 0.0, *_pack(mu, comps), float(mu[-1]))
    want = np.array([ref_total(m, 0.0, mu, comps) for m in ms])
    np.testing.assert_allclose(got, want, rtol=1e-7, atol=1e-7)


@pytest.mark.parametrize("seed", range(3))
def test_conformal_law_at_fixed_fold_matches_the_reference(seed: int) -> None:
    mu, y, _ = _data(seed)
    comps = [_Comp(y, 1.0 / (1e-3 * y), np.array([1.0, 2.0]), True, True, conformal=True)]
    ms = mu[-1] + np.geomspace(1e-3, 1.0, 7)
    for u in (1e-3, 0.3, 4.0):
        got = nll_fixed_u(ms, u, *_pack(mu, comps), float(mu[-1]))
        want = np.array([ref_total(m, u, mu, comps) for m in ms])
        np.testing.assert_allclose(got, want, rtol=1e-7, atol=1e-7)


def test_fold_profile_reaches_the_brute_force_minimum() -> None:
    """The kernel's profiled minimum over the fold parameter is at or below a 400-point brute
    force (and never below the true minimum: it is a value of the same function)."""
    from sim.euler_beam import spectrum

    mu = np.arange(1.5, 1.96, 0.05)
    y = np.array([-spectrum("symmetric", m, "U_A", modes=1).sigma2[0] for m in mu])
    comps = [_Comp(y, 1.0 / (1e-4 * y), np.array([1.0, 2.0, 3.0]), True, True, conformal=True)]
    ms = np.array([1.995, 2.0, 2.005])
    got, u = nll_rows(ms, *_pack(mu, comps), float(mu[-1]), _LOGU, True)
    grid = np.exp(np.linspace(_LOGU[0], _LOGU[-1], 400))
    for m, g, ub in zip(ms, got, u, strict=True):
        brute = min(ref_total(m, uu, mu, comps) for uu in [0.0, *grid])
        assert g <= brute * (1 + 1e-6) + 1e-6
        assert g == pytest.approx(ref_total(m, ub, mu, comps), rel=1e-7, abs=1e-7)
    # the secondary fold is found: delta = (mu* - mu_last) / u ~ mu2* - mu* = 0.0119 at mu* = 2
    delta = (2.0 - mu[-1]) / u[1]
    assert 0.005 < delta < 0.03


def test_fold_scan_walk_bounds_and_finds_the_same_lowest_point() -> None:
    """The scan's walk over the fold parameter's grid (continued from the previous mu*) is
    the whole grid's minimum from a cold start and never below it from any start; along a
    scan of the symmetric beam it finds the whole grid's lowest mu* with the same value (far
    from it the walk may stay in a worse basin of u: measured once in 40 points, 4.4e5
    against 3.4e5 at a minimum of 168)."""
    from service.analysis.predictor._kernels.fold import _profile_u, _profile_u_walk
    from service.analysis.predictor._kernels.laws import _work
    from sim.euler_beam import spectrum

    mu = np.arange(1.5, 1.96, 0.05)
    y = np.array([-spectrum("symmetric", m, "U_A", modes=1).sigma2[0] for m in mu])
    comps = [_Comp(y, 1.0 / (1e-4 * y), np.array([1.0, 2.0, 3.0]), True, True, conformal=True)]
    D, E, M = _pack(mu, comps)
    WK, RK = _work(D, M)
    last = float(mu[-1])
    j = -1
    whole, walk = [], []
    for m in last + np.geomspace(1e-4, 1.0, 40):
        v_whole, _ = _profile_u(m, D, E, M, last, _LOGU, WK, RK, False)
        cold, _ = _profile_u_walk(m, D, E, M, last, _LOGU, WK, RK, -1)
        assert cold == v_whole
        for j0 in range(_LOGU.size):
            assert _profile_u_walk(m, D, E, M, last, _LOGU, WK, RK, j0)[0] >= v_whole
        v, j = _profile_u_walk(m, D, E, M, last, _LOGU, WK, RK, j)
        whole.append(v_whole)
        walk.append(v)
    assert np.all(np.array(walk) >= np.array(whole))
    assert int(np.argmin(walk)) == int(np.argmin(whole))
    assert min(walk) == min(whole)


def _precise_symmetric(rel: float = 1e-6, n: int = 16):
    """The symmetric beam's exact sigma^2 at 20 points approaching mu* = 2 geometrically, with
    relative noise ``rel``: the nearest ``n`` as a conformal component with two corrections
    (precise data: the profile over the fold parameter is a valley ~1e-4 wide in log u)."""
    from sim.euler_beam import spectrum

    mu = 2.0 - np.geomspace(0.999 * 2.0, 1e-5, 20)
    s2 = np.array([spectrum("symmetric", m, "U_A", modes=1).sigma2[0] for m in mu])
    rng = np.random.default_rng(11)
    y = -s2 * (1 + rel * rng.standard_normal(mu.size))
    c = _Comp(y[-n:], 1.0 / (rel * np.abs(y[-n:])), np.array([1.0, 2.0, 3.0]), True, True,
              conformal=True)  # fmt: skip
    return mu[-n:], [c]


def test_fold_parameter_is_refined_to_the_valley_floor_of_precise_data() -> None:
    """On precise data the refined profile over u equals the reference's minimum (scipy's
    bounded Brent to 1e-10 in log u, around the kernel's optimum) to 1e-3 in -2 log L: the
    valley is ~1e-4 wide in log u, and a refinement to 1e-3 in log u (the tolerance before)
    left errors of 10-80 that varied from one mu* to the next and broke the intervals."""
    from scipy import optimize

    mu, comps = _precise_symmetric()
    last = float(mu[-1])
    ms = 2.0 + np.array([-4e-11, 0.0, 7e-12, 4e-11, 1e-9])
    got, u = nll_rows(ms, *_pack(mu, comps), last, _LOGU, True)
    for m, g, ub in zip(ms, got, u, strict=True):
        lu = math.log(ub)
        res = optimize.minimize_scalar(
            lambda v, m=m: ref_total(m, math.exp(v), mu, comps),
            bounds=(lu - 0.01, lu + 0.01), method="bounded", options={"xatol": 1e-10},
        )  # fmt: skip
        assert g <= res.fun + 1e-3
        assert g >= res.fun - 1e-3 - 1e-9 * abs(res.fun)


def test_warm_fold_parameter_equals_the_cold_search() -> None:
    """Along the small steps of a minimisation over mu*, the fold parameter refined from the
    previous step's optimum (:func:`_profile_u_warm`) gives the cold search's value (whole
    grid and refinement) to 1e-3 in -2 log L (both within that of the valley's floor), on
    precise and on noisier data; so do larger steps (the optimum followed beyond the first
    bracket) and steps far past mu* (where the precise data's fold parameter is pinned at its
    range's end)."""
    from service.analysis.predictor._kernels.fold import _profile_u_from, _profile_u_warm
    from service.analysis.predictor._kernels.laws import _work

    for rel in (1e-6, 1e-3):
        mu, comps = _precise_symmetric(rel)
        D, E, M = _pack(mu, comps)
        WK, RK = _work(D, M)
        last = float(mu[-1])
        t0 = math.log(2.0 - last)
        j, lu = -1, math.nan
        # (between, where the profile over u has two basins, a warm start follows its own as
        # the grid's descent from the previous index did: at t0 + 0.2 its value is 3.8e10
        # where the whole grid's is 3.4e10, both far from the minimum's 30)
        steps = [-2e-3, -1e-3, -1e-4, -1e-5, -1e-6, 0.0, 1e-6, 1e-4, 2e-3, 0.05, 0.02, -0.05,
                 0.0, 1.0, 2.0, 3.0, 2.5]  # fmt: skip
        for t in t0 + np.array(steps):
            m = last + math.exp(t)
            cold = _profile_u_from(m, D, E, M, last, _LOGU, WK, RK, True, -1)[0]
            if j < 0:
                v, _, j, lu = _profile_u_from(m, D, E, M, last, _LOGU, WK, RK, True, -1)
            else:
                v, _, j, lu = _profile_u_warm(m, D, E, M, last, _LOGU, WK, RK, j, lu)
            assert v == pytest.approx(cold, rel=1e-9, abs=1e-3)


@pytest.mark.parametrize("conformal", [False, True])
def test_exponent_rows_equal_one_exponent_at_a_time(conformal: bool) -> None:
    """``nll_exponent_rows`` (every exponent of a grid at one mu* in one call) against
    ``nll_rows`` called with each exponent's own packed component."""
    rng = np.random.default_rng(3)
    mu = np.sort(rng.uniform(0.0, 1.9, 14))
    x = 2.0 - mu
    w = 0.3 + 1.2 * np.sqrt(x) * (1 + 0.1 * x) + 1e-4 * rng.standard_normal(mu.size)
    grid = np.linspace(0.25, 1.9, 12)

    def comp(b: float) -> _Comp:
        return _Comp(w, np.full(mu.size, 1e4), np.array([0.0, b, 2 * b]), True, True, 1,
                     False, conformal=conformal)  # fmt: skip

    D, _, M = _pack(mu, [comp(grid[0])])
    rows = np.array([comp(b).exps for b in grid])
    got = nll_exponent_rows(2.0, D, rows, M, float(mu[-1]), _LOGU)
    ref = [float(nll_rows(np.array([2.0]), *_pack(mu, [comp(b)]), float(mu[-1]), _LOGU)[0][0])
           for b in grid]  # fmt: skip
    np.testing.assert_allclose(got, ref, rtol=1e-12, atol=1e-12)
    assert np.ptp(got) > 1.0  # the exponents matter: a grid of distinct values


def test_brent_step_minimises_as_scipy_fminbound() -> None:
    """The shared Brent step (with :func:`brent_keep`) finds scipy's ``fminbound`` minimum of
    smooth and kinked functions on a bracket, to its tolerance."""
    import math

    from scipy import optimize

    from service.analysis.predictor._kernels.brent import GOLD, brent_keep, brent_step

    def brent(fn, a, b, xatol):
        x = a + GOLD * (b - a)
        fx = fn(x)
        w, fw, v, fv = x, fx, x, fx
        d = e = 0.0
        for _ in range(500):
            u, d, e = brent_step(a, b, x, fx, w, fw, v, fv, d, e, xatol)
            if math.isnan(u):
                break
            a, b, x, fx, w, fw, v, fv = brent_keep(a, b, x, fx, w, fw, v, fv, u, fn(u))
        return x

    for fn, a, b in [
        (lambda t: (t - 0.3) ** 2 + 1.0, -1.0, 2.0),
        (lambda t: math.cosh(3.0 * (t - 1.7)), 0.0, 4.0),
        (lambda t: abs(t - 0.123) + 0.1 * t * t, -2.0, 1.0),
        (lambda t: math.exp(t) - 5.0 * t, 0.0, 3.0),
    ]:
        ref = optimize.fminbound(fn, a, b, xtol=1e-10)
        assert abs(brent(fn, a, b, 1e-10) - ref) < 1e-7
