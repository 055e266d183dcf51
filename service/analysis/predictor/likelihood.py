"""The profile likelihood of laws linear in their coefficients (the engine's primitives).

For a trial transition point ``mu*`` every law of :mod:`.compare` is linear in its
coefficients, so ``-2 log L`` is a weighted linear least-squares residual (compiled:
:mod:`._kernels.laws`) and the likelihood is profiled over ``mu*`` (variable
projection): a 1-D search on a logarithmic grid of ``mu* - mu[-1]``, refined by Brent's method,
with profile-likelihood intervals. A law that knows a secondary fold beyond ``mu*`` (conformal
variable, see the kernels) profiles the fold distance as well, inside the kernel.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field

import numpy as np

from service.analysis.common import Flag
from service.analysis.predictor._dist import chi2_ppf
from service.analysis.predictor._kernels.fold import nll_rows
from service.analysis.predictor._kernels.laws import poly_rss
from service.analysis.predictor._kernels.profile import (
    profile_local,
    profile_scan,
    profile_search,
    profile_search_scanned,
)
from service.analysis.predictor.cache import fit_cache
from service.analysis.predictor.sweep import Sweep

_GRID = 81  # scan of log(mu* - mu_last) for a plain law
_GRID_CF = 61  # for a conformal law (the fold parameter profiled at every point)
# local minima of the scan refined (lowest first): a valley of precise data narrower than the
# grid's step shows as a grid point thousands above its floor, above a far, shallow basin's
# lowest point (measured: a beam plan's 8-point window with 2 corrections, the valley at
# mu* - mu_last = 0.0288 with -2 log L = 12.9, missed for 2513 at 5.7 when only the lowest
# grid point was refined)
_POLISH = 3
# the kernels' optional arguments, all passed: numba's dispatcher types a call that leaves
# one out in Python (measured: some 0.4 ms a call, more than most searches cost)
_NO_HINT = (1, math.nan, -1, math.nan)  # polish, hint's t, fold grid index, log u

@dataclass(frozen=True)
class _Comp:
    """One data component: y ~ sum_j beta_j x^e_j, weights 1/sd (``known``) or unknown scale."""

    y: np.ndarray
    wt: np.ndarray
    exps: np.ndarray
    known: bool
    lead: bool = False  # constrain the corrections to stay below _RHO of the leading term
    lead_col: int = 0  # column of the leading term (the columns after it are corrections)
    signed: bool = True  # the leading term must have the sign of y (|sigma^2| > 0)
    mu: np.ndarray | None = None  # own control values (a suffix of the sweep); None: the window
    conformal: bool = False  # series in z (a secondary fold at mu* + delta, delta profiled)


U_MAX = 10.0  # largest u = (mu* - mu_last) / delta: a secondary fold no nearer than that
_LOGU = np.linspace(math.log(1e-4), math.log(U_MAX), 11)  # grid of log u
_T_LO, _T_HI, _T_MIN = math.log(1e-9), math.log(30.0), math.log(1e-12)  # range of log(d/scale)
_UNIT = {n: np.linspace(0.0, 1.0, n) for n in (21, _GRID_CF, _GRID)}  # scans of the range
_NEAR = np.linspace(-1.0, 1.0, 9)  # around a known optimum
_CLOSE = np.linspace(-0.3, 0.3, 5)  # around the optimum of a neighbouring exponent
_FINE = np.linspace(-0.01, 0.01, 5)  # around a two-point seed
#: grids around the two-point seeds, (half-width in t, points across it) per variant (plain,
#: conformal): a coarse one and a fine one
_SEED_GRIDS = {False: ((1.0, 31), (0.01, 21)), True: ((1.0, 15), (0.01, 9))}


def _range_grid(scale: float, n: int) -> np.ndarray:
    """``n`` points of ``log(mu* - mu_last)`` from ``1e-9`` to ``30`` times ``scale``."""
    lo = math.log(scale) + _T_LO
    return lo + (_T_HI - _T_LO) * _UNIT[n]


def _sorted_unique(t: np.ndarray) -> np.ndarray:
    """``np.unique(t)`` of a fresh array (sorted in place), without its wrapper's cost (some
    5 us a call, paid by every search)."""
    t.sort()
    return t[np.concatenate(([True], t[1:] != t[:-1]))] if t.size else t


def _clip(t: np.ndarray, scale: float) -> np.ndarray:
    ls = math.log(scale)
    return t[(t >= ls + _T_MIN) & (t <= ls + _T_HI)]


def _pack(mu_w: np.ndarray, comps: list[_Comp]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The components as the kernels' plain arrays ``(D, E, M)``: ``D`` (3, N) rows mu, y, wt of
    every component one after the other; ``E`` (C, kmax) exponents; ``M`` (C, 8) integers
    ``(offset, n, k, known, lead, lead_col, signed, conformal)``."""
    nc = len(comps)
    if nc == 1 and comps[0].mu is None:  # the common case, without the general loop's cost
        c = comps[0]
        D = np.array((mu_w, c.y, c.wt), dtype=float)
        row = (0, mu_w.size, c.exps.size, c.known, c.lead, c.lead_col, c.signed, c.conformal)
        E = np.array(c.exps, dtype=float).reshape(1, -1)  # a writable copy: one kernel type
        return D, E, np.array([row], dtype=np.int64)
    mus = [mu_w if c.mu is None else c.mu for c in comps]
    N = sum(m.size for m in mus)
    D = np.empty((3, N))
    M = np.empty((nc, 8), dtype=np.int64)
    E = np.zeros((nc, max(c.exps.size for c in comps)))
    o = 0
    for i, (c, m) in enumerate(zip(comps, mus, strict=True)):
        n = m.size
        D[0, o : o + n], D[1, o : o + n], D[2, o : o + n] = m, c.y, c.wt
        M[i] = (o, n, c.exps.size, c.known, c.lead, c.lead_col, c.signed, c.conformal)
        E[i, : c.exps.size] = c.exps
        o += n
    return D, E, M


