"""Compiled profile of the secondary fold's parameter (see :mod:`._kernels.laws`).

A law that knows a secondary fold at ``mu* + delta`` (the conformal variable of
:func:`~._kernels.laws._comp_nll`) has, besides its linear coefficients, the
fold parameter ``u = (mu* - mu_last) / delta`` in ``[0, u_max]``: at every trial mu* it is
profiled out, over a grid of ``log u`` and then refined (golden-section/parabolic steps across
a grid step, successive parabolic interpolation in a narrow bracket), from the whole grid or
from a neighbouring mu*'s optimum (a minimisation's or root finder's successive steps, a
scan's walk along mu*). ``nll_rows`` and ``nll_exponent_rows`` are the entry points of one
or many evaluations; the searches over mu* (:mod:`._kernels.profile`) call the
rest. A slow reference (scipy's bounded Brent over u, numpy least squares) lives in the tests.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from service.analysis.predictor._kernels.brent import GOLD, brent_keep, brent_parabola
from service.analysis.predictor._kernels.laws import _total, _work

# tolerance (in log u) of the fold parameter's refinement: precise data make the profile over
# u a valley some 1e-4 wide (measured: a beam sweep with 1e-6 noise, -2 log L rising by 80 over
# 3.5e-4 in log u), so a coarse tolerance leaves errors of tens in -2 log L that vary from one
# mu* to the next and corrupt the search over mu* (its intervals above all)
_U_TOL = 1e-6
_U_COARSE = 1e-3  # the tolerance of a refinement across a grid step, before the narrow one
_U_NARROW = 4e-3  # half-width of the narrow bracket
# A constant integer argument is passed as ``np.int64(...)`` here and in ._kernels.profile and
# ._kernels.laws: numba types a literal ``-1`` or ``0`` as ``Literal[int]`` and compiles the
# callee (and what it calls) once more for it, besides its ``int64`` version.



@njit(cache=True, error_model="numpy")
def _refine_u(ms, a, c, xb, fxb, fa, fc, D, E, M, x_last, WK, RK, tol):
    """Golden section with parabolic steps for the log fold parameter on ``[a, c]`` around
    ``xb`` (value ``fxb``); returns the best (log u, -2 log L). ``fa``, ``fc``: the values at
    the bracket's ends when known (grid neighbours of ``xb``; ``inf`` otherwise): the first
    step is then the parabola through the three points instead of a golden section (some
    four fits fewer to the same tolerance)."""
    w, fw, v, fv = xb, fxb, xb, fxb
    d = 0.0
    e = 0.0
    if fa < 1e300 and fc < 1e300 and a < xb < c:
        if fa <= fc:
            w, fw, v, fv = a, fa, c, fc
        else:
            w, fw, v, fv = c, fc, a, fa
        e = c - a
        d = e
    for _ in range(100):
        m = 0.5 * (a + c)
        if abs(xb - m) <= 2 * tol - 0.5 * (c - a):
            break
        use_golden = True
        if abs(e) > tol:
            p, q = brent_parabola(xb, fxb, w, fw, v, fv)
            if abs(p) < abs(0.5 * q * e) and p > q * (a - xb) and p < q * (c - xb):
                e = d
                d = p / q
                use_golden = False
        if use_golden:
            e = (c - xb) if xb < m else (a - xb)
            d = GOLD * e
        ut = xb + (d if abs(d) >= tol else (tol if d > 0 else -tol))
        fu = _total(ms, math.exp(ut), D, E, M, x_last, WK, RK)
        if not math.isfinite(fu):
            fu = 1e300
        a, c, xb, fxb, w, fw, v, fv = brent_keep(a, c, xb, fxb, w, fw, v, fv, ut, fu)
    return xb, fxb


@njit(cache=True, error_model="numpy")
def _refine_narrow(ms, a, c, xb, fxb, fa, fc, D, E, M, x_last, WK, RK):
    """The log fold parameter's minimum in a narrow bracket ``a < xb < c`` whose middle point
    is the lowest (``fxb <= fa, fc``): successive parabolic interpolation through the lowest
    point and its two nearest neighbours on either side (the bracket kept), until the next
    vertex lies within ``_U_TOL`` of the lowest point and both neighbours within ``100
    _U_TOL`` (a far neighbour is brought in by a probe ``10 _U_TOL`` beyond the lowest point),
    that vertex evaluated last. In a narrow bracket the profile is a parabola to high
    accuracy: some four fits, where the
    golden-section safeguards of :func:`_refine_u` take seven to shrink the bracket itself to
    the tolerance. Returns the lowest (log u, -2 log L) seen; a vertex outside the bracket
    (rounding) ends it."""
    x0, f0, x1, f1, x2, f2 = a, fa, xb, fxb, c, fc
    for _ in range(20):
        d0 = x1 - x0
        d2 = x1 - x2
        num = d0 * d0 * (f1 - f2) - d2 * d2 * (f1 - f0)
        den = d0 * (f1 - f2) - d2 * (f1 - f0)
        if not den != 0.0:
            break
        v = x1 - 0.5 * num / den
        if not x0 < v < x2:
            break
        if abs(v - x1) < _U_TOL:
            if max(x1 - x0, x2 - x1) <= 100 * _U_TOL:
                # converged: the vertex itself (a parabola through near points: its error
                # is far below the step, which the valley's curvature makes count)
                fv = _total(ms, math.exp(v), D, E, M, x_last, WK, RK)
                if fv < f1:
                    x1, f1 = v, fv
                break
            # a vertex from a parabola through a far end can stall next to the lowest point:
            # a probe just beyond the lowest point on that side brings the end in
            v = x1 - 10 * _U_TOL if x1 - x0 > x2 - x1 else x1 + 10 * _U_TOL
        fv = _total(ms, math.exp(v), D, E, M, x_last, WK, RK)
        if not math.isfinite(fv):
            break
        if fv < f1:
            if v < x1:
                x2, f2 = x1, f1
            else:
                x0, f0 = x1, f1
            x1, f1 = v, fv
        elif v < x1:
            x0, f0 = v, fv
        else:
            x2, f2 = v, fv
    return x1, f1


@njit(cache=True, error_model="numpy")
def _grid_u(ms, g, D, E, M, x_last, logu, WK, RK):
    """-2 log L at grid point ``g`` of the log fold parameter (1e300 if not finite)."""
    v = _total(ms, math.exp(logu[g]), D, E, M, x_last, WK, RK)
    return v if math.isfinite(v) else 1e300


@njit(cache=True, error_model="numpy")
def _scan_u(ms, D, E, M, x_last, logu, WK, RK):
    """``(value, index, left, right)`` of the lowest point of the ``logu`` grid at one mu*
    and its neighbours' values (``inf`` beyond the grid)."""
    jb = -1
    fb = math.inf
    fl = fr = math.inf
    prev = math.inf
    pending = False  # the right neighbour of a new lowest point is the next one
    for g in range(logu.size):
        v = _grid_u(ms, g, D, E, M, x_last, logu, WK, RK)
        if pending:
            fr = v
            pending = False
        if v < fb:
            fb, jb, fl = v, g, prev
            fr = math.inf
            pending = True
        prev = v
    return fb, jb, fl, fr


