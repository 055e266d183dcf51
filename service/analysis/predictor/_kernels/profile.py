"""Compiled search of the profile likelihood over ``mu*`` (see :mod:`.likelihood`).

The profile ``-2 log L(mu*)`` of a law (:mod:`._kernels.laws`) is searched in
``t = log(mu* - mu_last)``: a scan of a given grid, a bounded minimisation (Brent's parabolic
interpolation with golden-section safeguard) in the bracket of the grid's lowest point (and,
with ``polish > 1``, of the next lowest local minima: a valley narrower than the grid's step
may lie between two points that stand above another basin's lowest one), and the
profile-likelihood interval ends where ``-2 log L`` rises by ``delta`` above its minimum (Brent's
root finder between the last grid point below and the first above). One call does all of it, so
a profile costs no Python call per evaluation. A slow reference (the same steps with scipy's
``minimize_scalar`` and ``brentq``) lives in the tests.

Data are the packed component arrays of :func:`.likelihood._pack` passed as one
tuple ``P = (D, E, M)`` (see :func:`._kernels.laws._comp_nll`).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from service.analysis.predictor._kernels.brent import GOLD, brent_keep, brent_step
from service.analysis.predictor._kernels.fold import (
    _profile_u,
    _profile_u_from,
    _profile_u_walk,
    _profile_u_warm,
)
from service.analysis.predictor._kernels.laws import _total, _work

_EPS = 2.220446049250313e-16
BIG = 1e300  # value of a non-finite -2 log L inside the searches
_XTOL_PROBE = 1e-4  # tolerance (in t) of the refinement probing a further local minimum
_HINT_HALF = 0.3  # half-width (in t) of the local search from a minimum found before


@njit(cache=True, error_model="numpy")
def _row(ms, P, mu_last, logu, W, cf, refine):
    """-2 log L at one mu* (fold parameter profiled for a conformal law: on its grid only
    without ``refine``); BIG if not finite."""
    D, E, M = P
    WK, RK = W
    if cf:
        v, _ = _profile_u(ms, D, E, M, mu_last, logu, WK, RK, refine)
    else:
        x_last = ms - mu_last
        if x_last < 1e-300:
            x_last = 1e-300
        v = _total(ms, 0.0, D, E, M, x_last, WK, RK)
    return v if math.isfinite(v) else BIG


@njit(cache=True, error_model="numpy")
def _row_exact(ms, P, mu_last, logu, W, cf, S, j):
    """:func:`_row` (refined) at grid point ``j`` of a scan, the conformal optimum's grid
    index and log u kept in ``S[:, j]`` (where a search from that point starts)."""
    if not cf:
        return _row(ms, P, mu_last, logu, W, False, True)
    D, E, M = P
    WK, RK = W
    v, _, jb, lu = _profile_u_from(ms, D, E, M, mu_last, logu, WK, RK, True, np.int64(-1))
    S[0, j] = jb
    S[1, j] = lu
    return v if math.isfinite(v) else BIG


@njit(cache=True, error_model="numpy")
def _row_near(ms, P, mu_last, logu, W, cf, H, L):
    """:func:`_row` (refined) for the successive steps of a minimisation or root finder: a
    conformal law's fold parameter searched from the previous step's optimum, ``H[0]`` (its
    grid index; -1: none yet, the whole grid) and ``L[0]`` (its log u), which it updates.
    Neighbouring steps have nearly the same optimal u: a narrow bracket around the previous
    one (:func:`_profile_u_warm`, some six fits) instead of the grid and a refinement across
    a grid step (some 25)."""
    if not cf:
        return _row(ms, P, mu_last, logu, W, False, True)
    D, E, M = P
    WK, RK = W
    if H[0] < 0:
        v, _, jb, lu = _profile_u_from(ms, D, E, M, mu_last, logu, WK, RK, True, np.int64(-1))
    else:
        v, _, jb, lu = _profile_u_warm(ms, D, E, M, mu_last, logu, WK, RK, H[0], L[0])
    H[0] = jb
    L[0] = lu
    return v if math.isfinite(v) else BIG


@njit(cache=True, error_model="numpy")
def _minimise(a, b, xatol, P, mu_last, logu, W, cf, H, L, x0, f0, fa, fb):
    """Brent's bounded minimisation of the refined profile on ``[a, b]`` (in t); (t, value).
    ``H``, ``L``: the fold parameter's state (:func:`_row_near`) to start from, updated.

    ``x0`` inside ``(a, b)`` with a finite value ``f0`` (a grid point's exact value, ``H`` and
    ``L`` its state): the search starts there instead of at a golden-section point, and with
    the ends' values ``fa``, ``fb`` (its grid neighbours', finite) its first step is the
    parabola through the three (an end's value may be an upper bound, which only moves that
    first trial point). Measured on the symmetric bench sweep's prediction: 2455 -> 2086 rows
    over its 205 minimisations. Otherwise (``f0`` NaN) Brent's own start."""
    if a < x0 < b and math.isfinite(f0):
        x, fx = x0, f0
        if fa < BIG and fb < BIG:
            if fa <= fb:
                w, fw, v, fv = a, fa, b, fb
            else:
                w, fw, v, fv = b, fb, a, fa
            d = e = b - a
        else:
            v, w, fv, fw = x, x, fx, fx
            d = e = 0.0
    else:
        x = a + GOLD * (b - a)
        fx = _row_near(mu_last + math.exp(x), P, mu_last, logu, W, cf, H, L)
        v, w, fv, fw = x, x, fx, fx
        d = 0.0
        e = 0.0
    for _ in range(500):
        u, d, e = brent_step(a, b, x, fx, w, fw, v, fv, d, e, xatol)
        if math.isnan(u):
            break
        fu = _row_near(mu_last + math.exp(u), P, mu_last, logu, W, cf, H, L)
        a, b, x, fx, w, fw, v, fv = brent_keep(a, b, x, fx, w, fw, v, fv, u, fu)
    return x, fx