def _nll_u(
    mu_w: np.ndarray, comps: list[_Comp], mu_star: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """-2 log L (up to constants) at each mu* and the secondary-fold parameter
    ``u = (mu* - mu_w[-1]) / delta`` profiled there (0: none, or no conformal component)."""
    ms = np.ascontiguousarray(np.atleast_1d(np.asarray(mu_star, dtype=float)))
    return nll_rows(ms, *_pack(mu_w, comps), float(mu_w[-1]), _LOGU)


def _nll(mu_w: np.ndarray, comps: list[_Comp], mu_star: np.ndarray) -> np.ndarray:
    return _nll_u(mu_w, comps, mu_star)[0]


@dataclass(frozen=True)
class _Profile:
    mu_star: float
    nll: float
    lo: float  # 95 % (profile) interval
    hi: float
    lo68: float
    hi68: float
    flags: tuple[Flag, ...] = ()
    # a conformal law's log fold parameter near the minimum (where a neighbour's search starts)
    log_u: float = field(default=math.nan, compare=False)


def _profile(
    mu_w: np.ndarray,
    comps: list[_Comp],
    scale: float,
    *,
    level: float = 0.95,
    inflate: float = 1.0,
    with_interval: bool = True,
    xatol: float | None = None,
    only68: bool = False,
    hint: tuple[float, float] | None = None,
) -> _Profile:
    """Minimise the profile -2 log L over mu* > mu_w[-1] and read off profile intervals.

    ``hint``: ``(t, log u)`` of a minimum of the same law on the same window found before
    (the window choice's local searches): searched from as well (``profile_search``), so
    that a fit never misses a valley its window was accepted on.

    ``only68`` (with ``with_interval``): the 68 % interval alone, ``lo`` and ``hi`` NaN (and
    without their flags); mu*, -2 log L and the 68 % ends are those of the full profile (the
    same search and tolerance, and the kernel's 68 % ends do not depend on whether the
    ``level`` ends are searched too), at the cost of one interval instead of two.

    Deterministic in its inputs: a result is memoised on the packed data and the options (model
    selection, the exponent profiles and the final fits revisit the same windows and laws).
    """
    packed = _pack(mu_w, comps)
    only68 = only68 and with_interval
    memo = fit_cache()
    if memo is None:
        return _profile_uncached(
            mu_w, comps, packed, scale, level, inflate, with_interval, xatol, only68, hint
        )
    key = _memo_key(mu_w, comps, packed, scale, level, inflate, with_interval, xatol)
    if hint is not None:
        key = (*key, "hint", *hint)
    if only68:
        hit = memo.get(key)  # the full profile, if computed: the same 68 % interval
        if hit is not None:
            return hit
        key = (*key, "68")
    hit = memo.get(key)
    if hit is None:
        hit = memo[key] = _profile_uncached(
            mu_w, comps, packed, scale, level, inflate, with_interval, xatol, only68, hint
        )
    return hit


def _memo_key(mu_w, comps, packed, scale, level, inflate, with_interval, xatol) -> tuple:
    """Exact key of a profile: the bytes of the window and of the packed components (which
    hold every component's data, weights, exponents and options; the seeds read the first
    component's y, in ``D``) and the options. Bytes compare exactly: no collision possible."""
    D, E, M = packed
    return (
        np.ascontiguousarray(mu_w, dtype=float).tobytes(),
        D.tobytes(), E.tobytes(), E.shape, M.tobytes(),
        scale, level, inflate, with_interval, xatol,
    )  # fmt: skip


def _profile_uncached(
    mu_w: np.ndarray,
    comps: list[_Comp],
    packed: tuple,
    scale: float,
    level: float,
    inflate: float,
    with_interval: bool,
    xatol: float | None,
    only68: bool = False,
    hint: tuple[float, float] | None = None,
) -> _Profile:
    last = float(mu_w[-1])
    cf = any(c.conformal for c in comps)
    t = _search_grid(mu_w, comps[0], scale, cf)
    # tolerance on log(mu* - mu[-1]): 1e-10 relative for final fits, 1e-5 for model selection
    tol = xatol if xatol is not None else (1e-10 if with_interval else 1e-5)
    d95 = _chi2_1_quantile(level) * inflate if with_interval and not only68 else 0.0
    d68 = 1.0 * inflate if with_interval else 0.0
    th, fh, ig, tl, tu, tl68, tu68, _, lu = _search(
        mu_w, t, packed, last, cf, tol, d95, d68, hint
    )
    i, G = int(ig), t.size
    flags: list[Flag] = []
    if i == 0:
        flags.append(
            Flag("mu_star_at_last_point", f"the fit puts mu* at the last measured mu={last:.6g}")
        )
    if i == G - 1:
        flags.append(Flag("mu_star_far", "the fit puts mu* far beyond the measured range"))
    mh = last + math.exp(th)
    if not with_interval:
        return _Profile(mh, fh, mh, mh, mh, mh, tuple(flags), float(lu))
    lo68 = last if math.isnan(tl68) else last + math.exp(tl68)
    hi68 = last + math.exp(t[-1]) if math.isnan(tu68) else last + math.exp(tu68)
    if only68:
        return _Profile(mh, fh, math.nan, math.nan, lo68, hi68, tuple(flags), float(lu))
    lo = last if math.isnan(tl) else last + math.exp(tl)
    hi = last + math.exp(t[-1]) if math.isnan(tu) else last + math.exp(tu)
    if math.isnan(tu):
        flags.append(
            Flag("interval_unbounded", "the profile likelihood does not bound mu* from above")
        )
    if math.isnan(tl):
        flags.append(
            Flag(
                "interval_reaches_last_point",
                f"the {100 * level:.0f}% interval reaches the last measured mu={last:.6g}",
            )
        )
    return _Profile(mh, fh, lo, hi, lo68, hi68, tuple(flags), float(lu))


def _search(
    mu_w: np.ndarray, t: np.ndarray, packed: tuple, last: float, cf: bool, tol: float,
    d95: float, d68: float, hint: tuple[float, float] | None = None,
) -> np.ndarray:
    """The kernel's full search (:func:`profile_search`), its scan of the grid kept in a
    :func:`profile_memo` scope: a window and law searched again with another tolerance or
    intervals (a model-selection search, then the final fit or a truncation refit) scans its
    grid once, and probes its further basins once. The scan depends on the grid and the data
    alone, and the search after it is given copies (its interval walks update them) and the
    scan's probes: the same result to the bit."""
    t = np.ascontiguousarray(t)
    ht, hlu = hint if hint is not None else (math.nan, math.nan)
    hj = _u_index(hlu) if math.isfinite(hlu) else -1
    memo = fit_cache()
    if memo is None:
        return profile_search(
            t, packed, last, _LOGU, cf, tol, d95, d68, _POLISH, ht, hj, hlu
        )
    D, E, M = packed
    key = ("scan", mu_w.tobytes(), t.tobytes(), D.tobytes(), E.tobytes(), E.shape,
           M.tobytes(), cf)  # fmt: skip
    hit = memo.get(key)
    if hit is None:
        scan = profile_scan(t, packed, last, _LOGU, cf)
        hit = memo[key] = (*scan, np.full((2, t.size), math.nan))  # type: ignore[assignment]
    f, exact, S, Q = hit  # type: ignore[misc]
    return profile_search_scanned(
        t, f.copy(), exact.copy(), S.copy(), Q, packed, last, _LOGU, cf, tol, d95, d68,
        _POLISH, ht, hj, hlu,
    )  # fmt: skip


@functools.lru_cache(maxsize=16)
def _chi2_1_quantile(level: float) -> float:
    """``scipy.stats.chi2.ppf(level, 1)`` (:func:`._dist.chi2_ppf`, the same value; the
    distribution machinery costs some 0.2 ms a call, paid by every interval)."""
    return float(chi2_ppf(level, 1))


def _seed_grid(centres: list[float], half: float, points: int) -> list[np.ndarray]:
    """Grids of step ``2 half / (points - 1)`` over ``centre +- half`` for each centre, the
    overlapping ones merged into one grid over their union (the seeds of one law usually lie
    within a few hundredths in t of each other: three overlapping grids scanned the same
    stretch three times over)."""
    step = 2.0 * half / (points - 1)
    out = []
    cs = sorted(centres)
    lo, hi = cs[0] - half, cs[0] + half
    for c in cs[1:] + [math.inf]:
        if c - half <= hi:
            hi = c + half
            continue
        out.append(lo + step * np.arange(int(round((hi - lo) / step)) + 1))
        lo, hi = c - half, c + half
    return out


def _search_grid(mu_w: np.ndarray, c: _Comp, scale: float, cf: bool) -> np.ndarray:
    """The full search's grid of ``log(mu* - mu_last)``: the range's uniform grid and, for a
    law whose leading term leads (``c.lead``), a coarse and a fine grid around each two-point
    seed of ``c`` (overlapping ones merged, :func:`_seed_grid`: the seeds usually lie within
    0.02 in t of each other, and their three grids scanned the same stretch three times; the
    merge left 1800 calibration plans with the same coverage and types, 4 of them moved by
    0.1-1 standard error, and cut the median CPU of a prediction by 10-35 %). A conformal law
    profiles the secondary fold at every mu* (some 25 fits each): a coarser grid around the
    same seeds keeps its cost near the plain laws'. Memoised
    in a :func:`profile_memo` scope (a window's joint fits share their eigenvalue law's)."""
    memo = fit_cache()
    key = None
    if memo is not None:
        key = ("grid", mu_w.tobytes(), c.y.tobytes(), c.exps.tobytes(), c.lead, scale, cf)
        hit = memo.get(key)
        if hit is not None:
            return hit  # type: ignore[return-value]
    t = _range_grid(scale, _GRID_CF if cf else _GRID)
    seeds = _seeds(mu_w, c) if c.lead else []
    if seeds:
        centres = [math.log(d0) for d0 in seeds]
        parts = [g for half, k in _SEED_GRIDS[cf] for g in _seed_grid(centres, half, k)]
        t = _clip(_sorted_unique(np.concatenate([t, *parts])), scale)
    t = np.ascontiguousarray(t)
    if key is not None:
        memo[key] = t  # type: ignore[assignment]
    return t


def _seeds(mu_w: np.ndarray, c: _Comp) -> list[float]:
    """Distances mu* - mu[-1] from the paper's two-point extrapolation of |sigma^2|^(1/p) through
    the last pairs of points: starting points that bracket the (possibly very narrow) valley of
    the profile likelihood of precise data."""
    p = float(c.exps[0])
    z = (c.y[-4:] ** (1.0 / p)).tolist()  # the last pairs only, as Python floats (cheaper)
    m = mu_w[-4:].tolist()
    out = []
    for k in range(1, min(4, mu_w.size)):
        dz = z[-k - 1] - z[-k]
        if dz > 0:
            d = z[-k] * (m[-k] - m[-k - 1]) / dz + (m[-k] - m[-1])
            if d > 0 and math.isfinite(d):
                out.append(float(d))
    return out


def _polynomial_bound(mu: np.ndarray, y: np.ndarray, wt: np.ndarray, degree: int) -> float:
    """A lower bound of the chi^2 of a plain pitchfork law with ``degree - 1`` corrections at
    every mu*: its terms ``x, ..., x^degree`` (``x = mu* - mu``) are polynomials of that degree
    in ``mu``, so no mu* fits better than the best polynomial (weighted least squares, less
    a rounding margin). Exact, and costs one small fit instead of a profile search."""
    if degree + 1 >= mu.size:
        return 0.0
    b = y * wt
    rss = float(poly_rss(mu, y, wt, degree))  # compiled: a tenth of numpy's lstsq call
    return max(rss - 1e-9 * float(b @ b), 0.0)


@functools.lru_cache(maxsize=256)
def _sigma_exps(p: float, h: float, K: int) -> np.ndarray:
    """Exponents ``p, p + h, ..., p + K h`` of the eigenvalue law (read-only: memoised)."""
    e = p + h * np.arange(K + 1, dtype=float)
    e.flags.writeable = False
    return e


def _w_exps(b: float, Kw: int) -> np.ndarray:
    if b == 0.5:
        e = [0.0, 0.5, 1.0, 1.5, 2.0]
    elif b == 1.0:
        e = [0.0, 1.0, 2.0, 3.0, 4.0]
    else:  # free exponent: w - w* a series in x^b
        e = [0.0, b, 2 * b, 3 * b, 4 * b]
    return np.asarray(e[: Kw + 1], dtype=float)


_KCF = 2  # most corrections of a conformal law (one parameter more than the plain law: with
# three corrections it out-fits a true fold's series over a fixed grid's far points)


def _variants(p: float, h: float, K: int = 0) -> tuple[bool, ...]:
    """Plain law, and for a pitchfork (|sigma^2| ~ x) also the law that knows a secondary fold
    of the measured branch beyond mu* (series in the conformal variable z; see
    :mod:`._kernels.laws`). A subcritical pitchfork's trivial branch, unstable
    past mu*, may fold soon after it (the symmetric beam: mu2* = mu* + 0.012); the series in
    x = mu* - mu then converges only within that distance, the series in z much farther."""
    return (False, True) if (p == 1.0 and h == 1.0 and K <= _KCF) else (False,)


def _sigma_comp(
    sw: Sweep, idx: slice, p: float, h: float, K: int, conformal: bool = False
) -> _Comp:
    return _Comp(
        sw.y[idx], 1.0 / sw.sd[idx], _sigma_exps(p, h, K), True, True, conformal=conformal
    )


def _w_comp(
    sw: Sweep, idx: slice, b: float, Kw: int, conformal: bool = False
) -> _Comp | None:
    """Static-deflection component on the window ``idx`` (its own: the static law holds farther
    from mu* than the eigenvalue law, and near mu* w hardly moves)."""
    if sw.w is None:
        return None
    # w - w* = g x^b (1 + corrections): the x^b term must lead inside the window, otherwise the
    # b = 1/2 series (which contains x, x^2 ...) would fit a smooth deflection as well as b = 1
    if sw.w_sd is not None:
        return _Comp(
            sw.w[idx],
            1.0 / sw.w_sd[idx],
            _w_exps(b, Kw),
            sw.w_noise_given,  # an estimated noise is profiled in the final fits
            True,
            1,
            False,
            sw.mu[idx],
            conformal and b == 1.0,
        )
    return _Comp(
        sw.w[idx], np.ones(sw.w[idx].size), _w_exps(b, Kw), False, True, 1, False, sw.mu[idx],
        conformal and b == 1.0,
    )  # fmt: skip


def _profile_near(
    mu_w: np.ndarray, comps: list[_Comp], scale: float, t0: float, xatol: float,
    lu0: float = math.nan,
) -> tuple[float, float, float]:
    """Minimum of the profile near ``t0 = log(mu* - mu_w[-1])`` (a law close to one whose
    optimum is known): a local grid of +-0.3 around ``t0`` (moved while the minimum sits on its
    edge; the full search after four moves), then Brent's method. A conformal law with the
    neighbour's log fold parameter ``lu0`` is first searched from there (:func:`profile_local`,
    its rows starting from ``lu0``: the grid's five points are each profiled over the fold
    parameter's whole grid, some 27 fits a point); a bracketed minimum inside ``t0 +- 0.3``
    ends it. Returns ``(t, -2 log L, log u)`` (log u NaN for plain laws)."""
    last = float(mu_w[-1])
    cf = any(c.conformal for c in comps)
    packed = _pack(mu_w, comps)
    if cf and math.isfinite(lu0):
        a, b = t0 + float(_CLOSE[0]), t0 + float(_CLOSE[-1])
        th, fh, _, lu, ok = profile_local(t0, a, b, packed, last, _LOGU, cf, xatol,
                                          _u_index(lu0), lu0)  # fmt: skip
        if ok and a < th < b:
            return float(th), float(fh), float(lu)
    for _ in range(4):  # follow the valley while it leaves the local grid
        t = t0 + _CLOSE
        out = profile_search(t, packed, last, _LOGU, cf, xatol, 0.0, 0.0, *_NO_HINT)
        th, fh, ig = float(out[0]), float(out[1]), int(out[2])
        if 0 < ig < t.size - 1:
            return th, fh, float(out[8])
        t0 = float(t[ig])
    pr = _profile(mu_w, comps, scale, with_interval=False, xatol=xatol)
    return math.log(max(pr.mu_star - last, 1e-300)), pr.nll, pr.log_u


def _profile_screen(
    mu_w: np.ndarray,
    comps: list[_Comp],
    scale: float,
    t0: float | None,
    lu0: float = math.nan,
    crit: float | None = None,
) -> tuple[float, float, float]:
    """A cheap search of the profile's minimum for a screening test: a coarse grid over the
    whole range (21 points), +-1 around ``t0`` (the optimum of a neighbouring window or law,
    if any) and the law's two-point seeds, then Brent's method. An upper bound of the global
    minimum (equal to it unless a valley narrower than the grid lies away from every seed).

    With ``crit`` (the test's critical value) and ``t0``, a local search comes first: Brent's
    method on ``t0 +- _LOCAL`` from ``t0``, a conformal law's fold parameter from ``lu0``
    (:func:`profile_local`); a value at or below ``crit`` ends the screen there (the test
    passes on an upper bound of the minimum either way), otherwise the search above follows.
    In a window selection the optimum moves little from one window to the next, and most
    screens of a law that held pass (:func:`profile_local`: measured on the symmetric bench
    sweep, 60-125 fits of the conformal law per screen instead of 325-400).

    Returns ``(t, -2 log L, log u)`` with ``t = log(mu* - mu_w[-1])`` and a conformal law's
    log fold parameter near there (NaN for plain laws)."""
    last = float(mu_w[-1])
    packed = _pack(mu_w, comps)
    memo = fit_cache()
    key = None
    if memo is not None:  # the per-law refits of a prediction repeat the same screens
        key = ("screen", *_memo_key(mu_w, comps, packed, scale, 0.0, 1.0, False, t0), lu0, crit)
        hit = memo.get(key)
        if hit is not None:
            return hit  # type: ignore[return-value]
    cf = any(c.conformal for c in comps)
    ls = math.log(scale)
    res: tuple[float, float, float] | None = None
    if crit is not None and t0 is not None and math.isfinite(t0):
        a = max(t0 - _LOCAL, ls + _T_MIN)
        b = min(t0 + _LOCAL, ls + _T_HI)
        if a < t0 < b:
            j0 = -1 if math.isnan(lu0) else _u_index(lu0)
            th, fh, _, lu, _ = profile_local(t0, a, b, packed, last, _LOGU, cf, 1e-4, j0, lu0)
            if fh <= crit:
                res = (float(th), float(fh), float(lu) if cf else math.nan)
    if res is None:
        parts = [_range_grid(scale, 21)]
        if t0 is not None and math.isfinite(t0):
            parts.append(t0 + _NEAR)
        if comps[0].lead:
            parts += [math.log(d0) + _FINE for d0 in _seeds(mu_w, comps[0])]
        t = _clip(_sorted_unique(np.concatenate(parts)), scale)
        out = profile_search(t, packed, last, _LOGU, cf, 1e-4, 0.0, 0.0, *_NO_HINT)
        res = (float(out[0]), float(out[1]), float(out[8]))
    if key is not None:
        memo[key] = res  # type: ignore[assignment]
    return res


_LOCAL = 0.3  # half-width (in t) of a screen's local search around a neighbour's optimum


def _u_index(lu: float) -> int:
    """The ``_LOGU`` grid index nearest to the log fold parameter ``lu``."""
    j = round((lu - float(_LOGU[0])) / float(_LOGU[1] - _LOGU[0]))
    return min(max(int(j), 0), _LOGU.size - 1)
