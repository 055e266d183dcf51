"""Numba kernels of the pole detector (hot loops over plain arrays, written in place).

Every kernel here works in *sample units* (time step 1): the validating wrapper in
:mod:`service.analysis.detect` rescales time and amplitude before and after. Each kernel has a
slow pure-numpy reference in ``tests/analysis/test_detect_kernels.py``.

Mode parametrisation
--------------------
A mode is the free response of ``x'' + p x' + q x = 0`` (``p = 2 gamma``, ``q = -sigma^2``),
whose two poles are the roots of ``s^2 + p s + q = 0``. Its two-dimensional solution space is
spanned by::

    u1(n) = exp(-p n / 2) cosh(sqrt(D) n)
    u2(n) = exp(-p n / 2) sinh(sqrt(D) n) / sqrt(D),      D = p^2 / 4 - q

Both are entire functions of ``D``, hence smooth in ``(p, q)`` across critical damping
(``D < 0``: underdamped, ``cos`` / ``sin``; ``D > 0``: overdamped, two real poles). Samples obey
the exact two-term recurrence ``u[n+1] = A u[n] + B u[n-1]`` with ``A = 2 exp(-p/2) cosh(sqrt D)``
and ``B = -exp(-p)``, which the kernels run forward together with its derivatives in ``p``
and ``q`` (forward-mode differentiation of the recurrence), so no transcendental function is
called per sample.
"""

from __future__ import annotations

import math

import numpy as np

from service.analysis._numba_load import install as _fast_cache_load
from service.analysis._numba_load import njit  # numba without its optional imports

_fast_cache_load()

_SERIES_D = 1e-2  # |D| below which the entire functions are summed as power series


@njit(cache=True)
def _ch_sh(D: float) -> tuple[float, float, float]:
    """Return ``cosh(sqrt D)``, ``sinh(sqrt D)/sqrt D`` and ``d/dD [sinh(sqrt D)/sqrt D]``."""
    if abs(D) < _SERIES_D:
        # Taylor series in D (|D| < 1e-2: the D^6 terms are below 1e-16 relative).
        ch = 1.0
        sh = 1.0
        dsh = 0.0
        term_c = 1.0  # D^k / (2k)!
        term_s = 1.0  # D^k / (2k+1)!
        dk = 1.0  # D^(k-1)
        for k in range(1, 8):
            term_c *= D / ((2 * k - 1) * (2 * k))
            term_s *= D / ((2 * k) * (2 * k + 1))
            ch += term_c
            sh += term_s
            # d/dD D^k/(2k+1)! = k D^(k-1) / (2k+1)!
            fact = 1.0
            for m in range(2, 2 * k + 2):
                fact *= m
            dsh += k * dk / fact
            dk *= D
        return ch, sh, dsh
    if D < 0.0:
        w = math.sqrt(-D)
        ch = math.cos(w)
        sh = math.sin(w) / w
    else:
        w = math.sqrt(D)
        ch = math.cosh(w)
        sh = math.sinh(w) / w
    dsh = (ch - sh) / (2.0 * D)
    return ch, sh, dsh


@njit(cache=True, inline="always")
def _recurrence_step(A, B, Ap, Bp, Aq, a0, a1, b0, b1, a0p, a1p, a0q, a1q, b0p, b1p, b0q, b1q):
    """One step of the pole-pair recurrence u[i] = A u[i-1] + B u[i-2] for both basis
    sequences (a, b) and their derivatives in p and q (B does not depend on q).
    Shared by ``pair_basis`` and ``model_gram``."""
    a2 = A * a1 + B * a0
    b2 = A * b1 + B * b0
    a2p = A * a1p + B * a0p + Ap * a1 + Bp * a0
    a2q = A * a1q + B * a0q + Aq * a1
    b2p = A * b1p + B * b0p + Ap * b1 + Bp * b0
    b2q = A * b1q + B * b0q + Aq * b1
    return a2, b2, a2p, a2q, b2p, b2q