@njit(cache=True, error_model="numpy")
def _crossing(a, b, fa, fb, level, P, mu_last, logu, W, cf, H0, L0):
    """t in [a, b] where the refined profile equals ``level`` (Brent's root finder on
    ``f - level``; ``fa``, ``fb``: the differences at the ends, of opposite signs), the fold
    parameter started from the state ``H0``, ``L0`` (:func:`_row_near`; not modified)."""
    xtol = 1e-9
    H = H0.copy()
    L = L0.copy()
    c, fc = a, fa
    d = b - a
    e = d
    for _ in range(200):
        if (fb > 0.0) == (fc > 0.0):
            c, fc = a, fa
            d = b - a
            e = d
        if abs(fc) < abs(fb):
            a, b, c = b, c, b
            fa, fb, fc = fb, fc, fb
        tol = 2.0 * _EPS * abs(b) + 0.5 * xtol
        m = 0.5 * (c - b)
        if abs(m) <= tol or fb == 0.0:
            return b
        if abs(e) < tol or abs(fa) <= abs(fb):
            d = m
            e = m
        else:
            s = fb / fa
            if a == c:
                p = 2.0 * m * s
                q = 1.0 - s
            else:
                q = fa / fc
                r = fb / fc
                p = s * (2.0 * m * q * (q - r) - (b - a) * (r - 1.0))
                q = (q - 1.0) * (r - 1.0) * (s - 1.0)
            if p > 0.0:
                q = -q
            else:
                p = -p
            if 2.0 * p < min(3.0 * m * q - abs(tol * q), abs(e * q)):
                e = d
                d = p / q
            else:
                d = m
                e = m
        a, fa = b, fb
        b += d if abs(d) > tol else (tol if m > 0.0 else -tol)
        fb = _row_near(mu_last + math.exp(b), P, mu_last, logu, W, cf, H, L) - level
    return b


@njit(cache=True, error_model="numpy")
def _scan(t, P, mu_last, logu, W, cf, f, exact, S):
    """Fill ``f`` with the profile on the grid ``t``: a conformal law's fold parameter by a
    descent on its own grid continued from the previous point (an upper bound) except at the
    five lowest points, profiled over its whole grid and refined (their fold parameter's
    optimum kept in ``S``)."""
    G = t.size
    if not cf:
        for j in range(G):
            f[j] = _row(mu_last + math.exp(t[j]), P, mu_last, logu, W, False, True)
            exact[j] = True
        return
    D, E, M = P
    WK, RK = W
    jb = np.int64(-1)  # not the literal -1: numba would compile the walk for it too
    for j in range(G):
        v, jb = _profile_u_walk(mu_last + math.exp(t[j]), D, E, M, mu_last, logu, WK, RK, jb)
        f[j] = v if math.isfinite(v) else BIG
        exact[j] = False
    order = np.argsort(f)
    for r in range(min(5, G)):
        j = order[r]
        f[j] = _row_exact(mu_last + math.exp(t[j]), P, mu_last, logu, W, cf, S, j)  # cf: True
        exact[j] = True


