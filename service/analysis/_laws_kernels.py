"""Compiled kernels of the profile likelihood (see :mod:`service.analysis._laws`).

For a trial transition point ``mu*`` every law is linear in its coefficients: the data ``y`` of
one component are fitted by ``sum_j beta_j v^(e_j)`` with ``v = x = mu* - mu`` or, for a law
that knows a secondary fold at ``mu* + delta``, the conformal variable

    v = z = 2 x / (1 + sqrt(1 + x / delta))  =  2 sqrt(delta) (sqrt(delta + x) - sqrt(delta)),

a series in ``z`` being a series in the fold's own amplitude ``s = sqrt(mu* + delta - mu)``
(``z -> x`` as ``delta -> inf``). The kernels return ``-2 log L`` (up to constants) of the
weighted linear least-squares fit (Householder QR), summed over components, for many ``mu*``;
with conformal components the secondary fold distance is profiled out per ``mu*`` over
``u = (mu* - mu_last) / delta`` in ``[0, u_max]`` (a grid, then golden-section/parabolic
refinement in ``log u``).

Components are packed in plain arrays (``start[c]:start[c+1]`` slices of ``mu``, ``y``, ``wt``;
``exps[c, :nexp[c]]``; ``opts[c] = (known, lead, lead_col, signed, conformal)``). A slow numpy
reference lives in the tests.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

RHO = 0.5  # corrections may reach this fraction of the leading term inside the window
REL_FLOOR = 1e-12  # relative noise floor (exact data)
_GOLD = 0.3819660112501051


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
def _comp_nll(
    ms, u, mu, y, wt, exps, k, known, lead, lead_col, signed, conformal, x_last, A, A0, b, R, coef
):
    """-2 log L of one component at transition point ``ms`` and fold parameter ``u``
    (``A``, ``A0``, ``b``, ``R``, ``coef``: work arrays of at least (n, k), (n, k), (n,), (k, k),
    (k,))."""
    n = mu.size
    delta = x_last / u if (conformal and u > 0.0) else 0.0
    arith = k >= 2
    step = exps[1] - exps[0] if k >= 2 else 0.0
    for j in range(2, k):
        if abs(exps[j] - exps[j - 1] - step) > 1e-12:
            arith = False
    bmax = 0.0
    for i in range(n):
        x = ms - mu[i]
        if x < 1e-300:
            x = 1e-300
        if delta > 0.0:
            x = 2.0 * x / (1.0 + math.sqrt(1.0 + x / delta))
        if arith:
            v = _pow(x, exps[0])
            r = _pow(x, step)
            for j in range(k):
                A[i, j] = v * wt[i]
                v *= r
        else:
            for j in range(k):
                A[i, j] = _pow(x, exps[j]) * wt[i]
        b[i] = y[i] * wt[i]
        if abs(b[i]) > bmax:
            bmax = abs(b[i])
    for j in range(k):
        s = 0.0
        for i in range(n):
            s += A[i, j] * A[i, j]
        s = math.sqrt(s)
        if s == 0.0 or not math.isfinite(s):
            s = 1.0 if s == 0.0 else s
        for i in range(n):
            A[i, j] /= s
            A0[i, j] = A[i, j]
    # Householder QR, applied to b as we go
    for j in range(k):
        for jj in range(k):
            R[j, jj] = 0.0
    for j in range(k):
        nrm = 0.0
        for i in range(j, n):
            nrm += A[i, j] * A[i, j]
        nrm = math.sqrt(nrm)
        if nrm == 0.0:
            continue
        alpha = -nrm if A[j, j] > 0 else nrm
        v0 = A[j, j] - alpha
        vnorm2 = v0 * v0
        for i in range(j + 1, n):
            vnorm2 += A[i, j] * A[i, j]
        if vnorm2 == 0.0:
            R[j, j] = A[j, j]
            continue
        # reflect the remaining columns
        for jj in range(j + 1, k):
            d = v0 * A[j, jj]
            for i in range(j + 1, n):
                d += A[i, j] * A[i, jj]
            f = 2.0 * d / vnorm2
            A[j, jj] -= f * v0
            for i in range(j + 1, n):
                A[i, jj] -= f * A[i, j]
        d = v0 * b[j]
        for i in range(j + 1, n):
            d += A[i, j] * b[i]
        f = 2.0 * d / vnorm2
        b[j] -= f * v0
        for i in range(j + 1, n):
            b[i] -= f * A[i, j]
        A[j, j] = alpha
        for jj in range(j, k):
            R[j, jj] = A[j, jj]
    rss = 0.0
    for i in range(k, n):
        rss += b[i] * b[i]
    if known:
        out = rss
    else:
        floor = n * (REL_FLOOR * max(bmax, 1e-300)) ** 2
        dof = n - k if n - k > 1 else 1
        out = dof * math.log(max(rss, floor) / n)
    if lead and k > lead_col + 1:
        for j in range(k):
            coef[j] = 0.0
        ok = True
        for j in range(k - 1, -1, -1):
            s = b[j]
            for jj in range(j + 1, k):
                s -= R[j, jj] * coef[jj]
            if R[j, j] == 0.0:
                ok = False
                break
            coef[j] = s / R[j, j]
        if ok:
            worst = 0.0
            for i in range(n):
                ld = A0[i, lead_col] * coef[lead_col]
                corr = 0.0
                for j in range(lead_col + 1, k):
                    corr += A0[i, j] * coef[j]
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
def _total(ms, u, mu, y, wt, start, exps, nexp, opts, x_last, W):
    A, A0, b, R, coef = W
    out = 0.0
    for c in range(start.size - 1):
        a, e = start[c], start[c + 1]
        out += _comp_nll(
            ms, u, mu[a:e], y[a:e], wt[a:e], exps[c], nexp[c], opts[c, 0] == 1,
            opts[c, 1] == 1, opts[c, 2], opts[c, 3] == 1, opts[c, 4] == 1, x_last, A, A0, b, R,
            coef,
        )  # fmt: skip
    return out


@njit(cache=True, error_model="numpy")
def _refine_u(ms, a, c, xb, fxb, mu, y, wt, start, exps, nexp, opts, x_last, W):
    """Golden section with parabolic steps for the log fold parameter on ``[a, c]`` around
    ``xb`` (value ``fxb``); returns the best (log u, -2 log L)."""
    w, fw, v, fv = xb, fxb, xb, fxb
    d = 0.0
    e = 0.0
    for _ in range(20):
        m = 0.5 * (a + c)
        tol = 1e-3
        if abs(xb - m) <= 2 * tol - 0.5 * (c - a):
            break
        use_golden = True
        if abs(e) > tol:
            r = (xb - w) * (fxb - fv)
            q = (xb - v) * (fxb - fw)
            p = (xb - v) * q - (xb - w) * r
            q = 2.0 * (q - r)
            if q > 0:
                p = -p
            q = abs(q)
            if abs(p) < abs(0.5 * q * e) and p > q * (a - xb) and p < q * (c - xb):
                e = d
                d = p / q
                use_golden = False
        if use_golden:
            e = (c - xb) if xb < m else (a - xb)
            d = _GOLD * e
        ut = xb + (d if abs(d) >= tol else (tol if d > 0 else -tol))
        fu = _total(ms, math.exp(ut), mu, y, wt, start, exps, nexp, opts, x_last, W)
        if not math.isfinite(fu):
            fu = 1e300
        if fu <= fxb:
            if ut < xb:
                c = xb
            else:
                a = xb
            v, fv, w, fw, xb, fxb = w, fw, xb, fxb, ut, fu
        else:
            if ut < xb:
                a = ut
            else:
                c = ut
            if fu <= fw or w == xb:
                v, fv, w, fw = w, fw, ut, fu
            elif fu <= fv or v == xb or v == w:
                v, fv = ut, fu
    return xb, fxb


@njit(cache=True, error_model="numpy")
def _profile_u(ms, mu, y, wt, start, exps, nexp, opts, mu_last, logu, W, refine):
    """min over the fold parameter u (0 and exp(logu) grid, refined) at one mu*."""
    x_last = ms - mu_last
    if x_last < 1e-300:
        x_last = 1e-300
    best = _total(ms, 0.0, mu, y, wt, start, exps, nexp, opts, x_last, W)
    best_u = 0.0
    G = logu.size
    f = np.empty(G)
    jb = -1
    fb = math.inf
    for g in range(G):
        v = _total(ms, math.exp(logu[g]), mu, y, wt, start, exps, nexp, opts, x_last, W)
        f[g] = v if math.isfinite(v) else 1e300
        if f[g] < fb:
            fb = f[g]
            jb = g
    if jb < 0:
        return best, best_u
    if not refine:
        if fb < best:
            return fb, math.exp(logu[jb])
        return best, best_u
    a = logu[jb - 1] if jb > 0 else logu[0]
    c = logu[jb + 1] if jb < G - 1 else logu[G - 1]
    xb, fxb = _refine_u(ms, a, c, logu[jb], fb, mu, y, wt, start, exps, nexp, opts, x_last, W)
    if fxb < best:
        best = fxb
        best_u = math.exp(xb)
    return best, best_u


@njit(cache=True, error_model="numpy")
def _work(mu, nexp):
    k = 1
    for c in range(nexp.size):
        k = max(k, nexp[c])
    n = mu.size
    return np.empty((n, k)), np.empty((n, k)), np.empty(n), np.empty((k, k)), np.empty(k)


@njit(cache=True, error_model="numpy")
def nll_rows(mu_star, mu, y, wt, start, exps, nexp, opts, mu_last, logu, refine=True):
    """-2 log L at each ``mu_star`` (shape (G,)) and the fold parameter ``u`` profiled there
    (0 without conformal components or when the plain law is best); ``refine=False``: the
    minimum over the ``logu`` grid only (an upper bound, for a coarse scan)."""
    G = mu_star.size
    out = np.empty(G)
    ubest = np.zeros(G)
    W = _work(mu, nexp)
    conformal = False
    for c in range(opts.shape[0]):
        if opts[c, 4] == 1:
            conformal = True
    for g in range(G):
        ms = mu_star[g]
        if conformal:
            out[g], ubest[g] = _profile_u(
                ms, mu, y, wt, start, exps, nexp, opts, mu_last, logu, W, refine
            )
        else:
            x_last = max(ms - mu_last, 1e-300)
            out[g] = _total(ms, 0.0, mu, y, wt, start, exps, nexp, opts, x_last, W)
    return out, ubest


@njit(cache=True, error_model="numpy")
def nll_fixed_u(mu_star, u, mu, y, wt, start, exps, nexp, opts, mu_last):
    """-2 log L at each ``mu_star`` with the fold parameter fixed at ``u`` (0: plain laws)."""
    G = mu_star.size
    out = np.empty(G)
    W = _work(mu, nexp)
    for g in range(G):
        ms = mu_star[g]
        x_last = max(ms - mu_last, 1e-300)
        out[g] = _total(ms, u, mu, y, wt, start, exps, nexp, opts, x_last, W)
    return out