@njit(cache=True)
def pair_basis(n: int, p: np.ndarray, q: np.ndarray, out: np.ndarray, col0: int) -> None:
    """Fill the basis columns of ``len(p)`` modes and their ``(p, q)`` derivatives.

    Parameters
    ----------
    n : int
        Number of samples (rows of ``out`` that are written).
    p, q : ndarray, shape (K,)
        Per-sample damping sum ``p = 2 gamma dt`` and stiffness ``q = -sigma^2 dt^2``.
    out : ndarray, shape (>= n, >= col0 + 6 K)
        Written in place. For mode ``k`` the six columns starting at ``col0 + 6 k`` are
        ``u1, u2, du1/dp, du1/dq, du2/dp, du2/dq`` (sample index as time).
    col0 : int
        First column written.
    """
    K = p.shape[0]
    for k in range(K):
        pk = p[k]
        qk = q[k]
        D = 0.25 * pk * pk - qk
        ch, sh, dsh = _ch_sh(D)
        E = math.exp(-0.5 * pk)
        A = 2.0 * E * ch
        B = -E * E
        # partial derivatives at fixed D (suffix _p) and in D (suffix _D)
        A_p = -E * ch
        A_D = E * sh
        B_p = E * E
        u1_1 = E * ch
        u2_1 = E * sh
        u1_1p = -0.5 * E * ch
        u1_1D = 0.5 * E * sh
        u2_1p = -0.5 * E * sh
        u2_1D = E * dsh
        # total derivatives: d/dq = -d/dD ; d/dp = d/dp|_D + (p/2) d/dD
        half_p = 0.5 * pk
        Ap = A_p + half_p * A_D
        Aq = -A_D
        Bp = B_p
        c = col0 + 6 * k
        # n = 0
        out[0, c] = 1.0
        out[0, c + 1] = 0.0
        out[0, c + 2] = 0.0
        out[0, c + 3] = 0.0
        out[0, c + 4] = 0.0
        out[0, c + 5] = 0.0
        if n < 2:
            continue
        out[1, c] = u1_1
        out[1, c + 1] = u2_1
        out[1, c + 2] = u1_1p + half_p * u1_1D
        out[1, c + 3] = -u1_1D
        out[1, c + 4] = u2_1p + half_p * u2_1D
        out[1, c + 5] = -u2_1D
        a0 = 1.0
        a1 = u1_1
        b0 = 0.0
        b1 = u2_1
        a0p = 0.0
        a1p = out[1, c + 2]
        a0q = 0.0
        a1q = out[1, c + 3]
        b0p = 0.0
        b1p = out[1, c + 4]
        b0q = 0.0
        b1q = out[1, c + 5]
        for i in range(2, n):
            a2, b2, a2p, a2q, b2p, b2q = _recurrence_step(
                A, B, Ap, Bp, Aq, a0, a1, b0, b1, a0p, a1p, a0q, a1q, b0p, b1p, b0q, b1q
            )
            out[i, c] = a2
            out[i, c + 1] = b2
            out[i, c + 2] = a2p
            out[i, c + 3] = a2q
            out[i, c + 4] = b2p
            out[i, c + 5] = b2q
            a0 = a1
            a1 = a2
            b0 = b1
            b1 = b2
            a0p = a1p
            a1p = a2p
            a0q = a1q
            a1q = a2q
            b0p = b1p
            b1p = b2p
            b0q = b1q
            b1q = b2q