@njit(cache=True, error_model="numpy")
def _fval(j, t, f, exact, S, P, mu_last, logu, W, cf):
    if not exact[j]:
        f[j] = _row_exact(mu_last + math.exp(t[j]), P, mu_last, logu, W, cf, S, j)
        exact[j] = True
    return f[j]


@njit(cache=True, error_model="numpy")
def _ends(th, fh, delta, t, f, exact, S, P, mu_last, logu, W, cf, H, L):
    """Interval ends (in t) where the profile rises ``delta`` above ``fh``; open ends as NaN.
    ``H``, ``L``: the fold parameter's state at the minimum, where each crossing starts."""
    G = t.size
    j = np.searchsorted(t, th) - 1
    while j >= 0 and _fval(j, t, f, exact, S, P, mu_last, logu, W, cf) - fh < delta:
        j -= 1
    lo = math.nan
    if j >= 0:
        lo = _crossing(
            t[j], th, f[j] - fh - delta, -delta, fh + delta, P, mu_last, logu, W, cf, H, L
        )
    j = np.searchsorted(t, th)
    while j < G and _fval(j, t, f, exact, S, P, mu_last, logu, W, cf) - fh < delta:
        j += 1
    hi = math.nan
    if j < G:
        hi = _crossing(
            th, t[j], -delta, f[j] - fh - delta, fh + delta, P, mu_last, logu, W, cf, H, L
        )
    return lo, hi


@njit(cache=True, error_model="numpy")
def _polish(i, t, f, exact, S, xatol, P, mu_last, logu, W, cf):
    """Minimum in the bracket of grid point ``i`` (its neighbours), never above ``f[i]``, and
    the fold parameter's state there (:func:`_row_near`; started from grid point ``i``'s)."""
    G = t.size
    a = t[i - 1] if i > 0 else t[0]
    b = t[i + 1] if i < G - 1 else t[G - 1]
    H = np.full(1, np.int64(S[0, i]), dtype=np.int64)
    L = np.full(1, S[1, i])
    f0 = fa = fb = math.nan
    if exact[i] and 0 < i < G - 1:
        f0, fa, fb = f[i], f[i - 1], f[i + 1]
    th, fh = _minimise(a, b, xatol, P, mu_last, logu, W, cf, H, L, t[i], f0, fa, fb)
    if not fh <= f[i]:
        th, fh = t[i], f[i]
        H[0] = np.int64(S[0, i])
        L[0] = S[1, i]
    return th, fh, H, L


@njit(cache=True, error_model="numpy")
def profile_scan(t, P, mu_last, logu, cf):
    """The scan of :func:`profile_search` alone: ``(f, exact, S)``, the profile on the grid
    ``t``, which of its values are exact (a conformal law's others are upper bounds) and, at
    those, the fold parameter's optimum (``S[0]`` its ``logu`` grid index, ``S[1]`` its log u;
    -1 and NaN elsewhere). It depends on the grid and the data only, not on the search's
    tolerance or intervals: a scan kept serves every later search of the same grid and data
    (:func:`profile_search_scanned`)."""
    W = _work(P[0], P[2])
    G = t.size
    f = np.empty(G)
    exact = np.zeros(G, dtype=np.bool_)
    S = np.empty((2, G))
    S[0, :] = -1.0
    S[1, :] = math.nan
    _scan(t, P, mu_last, logu, W, cf, f, exact, S)
    return f, exact, S


