"""Compiled cusp (unfolded pitchfork) law: the amplitude, the stiffness and the eigenvalue misfit.

The imperfect pitchfork's equilibrium ``eps + (mu* - mu) x -+ c x^3 = 0`` (softening ``-``,
stiffening ``+``), in the units ``G = c^(1/3) eps^(2/3)`` (a load) and ``v = x (c/eps)^(1/3)``,
reads ``r = lambda / G = 1/v + s v^2`` with ``lambda = mu* - mu`` and ``s = +1`` softening,
``-1`` stiffening; the stiffness along it is ``k = lambda - 3 s G v^2``. Softening: the branch
``v`` in ``(0, 2^(-1/3)]`` ends at the fold ``r_f = 3 2^(-2/3)`` where ``k = 0``; stiffening:
``v > 0`` for every ``lambda``, ``k`` least (``K_MIN G``) at ``r_m = 4^(1/3) - 4^(-2/3)``.
``G = 0`` is the perfect pitchfork, ``k = lambda``.

The eigenvalue law is ``|sigma^2| = k sum_j alpha_j (lambda / scale)^j`` (``j <= K``), the
``alpha_j`` by weighted least squares (normal equations, at most 4 unknowns). A slow reference
(numpy's roots and least squares) lives in the tests.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

R_FOLD = 3.0 * 2.0 ** (-2.0 / 3.0)  # lambda_f / G of the softening branch's fold
R_MIN = 4.0 ** (1.0 / 3.0) - 4.0 ** (-2.0 / 3.0)  # lambda / G where a stiffening k is least
K_MIN = 4.0 ** (1.0 / 3.0) + 2.0 * 4.0 ** (-2.0 / 3.0)  # that least k over G
V_FOLD = 2.0 ** (-1.0 / 3.0)


@njit(cache=True)
def amplitude(r: float, soft: bool) -> float:
    """The branch's reduced amplitude ``v`` at ``r = lambda / G`` (NaN past a softening fold)."""
    if soft:
        if r < R_FOLD:
            return math.nan
        if r > 8.0:  # v = (1 + v^3) / r: a contraction of ratio ~3 / r^3
            v = 1.0 / r
            for _ in range(5):
                v = (1.0 + v * v * v) / r
            return v
        c = -(1.5 / r) * math.sqrt(3.0 / r)
        c = min(1.0, max(-1.0, c))
        v = 2.0 * math.sqrt(r / 3.0) * math.cos(math.acos(c) / 3.0 - 2.0 * math.pi / 3.0)
        for _ in range(3):  # Newton polish of v^3 - r v + 1 = 0 (away from the fold)
            d = 3.0 * v * v - r
            if abs(d) < 1e-9:
                break
            v = v - (v * v * v - r * v + 1.0) / d
        return min(v, V_FOLD)
    if r > 8.0:  # v = 1 / (r + v^2)
        v = 1.0 / r
        for _ in range(5):
            v = 1.0 / (r + v * v)
        return v
    disc = 0.25 + r * r * r / 27.0
    if disc > 0:
        s = math.sqrt(disc)
        v = np.cbrt(0.5 + s) + np.cbrt(0.5 - s)
    else:
        c = (-1.5 / r) * math.sqrt(-3.0 / r)
        c = min(1.0, max(-1.0, c))
        v = 2.0 * math.sqrt(-r / 3.0) * math.cos(math.acos(c) / 3.0)
    for _ in range(3):  # Newton polish of v^3 + r v - 1 = 0 (3 v^2 + r > 0 at the root)
        d = 3.0 * v * v + r
        if d <= 0:
            break
        v = v - (v * v * v + r * v - 1.0) / d
    return v


@njit(cache=True)
def stiffness(lam: float, G: float, soft: bool) -> float:
    """``k`` at ``lambda = mu* - mu`` (NaN past a softening fold); ``G = 0``: ``lambda``."""
    if G <= 0:
        return lam
    v = amplitude(lam / G, soft)
    if soft:
        return lam - 3.0 * G * v * v
    return lam + 3.0 * G * v * v


