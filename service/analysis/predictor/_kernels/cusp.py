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
def cusp_nll(
    mu: np.ndarray, y: np.ndarray, wt: np.ndarray, scale: float, mu_star: float, G: float,
    soft: bool, K: int,
) -> float:
    """``-2 log L`` (the weighted residual sum of squares) of the eigenvalue law at ``mu*`` and
    ``G`` with ``K`` corrections, the ``alpha_j`` profiled; ``inf`` where a point lies past the
    fold or the stiffness is not positive."""
    n = mu.size
    m = K + 1
    A = np.zeros((m, m))
    b = np.zeros(m)
    basis = np.empty(m)
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
    rhs = b.copy()
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
    """``cusp_nll`` in the search variables: the point it predicts ``mu_p = mu[-1] +
    scale exp(t) - shift G`` (the fold, softening; the least stiffness, stiffening) and
    ``G = scale exp(g)`` (``g = -inf``: the perfect law, ``mu* = mu_p``)."""
    G = scale * math.exp(g) if g > -700 else 0.0
    mu_p = mu[-1] + scale * math.exp(t) - shift * G
    mu_star = mu_p + (R_FOLD if soft else R_MIN) * G
    return cusp_nll(mu, y, wt, scale, mu_star, G, soft, K)


@njit(cache=True)
def profile_g(
    mu: np.ndarray, y: np.ndarray, wt: np.ndarray, scale: float, t: float, gs: np.ndarray,
    soft: bool, K: int, shift: float, refine: bool = True,
) -> tuple[float, float]:
    """The profile over ``g`` at ``t``: the grid ``gs`` (and the perfect law, ``g = -inf``),
    then (``refine``) golden-section search between the best point's neighbours. Returns
    ``(nll, g)``."""
    best = _at(mu, y, wt, scale, t, -math.inf, soft, K, shift)
    gb = -math.inf
    ib = -1
    for i in range(gs.size):
        f = _at(mu, y, wt, scale, t, gs[i], soft, K, shift)
        if f < best:
            best, gb, ib = f, gs[i], i
    if ib < 0 or not refine:
        return best, gb
    a = gs[ib - 1] if ib > 0 else gs[0] - (gs[1] - gs[0])
    c = gs[ib + 1] if ib < gs.size - 1 else gs[-1]
    gr = 0.5 * (math.sqrt(5.0) - 1.0)
    x1 = c - gr * (c - a)
    x2 = a + gr * (c - a)
    f1 = _at(mu, y, wt, scale, t, x1, soft, K, shift)
    f2 = _at(mu, y, wt, scale, t, x2, soft, K, shift)
    for _ in range(60):
        if f1 < f2:
            c, x2, f2 = x2, x1, f1
            x1 = c - gr * (c - a)
            f1 = _at(mu, y, wt, scale, t, x1, soft, K, shift)
        else:
            a, x1, f1 = x1, x2, f2
            x2 = a + gr * (c - a)
            f2 = _at(mu, y, wt, scale, t, x2, soft, K, shift)
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
    for i in range(ts.size):
        f[i], g[i] = profile_g(mu, y, wt, scale, ts[i], gs, soft, K, shift, refine)
    return f, g