@njit(cache=True, fastmath={"reassoc", "contract"})
def hankel_gram(x: np.ndarray, L: int, stride: int, out: np.ndarray) -> int:
    """Gram matrix of the strided Hankel matrix of ``x`` (the ESPRIT covariance), in place.

    ``out[i, j] = sum_{m < M} x[m + i*stride] * x[m + j*stride]`` with
    ``M = len(x) - (L - 1) * stride`` columns, computed in ``O(M L + L^2 stride)`` by the
    diagonal recurrence ``out[i+1, j+1] = out[i, j] - head + tail``.

    Parameters
    ----------
    x : ndarray, shape (N,)
    L : int
        Number of rows of the Hankel matrix (``L >= 2``).
    stride : int
        Lag between rows (decimation factor, ``>= 1``).
    out : ndarray, shape (L, L)
        Written in place (symmetric).

    Returns
    -------
    int
        ``M``, the number of Hankel columns.
    """
    N = x.shape[0]
    M = N - (L - 1) * stride
    for j in range(L):
        s = 0.0
        oj = j * stride
        for m in range(M):
            s += x[m] * x[m + oj]
        out[0, j] = s
    for i in range(L - 1):
        for j in range(i, L - 1):
            oi = i * stride
            oj = j * stride
            head = 0.0
            tail = 0.0
            for m in range(stride):
                head += x[m + oi] * x[m + oj]
                tail += x[M + m + oi] * x[M + m + oj]
            out[i + 1, j + 1] = out[i, j] - head + tail
    for i in range(L):
        for j in range(i):
            out[i, j] = out[j, i]
    return M


_BLOCK = 256


@njit(cache=True)
def _mode_coeffs(pk: float, qk: float) -> np.ndarray:
    """Recurrence coefficients and first-step values of one mode (see the module notes).

    Returns ``[A, B, Ap, Aq, Bp, u1(1), u2(1), du1(1)/dp, du1(1)/dq, du2(1)/dp, du2(1)/dq]``.
    """
    D = 0.25 * pk * pk - qk
    ch, sh, dsh = _ch_sh(D)
    E = math.exp(-0.5 * pk)
    half_p = 0.5 * pk
    out = np.empty(11)
    out[0] = 2.0 * E * ch
    out[1] = -E * E
    out[2] = -E * ch + half_p * E * sh
    out[3] = -E * sh
    out[4] = E * E
    out[5] = E * ch
    out[6] = E * sh
    out[7] = -0.5 * E * ch + half_p * 0.5 * E * sh
    out[8] = -0.5 * E * sh
    out[9] = -0.5 * E * sh + half_p * E * dsh
    out[10] = -E * dsh
    return out


@njit(cache=True, fastmath={"reassoc", "contract"})
def _accumulate(buf: np.ndarray, nrows: int, ncols: int, G: np.ndarray) -> None:
    """``G += buf[:nrows, :ncols].T @ buf[:nrows, :ncols]`` (upper triangle), F-order ``buf``.

    Four columns ``b`` per pass over column ``a`` (five loads for four products instead of
    eight): each sum is still formed alone, in the same order, so ``G`` is bit for bit the
    one-dot-product-at-a-time result (checked in ``tests/analysis/test_detect_kernels.py``)."""
    for a in range(ncols):
        b = a
        while b + 4 <= ncols:
            s0 = 0.0
            s1 = 0.0
            s2 = 0.0
            s3 = 0.0
            for i in range(nrows):
                x = buf[i, a]
                s0 += x * buf[i, b]
                s1 += x * buf[i, b + 1]
                s2 += x * buf[i, b + 2]
                s3 += x * buf[i, b + 3]
            G[a, b] += s0
            G[a, b + 1] += s1
            G[a, b + 2] += s2
            G[a, b + 3] += s3
            b += 4
        while b < ncols:
            s = 0.0
            for i in range(nrows):
                s += buf[i, a] * buf[i, b]
            G[a, b] += s
            b += 1


@njit(cache=True)
def _symmetrize(G: np.ndarray) -> None:
    m = G.shape[0]
    for a in range(m):
        for b in range(a):
            G[a, b] = G[b, a]


