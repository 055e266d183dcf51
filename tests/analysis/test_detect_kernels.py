"""Numba kernels of the detector against slow pure-numpy references."""

from __future__ import annotations

import numpy as np
import pytest

from service.analysis.detect._kernels import (
    _ch_sh,
    hankel_gram,
    model_gram,
    model_values,
    pair_basis,
    psd_pinv,
    sym_eig,
    top_eigenpairs,
)


def ref_basis(n: int, p: float, q: float) -> tuple[np.ndarray, np.ndarray]:
    """u1 = exp(-p t/2) cosh(lam t), u2 = exp(-p t/2) sinh(lam t)/lam, lam = sqrt(p^2/4 - q)."""
    t = np.arange(n, dtype=float)
    lam = np.sqrt(complex(0.25 * p * p - q))
    e = np.exp(-0.5 * p * t)
    u1 = (e * np.cosh(lam * t)).real
    if abs(lam) == 0:
        u2 = e * t
    else:
        u2 = (e * np.sinh(lam * t) / lam).real
    return u1, u2


def ref_derivs(n: int, p: float, q: float, h: float = 1e-8) -> np.ndarray:
    """Central finite differences of the reference basis in p and q: (n, 4)."""
    cols = []
    for which in (0, 1):
        for dp, dq in ((h, 0.0), (0.0, h)):
            plus = ref_basis(n, p + dp, q + dq)[which]
            minus = ref_basis(n, p - dp, q - dq)[which]
            cols.append((plus - minus) / (2 * h))
    # order: du1/dp, du1/dq, du2/dp, du2/dq
    return np.column_stack(cols)


CASES = [
    (2e-3, 4e-2),  # underdamped, light
    (0.05, 0.3),  # underdamped, heavier
    (0.02, 1e-4 + 0.25 * 0.02**2),  # just underdamped, D tiny (series branch)
    (0.02, 0.25 * 0.02**2 - 5e-5),  # just overdamped, D tiny (series branch)
    (0.01, 1e-5),  # overdamped
    (0.03, -1e-4),  # unstable (one growing real pole)
]


@pytest.mark.parametrize(("p", "q"), CASES)
def test_pair_basis_matches_closed_form(p: float, q: float) -> None:
    n = 400
    out = np.empty((n, 6))
    pair_basis(n, np.array([p]), np.array([q]), out, 0)
    u1, u2 = ref_basis(n, p, q)
    scale1 = np.max(np.abs(u1))
    scale2 = np.max(np.abs(u2))
    np.testing.assert_allclose(out[:, 0], u1, rtol=0, atol=1e-11 * scale1)
    np.testing.assert_allclose(out[:, 1], u2, rtol=0, atol=1e-11 * scale2)
    d = ref_derivs(n, p, q)
    got = out[:, [2, 3, 4, 5]]
    for j in range(4):
        s = np.max(np.abs(d[:, j]))
        np.testing.assert_allclose(got[:, j], d[:, j], rtol=0, atol=2e-5 * s)


def test_series_branch_is_continuous() -> None:
    for D in (-1e-2, 1e-2):
        a = np.array(_ch_sh(D * (1 - 1e-12)))
        b = np.array(_ch_sh(D * (1 + 1e-12)))
        np.testing.assert_allclose(a, b, rtol=1e-12)
    # exact values at D = -x^2: cos x, sin x / x, derivative (cos x - sin x/x)/(2D)
    x = 0.09
    ch, sh, dsh = _ch_sh(-(x**2))
    assert ch == pytest.approx(np.cos(x), rel=1e-15)
    assert sh == pytest.approx(np.sin(x) / x, rel=1e-15)
    assert dsh == pytest.approx((np.cos(x) - np.sin(x) / x) / (-2 * x**2), rel=1e-9)


def _ref_columns(y, p, q, c, common, jacobian):
    n = y.size
    K = len(p)
    phi = [np.ones(n)]
    der = []
    for k in range(K):
        u1, u2 = ref_basis(n, p[k], q[k])
        phi += [u1, u2]
        d = ref_derivs(n, p[k], q[k])
        der.append(
            (
                c[1 + 2 * k] * d[:, 0] + c[2 + 2 * k] * d[:, 2],
                c[1 + 2 * k] * d[:, 1] + c[2 + 2 * k] * d[:, 3],
            )
        )
    cols = []
    if jacobian:
        if common:
            cols.append(sum(dp for dp, _ in der))
            cols += [dq for _, dq in der]
        else:
            for dp, dq in der:
                cols += [dp, dq]
    return np.column_stack(cols + phi + [y])