@njit(cache=True, error_model="numpy")
def _descend_u(ms, D, E, M, x_last, logu, WK, RK, j0):
    """``(value, index, left, right)`` of the local minimum of the ``logu`` grid reached by
    descending from index ``j0`` (left first, then right) and its neighbours' values
    (evaluated by the descent itself; ``inf`` beyond the grid)."""
    G = logu.size
    jb = j0
    fb = _grid_u(ms, j0, D, E, M, x_last, logu, WK, RK)
    fl = fr = math.inf
    j = j0 - 1
    while j >= 0:
        v = _grid_u(ms, j, D, E, M, x_last, logu, WK, RK)
        if not v < fb:
            fl = v
            break
        fr = fb
        fb, jb = v, j
        j -= 1
    if jb == j0:
        j = j0 + 1
        while j < G:
            v = _grid_u(ms, j, D, E, M, x_last, logu, WK, RK)
            if not v < fb:
                fr = v
                break
            fl = fb
            fb, jb = v, j
            j += 1
    return fb, jb, fl, fr


@njit(cache=True, error_model="numpy")
def _profile_u(ms, D, E, M, mu_last, logu, WK, RK, refine):
    """min over the fold parameter u (0 and exp(logu) grid, refined) at one mu*."""
    v, u, _, _ = _profile_u_from(ms, D, E, M, mu_last, logu, WK, RK, refine, np.int64(-1))
    return v, u