@njit(cache=True)
def _pair_block(buf: np.ndarray, nr: int, co: np.ndarray, st: np.ndarray, k: int, ia: int) -> None:
    """Basis columns of modes ``k`` and ``k + 1`` (columns ``ia .. ia + 3``) over one block
    after the first, their recurrences interleaved; state in ``st`` as in :func:`model_gram`."""
    A = co[k, 0]
    B = co[k, 1]
    A_ = co[k + 1, 0]
    B_ = co[k + 1, 1]
    a0 = st[k, 0]
    a1 = st[k, 1]
    b0 = st[k, 2]
    b1 = st[k, 3]
    a0_ = st[k + 1, 0]
    a1_ = st[k + 1, 1]
    b0_ = st[k + 1, 2]
    b1_ = st[k + 1, 3]
    for i in range(nr):
        a2 = A * a1 + B * a0
        b2 = A * b1 + B * b0
        a2_ = A_ * a1_ + B_ * a0_
        b2_ = A_ * b1_ + B_ * b0_
        buf[i, ia] = a2
        buf[i, ia + 1] = b2
        buf[i, ia + 2] = a2_
        buf[i, ia + 3] = b2_
        a0 = a1
        a1 = a2
        b0 = b1
        b1 = b2
        a0_ = a1_
        a1_ = a2_
        b0_ = b1_
        b1_ = b2_
    st[k, 0] = a0
    st[k, 1] = a1
    st[k, 2] = b0
    st[k, 3] = b1
    st[k + 1, 0] = a0_
    st[k + 1, 1] = a1_
    st[k + 1, 2] = b0_
    st[k + 1, 3] = b1_