@pytest.mark.parametrize("common", [False, True])
@pytest.mark.parametrize("jacobian", [False, True])
@pytest.mark.parametrize("n", [1, 2, 3, 255, 256, 257, 700])
def test_model_gram_matches_numpy(common: bool, jacobian: bool, n: int) -> None:
    rng = np.random.default_rng(n)
    y = rng.standard_normal(n)
    p = np.array([2e-3, 0.05, 0.01])
    q = np.array([4e-2, 0.3, 1e-5])
    c = rng.standard_normal(7)
    Z = _ref_columns(y, p, q, c, common, jacobian)
    ref = Z.T @ Z
    G = np.empty_like(ref)
    model_gram(y, p, q, c, common, jacobian, G)
    tol = 1e-4 if jacobian else 1e-10  # finite-difference reference for the Jacobian
    np.testing.assert_allclose(G, ref, rtol=0, atol=tol * np.max(np.abs(ref)))


def test_model_values_matches_reference() -> None:
    n = 600
    p = np.array([2e-3, 0.01])
    q = np.array([4e-2, 1e-5])
    c = np.array([0.3, 1.0, -2.0, 0.5, 4.0])
    ref = c[0] + sum(
        c[1 + 2 * k] * ref_basis(n, p[k], q[k])[0] + c[2 + 2 * k] * ref_basis(n, p[k], q[k])[1]
        for k in range(2)
    )
    out = np.empty(n)
    model_values(p, q, c, out)
    # forward error of a two-term recurrence: ~ n eps / |z1 - z2| (close roots amplify it)
    dz = min(abs(np.diff(np.exp(np.roots([1.0, pk, qk])))[0]) for pk, qk in zip(p, q, strict=True))
    tol = 10 * n * np.finfo(float).eps / dz
    np.testing.assert_allclose(out, ref, rtol=0, atol=tol * np.max(np.abs(ref)))


def _scalar_model_values(p: np.ndarray, q: np.ndarray, c: np.ndarray, n: int) -> np.ndarray:
    """The model one mode at a time, in Python floats (IEEE doubles, no fused multiply-add):
    the order of operations of the kernel, whose paired loop must not change one bit."""
    from service.analysis.detect._kernels import _mode_coeffs

    out = [float(c[0])] * n
    for k in range(p.size):
        co = _mode_coeffs(float(p[k]), float(q[k]))
        A, B, c1, c2 = float(co[0]), float(co[1]), float(c[1 + 2 * k]), float(c[2 + 2 * k])
        out[0] += c1
        if n < 2:
            continue
        a0, b0, a1, b1 = 1.0, 0.0, float(co[5]), float(co[6])
        out[1] += c1 * a1 + c2 * b1
        for i in range(2, n):
            a2 = A * a1 + B * a0
            b2 = A * b1 + B * b0
            out[i] += c1 * a2 + c2 * b2
            a0, a1, b0, b1 = a1, a2, b1, b2
    return np.asarray(out)


@pytest.mark.parametrize("K", [1, 2, 3, 4, 5])
@pytest.mark.parametrize("n", [1, 2, 3, 600])
def test_model_values_bit_exact(K: int, n: int) -> None:
    rng = np.random.default_rng(10 * K + n)
    p = rng.uniform(-1e-3, 2e-2, K)
    q = rng.uniform(-1e-4, 0.5, K)
    c = rng.standard_normal(2 * K + 1)
    out = np.empty(n)
    model_values(p, q, c, out)
    assert np.array_equal(out, _scalar_model_values(p, q, c, n))


@pytest.mark.parametrize(("L", "stride"), [(2, 1), (8, 1), (12, 3), (5, 40)])
def test_hankel_gram_matches_explicit_product(L: int, stride: int) -> None:
    x = np.random.default_rng(L).standard_normal(1000)
    M = x.size - (L - 1) * stride
    H = np.stack([x[i * stride : i * stride + M] for i in range(L)])
    out = np.empty((L, L))
    assert hankel_gram(x, L, stride, out) == M
    np.testing.assert_allclose(out, H @ H.T, rtol=1e-11, atol=1e-9)