@njit(cache=True, error_model="numpy")
def profile_search(
    t, P, mu_last, logu, cf, xatol, d95, d68, polish=1, ht=math.nan, hj=-1, hlu=math.nan
):
    """Minimum of the profile over the grid ``t`` (log distances, increasing) and its intervals.

    Parameters
    ----------
    t : ndarray, shape (G,)
        Increasing grid of ``log(mu* - mu_last)``.
    P : tuple
        Packed components ``(D, E, M)``.
    mu_last : float
        Last measured control value.
    logu : ndarray
        Grid of the log fold parameter (conformal laws).
    cf : bool
        Whether a component is conformal (fold parameter profiled at every mu*).
    xatol : float
        Tolerance of the minimisation in t.
    d95, d68 : float
        Rises of ``-2 log L`` that end the intervals; an interval whose rise is ``<= 0`` is not
        searched (its ends NaN). Each interval's ends are the same whether or not the other is
        searched: the grid values the walks make exact are the same refined rows, and each
        crossing starts from the same fold-parameter state, the minimum's.
    polish : int
        Local minima of the scan refined (the lowest, then the next lowest ones).
    ht, hj, hlu : float, int, float
        A hint: ``t`` of a minimum found before (NaN: none) and a conformal law's fold
        parameter there (grid index, log u; -1 and NaN: unknown). The minimum is also searched
        locally from there (Brent's method within ``_HINT_HALF``) and kept where lower: a
        valley narrower than the grid can lie where the walk's grid of the fold parameter
        overestimates the profile by orders of magnitude, out of the scan's lowest points.

    Returns
    -------
    out : ndarray, shape (9,)
        ``(t_hat, nll_hat, i_grid, t_lo95, t_hi95, t_lo68, t_hi68, j_u, log_u)``: the interval
        ends in t, NaN where the profile does not rise that far within the grid; ``i_grid`` the
        index of the grid's lowest point; ``j_u``, ``log_u``: a conformal law's fold parameter
        near the minimum (its ``logu`` grid index and log u, where a search of a neighbouring
        window can start: :func:`profile_local`; NaN for plain laws).
    """
    f, exact, S = profile_scan(t, P, mu_last, logu, cf)
    Q = np.full((2, t.size), math.nan)
    return profile_search_scanned(
        t, f, exact, S, Q, P, mu_last, logu, cf, xatol, d95, d68, polish, ht, hj, hlu
    )


@njit(cache=True, error_model="numpy")
def profile_search_scanned(
    t, f, exact, S, Q, P, mu_last, logu, cf, xatol, d95, d68, polish=1, ht=math.nan, hj=-1,
    hlu=math.nan,
):
    """:func:`profile_search` after its scan, ``(f, exact, S)`` of :func:`profile_scan` on the
    same grid and data (the same result, to the bit). ``f``, ``exact`` and ``S`` are updated in
    place (the interval walks make values exact): pass copies to keep a scan for another
    search. ``Q`` (2, G): the coarse probes of the scan's further local minima (t and value
    per grid point, NaN where not probed), filled in place: pass the same array to every
    search of one scan and each basin is probed once (measured: some 8 searches of a symmetric
    bench prediction repeat a scan's probes, some 150 fits each for a conformal law)."""
    W = _work(P[0], P[2])
    G = t.size
    i = int(np.argmin(f))
    th, fh, H, L = _polish(i, t, f, exact, S, xatol, P, mu_last, logu, W, cf)
    if polish > 1:
        # the next lowest local minima of the scan: a narrow valley between grid points may
        # hold a lower minimum than the basin of the lowest grid point
        cand = np.empty(G, dtype=np.int64)
        nc = 0
        for j in range(G):
            if j != i and (j == 0 or f[j] <= f[j - 1]) and (j == G - 1 or f[j] <= f[j + 1]):
                cand[nc] = j
                nc += 1
        vals = np.empty(nc)
        for r in range(nc):
            vals[r] = f[cand[r]]
        order = np.argsort(vals)
        for r in range(min(polish - 1, nc)):
            j = cand[order[r]]
            # a coarse refinement tells whether this basin goes lower; only then the full one.
            # Kept in Q: a later search of the same scan probes the same basins from the same
            # values (the walks that update them come after), to the bit the same
            ptol = max(xatol, _XTOL_PROBE)
            if ptol == _XTOL_PROBE and not math.isnan(Q[1, j]):
                tj, fj = Q[0, j], Q[1, j]
            else:
                tj, fj, _, _ = _polish(j, t, f, exact, S, ptol, P, mu_last, logu, W, cf)
                if ptol == _XTOL_PROBE:
                    Q[0, j], Q[1, j] = tj, fj
            if fj < fh:
                tj, fj, Hj, Lj = _polish(j, t, f, exact, S, xatol, P, mu_last, logu, W, cf)
                if fj < fh:
                    th, fh, i, H, L = tj, fj, j, Hj, Lj
    if math.isfinite(ht):
        # a minimum found before (a window choice's local search): a valley narrower than
        # the grid that the scan's walk passed over is searched from there
        a = max(ht - _HINT_HALF, t[0])
        b = min(ht + _HINT_HALF, t[G - 1])
        if a < ht < b:
            Hh = np.full(1, hj, dtype=np.int64)
            Lh = np.full(1, hlu)
            tj, fj, _ = _local(ht, a, b, P, mu_last, logu, W, cf, xatol, Hh, Lh)
            if fj < fh:
                th, fh, H, L = tj, fj, Hh, Lh
                i = min(max(int(np.searchsorted(t, th)), 0), G - 1)
    out = np.full(9, math.nan)
    out[0], out[1], out[2] = th, fh, i
    if cf:
        out[7], out[8] = H[0], L[0]
    if d95 > 0.0:
        out[3], out[4] = _ends(th, fh, d95, t, f, exact, S, P, mu_last, logu, W, cf, H, L)
    if d68 > 0.0:
        out[5], out[6] = _ends(th, fh, d68, t, f, exact, S, P, mu_last, logu, W, cf, H, L)
    return out