@njit(cache=True)
def model_gram(
    y: np.ndarray,
    p: np.ndarray,
    q: np.ndarray,
    c: np.ndarray,
    common: bool,
    jacobian: bool,
    G: np.ndarray,
) -> None:
    """Gram matrix of the model columns, fused with the basis recurrences (no N x P storage).

    Without ``jacobian`` the columns are ``[1, u1_0, u2_0, u1_1, ..., y]`` (``2 K + 2``).
    With ``jacobian`` they are ``[J_theta, 1, u1_0, u2_0, ..., y]`` where ``J_theta`` are the
    derivatives of the model ``sum_k c1_k u1_k + c2_k u2_k`` in ``theta = (p_0, q_0, p_1, ...)``
    or, with ``common``, in ``theta = (p, q_0, q_1, ...)``; ``c`` holds
    ``[c0, c1_0, c2_0, c1_1, ...]``.

    Parameters
    ----------
    y : ndarray, shape (N,)
    p, q : ndarray, shape (K,)
        Per-sample mode parameters.
    c : ndarray, shape (2 K + 1,)
        Linear coefficients (used only with ``jacobian``).
    common, jacobian : bool
    G : ndarray, shape (m, m)
        Overwritten with the Gram matrix; ``m = 2K + 2`` (+ ``ntheta`` with ``jacobian``).
    """
    N = y.shape[0]
    K = p.shape[0]
    nth = 0
    if jacobian:
        nth = K + 1 if common else 2 * K
    m = nth + 2 * K + 2
    co = np.empty((K, 11))
    for k in range(K):
        co[k] = _mode_coeffs(p[k], q[k])
    # state per mode: u1[n-2], u1[n-1], u2[n-2], u2[n-1], then the derivatives likewise
    st = np.zeros((K, 12))
    buf = np.empty((m, _BLOCK)).T  # F-order block buffer: columns contiguous
    for a in range(m):
        for b in range(m):
            G[a, b] = 0.0
    n0 = 0
    while n0 < N:
        nr = min(_BLOCK, N - n0)
        for i in range(nr):
            buf[i, nth] = 1.0
            buf[i, m - 1] = y[n0 + i]
        for a in range(nth):
            for i in range(nr):
                buf[i, a] = 0.0
        k = 0
        while k < K:
            A = co[k, 0]
            B = co[k, 1]
            Ap = co[k, 2]
            Aq = co[k, 3]
            Bp = co[k, 4]
            ia = nth + 1 + 2 * k
            ib = ia + 1
            if not jacobian and n0 > 0 and k + 1 < K:
                # two modes' recurrences interleaved (each alone is bound by the latency of
                # its multiply-add chain); every value is formed exactly as one at a time
                _pair_block(buf, nr, co, st, k, ia)
                k += 2
                continue
            if not jacobian:
                a0 = st[k, 0]
                a1 = st[k, 1]
                b0 = st[k, 2]
                b1 = st[k, 3]
                i0 = 0
                if n0 == 0:
                    buf[0, ia] = 1.0
                    buf[0, ib] = 0.0
                    a0 = 1.0
                    b0 = 0.0
                    if nr > 1:
                        a1 = co[k, 5]
                        b1 = co[k, 6]
                        buf[1, ia] = a1
                        buf[1, ib] = b1
                    i0 = 2
                for i in range(i0, nr):
                    a2 = A * a1 + B * a0
                    b2 = A * b1 + B * b0
                    buf[i, ia] = a2
                    buf[i, ib] = b2
                    a0 = a1
                    a1 = a2
                    b0 = b1
                    b1 = b2
                st[k, 0] = a0
                st[k, 1] = a1
                st[k, 2] = b0
                st[k, 3] = b1
            else:
                c1 = c[1 + 2 * k]
                c2 = c[2 + 2 * k]
                jp = 0 if common else 2 * k
                jq = 1 + k if common else 2 * k + 1
                a0 = st[k, 0]
                a1 = st[k, 1]
                b0 = st[k, 2]
                b1 = st[k, 3]
                a0p = st[k, 4]
                a1p = st[k, 5]
                a0q = st[k, 6]
                a1q = st[k, 7]
                b0p = st[k, 8]
                b1p = st[k, 9]
                b0q = st[k, 10]
                b1q = st[k, 11]
                i0 = 0
                if n0 == 0:
                    buf[0, ia] = 1.0
                    buf[0, ib] = 0.0
                    a0 = 1.0
                    b0 = 0.0
                    a0p = 0.0
                    a0q = 0.0
                    b0p = 0.0
                    b0q = 0.0
                    if nr > 1:
                        a1 = co[k, 5]
                        b1 = co[k, 6]
                        a1p = co[k, 7]
                        a1q = co[k, 8]
                        b1p = co[k, 9]
                        b1q = co[k, 10]
                        buf[1, ia] = a1
                        buf[1, ib] = b1
                        buf[1, jp] += c1 * a1p + c2 * b1p
                        buf[1, jq] += c1 * a1q + c2 * b1q
                    i0 = 2
                for i in range(i0, nr):
                    a2, b2, a2p, a2q, b2p, b2q = _recurrence_step(
                        A, B, Ap, Bp, Aq, a0, a1, b0, b1, a0p, a1p, a0q, a1q, b0p, b1p, b0q, b1q
                    )
                    buf[i, ia] = a2
                    buf[i, ib] = b2
                    buf[i, jp] += c1 * a2p + c2 * b2p
                    buf[i, jq] += c1 * a2q + c2 * b2q
                    a0 = a1
                    a1 = a2
                    b0 = b1
                    b1 = b2
                    a0p = a1p
                    a1p = a2p
                    a0q = a1q
                    a1q = a2q
                    b0p = b1p
                    b1p = b2p
                    b0q = b1q
                    b1q = b2q
                st[k, 0] = a0
                st[k, 1] = a1
                st[k, 2] = b0
                st[k, 3] = b1
                st[k, 4] = a0p
                st[k, 5] = a1p
                st[k, 6] = a0q
                st[k, 7] = a1q
                st[k, 8] = b0p
                st[k, 9] = b1p
                st[k, 10] = b0q
                st[k, 11] = b1q
            k += 1
        _accumulate(buf, nr, m, G)
        n0 += nr
    _symmetrize(G)


