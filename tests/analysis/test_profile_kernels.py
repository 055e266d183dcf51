"""The compiled profile search against a slow reference built from scipy.

Reference: the same grid scanned with ``nll_rows`` (the per-mu* kernel, tested against numpy
least squares in ``test_laws_kernels``), ``scipy.optimize.minimize_scalar(method="bounded")`` in
the bracket of the lowest grid point, ``scipy.optimize.brentq`` for the interval ends. Also: the
screening search is an upper bound of the full one, and the exponent profile continued from
exponent to exponent finds the exponent of the full search.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import optimize, stats

from service.analysis.predictor._kernels.fold import nll_rows
from service.analysis.predictor._kernels.profile import (
    profile_local,
    profile_scan,
    profile_search,
    profile_search_scanned,
)
from service.analysis.predictor.cache import profile_memo
from service.analysis.predictor.exponents import free_exponent
from service.analysis.predictor.likelihood import (
    _GRID,
    _GRID_CF,
    _LOGU,
    _Comp,
    _nll,
    _pack,
    _profile,
    _profile_screen,
    _range_grid,
    _sigma_exps,
)


def _sweep(seed: int, n: int = 16, rel: float = 1e-4, fold: bool = False):
    """|sigma^2| of a pitchfork law (exponent 1, corrections) near mu* = 2, relative noise
    ``rel``; ``fold``: the branch folds at mu* + 0.012 (|sigma^2| ~ sqrt(mu2* - mu) - ...)."""
    rng = np.random.default_rng(seed)
    mu = np.sort(rng.uniform(0.5, 1.97, n))
    x = 2.0 - mu
    if fold:
        d = 0.012
        y = 40 * (np.sqrt(d + x) - math.sqrt(d)) * (1 + 0.2 * x)
    else:
        y = 30 * x * (1 + 0.3 * x - 0.1 * x**2)
    return mu, y * (1 + rel * rng.standard_normal(n)), rel * y


def _reference(t, mu, comps, d95):
    packed = _pack(mu, comps)
    last = float(mu[-1])

    def g(tt: float) -> float:
        v = float(nll_rows(np.array([last + math.exp(tt)]), *packed, last, _LOGU)[0][0])
        return v if math.isfinite(v) else 1e300

    f = np.array([g(tt) for tt in t])
    i = int(np.argmin(f))
    res = optimize.minimize_scalar(
        g, bounds=(t[max(i - 1, 0)], t[min(i + 1, t.size - 1)]), method="bounded",
        options={"xatol": 1e-10},
    )  # fmt: skip
    th, fh = (float(res.x), float(res.fun)) if res.fun <= f[i] else (float(t[i]), float(f[i]))
    j = int(np.searchsorted(t, th)) - 1
    while j >= 0 and f[j] - fh < d95:
        j -= 1
    lo = optimize.brentq(lambda s: g(s) - fh - d95, t[j], th, xtol=1e-9) if j >= 0 else math.nan
    j = int(np.searchsorted(t, th))
    while j < t.size and f[j] - fh < d95:
        j += 1
    hi = optimize.brentq(lambda s: g(s) - fh - d95, th, t[j], xtol=1e-9) if j < t.size else math.nan
    return th, fh, lo, hi


@pytest.mark.parametrize("seed", range(4))
@pytest.mark.parametrize("K", [0, 1, 2])
def test_plain_search_matches_the_scipy_reference(seed: int, K: int) -> None:
    mu, y, sd = _sweep(seed)
    comps = [_Comp(y, 1.0 / sd, _sigma_exps(1.0, 1.0, K), True, True)]
    scale = float(mu[-1] - mu[0])
    t = _range_grid(scale, _GRID)
    d95 = float(stats.chi2.ppf(0.95, 1))
    got = profile_search(t, _pack(mu, comps), float(mu[-1]), _LOGU, False, 1e-10, d95, 1.0)
    th, fh, lo, hi = _reference(t, mu, comps, d95)
    assert got[1] == pytest.approx(fh, rel=1e-9, abs=1e-9)
    assert got[0] == pytest.approx(th, abs=1e-5)
    for a, b in ((got[3], lo), (got[4], hi)):
        assert (math.isnan(a) and math.isnan(b)) or a == pytest.approx(b, abs=1e-7)


@pytest.mark.parametrize("seed", range(3))
def test_fold_search_matches_the_scipy_reference(seed: int) -> None:
    mu, y, sd = _sweep(seed, fold=True)
    comps = [_Comp(y, 1.0 / sd, _sigma_exps(1.0, 1.0, 1), True, True, conformal=True)]
    scale = float(mu[-1] - mu[0])
    t = _range_grid(scale, 61)
    got = profile_search(t, _pack(mu, comps), float(mu[-1]), _LOGU, True, 1e-8, 0.0, 0.0)
    th, fh, _, _ = _reference(t, mu, comps, 3.84)
    # the same function searched the same way: the same minimum at the same mu*
    assert got[1] == pytest.approx(fh, rel=1e-9, abs=1e-9)
    assert got[0] == pytest.approx(th, abs=1e-6)


@pytest.mark.parametrize("seed", range(3))
def test_screening_search_bounds_the_full_search_from_above(seed: int) -> None:
    mu, y, sd = _sweep(seed, n=20, rel=1e-3)
    scale = float(mu[-1] - mu[0])
    for K in (0, 1, 2):
        comps = [_Comp(y, 1.0 / sd, _sigma_exps(1.0, 1.0, K), True, True)]
        full = _profile(mu, comps, scale, with_interval=False)
        t_screen, screen, _ = _profile_screen(mu, comps, scale, None)
        assert screen >= full.nll - 1e-6 * max(1.0, full.nll)
        # on a smooth single-valley profile both find the same minimum: the screen's point
        # within its tolerance in t (1e-4, Brent's stop: within twice that of the minimum),
        # and its value within what the valley's curvature makes of that distance
        t_full = math.log(full.mu_star - float(mu[-1]))
        assert abs(t_screen - t_full) <= 2e-4
        last, h = float(mu[-1]), 1e-3
        f = _nll(mu, comps, last + np.exp(t_full + np.array([-h, 0.0, h])))
        curv = (f[0] - 2 * f[1] + f[2]) / h**2
        assert screen - full.nll <= 0.5 * abs(curv) * (2e-4) ** 2 + 1e-9 * max(1.0, full.nll)


@pytest.mark.parametrize("seed", range(3))
@pytest.mark.parametrize("fold", [False, True])
def test_local_search_finds_the_minimum_near_a_neighbours_optimum(seed: int, fold: bool) -> None:
    """``profile_local`` started 0.05 (in t) off the minimum, the fold parameter from a grid
    index two steps off: the minimum of the reference (cold rows, scipy's bounded Brent) to
    the same tolerance; and a screen with the critical value returns it when it passes."""
    mu, y, sd = _sweep(seed, fold=fold)
    K = 1
    comps = [_Comp(y, 1.0 / sd, _sigma_exps(1.0, 1.0, K), True, True, conformal=fold)]
    scale = float(mu[-1] - mu[0])
    last = float(mu[-1])
    full = _profile(mu, comps, scale, with_interval=False, xatol=1e-10)
    t_min = math.log(full.mu_star - last)
    packed = _pack(mu, comps)

    def g(tt: float) -> float:
        return float(nll_rows(np.array([last + math.exp(tt)]), *packed, last, _LOGU)[0][0])

    t0 = t_min + 0.05
    j0 = int(np.argmin(np.abs(_LOGU - full.log_u))) + 2 if fold else -1
    j0 = min(j0, _LOGU.size - 1)
    lu0 = float(_LOGU[j0]) if fold else math.nan
    th, fh, _, lu, ok = profile_local(t0, t0 - 0.3, t0 + 0.3, packed, last, _LOGU, fold, 1e-8,
                                      j0, lu0)  # fmt: skip
    assert ok
    ref = optimize.minimize_scalar(g, bounds=(t0 - 0.3, t0 + 0.3), method="bounded",
                                   options={"xatol": 1e-8})  # fmt: skip
    assert fh == pytest.approx(float(ref.fun), rel=1e-9, abs=1e-9)
    assert th == pytest.approx(float(ref.x), abs=1e-5)
    assert fh == pytest.approx(full.nll, rel=1e-9, abs=1e-9)
    if fold:
        assert lu == pytest.approx(full.log_u, abs=1e-4)
    # the screen: the local search's value when it passes, the global one's otherwise
    t_s, f_s, _ = _profile_screen(mu, comps, scale, t0, lu0, crit=fh + 1.0)
    assert f_s == pytest.approx(fh, rel=1e-6, abs=1e-6) and abs(t_s - th) <= 2e-4
    t_g, f_g, _ = _profile_screen(mu, comps, scale, t0, lu0, crit=fh - 1.0)
    assert f_g >= full.nll - 1e-9 and (t_g, f_g) == _profile_screen(mu, comps, scale, t0)[:2]


def test_continued_exponent_profile_matches_the_full_one() -> None:
    """The exponent profile searched near the neighbouring exponent's optimum gives the same
    estimate and standard error as a full search at every exponent."""
    mu, y, sd = _sweep(2, n=20, rel=1e-4)
    scale = float(mu[-1] - mu[0])

    def make(p: float) -> list[_Comp]:
        return [_Comp(y, 1.0 / sd, _sigma_exps(p, 1.0, 1), True, True)]

    grid = np.unique(np.concatenate([np.linspace(0.2, 2.5, 16), [0.48, 0.5, 0.52, 1.0, 2.0]]))
    e_cont, se_cont = free_exponent(mu, make, grid, scale, center=1.0)

    def full(p: float) -> float:
        return _profile(mu, make(p), scale, with_interval=False, xatol=1e-7).nll

    f = np.array([full(p) for p in grid])
    i = int(np.argmin(f))
    res = optimize.minimize_scalar(
        full, bounds=(grid[i - 1], grid[i + 1]), method="bounded", options={"xatol": 1e-4}
    )
    assert e_cont == pytest.approx(res.x, abs=max(1e-3, 0.05 * se_cont))
    assert se_cont > 0 and math.isfinite(se_cont)


def test_a_valley_narrower_than_the_grid_is_found() -> None:
    """A lab plan on the Euler beam (antisymmetric, steps of 0.0905 ending 0.0287 before mu*,
    4.8e-5 noise): on its nearest 8 points the plain pitchfork law with 2 corrections has a
    valley 0.01 wide in log(mu* - mu_last), 0.04 from the nearest two-point seed, whose grid
    points stand above a far, shallow basin's lowest point (2513 at 5.7). Reference: the
    kernel at 200,001 values of mu*. Refining the scan's three lowest local minima finds the
    valley (refining only the lowest point, the search's former behaviour, fails this test)."""
    from service.analysis.predictor._kernels.laws import nll_fixed_u
    from sim.euler_beam import bifurcation, spectrum

    b = bifurcation("antisymmetric")
    last = b.mu_star - 0.02874122717284692
    mu = last - 0.09054011581051227 * np.arange(int(last / 0.09054011581051227) + 1)[::-1]
    s2 = np.array([spectrum("antisymmetric", m, "U_A", modes=1).sigma2[0] for m in mu])
    rng = np.random.default_rng(821606719)
    y = -(s2 + 4.8409304745018225e-05 * np.abs(s2) * rng.standard_normal(mu.size))
    sd = 4.8409304745018225e-05 * np.abs(s2)
    m8, comps = mu[-8:], [_Comp(y[-8:], 1.0 / sd[-8:], _sigma_exps(1.0, 1.0, 2), True, True)]
    ms = m8[-1] + np.geomspace(1e-6, 1.0, 200_001)
    dense = nll_fixed_u(ms, 0.0, *_pack(m8, comps), float(m8[-1]))
    got = _profile(m8, comps, float(mu[-1] - mu[0]), with_interval=False)
    assert got.nll <= float(dense.min()) + 1e-6
    assert got.mu_star == pytest.approx(float(ms[dense.argmin()]), abs=1e-5)


def _search_case(seed: int, fold: bool) -> tuple:
    """A sweep's one-component law (plain or conformal), its scale, range grid, packed arrays,
    last control value and the 95 % threshold of -2 log L."""
    mu, y, sd = _sweep(seed, fold=fold)
    comps = [_Comp(y, 1.0 / sd, _sigma_exps(1.0, 1.0, 1), True, True, conformal=fold)]
    scale = float(mu[-1] - mu[0])
    t = _range_grid(scale, _GRID_CF if fold else _GRID)
    return mu, comps, scale, t, _pack(mu, comps), float(mu[-1]), float(stats.chi2.ppf(0.95, 1))


@pytest.mark.parametrize("fold", [False, True])
@pytest.mark.parametrize("seed", range(3))
def test_the_68_interval_alone_is_the_full_profiles(seed: int, fold: bool) -> None:
    """Searched without the 95 % ends (``d95 = 0``), the 68 % ends, mu* and -2 log L are the
    full search's to the bit (plain and conformal laws), and so is ``_profile(only68=True)``."""
    mu, comps, scale, t, P, last, d95 = _search_case(seed, fold)
    full = profile_search(t, P, last, _LOGU, fold, 1e-10, d95, 1.0, 3)
    only = profile_search(t, P, last, _LOGU, fold, 1e-10, 0.0, 1.0, 3)
    assert np.isnan(only[3]) and np.isnan(only[4])
    np.testing.assert_array_equal(only[[0, 1, 2, 5, 6]], full[[0, 1, 2, 5, 6]])
    pf = _profile(mu, comps, scale)
    p68 = _profile(mu, comps, scale, only68=True)
    assert (p68.mu_star, p68.nll, p68.lo68, p68.hi68) == (pf.mu_star, pf.nll, pf.lo68, pf.hi68)
    assert math.isnan(p68.lo) and math.isnan(p68.hi)


@pytest.mark.parametrize("fold", [False, True])
@pytest.mark.parametrize("seed", range(3))
def test_a_kept_scan_gives_the_full_search(seed: int, fold: bool) -> None:
    """The scan kept and searched again (copies: the walks update them), with and without
    intervals and at either tolerance, its probes kept from one search to the next, gives the
    full search's result to the bit; so does
    ``_profile`` in a memo scope, where a window's searches share their scan."""
    mu, comps, scale, t, P, last, d95 = _search_case(seed, fold)
    f, exact, S = profile_scan(t, P, last, _LOGU, fold)
    Q = np.full((2, t.size), np.nan)  # the probes, shared by every search of the scan
    for tol, a, b in ((1e-5, 0.0, 0.0), (1e-10, d95, 1.0), (1e-10, 0.0, 1.0)):
        full = profile_search(t, P, last, _LOGU, fold, tol, a, b, 3)
        kept = profile_search_scanned(
            t, f.copy(), exact.copy(), S.copy(), Q, P, last, _LOGU, fold, tol, a, b, 3
        )
        np.testing.assert_array_equal(kept, full)
    assert np.isfinite(Q[1]).sum() >= 1  # the probes were kept (and read by the later ones)
    plain = [_profile(mu, comps, scale, with_interval=w) for w in (False, True)]
    with profile_memo():
        shared = [_profile(mu, comps, scale, with_interval=w) for w in (False, True)]
    assert shared == plain
