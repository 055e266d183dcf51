"""Compiled kernels of the profile likelihood (see :mod:`.compare`).

For a trial transition point ``mu*`` every law is linear in its coefficients: the data ``y`` of
one component are fitted by ``sum_j beta_j v^(e_j)`` with ``v = x = mu* - mu`` or, for a law
that knows a secondary fold at ``mu* + delta``, the conformal variable

    v = z = 2 x / (1 + sqrt(1 + x / delta))  =  2 sqrt(delta) (sqrt(delta + x) - sqrt(delta)),

a series in ``z`` being a series in the fold's own amplitude ``s = sqrt(mu* + delta - mu)``
(``z -> x`` as ``delta -> inf``). The kernels return ``-2 log L`` (up to constants) of the
weighted linear least-squares fit (Householder QR), summed over components, at a trial mu*
and fold parameter ``u = (mu* - mu_last) / delta`` (0: none); the fold parameter is profiled
out per mu* in :mod:`._kernels.fold`.

Components are packed in three plain arrays (``D``: rows mu, y, wt of all components one after
the other; ``E[c, :k]``: exponents; ``M[c] = (offset, n, k, known, lead, lead_col, signed,
conformal)``). A slow numpy reference lives in the tests.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

RHO = 0.5  # corrections may reach this fraction of the leading term inside the window
REL_FLOOR = 1e-12  # relative noise floor (exact data)
@njit(cache=True, error_model="numpy")
def _pow(x, e):
    if e == 0.0:
        return 1.0
    if e == 1.0:
        return x
    if e == 0.5:
        return math.sqrt(x)
    if e == 2.0:
        return x * x
    return x**e


@njit(cache=True, error_model="numpy")
def _dot(A, ja, jb, i0, n):
    """``sum(A[ja, i0:n] * A[jb, i0:n])`` in four interleaved partial sums (a small window's
    fits are bound by the latency of one running sum; four halve their time)."""
    s0 = s1 = s2 = s3 = 0.0
    i = i0
    while i + 3 < n:
        s0 += A[ja, i] * A[jb, i]
        s1 += A[ja, i + 1] * A[jb, i + 1]
        s2 += A[ja, i + 2] * A[jb, i + 2]
        s3 += A[ja, i + 3] * A[jb, i + 3]
        i += 4
    while i < n:
        s0 += A[ja, i] * A[jb, i]
        i += 1
    return (s0 + s1) + (s2 + s3)


@njit(cache=True, error_model="numpy")
def _comp_nll(ms, u, D, E, M, c, x_last, WK, RK):
    """-2 log L of component ``c`` at transition point ``ms`` and fold parameter ``u``.

    ``D``: (3, N) rows mu, y, wt; ``E``: (C, kmax) exponents; ``M``: (C, 8) integers
    ``(offset, n, k, known, lead, lead_col, signed, conformal)``; ``WK``: work of at least
    (2 kmax + 1, N) (rows: the design, its copy, the data); ``RK``: (kmax, kmax + 1) (R and the
    coefficients). Few arrays, rows contiguous: per evaluation, passing arrays costs more than
    the arithmetic of a small window."""
    o, n, k = M[c, 0], M[c, 1], M[c, 2]
    known, lead, lead_col, signed = M[c, 3] == 1, M[c, 4] == 1, M[c, 5], M[c, 6] == 1
    conformal = M[c, 7] == 1
    delta = x_last / u if (conformal and u > 0.0) else 0.0
    inv_delta = 1.0 / delta if delta > 0.0 else 0.0
    arith = k >= 2
    step = E[c, 1] - E[c, 0] if k >= 2 else 0.0
    for j in range(2, k):
        if abs(E[c, j] - E[c, j - 1] - step) > 1e-12:
            arith = False
    e0 = E[c, 0]
    kb = 2 * k  # row of the data in WK; the design: rows 0..k-1, its copy: k..2k-1
    check = lead and k > lead_col + 1  # the corrections' constraint needs the design kept
    bmax = 0.0
    for i in range(n):
        x = ms - D[0, o + i]
        if x < 1e-300:
            x = 1e-300
        if delta > 0.0:
            x = 2.0 * x / (1.0 + math.sqrt(1.0 + x * inv_delta))
        wi = D[2, o + i]
        if arith:
            r = _pow(x, step)
            v = (r if e0 == step else _pow(x, e0)) * wi
            for j in range(k):
                WK[j, i] = v
                v *= r
        else:
            for j in range(k):
                WK[j, i] = _pow(x, E[c, j]) * wi
        bi = D[1, o + i] * wi
        WK[kb, i] = bi
        if abs(bi) > bmax:
            bmax = abs(bi)
    for j in range(k):
        s = math.sqrt(_dot(WK, j, j, np.int64(0), n))
        if s == 0.0 or not math.isfinite(s):
            s = 1.0 if s == 0.0 else s
        inv = 1.0 / s
        if check:
            for i in range(n):
                v = WK[j, i] * inv
                WK[j, i] = v
                WK[k + j, i] = v
        else:
            for i in range(n):
                WK[j, i] *= inv
    for j in range(k):
        for jj in range(k):
            RK[j, jj] = 0.0
    for j in range(k):
        nrm2 = _dot(WK, j, j, j, n)
        nrm = math.sqrt(nrm2)
        if nrm == 0.0:
            continue
        alpha = -nrm if WK[j, j] > 0 else nrm
        v0 = WK[j, j] - alpha
        vnorm2 = nrm2 - WK[j, j] * WK[j, j] + v0 * v0
        if vnorm2 == 0.0:
            RK[j, j] = WK[j, j]
            continue
        for jj in range(j + 1, k):
            d = v0 * WK[jj, j] + _dot(WK, j, jj, j + 1, n)
            f = 2.0 * d / vnorm2
            WK[jj, j] -= f * v0
            for i in range(j + 1, n):
                WK[jj, i] -= f * WK[j, i]
        d = v0 * WK[kb, j] + _dot(WK, j, kb, j + 1, n)
        f = 2.0 * d / vnorm2
        WK[kb, j] -= f * v0
        for i in range(j + 1, n):
            WK[kb, i] -= f * WK[j, i]
        WK[j, j] = alpha
        for jj in range(j, k):
            RK[j, jj] = WK[jj, j]
    rss = _dot(WK, kb, kb, k, n)
    if known:
        out = rss
    else:
        floor = n * (REL_FLOOR * max(bmax, 1e-300)) ** 2
        dof = n - k if n - k > 1 else 1
        out = dof * math.log(max(rss, floor) / n)
    if check:
        kc = k  # the coefficients: column k of RK
        for j in range(k):
            RK[j, kc] = 0.0
        ok = True
        for j in range(k - 1, -1, -1):
            s = WK[kb, j]
            for jj in range(j + 1, k):
                s -= RK[j, jj] * RK[jj, kc]
            if RK[j, j] == 0.0:
                ok = False
                break
            RK[j, kc] = s / RK[j, j]
        if ok:
            worst = 0.0
            for i in range(n):
                ld = WK[k + lead_col, i] * RK[lead_col, kc]
                corr = 0.0
                for j in range(lead_col + 1, k):
                    corr += WK[k + j, i] * RK[j, kc]
                if signed:
                    r = abs(corr) / ld if ld > 0 else math.inf
                else:
                    r = abs(corr / ld) if ld != 0 else math.inf
                if not (r <= worst):
                    worst = r
            ex = worst - RHO
            if ex > 0:
                if ex > 1e3 or not math.isfinite(ex):
                    ex = 1e3
                out += 1e4 * ex * ex
    return out

@njit(cache=True, error_model="numpy")
def _total(ms, u, D, E, M, x_last, WK, RK):
    out = 0.0
    for c in range(M.shape[0]):
        out += _comp_nll(ms, u, D, E, M, c, x_last, WK, RK)
    return out


@njit(cache=True, error_model="numpy")
def _work(D, M):
    """Work arrays ``(WK, RK)`` of :func:`_comp_nll` for the packed data."""
    k = 1
    for c in range(M.shape[0]):
        k = max(k, M[c, 2])
    return np.empty((2 * k + 1, D.shape[1])), np.empty((k, k + 1))


@njit(cache=True, error_model="numpy")
def nll_fixed_u(mu_star, u, D, E, M, mu_last):
    """-2 log L at each ``mu_star`` with the fold parameter fixed at ``u`` (0: plain laws)."""
    G = mu_star.size
    out = np.empty(G)
    WK, RK = _work(D, M)
    for g in range(G):
        ms = mu_star[g]
        x_last = max(ms - mu_last, 1e-300)
        out[g] = _total(ms, u, D, E, M, x_last, WK, RK)
    return out


@njit(cache=True, error_model="numpy")
def poly_rss(mu, y, wt, degree):
    """Weighted least-squares residual ``sum (wt (y - P(mu)))^2`` of the best polynomial ``P``
    of ``degree`` in ``mu`` (shapes (n,); ``degree + 1 < n``): :func:`_comp_nll` with the
    exponents ``0..degree`` of ``x = mu_ref - mu``, ``mu_ref`` one span beyond the largest
    ``mu`` (``x`` in ``[span, 2 span]``: the same polynomials, well conditioned)."""
    n = mu.size
    k = degree + 1
    D = np.empty((3, n))
    for i in range(n):
        D[0, i] = mu[i]
        D[1, i] = y[i]
        D[2, i] = wt[i]
    E = np.empty((1, k))
    for j in range(k):
        E[0, j] = float(j)
    M = np.zeros((1, 8), dtype=np.int64)
    M[0, 1] = n
    M[0, 2] = k
    M[0, 3] = 1  # known noise: the value is the residual itself
    hi = mu.max()
    span = max(hi - mu.min(), 1e-300)
    WK, RK = _work(D, M)
    return _comp_nll(hi + span, 0.0, D, E, M, np.int64(0), span, WK, RK)