@njit(cache=True)
def sym_eig(A: np.ndarray, w: np.ndarray, V: np.ndarray) -> None:
    """Eigen-decomposition of a small symmetric matrix by cyclic Jacobi rotations.

    Single-threaded and free of BLAS thread pools (small LAPACK calls are slowed down by
    thread contention on busy machines). Accurate to a few ulps of ``max|A|``.

    Parameters
    ----------
    A : ndarray, shape (n, n)
        Symmetric; not modified.
    w : ndarray, shape (n,)
        Eigenvalues in ascending order (written in place).
    V : ndarray, shape (n, n)
        Orthonormal eigenvectors in columns, matching ``w`` (written in place).
    """
    n = A.shape[0]
    M = A.copy()
    # the eigenvectors accumulated in rows (VT = V^T): each rotation's update runs over
    # contiguous memory (the same products and sums as on V's columns)
    VT = np.empty((n, n))
    for i in range(n):
        for j in range(n):
            VT[i, j] = 1.0 if i == j else 0.0
    for _sweep in range(60):
        off = 0.0
        diag = 0.0
        for i in range(n):
            diag += M[i, i] * M[i, i]
            for j in range(i + 1, n):
                off += M[i, j] * M[i, j]
        # off-diagonal elements below ~1e-14 of the diagonal: eigenvalues exact to ~1e-28
        if off <= 1e-28 * diag or off == 0.0:
            break
        for pi in range(n - 1):
            for qi in range(pi + 1, n):
                apq = M[pi, qi]
                if apq == 0.0:
                    continue
                app = M[pi, pi]
                aqq = M[qi, qi]
                if abs(apq) < 1e-300 or apq * apq <= 1e-34 * abs(app * aqq):
                    M[pi, qi] = 0.0
                    M[qi, pi] = 0.0
                    continue
                theta = 0.5 * (aqq - app) / apq
                t = 1.0 / (abs(theta) + math.sqrt(theta * theta + 1.0))
                if theta < 0.0:
                    t = -t
                c = 1.0 / math.sqrt(t * t + 1.0)
                s = t * c
                for k in range(n):
                    mkp = M[k, pi]
                    mkq = M[k, qi]
                    M[k, pi] = c * mkp - s * mkq
                    M[k, qi] = s * mkp + c * mkq
                for k in range(n):
                    mpk = M[pi, k]
                    mqk = M[qi, k]
                    M[pi, k] = c * mpk - s * mqk
                    M[qi, k] = s * mpk + c * mqk
                for k in range(n):
                    vkp = VT[pi, k]
                    vkq = VT[qi, k]
                    VT[pi, k] = c * vkp - s * vkq
                    VT[qi, k] = s * vkp + c * vkq
    order = np.argsort(np.diag(M).copy())
    d = np.diag(M).copy()
    for j in range(n):
        w[j] = d[order[j]]
        for i in range(n):
            V[i, j] = VT[order[j], i]


@njit(cache=True)
def psd_pinv(A: np.ndarray, rcond: float, out: np.ndarray) -> None:
    """Pseudo-inverse of a symmetric positive semi-definite matrix, Jacobi-scaled.

    ``out = D^-1 pinv(D^-1 A D^-1) D^-1`` with ``D = sqrt(diag(A))``, discarding scaled
    eigenvalues below ``rcond`` times the largest (written in place).
    """
    n = A.shape[0]
    d = np.empty(n)
    for i in range(n):
        v = math.sqrt(abs(A[i, i]))
        d[i] = v if v > 0.0 else 1.0
    As = np.empty((n, n))
    for i in range(n):
        for j in range(n):
            As[i, j] = A[i, j] / (d[i] * d[j])
    w = np.empty(n)
    V = np.empty((n, n))
    sym_eig(As, w, V)
    wmax = max(w[n - 1], 0.0) if n > 0 else 0.0
    # out[i, j] = sum over the kept k (increasing) of V[i, k] V[j, k] / w[k], over d[i] d[j]:
    # every sum formed term by term in that order as one dot product at a time would, but
    # the terms of a row added across j at once (a loop over contiguous VT[k, :], which
    # vectorises) and each symmetric pair once (the products commute exactly: out[j, i] is
    # the same number)
    keep = np.empty(n, np.int64)
    nk = 0
    for k in range(n):
        if w[k] > rcond * wmax and w[k] > 0.0:
            keep[nk] = k
            nk += 1
    VT = np.empty((n, n))
    for k in range(n):
        for j in range(n):
            VT[k, j] = V[j, k]
    acc = np.empty(n)
    for i in range(n):
        for j in range(i, n):
            acc[j] = 0.0
        for r in range(nk):
            k = keep[r]
            vik = V[i, k]
            wk = w[k]
            for j in range(i, n):
                acc[j] += vik * VT[k, j] / wk
        di = d[i]
        for j in range(i, n):
            v = acc[j] / (di * d[j])
            out[i, j] = v
            out[j, i] = v


