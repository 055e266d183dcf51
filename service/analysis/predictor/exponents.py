"""The profile likelihood of a law's free exponent (the time exponent ``a``, the static
exponent ``b``): the classification's check that the data follow the candidate's exponent.

The exponent is profiled with mu* profiled too (or fixed at a fit's mu*), over a grid walked
from the law's own exponent, then refined by Brent's method; its standard error is the
distance where ``-2 log L`` rises by 1. The profile at each exponent is a search of
:mod:`.likelihood`.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
from scipy import optimize

from service.analysis.predictor._kernels.brent import brent_keep, brent_step
from service.analysis.predictor._kernels.fold import nll_exponent_rows
from service.analysis.predictor.likelihood import _LOGU, _Comp, _nll, _pack, _profile, _profile_near


def exponent_grid(lo: float, hi: float, cands: list[float]) -> np.ndarray:
    """Grid for a free exponent: uniform, plus the candidate values and their close neighbours
    (precise data give valleys far narrower than the uniform step)."""
    extra = [c + d for c in cands for d in (-0.02, -0.005, 0.0, 0.005, 0.02)]
    return np.unique(np.concatenate([np.linspace(lo, hi, 16), extra]))


def _brent_min(
    fn: Callable[[float], float], x3: tuple[float, float, float],
    f3: tuple[float, float, float], xatol: float,
) -> tuple[float, float, float]:
    """Brent's bounded minimisation of ``fn`` on ``[x3[0], x3[2]]`` (scipy's ``fminbound``
    steps, tolerance ``xatol``) started from the bracket's three known values, the middle one
    the lowest: its first step is the parabola through them, where ``fminbound`` starts with
    golden sections from nothing (on precise data some six evaluations instead of twelve).
    The steps are those of the compiled searches' Brent (``_profile_kernels._minimise``),
    here for a Python callable: the profile at an exponent is itself a search.
    Returns ``(x, fn(x), curvature)``: the lowest point and the second derivative of the
    parabola through the last three points (NaN if they do not make one)."""
    a, x, c = x3
    fa, fx, fc = f3
    w, fw, v, fv = (a, fa, c, fc) if fa <= fc else (c, fc, a, fa)
    d = e = c - a
    for _ in range(500):
        u, d, e = brent_step(a, c, x, fx, w, fw, v, fv, d, e, xatol)
        if math.isnan(u):
            break
        fu = fn(u)
        a, c, x, fx, w, fw, v, fv = brent_keep(a, c, x, fx, w, fw, v, fv, u, fu)
    curv = math.nan
    if len({x, w, v}) == 3 and all(math.isfinite(f) for f in (fx, fw, fv)):
        curv = 2.0 * ((fw - fx) / (w - x) - (fv - fx) / (v - x)) / (w - v)
    return x, fx, curv


_FAR = 100.0  # rise of -2 log L above its minimum that ends the walk along an exponent grid


def free_exponent(
    mu_w: np.ndarray,
    make: Callable[[float], list[_Comp]],
    grid: np.ndarray,
    scale: float,
    fixed_mu: float | None = None,
    center: float | None = None,
    hint: tuple[float, float] | None = None,
) -> tuple[float, float]:
    """Profile -2 log L over an exponent; return (estimate, standard error from Delta = 1).

    With mu* profiled, the profile at each exponent is searched near the optimum of the
    neighbouring exponent (continuation from ``center``, the law's own exponent, whose profile
    gets the full search): the optimum moves smoothly with the exponent. The grid is walked
    from ``center`` each way until the profile, rising, stands ``_FAR`` above the lowest value
    seen (a minimum beyond such a ridge is not looked for: on precise data the profile rises
    by 1e4-1e8 within a few grid points, and every point of it cost a search). Without a
    ``center`` every grid point is evaluated (the static exponent's profile has a second
    valley at the grid's low edge, where a series in x^(b/2) fits too). ``hint``: ``(t, log
    u)`` of the law's own optimum (its fit's), where the search at ``center`` starts as well
    (see :func:`~.likelihood._profile`)."""
    last = float(mu_w[-1])
    known: dict[float, tuple[float, float]] = {}  # exponent -> (t, log u) at its optimum

    values: dict[float, float] = {}  # exponent -> profile value (a point is searched once)
    if fixed_mu is not None and center is None:
        # every grid point is evaluated: in one kernel call (make's component differs from
        # one exponent to the next in its exponents alone)
        comps0 = make(float(grid[0]))
        if len(comps0) == 1:
            rows = np.array([make(float(e))[0].exps for e in grid], dtype=float)
            D, E, M = _pack(mu_w, comps0)
            vals = nll_exponent_rows(float(fixed_mu), D, rows, M, last, _LOGU)
            values.update(zip(grid.tolist(), vals.tolist(), strict=True))

    def prof(e: float) -> float:
        e = float(e)
        if e in values:
            return values[e]
        comps = make(e)
        if fixed_mu is not None:
            v = float(_nll(mu_w, comps, np.array([fixed_mu]))[0])
        elif not known:
            pr = _profile(mu_w, comps, scale, with_interval=False, xatol=1e-7, hint=hint)
            known[e] = (math.log(max(pr.mu_star - last, 1e-300)), pr.log_u)
            v = pr.nll
        else:
            near = min(known, key=lambda k: abs(k - e))
            t_near, lu_near = known[near]
            t_e, v, lu_e = _profile_near(mu_w, comps, scale, t_near, 1e-6, lu_near)
            known[e] = (t_e, lu_e)
        values[e] = v
        return v

    c = float(grid[np.argmin(np.abs(grid - center))]) if center is not None else float(grid[0])
    ic = int(np.searchsorted(grid, c))
    f = np.full(grid.size, np.inf)  # inf: beyond the walk (the profile risen out of reach)
    f[ic] = prof(float(grid[ic]))
    for step in (1, -1):  # walk each way while the profile is within reach of its minimum
        j = ic + step
        while 0 <= j < grid.size:
            f[j] = prof(float(grid[j]))
            lowest = float(np.min(f[np.isfinite(f)], initial=np.inf))
            if center is not None and f[j] - lowest > _FAR and f[j] >= f[j - step]:
                break
            j += step
    f = np.where(np.isfinite(f), f, np.inf)
    i = int(np.argmin(f))
    curv = math.nan  # second derivative of the profile at its minimum, when known
    if 0 < i < grid.size - 1 and math.isfinite(f[i - 1]) and math.isfinite(f[i + 1]):
        eh, fh, curv = _brent_min(
            prof, (float(grid[i - 1]), float(grid[i]), float(grid[i + 1])),
            (float(f[i - 1]), float(f[i]), float(f[i + 1])), 1e-4,
        )  # fmt: skip
    else:
        a_, b_ = grid[max(i - 1, 0)], grid[min(i + 1, grid.size - 1)]
        res = optimize.minimize_scalar(
            prof, bounds=(a_, b_), method="bounded", options={"xatol": 1e-4}
        )
        eh, fh = float(res.x), float(res.fun)
        if not fh <= f[i]:
            eh, fh = float(grid[i]), float(f[i])

    def cross(sign: int) -> float:
        return _crossing_distance(prof, grid, f, eh, fh, curv, sign)

    up, dn = cross(+1), cross(-1)
    se = 0.5 * (up + dn) if math.isfinite(up) and math.isfinite(dn) else min(up, dn)
    return eh, se


def _crossing_distance(
    prof: Callable[[float], float], grid: np.ndarray, f: np.ndarray, eh: float, fh: float,
    curv: float, sign: int,
) -> float:
    """Distance from the exponent's estimate ``eh`` (profile ``fh``) to where the profile
    ``prof`` rises by 1 on the side ``sign`` (``inf`` if not within the grid, whose values
    ``f`` are known where walked), by Brent's root finder between ``eh`` and the first grid
    point that far up; with the profile's curvature ``curv`` known, in the bracket its
    parabola gives instead (1.5 times its crossing: on precise data the crossing lies 1e-4
    from ``eh`` and the grid's points 5e-3 away)."""
    j = int(np.searchsorted(grid, eh)) + (0 if sign > 0 else -1)
    while 0 <= j < grid.size and f[j] - fh < 1.0:
        j += sign
    if not 0 <= j < grid.size:
        return math.inf
    lo, hi = sorted((eh, float(grid[j])))
    if curv > 0:
        c = eh + sign * 1.5 / math.sqrt(curv / 2.0)
        if lo < c < hi:
            if prof(c) - fh - 1.0 > 0:
                lo, hi = min(eh, c), max(eh, c)
            else:
                lo, hi = (c, hi) if sign > 0 else (lo, c)
    try:
        root = optimize.brentq(lambda e: prof(e) - fh - 1.0, lo, hi, xtol=1e-5)
    except ValueError:  # a profile value not finite inside the bracket: not bounded there
        return math.inf
    return abs(root - eh)