@njit(cache=True, error_model="numpy")
def _profile_u_from(ms, D, E, M, mu_last, logu, WK, RK, refine, j0):
    """:func:`_profile_u`, the ``logu`` grid searched from index ``j0`` by descent (the best
    grid point of a nearby mu*: a minimisation's or root finder's successive steps) instead
    of whole (``j0 < 0``). Returns ``(value, u, j, lu)``: ``j`` the best grid index (-1:
    none) and ``lu`` the log fold parameter of the conformal law's own optimum (refined, or
    ``logu[j]``; NaN without one), whether or not the plain law (u = 0) is better."""
    x_last = max(ms - mu_last, 1e-300)
    best = _total(ms, 0.0, D, E, M, x_last, WK, RK)
    best_u = 0.0
    if 0 <= j0 < logu.size:
        fb, jb, fl, fr = _descend_u(ms, D, E, M, x_last, logu, WK, RK, j0)
    else:
        fb, jb, fl, fr = _scan_u(ms, D, E, M, x_last, logu, WK, RK)
    if jb < 0:
        return best, best_u, jb, math.nan
    if not refine:
        if fb < best:
            return fb, math.exp(logu[jb]), jb, logu[jb]
        return best, best_u, jb, logu[jb]
    G = logu.size
    a = logu[jb - 1] if jb > 0 else logu[0]
    c = logu[jb + 1] if jb < G - 1 else logu[G - 1]
    xb, fxb = _refine_u(ms, a, c, logu[jb], fb, fl, fr, D, E, M, x_last, WK, RK, _U_COARSE)
    # then to _U_TOL in a bracket of a few coarse tolerances: a golden section from the grid's
    # bracket to _U_TOL costs some 25 fits where a parabola in the narrow one takes a few
    h = _U_NARROW
    if a + h <= xb <= c - h:
        fm = _total(ms, math.exp(xb - h), D, E, M, x_last, WK, RK)
        fp = _total(ms, math.exp(xb + h), D, E, M, x_last, WK, RK)
        if fxb <= fm and fxb <= fp:
            xb, fxb = _refine_narrow(ms, xb - h, xb + h, xb, fxb, fm, fp, D, E, M, x_last,
                                     WK, RK)  # fmt: skip
    if fxb < best:
        best = fxb
        best_u = math.exp(xb)
    return best, best_u, jb, xb


_H_WARM = 0.01  # step (in log u) of the parabola around a nearby mu*'s optimal fold parameter
_WARM_DOUBLINGS = 6  # steps of the descent from there (to 1.27 in log u) before the grid's


@njit(cache=True, error_model="numpy")
def _profile_u_warm(ms, D, E, M, mu_last, logu, WK, RK, j0, lu0):
    """:func:`_profile_u_from` (refined) for a mu* next to one whose conformal optimum was
    ``lu0`` (log u) at grid index ``j0``: when ``lu0`` is lower than ``lu0 +- _H_WARM``, the
    refinement of :func:`_refine_narrow` in that bracket (some six fits instead of the grid
    descent's and the wide bracket's twenty or so, to the same tolerance); when one of them is
    lower, the descent followed with doubling steps (at most ``_WARM_DOUBLINGS``) to a
    bracket first; an ``lu0`` within two steps of the range's ends stays there while the
    profile still falls toward that end (two fits); otherwise (a local maximum, no bracket
    within reach, an end the optimum left) the search of :func:`_profile_u_from` from ``j0``.
    Returns ``(value, u, j, lu)`` as it does."""
    G = logu.size
    h = _H_WARM
    if not (0 <= j0 < G and math.isfinite(lu0)):
        return _profile_u_from(ms, D, E, M, mu_last, logu, WK, RK, True, j0)
    x_last = max(ms - mu_last, 1e-300)
    lo, hi = logu[0], logu[G - 1]
    if lu0 < lo + 2 * h or lu0 > hi - 2 * h:
        # pinned at an end of the range: still pinned if the profile still falls toward it
        end = lo if lu0 < lo + 2 * h else hi
        fe = _total(ms, math.exp(end), D, E, M, x_last, WK, RK)
        fi = _total(ms, math.exp(end + (h if end == lo else -h)), D, E, M, x_last, WK, RK)
        if not (math.isfinite(fe) and fe <= fi):
            return _profile_u_from(ms, D, E, M, mu_last, logu, WK, RK, True, j0)
        return _u_result(ms, D, E, M, x_last, logu, WK, RK, end, fe)
    f0 = _total(ms, math.exp(lu0), D, E, M, x_last, WK, RK)
    fm = _total(ms, math.exp(lu0 - h), D, E, M, x_last, WK, RK)
    fp = _total(ms, math.exp(lu0 + h), D, E, M, x_last, WK, RK)
    if not (math.isfinite(f0) and math.isfinite(fm) and math.isfinite(fp)) or (
        f0 > fm and f0 > fp
    ):
        return _profile_u_from(ms, D, E, M, mu_last, logu, WK, RK, True, j0)
    if f0 <= fm and f0 <= fp:
        a, fa, xb, fxb, c, fc = lu0 - h, fm, lu0, f0, lu0 + h, fp
    else:
        # the optimum moved beyond a step: follow the descent with doubling steps until
        # the profile rises again (a bracket), or fall back to the grid's search
        sgn = -1.0 if fm < fp else 1.0
        xa, fa_, xm, fm_ = lu0, f0, lu0 + sgn * h, (fm if sgn < 0 else fp)
        step = h
        found = False
        for _ in range(_WARM_DOUBLINGS):
            step *= 2.0
            xc = xm + sgn * step
            if not logu[0] <= xc <= logu[G - 1]:
                break
            fc_ = _total(ms, math.exp(xc), D, E, M, x_last, WK, RK)
            if not math.isfinite(fc_):
                break
            if fc_ >= fm_:
                found = True
                break
            xa, fa_, xm, fm_ = xm, fm_, xc, fc_
        if not found:
            return _profile_u_from(ms, D, E, M, mu_last, logu, WK, RK, True, j0)
        if sgn > 0:
            a, fa, xb, fxb, c, fc = xa, fa_, xm, fm_, xc, fc_
        else:
            a, fa, xb, fxb, c, fc = xc, fc_, xm, fm_, xa, fa_
    xb, fxb = _refine_narrow(ms, a, c, xb, fxb, fa, fc, D, E, M, x_last, WK, RK)
    return _u_result(ms, D, E, M, x_last, logu, WK, RK, xb, fxb)