@njit(cache=True)
def model_values(p: np.ndarray, q: np.ndarray, c: np.ndarray, out: np.ndarray) -> None:
    """Noise-free model ``c0 + sum_k c1_k u1_k(n) + c2_k u2_k(n)`` for ``n < len(out)``.

    Parameters
    ----------
    p, q : ndarray, shape (K,)
    c : ndarray, shape (2 K + 1,)
    out : ndarray, shape (N,)
        Written in place.
    """
    N = out.shape[0]
    K = p.shape[0]
    for n in range(N):
        out[n] = c[0]
    k = 0
    while k < K:
        co = _mode_coeffs(p[k], q[k])
        A = co[0]
        B = co[1]
        c1 = c[1 + 2 * k]
        c2 = c[2 + 2 * k]
        if k + 1 < K and N >= 2:
            # two modes at once (each recurrence alone is latency-bound); each sample still
            # receives mode k's term, then mode k + 1's
            _pair_values(co, _mode_coeffs(p[k + 1], q[k + 1]), c1, c2, c[3 + 2 * k],
                         c[4 + 2 * k], out)  # fmt: skip
            k += 2
            continue
        a0 = 1.0
        b0 = 0.0
        out[0] += c1
        k += 1
        if N < 2:
            continue
        a1 = co[5]
        b1 = co[6]
        out[1] += c1 * a1 + c2 * b1
        for n in range(2, N):
            a2 = A * a1 + B * a0
            b2 = A * b1 + B * b0
            out[n] += c1 * a2 + c2 * b2
            a0 = a1
            a1 = a2
            b0 = b1
            b1 = b2


@njit(cache=True)
def _pair_values(
    co: np.ndarray, co_: np.ndarray, c1: float, c2: float, c1_: float, c2_: float,
    out: np.ndarray,
) -> None:  # fmt: skip
    """Add two modes' terms to ``out`` (``len(out) >= 2``), their recurrences interleaved."""
    N = out.shape[0]
    A = co[0]
    B = co[1]
    A_ = co_[0]
    B_ = co_[1]
    out[0] += c1
    out[0] += c1_
    a0 = 1.0
    b0 = 0.0
    a1 = co[5]
    b1 = co[6]
    a0_ = 1.0
    b0_ = 0.0
    a1_ = co_[5]
    b1_ = co_[6]
    out[1] += c1 * a1 + c2 * b1
    out[1] += c1_ * a1_ + c2_ * b1_
    for n in range(2, N):
        a2 = A * a1 + B * a0
        b2 = A * b1 + B * b0
        a2_ = A_ * a1_ + B_ * a0_
        b2_ = A_ * b1_ + B_ * b0_
        out[n] += c1 * a2 + c2 * b2
        out[n] += c1_ * a2_ + c2_ * b2_
        a0 = a1
        a1 = a2
        b0 = b1
        b1 = b2
        a0_ = a1_
        a1_ = a2_
        b0_ = b1_
        b1_ = b2_