_H_LOCAL = 0.01  # first step (in t) of a local search's bracketing
_LOCAL_DOUBLINGS = 6  # its doubling steps at most (to 0.64 in t)


@njit(cache=True, error_model="numpy")
def profile_local(t0, a, b, P, mu_last, logu, cf, xatol, j0, lu0):
    """Minimum of the refined profile near ``t0`` inside ``[a, b]`` (in t, ``a < t0 < b``):
    ``t0 +- _H_LOCAL`` first, doubling steps downhill until the profile rises again (a
    bracket), then Brent's method from the bracket's three points; a conformal law's fold
    parameter searched at ``t0`` from ``j0``, ``lu0`` (its ``logu`` grid index and log u at a
    neighbouring window's or law's optimum; ``j0 < 0``: the whole grid) and from each step's
    optimum after it (:func:`_row_near`). Where a neighbour's optimum is known the minimum
    usually lies within a step or two: measured on the symmetric bench sweep's window
    choice, 60-125 fits of the conformal law where the screen's global search takes
    325-400. Any value it returns is an upper bound of the global minimum; without a bracket
    within reach (``[a, b]``, the doublings) the lowest point seen. Returns
    ``(t, value, j_u, log_u, bracketed)``: ``bracketed`` whether a minimum was bracketed (a
    point below its two neighbours) and refined, rather than the lowest point seen."""
    W = _work(P[0], P[2])
    H = np.full(1, j0, dtype=np.int64)
    L = np.full(1, lu0)
    th, fh, ok = _local(t0, a, b, P, mu_last, logu, W, cf, xatol, H, L)
    return th, fh, H[0], L[0], ok


@njit(cache=True, error_model="numpy")
def _local(t0, a, b, P, mu_last, logu, W, cf, xatol, H, L):
    """:func:`profile_local` on the work arrays ``W``, the fold parameter's state ``H``, ``L``
    (updated: the last row's). Returns ``(t, value, bracketed)``."""
    h = _H_LOCAL
    f0 = _row_near(mu_last + math.exp(t0), P, mu_last, logu, W, cf, H, L)
    if not (a < t0 - h and t0 + h < b):
        th, fh = _minimise(a, b, xatol, P, mu_last, logu, W, cf, H, L, t0, f0, math.nan, math.nan)
        return th, fh, False
    fm = _row_near(mu_last + math.exp(t0 - h), P, mu_last, logu, W, cf, H, L)
    fp = _row_near(mu_last + math.exp(t0 + h), P, mu_last, logu, W, cf, H, L)
    if f0 <= fm and f0 <= fp:
        lo, flo, xm, fxm, hi, fhi = t0 - h, fm, t0, f0, t0 + h, fp
    else:
        sgn = -1.0 if fm < fp else 1.0
        xa, fa, xm, fxm = t0, f0, t0 + sgn * h, min(fm, fp)
        step = h
        found = False
        for _ in range(_LOCAL_DOUBLINGS):
            step *= 2.0
            xc = xm + sgn * step
            if not a < xc < b:
                break
            fc = _row_near(mu_last + math.exp(xc), P, mu_last, logu, W, cf, H, L)
            if fc >= fxm:
                found = True
                break
            xa, fa, xm, fxm = xm, fxm, xc, fc
        if not found:
            return xm, fxm, False
        if sgn > 0:
            lo, flo, hi, fhi = xa, fa, xc, fc
        else:
            lo, flo, hi, fhi = xc, fc, xa, fa
    th, fh = _minimise(lo, hi, xatol, P, mu_last, logu, W, cf, H, L, xm, fxm, flo, fhi)
    if not fh <= fxm:
        th, fh = xm, fxm
    return th, fh, True