@njit(cache=True, error_model="numpy")
def _u_result(ms, D, E, M, x_last, logu, WK, RK, xb, fxb):
    """``(value, u, j, lu)`` of :func:`_profile_u_from` from the conformal optimum ``xb``
    (log u; value ``fxb``): the plain law (u = 0) when better, ``j`` the nearest grid index."""
    best = _total(ms, 0.0, D, E, M, x_last, WK, RK)
    best_u = 0.0
    if fxb < best:
        best = fxb
        best_u = math.exp(xb)
    G = logu.size
    jb = int(round((xb - logu[0]) / (logu[1] - logu[0])))
    jb = min(max(jb, 0), G - 1)
    return best, best_u, jb, xb


@njit(cache=True, error_model="numpy")
def _profile_u_walk(ms, D, E, M, mu_last, logu, WK, RK, j0):
    """Upper bound of the profile over u at one mu* for a scan along mu*: the grid point
    reached by descending the ``logu`` grid from index ``j0`` (the best grid point of the
    previous mu*; ``j0 < 0``: the whole grid), and u = 0 where that is the grid's first
    point (the profile falling toward u -> 0). The optimal u moves little between
    neighbouring mu*, so the walk costs some three fits instead of twelve; a scan's lowest
    points are then profiled over the whole grid (u = 0 included) and refined
    (:func:`_profile_u`).

    Returns
    -------
    value : float
    j : int
        Index of the best grid point (the next mu*'s start).
    """
    x_last = max(ms - mu_last, 1e-300)
    if 0 <= j0 < logu.size:
        fb, jb, _, _ = _descend_u(ms, D, E, M, x_last, logu, WK, RK, j0)
    else:
        fb, jb, _, _ = _scan_u(ms, D, E, M, x_last, logu, WK, RK)
    if jb > 0:
        return fb, jb  # an interior grid minimum: the plain law (u -> 0) left to exact rows
    return min(_total(ms, 0.0, D, E, M, x_last, WK, RK), fb), jb


@njit(cache=True, error_model="numpy")
def nll_rows(mu_star, D, E, M, mu_last, logu, refine=True):
    """-2 log L at each ``mu_star`` (shape (G,)) and the fold parameter ``u`` profiled there
    (0 without conformal components or when the plain law is best); ``refine=False``: the
    minimum over the ``logu`` grid only (an upper bound, for a coarse scan). ``D, E, M``: the
    packed components (:func:`_comp_nll`)."""
    G = mu_star.size
    out = np.empty(G)
    ubest = np.zeros(G)
    WK, RK = _work(D, M)
    conformal = False
    for c in range(M.shape[0]):
        if M[c, 7] == 1:
            conformal = True
    for g in range(G):
        ms = mu_star[g]
        if conformal:
            out[g], ubest[g] = _profile_u(ms, D, E, M, mu_last, logu, WK, RK, refine)
        else:
            x_last = max(ms - mu_last, 1e-300)
            out[g] = _total(ms, 0.0, D, E, M, x_last, WK, RK)
    return out, ubest


@njit(cache=True, error_model="numpy")
def nll_exponent_rows(ms, D, Erows, M, mu_last, logu):
    """-2 log L at one ``ms`` (mu*) of a single component for each row of exponents ``Erows``
    (shape (G, k), k = ``M[0, 2]``), its fold parameter profiled when conformal: an exponent's
    profile at a fixed mu* in one call (measured on a 26-point grid of 20 points: 5 us per
    exponent, where one call per exponent costs 13 us, most of it Python)."""
    G = Erows.shape[0]
    k = Erows.shape[1]
    out = np.empty(G)
    WK, RK = _work(D, M)
    E = np.empty((1, k))
    x_last = max(ms - mu_last, 1e-300)
    for g in range(G):
        for j in range(k):
            E[0, j] = Erows[g, j]
        if M[0, 7] == 1:
            out[g], _ = _profile_u(ms, D, E, M, mu_last, logu, WK, RK, True)
        else:
            out[g] = _total(ms, 0.0, D, E, M, x_last, WK, RK)
    return out
