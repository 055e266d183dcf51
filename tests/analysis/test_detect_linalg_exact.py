"""The detector's small linear algebra, made faster, gives the same numbers to the bit.

``sym_eig`` (eigenvectors kept as rows while rotating), ``psd_pinv`` (each symmetric pair
formed once, a row's terms added across the row) and the memo of ``_linalg._pinv_psd`` are
compared with the implementations they replaced (copied here verbatim, compiled without a
cache) on random symmetric PSD matrices of every size the detector uses, rank-deficient and
badly scaled ones included.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from numba import njit

from service.analysis.detect import _linalg
from service.analysis.detect._kernels import psd_pinv, sym_eig


@njit
def _sym_eig_before(A, w, V):  # noqa: ANN001, ANN202 - verbatim copy of the previous kernel
    n = A.shape[0]
    M = A.copy()
    for i in range(n):
        for j in range(n):
            V[i, j] = 1.0 if i == j else 0.0
    for _sweep in range(60):
        off = 0.0
        diag = 0.0
        for i in range(n):
            diag += M[i, i] * M[i, i]
            for j in range(i + 1, n):
                off += M[i, j] * M[i, j]
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
                    vkp = V[k, pi]
                    vkq = V[k, qi]
                    V[k, pi] = c * vkp - s * vkq
                    V[k, qi] = s * vkp + c * vkq
    order = np.argsort(np.diag(M).copy())
    d = np.diag(M).copy()
    Vc = V.copy()
    for j in range(n):
        w[j] = d[order[j]]
        for i in range(n):
            V[i, j] = Vc[i, order[j]]


@njit
def _psd_pinv_before(A, rcond, out):  # noqa: ANN001, ANN202 - verbatim copy
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
    _sym_eig_before(As, w, V)
    wmax = max(w[n - 1], 0.0) if n > 0 else 0.0
    for i in range(n):
        for j in range(n):
            s = 0.0
            for k in range(n):
                if w[k] > rcond * wmax and w[k] > 0.0:
                    s += V[i, k] * V[j, k] / w[k]
            out[i, j] = s / (d[i] * d[j])


def _matrices() -> list[np.ndarray]:
    """Symmetric PSD matrices as the detector's Grams: sizes 1-24, column scales 1e-20..1e20,
    full rank, rank-deficient and with a zero row and column."""
    rng = np.random.default_rng(20261128)
    out = []
    for n in range(1, 25):
        for kind in range(6):
            rows = n + int(rng.integers(0, 6)) if kind != 1 else max(1, n // 2)
            X = rng.standard_normal((rows, n)) * np.exp(rng.uniform(-20, 20, n))
            A = X.T @ X
            A = 0.5 * (A + A.T)
            if kind == 2:
                A[:, 0] = 0.0
                A[0, :] = 0.0
            if kind == 3:  # nearly dependent columns (a close pair of modes)
                A = A + 1e-12 * np.eye(n) * np.trace(A) / n
            out.append(A)
    return out


MATRICES = _matrices()


def _same(a: np.ndarray, b: np.ndarray) -> bool:
    return bool(np.array_equal(a, b, equal_nan=True))


def test_sym_eig_is_the_previous_kernel_to_the_bit() -> None:
    for A in MATRICES:
        n = A.shape[0]
        w0, V0, w1, V1 = np.empty(n), np.empty((n, n)), np.empty(n), np.empty((n, n))
        _sym_eig_before(A, w0, V0)
        sym_eig(A, w1, V1)
        assert _same(w0, w1) and _same(V0, V1), n


@pytest.mark.parametrize("rcond", [1e-13, 1e-6, 0.3])
def test_psd_pinv_is_the_previous_kernel_to_the_bit(rcond: float) -> None:
    for A in MATRICES:
        before, after = np.empty_like(A), np.empty_like(A)
        _psd_pinv_before(A, rcond, before)
        psd_pinv(A, rcond, after)
        assert _same(before, after), A.shape


def test_pinv_memo_returns_the_computed_array_and_a_fresh_copy() -> None:
    A = MATRICES[40]
    ref = np.empty_like(A)
    psd_pinv(A, 1e-13, ref)
    _linalg._PINV.clear()
    first = _linalg._pinv_psd(A)
    first[0, 0] = 123.0  # a caller writing into its result leaves the memo alone
    again = _linalg._pinv_psd(A.copy())
    assert _same(again, ref)
    assert again is not first
    other = _linalg._pinv_psd(A, 1e-6)  # rcond is part of the key
    ref6 = np.empty_like(A)
    psd_pinv(A, 1e-6, ref6)
    assert _same(other, ref6)
    for B in MATRICES[: 2 * _linalg._PINV_MAX]:  # bounded
        _linalg._pinv_psd(B)
    assert len(_linalg._PINV) <= _linalg._PINV_MAX