@njit(cache=True)
def _orthonormalize(Q: np.ndarray) -> None:
    """Modified Gram-Schmidt on the columns of ``Q`` (twice, for stability), in place."""
    L, r = Q.shape
    for _rep in range(2):
        for j in range(r):
            for i in range(j):
                d = 0.0
                for k in range(L):
                    d += Q[k, i] * Q[k, j]
                for k in range(L):
                    Q[k, j] -= d * Q[k, i]
            nrm = 0.0
            for k in range(L):
                nrm += Q[k, j] * Q[k, j]
            nrm = math.sqrt(nrm)
            if nrm > 0.0:
                for k in range(L):
                    Q[k, j] /= nrm


@njit(cache=True)
def _matmul(A: np.ndarray, B: np.ndarray) -> np.ndarray:
    """Plain triple loop (small matrices; keeps BLAS thread pools out of the way)."""
    n, m = A.shape
    k = B.shape[1]
    C = np.zeros((n, k))
    for i in range(n):
        for t in range(m):
            a = A[i, t]
            for j in range(k):
                C[i, j] += a * B[t, j]
    return C


@njit(cache=True)
def top_eigenpairs(R: np.ndarray, r: int, iters: int, w: np.ndarray, V: np.ndarray) -> None:
    """Leading ``r`` eigenpairs of a symmetric PSD matrix by block subspace iteration.

    Starts from the first ``r`` columns of ``R`` (its range), iterates ``Q <- orth(R Q)`` and
    finishes with a Rayleigh-Ritz step (Jacobi on ``Q^T R Q``).

    Parameters
    ----------
    R : ndarray, shape (L, L)
    r : int
        Number of eigenpairs (``r <= L``).
    iters : int
        Subspace iterations.
    w : ndarray, shape (r,)
        Eigenvalues, descending (written in place).
    V : ndarray, shape (L, r)
        Matching orthonormal eigenvectors (written in place).
    """
    L = R.shape[0]
    Q = np.empty((L, r))
    for i in range(L):
        for j in range(r):
            Q[i, j] = R[i, j] + (1e-3 if i == j else 0.0) * R[i, i]
    _orthonormalize(Q)
    for _ in range(iters):
        Q = _matmul(R, Q)
        _orthonormalize(Q)
    T = _matmul(Q.T.copy(), _matmul(R, Q))
    for i in range(r):
        for j in range(i):
            s = 0.5 * (T[i, j] + T[j, i])
            T[i, j] = s
            T[j, i] = s
    ws = np.empty(r)
    U = np.empty((r, r))
    sym_eig(T, ws, U)
    Vr = _matmul(Q, U)
    for j in range(r):
        w[j] = ws[r - 1 - j]
        for i in range(L):
            V[i, j] = Vr[i, r - 1 - j]


@njit(cache=True)
def _running_min(x: np.ndarray, h: int, out: np.ndarray) -> None:
    n = x.shape[0]
    dq = np.empty(n, np.int64)  # indices of increasing values: the window's minimum first
    head = 0
    tail = 0
    j = 0
    for i in range(n):
        hi = min(n - 1, i + h)
        while j <= hi:
            v = x[j]
            while tail > head and x[dq[tail - 1]] >= v:
                tail -= 1
            dq[tail] = j
            tail += 1
            j += 1
        while dq[head] < i - h:
            head += 1
        out[i] = x[dq[head]]


def running_min(x: np.ndarray, h: int) -> np.ndarray:
    """The lowest value of ``x`` over ``[i - h, i + h]`` (clipped to the record) at each sample:
    ``scipy.ndimage.minimum_filter1d(x, 2 h + 1, mode="nearest")`` in O(n) with a monotone
    queue, as float64 (a minimum is one of the values: exact)."""
    xf = np.ascontiguousarray(x, dtype=np.float64)
    out = np.empty(xf.shape[0])
    if xf.shape[0]:
        _running_min(xf, max(int(h), 0), out)
    return out