@pytest.mark.parametrize("n", [1, 2, 7, 14, 30])
def test_sym_eig_and_pinv_match_numpy(n: int) -> None:
    rng = np.random.default_rng(n)
    B = rng.standard_normal((n, n))
    A = B @ B.T + 1e-3 * np.eye(n)
    w = np.empty(n)
    V = np.empty((n, n))
    sym_eig(A, w, V)
    np.testing.assert_allclose(w, np.linalg.eigvalsh(A), rtol=1e-10, atol=1e-12 * np.abs(w).max())
    np.testing.assert_allclose(V @ np.diag(w) @ V.T, A, atol=1e-11 * np.abs(A).max())
    out = np.empty((n, n))
    psd_pinv(A, 1e-14, out)
    inv = np.linalg.inv(A)
    np.testing.assert_allclose(out, inv, rtol=0, atol=1e-8 * np.abs(inv).max())


def test_psd_pinv_handles_rank_deficiency() -> None:
    v = np.array([1.0, 2.0, 3.0])
    A = np.outer(v, v)
    out = np.empty((3, 3))
    psd_pinv(A, 1e-12, out)
    # a symmetric generalised inverse (Jacobi-scaled, so not Moore-Penrose): A X A = A
    assert np.all(np.isfinite(out))
    np.testing.assert_allclose(out, out.T, atol=1e-12)
    np.testing.assert_allclose(A @ out @ A, A, atol=1e-10)


def test_top_eigenpairs_match_numpy_on_a_hankel_covariance() -> None:
    rng = np.random.default_rng(3)
    n = np.arange(3000)
    x = np.cos(0.05 * n) + 0.5 * np.cos(0.13 * n + 1) + 0.05 * rng.standard_normal(n.size)
    L = 30
    R = np.empty((L, L))
    M = hankel_gram(x, L, 2, R)
    R /= M
    r = 8
    w = np.empty(r)
    V = np.empty((L, r))
    top_eigenpairs(R, r, 4, w, V)
    we, Ve = np.linalg.eigh(R)
    we, Ve = we[::-1], Ve[:, ::-1]
    # the signal eigenvalues (4 of them) to near machine precision, the rest approximately
    np.testing.assert_allclose(w[:4], we[:4], rtol=1e-10)
    assert np.all(w[4:] <= we[4:r] * (1 + 1e-12))
    # same signal subspace: all principal angles ~ 0
    s = np.linalg.svd(Ve[:, :4].T @ V[:, :4], compute_uv=False)
    np.testing.assert_allclose(s, 1.0, atol=1e-10)
    np.testing.assert_allclose(V.T @ V, np.eye(r), atol=1e-12)


@pytest.mark.parametrize("n", [1, 2, 7, 100, 2001])
@pytest.mark.parametrize("h", [0, 1, 3, 50, 5000])
def test_running_min_matches_scipy_minimum_filter(n: int, h: int) -> None:
    from scipy.ndimage import minimum_filter1d

    from service.analysis.detect._kernels import running_min

    rng = np.random.default_rng(n * 7 + h)
    for x in (rng.random(n), np.cumsum(rng.normal(size=n)), np.round(rng.random(n), 1)):
        ref = minimum_filter1d(x, size=2 * h + 1, mode="nearest")
        np.testing.assert_array_equal(running_min(x, h), ref)
    x32 = rng.random(n).astype(np.float32)
    ref32 = minimum_filter1d(x32, size=2 * h + 1, mode="nearest").astype(np.float64)
    np.testing.assert_array_equal(running_min(x32, h), ref32)


def test_prev_fast_len_matches_scipy() -> None:
    import scipy.fft

    from service.analysis.detect._spectral import prev_fast_len

    rng = np.random.default_rng(5)
    ns = [*range(1, 5000), *rng.integers(5000, 10**9, 3000).tolist(), 2**40 + 1]
    assert [prev_fast_len(n) for n in ns] == [scipy.fft.prev_fast_len(n, real=True) for n in ns]