@njit(cache=True)
def _solve(A: np.ndarray, b: np.ndarray, m: int) -> bool:
    """Solve the ``m x m`` symmetric positive system in place (Cholesky; ``b`` -> solution);
    False when it is singular."""
    for j in range(m):
        s = A[j, j]
        for k in range(j):
            s -= A[j, k] * A[j, k]
        if not s > 1e-300:
            return False
        d = math.sqrt(s)
        A[j, j] = d
        for i in range(j + 1, m):
            t = A[i, j]
            for k in range(j):
                t -= A[i, k] * A[j, k]
            A[i, j] = t / d
    for i in range(m):  # forward
        t = b[i]
        for k in range(i):
            t -= A[i, k] * b[k]
        b[i] = t / A[i, i]
    for i in range(m - 1, -1, -1):  # backward
        t = b[i]
        for k in range(i + 1, m):
            t -= A[k, i] * b[k]
        b[i] = t / A[i, i]
    return True


@njit(cache=True)
def _work(K: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Work arrays of :func:`_nll` for ``K`` corrections: the normal matrix, its right-hand
    side, a row of the design and the solution. A search allocates them once: four small
    arrays per evaluation cost some 15-25 % of an evaluation of a ten-point window."""
    m = K + 1
    return np.empty((m, m)), np.empty(m), np.empty(m), np.empty(m)


@njit(cache=True)
def cusp_nll(
    mu: np.ndarray, y: np.ndarray, wt: np.ndarray, scale: float, mu_star: float, G: float,
    soft: bool, K: int,
) -> float:
    """``-2 log L`` (the weighted residual sum of squares) of the eigenvalue law at ``mu*`` and
    ``G`` with ``K`` corrections, the ``alpha_j`` profiled; ``inf`` where a point lies past the
    fold or the stiffness is not positive."""
    return _nll(mu, y, wt, scale, mu_star, G, soft, K, _work(K))


@njit(cache=True)
def _nll(
    mu: np.ndarray, y: np.ndarray, wt: np.ndarray, scale: float, mu_star: float, G: float,
    soft: bool, K: int, W: tuple,
) -> float:
    """:func:`cusp_nll` on the work arrays ``W`` (:func:`_work`; overwritten): the same
    operations in the same order (the normal matrix and right-hand side start from zeros, the
    solution from a copy of the right-hand side, as when they were allocated here)."""
    A, b, basis, rhs = W
    n = mu.size
    m = K + 1
    for j in range(m):
        b[j] = 0.0
        for l in range(m):
            A[j, l] = 0.0
    yy = 0.0
    for i in range(n):
        lam = mu_star - mu[i]
        k = stiffness(lam, G, soft)
        if not k > 0:
            return math.inf
        q = lam / scale
        p = k * wt[i]
        for j in range(m):
            basis[j] = p
            p *= q
        yi = y[i] * wt[i]
        yy += yi * yi
        for j in range(m):
            b[j] += basis[j] * yi
            for l in range(j + 1):
                A[j, l] += basis[j] * basis[l]
    for j in range(m):
        for l in range(j + 1, m):
            A[j, l] = A[l, j]
    for j in range(m):
        rhs[j] = b[j]
    if not _solve(A, rhs, m):
        return math.inf
    fit = 0.0
    for j in range(m):
        fit += rhs[j] * b[j]
    return max(yy - fit, 0.0)


@njit(cache=True)
def _at(
    mu: np.ndarray, y: np.ndarray, wt: np.ndarray, scale: float, t: float, g: float,
    soft: bool, K: int, shift: float,
) -> float:
    """:func:`_at_w` with its own work arrays (one evaluation)."""
    return _at_w(mu, y, wt, scale, t, g, soft, K, shift, _work(K))


@njit(cache=True)
def _at_w(
    mu: np.ndarray, y: np.ndarray, wt: np.ndarray, scale: float, t: float, g: float,
    soft: bool, K: int, shift: float, W: tuple,
) -> float:
    """``cusp_nll`` in the search variables: the point it predicts ``mu_p = mu[-1] +
    scale exp(t) - shift G`` (the fold, softening; the least stiffness, stiffening) and
    ``G = scale exp(g)`` (``g = -inf``: the perfect law, ``mu* = mu_p``)."""
    G = scale * math.exp(g) if g > -700 else 0.0
    mu_p = mu[-1] + scale * math.exp(t) - shift * G
    mu_star = mu_p + (R_FOLD if soft else R_MIN) * G
    return _nll(mu, y, wt, scale, mu_star, G, soft, K, W)


@njit(cache=True)
def profile_g(
    mu: np.ndarray, y: np.ndarray, wt: np.ndarray, scale: float, t: float, gs: np.ndarray,
    soft: bool, K: int, shift: float, refine: bool = True,
) -> tuple[float, float]:
    """The profile over ``g`` at ``t``: the grid ``gs`` (and the perfect law, ``g = -inf``),
    then (``refine``) golden-section search between the best point's neighbours. Returns
    ``(nll, g)``."""
    return _profile_g(mu, y, wt, scale, t, gs, soft, K, shift, refine, _work(K))


@njit(cache=True)
def _profile_g(
    mu: np.ndarray, y: np.ndarray, wt: np.ndarray, scale: float, t: float, gs: np.ndarray,
    soft: bool, K: int, shift: float, refine: bool, W: tuple,
) -> tuple[float, float]:
    """:func:`profile_g` on the work arrays ``W``."""
    best = _at_w(mu, y, wt, scale, t, -math.inf, soft, K, shift, W)
    gb = -math.inf
    ib = -1
    for i in range(gs.size):
        f = _at_w(mu, y, wt, scale, t, gs[i], soft, K, shift, W)
        if f < best:
            best, gb, ib = f, gs[i], i
    if ib < 0 or not refine:
        return best, gb
    a = gs[ib - 1] if ib > 0 else gs[0] - (gs[1] - gs[0])
    c = gs[ib + 1] if ib < gs.size - 1 else gs[-1]
    gr = 0.5 * (math.sqrt(5.0) - 1.0)
    x1 = c - gr * (c - a)
    x2 = a + gr * (c - a)
    f1 = _at_w(mu, y, wt, scale, t, x1, soft, K, shift, W)
    f2 = _at_w(mu, y, wt, scale, t, x2, soft, K, shift, W)
    for _ in range(60):
        if f1 < f2:
            c, x2, f2 = x2, x1, f1
            x1 = c - gr * (c - a)
            f1 = _at_w(mu, y, wt, scale, t, x1, soft, K, shift, W)
        else:
            a, x1, f1 = x1, x2, f2
            x2 = a + gr * (c - a)
            f2 = _at_w(mu, y, wt, scale, t, x2, soft, K, shift, W)
        if c - a < 1e-6:
            break
    if f1 < best:
        best, gb = f1, x1
    if f2 < best:
        best, gb = f2, x2
    return best, gb


@njit(cache=True)
def profile_scan(
    mu: np.ndarray, y: np.ndarray, wt: np.ndarray, scale: float, ts: np.ndarray,
    gs: np.ndarray, soft: bool, K: int, shift: float, refine: bool,
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`profile_g` at every ``t`` of ``ts``: the profile ``nll(t)`` and its ``g``."""
    f = np.empty(ts.size)
    g = np.empty(ts.size)
    W = _work(K)
    for i in range(ts.size):
        f[i], g[i] = _profile_g(mu, y, wt, scale, ts[i], gs, soft, K, shift, refine, W)
    return f, g


@njit(cache=True)
def _boxed(
    mu: np.ndarray, y: np.ndarray, wt: np.ndarray, scale: float, t: float, g: float,
    soft: bool, K: int, shift: float, box: np.ndarray, W: tuple,
) -> float:
    """:func:`_at` inside ``box = (t_lo, t_hi, g_lo, g_hi)``, ``inf`` outside (far from the
    records, with ``G`` beyond the window's span, the normal equations lose every digit and
    ``-2 log L`` reads 0)."""
    if not (box[0] <= t <= box[1] and box[2] <= g <= box[3]):
        return math.inf
    return _at_w(mu, y, wt, scale, t, g, soft, K, shift, W)


@njit(cache=True)
def polish(
    mu: np.ndarray, y: np.ndarray, wt: np.ndarray, scale: float, t0: float, g0: float,
    soft: bool, K: int, shift: float, step: float, tol: float, max_eval: int,
    box: np.ndarray,
) -> tuple[float, float, float]:
    """The joint minimum of :func:`_at` over ``(t, g)`` from ``(t0, g0)``: Nelder-Mead's
    simplex (reflection 1, expansion 2, contraction 1/2, shrink 1/2), first steps ``step``,
    inside ``box`` (``t_lo, t_hi, g_lo, g_hi``), until the simplex spans less than ``tol`` in
    both variables or ``max_eval`` evaluations.

    The scan over ``t`` with ``g`` profiled on a grid (:func:`profile_scan`) only brackets the
    minimum: the law's valley in ``(t, g)`` is narrower than either grid (a stiffening column's
    records, 6 points, noise 7e-5: the scan's best ``-2 log L`` 1.8e5, the joint minimum 0.2).
    Returns ``(nll, t, g)``."""
    W = _work(K)
    xs = np.empty((3, 2))
    fs = np.empty(3)
    xs[0, 0], xs[0, 1] = t0, g0
    xs[1, 0], xs[1, 1] = t0 + step, g0
    xs[2, 0], xs[2, 1] = t0, g0 + step
    for i in range(3):
        fs[i] = _boxed(mu, y, wt, scale, xs[i, 0], xs[i, 1], soft, K, shift, box, W)
    n_eval = 3
    while n_eval < max_eval:
        # order: best 0, worst 2
        for i in range(2):
            for j in range(2 - i):
                if fs[j + 1] < fs[j] or (not fs[j] == fs[j]):
                    fs[j], fs[j + 1] = fs[j + 1], fs[j]
                    for c in range(2):
                        xs[j, c], xs[j + 1, c] = xs[j + 1, c], xs[j, c]
        span = 0.0
        for i in range(1, 3):
            for c in range(2):
                span = max(span, abs(xs[i, c] - xs[0, c]))
        if span < tol:
            break
        cx = 0.5 * (xs[0, 0] + xs[1, 0])
        cy = 0.5 * (xs[0, 1] + xs[1, 1])
        rx = cx + (cx - xs[2, 0])
        ry = cy + (cy - xs[2, 1])
        fr = _boxed(mu, y, wt, scale, rx, ry, soft, K, shift, box, W)
        n_eval += 1
        if fr < fs[0]:
            ex = cx + 2.0 * (cx - xs[2, 0])
            ey = cy + 2.0 * (cy - xs[2, 1])
            fe = _boxed(mu, y, wt, scale, ex, ey, soft, K, shift, box, W)
            n_eval += 1
            if fe < fr:
                xs[2, 0], xs[2, 1], fs[2] = ex, ey, fe
            else:
                xs[2, 0], xs[2, 1], fs[2] = rx, ry, fr
            continue
        if fr < fs[1]:
            xs[2, 0], xs[2, 1], fs[2] = rx, ry, fr
            continue
        if fr < fs[2]:  # outside contraction
            kx = cx + 0.5 * (rx - cx)
            ky = cy + 0.5 * (ry - cy)
        else:  # inside contraction
            kx = cx + 0.5 * (xs[2, 0] - cx)
            ky = cy + 0.5 * (xs[2, 1] - cy)
        fk = _boxed(mu, y, wt, scale, kx, ky, soft, K, shift, box, W)
        n_eval += 1
        if fk < min(fr, fs[2]):
            xs[2, 0], xs[2, 1], fs[2] = kx, ky, fk
            continue
        for i in range(1, 3):  # shrink toward the best
            xs[i, 0] = xs[0, 0] + 0.5 * (xs[i, 0] - xs[0, 0])
            xs[i, 1] = xs[0, 1] + 0.5 * (xs[i, 1] - xs[0, 1])
            fs[i] = _boxed(mu, y, wt, scale, xs[i, 0], xs[i, 1], soft, K, shift, box, W)
            n_eval += 1
    ib = 0
    for i in range(1, 3):
        if fs[i] < fs[ib]:
            ib = i
    return fs[ib], xs[ib, 0], xs[ib, 1]


@njit(cache=True)
def scan2(
    mu: np.ndarray, y: np.ndarray, wt: np.ndarray, scale: float, ts: np.ndarray,
    gs: np.ndarray, soft: bool, K: int, shift: float,
) -> np.ndarray:
    """:func:`_at` on the grid ``ts x gs``, shape ``(ts.size, gs.size)``: the starts of
    :func:`polish`."""
    F = np.empty((ts.size, gs.size))
    W = _work(K)
    for i in range(ts.size):
        for j in range(gs.size):
            F[i, j] = _at_w(mu, y, wt, scale, ts[i], gs[j], soft, K, shift, W)
    return F


@njit(cache=True)
def nll_point(
    mu: np.ndarray, y: np.ndarray, wt: np.ndarray, scale: float, mu_p: float, g: float,
    soft: bool, K: int, shift: float,
) -> float:
    """:func:`cusp_nll` at the point the law predicts, ``mu_p`` (the fold, softening; the
    least stiffness, stiffening), and ``G = scale exp(g)``; ``inf`` where ``mu_p`` lies more
    than ``shift G`` before the last point (the search's domain, as :func:`_at`'s)."""
    return _nll_point(mu, y, wt, scale, mu_p, g, soft, K, shift, _work(K))


@njit(cache=True)
def _nll_point(
    mu: np.ndarray, y: np.ndarray, wt: np.ndarray, scale: float, mu_p: float, g: float,
    soft: bool, K: int, shift: float, W: tuple,
) -> float:
    """:func:`nll_point` on the work arrays ``W``."""
    G = scale * math.exp(g) if g > -700 else 0.0
    if not mu_p - mu[-1] + shift * G > 0:
        return math.inf
    mu_star = mu_p + (R_FOLD if soft else R_MIN) * G
    return _nll(mu, y, wt, scale, mu_star, G, soft, K, W)


@njit(cache=True)
def profile_point(
    mu: np.ndarray, y: np.ndarray, wt: np.ndarray, scale: float, mu_p: float, soft: bool,
    K: int, shift: float, gc: float, width: float, g_max: float,
) -> tuple[float, float]:
    """The profile over ``g`` at the point ``mu_p``: golden-section search over ``[gc -
    width, min(gc + width, g_max)]`` (continued from a neighbouring point's ``gc``: at a fixed
    point the valley in ``g`` is narrow but single, at a fixed ``t`` it is not), the perfect
    law and ``gc`` itself. Returns ``(nll, g)``."""
    W = _work(K)
    best = _nll_point(mu, y, wt, scale, mu_p, gc, soft, K, shift, W)
    gb = gc
    f = _nll_point(mu, y, wt, scale, mu_p, -math.inf, soft, K, shift, W)
    if f < best:
        best, gb = f, -math.inf
    a = gc - width
    c = min(gc + width, g_max)
    gr = 0.5 * (math.sqrt(5.0) - 1.0)
    x1 = c - gr * (c - a)
    x2 = a + gr * (c - a)
    f1 = _nll_point(mu, y, wt, scale, mu_p, x1, soft, K, shift, W)
    f2 = _nll_point(mu, y, wt, scale, mu_p, x2, soft, K, shift, W)
    for _ in range(90):
        if f1 < f2:
            c, x2, f2 = x2, x1, f1
            x1 = c - gr * (c - a)
            f1 = _nll_point(mu, y, wt, scale, mu_p, x1, soft, K, shift, W)
        else:
            a, x1, f1 = x1, x2, f2
            x2 = a + gr * (c - a)
            f2 = _nll_point(mu, y, wt, scale, mu_p, x2, soft, K, shift, W)
        if c - a < 1e-10:
            break
    if f1 < best:
        best, gb = f1, x1
    if f2 < best:
        best, gb = f2, x2
    return best, gb


@njit(cache=True)
def fold_nll(
    mu: np.ndarray, y: np.ndarray, wt: np.ndarray, scale: float, mu_f: float, K: int,
) -> float:
    """``-2 log L`` of the perfect fold's eigenvalue law ``|sigma^2| = (mu_f - mu)^(1/2) sum_j
    alpha_j ((mu_f - mu)/scale)^j`` (``j <= K``, the ``alpha_j`` profiled), the comparator of
    a softening cusp's fold: ``inf`` where a point lies at or past ``mu_f``."""
    n = mu.size
    m = K + 1
    A = np.zeros((m, m))
    b = np.zeros(m)
    basis = np.empty(m)
    yy = 0.0
    for i in range(n):
        lam = mu_f - mu[i]
        if not lam > 0:
            return math.inf
        q = lam / scale
        p = math.sqrt(lam) * wt[i]
        for j in range(m):
            basis[j] = p
            p *= q
        yi = y[i] * wt[i]
        yy += yi * yi
        for j in range(m):
            b[j] += basis[j] * yi
            for l in range(j + 1):
                A[j, l] += basis[j] * basis[l]
    for j in range(m):
        for l in range(j + 1, m):
            A[j, l] = A[l, j]
    rhs = b.copy()
    if not _solve(A, rhs, m):
        return math.inf
    fit = 0.0
    for j in range(m):
        fit += rhs[j] * b[j]
    return max(yy - fit, 0.0)
