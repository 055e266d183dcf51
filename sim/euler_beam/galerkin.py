"""Legendre-Galerkin discretisation of the clamped beam on X in [0, 1].

Trial and test functions are Shen's clamped Legendre combinations (x = 2 X - 1)

    phi_k(x) = L_k - 2 (2k+5)/(2k+7) L_{k+2} + (2k+3)/(2k+7) L_{k+4},   k = 0 .. n-1,

which satisfy phi = phi' = 0 at both ends, so the clamped boundary conditions hold exactly and
the biharmonic stiffness is diagonal and well conditioned. Inhomogeneous end slopes are carried
by a cubic lift ell(X) = mu (h1(X) + s h2(X)), h1 = X (1-X)^2, h2 = X^2 (X-1).

Matrices (all integrals over X in [0, 1], Gauss-Legendre exact for the polynomial parts):

    M_ij  = int phi_i phi_j,   K4_ij = int phi_i'' phi_j'',   K2_ij = int phi_i' phi_j'.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from numpy.polynomial import legendre as npleg


@dataclass(frozen=True)
class Basis:
    """Quadrature, basis values and matrices for ``n`` clamped Legendre functions.

    Attributes
    ----------
    n : int
        Number of basis functions.
    X, w : ndarray, shape (q,)
        Quadrature nodes on [0, 1] and weights.
    phi, dphi, d2phi : ndarray, shape (q, n)
        Basis functions and their X-derivatives at the nodes.
    M, K2, K4 : ndarray, shape (n, n)
    """

    n: int
    X: np.ndarray
    w: np.ndarray
    phi: np.ndarray
    dphi: np.ndarray
    d2phi: np.ndarray
    M: np.ndarray
    K2: np.ndarray
    K4: np.ndarray

    def eval(self, X: np.ndarray, derivative: int = 0) -> np.ndarray:
        """Basis (or its X-derivative) at arbitrary points X; shape (len(X), n)."""
        return _values(self.n, np.atleast_1d(np.asarray(X, float)), derivative)


def _shen_coeffs(n: int) -> np.ndarray:
    """Legendre coefficients of the n Shen functions, shape (n, n + 4)."""
    P = np.zeros((n, n + 4))
    for k in range(n):
        P[k, k] = 1.0
        P[k, k + 2] = -2.0 * (2 * k + 5) / (2 * k + 7)
        P[k, k + 4] = (2 * k + 3) / (2 * k + 7)
    return P


def _values(n: int, X: np.ndarray, derivative: int) -> np.ndarray:
    P = _shen_coeffs(n)
    x = 2.0 * X - 1.0
    out = np.empty((X.size, n))
    for k in range(n):
        c = P[k]
        for _ in range(derivative):
            c = npleg.legder(c)
        out[:, k] = npleg.legval(x, c) * (2.0**derivative)
    return out


@lru_cache(maxsize=16)
def basis(n: int, quad: int | None = None) -> Basis:
    """Build (and cache) the clamped Legendre basis with ``n`` functions.

    ``quad`` Gauss-Legendre nodes (default n + 64: exact for the polynomial products and
    converged to round-off for the trigonometric equilibrium shapes with Lambda < ~40).
    """
    if n < 2:
        raise ValueError(f"n must be >= 2, got {n!r}")
    q = quad or (n + 64)
    xq, wq = npleg.leggauss(q)
    X = 0.5 * (xq + 1.0)
    w = 0.5 * wq
    phi = _values(n, X, 0)
    dphi = _values(n, X, 1)
    d2phi = _values(n, X, 2)
    M = phi.T @ (w[:, None] * phi)
    K2 = dphi.T @ (w[:, None] * dphi)
    K4 = d2phi.T @ (w[:, None] * d2phi)
    for A in (M, K2, K4):
        A[:] = 0.5 * (A + A.T)
    return Basis(n, X, w, phi, dphi, d2phi, M, K2, K4)


def lift(X: np.ndarray, s: float, derivative: int = 0) -> np.ndarray:
    """Unit-mu cubic lift with ell(0) = ell(1) = 0, ell'(0) = 1, ell'(1) = s."""
    X = np.asarray(X, float)
    if derivative == 0:
        return X * (1 - X) ** 2 + s * X**2 * (X - 1)
    if derivative == 1:
        return (1 - X) ** 2 - 2 * X * (1 - X) + s * (3 * X**2 - 2 * X)
    if derivative == 2:
        return -4 * (1 - X) + 2 * X + s * (6 * X - 2)
    raise ValueError(f"derivative must be 0..2, got {derivative!r}")


def constraint_null_space(g: np.ndarray) -> np.ndarray:
    """Orthonormal basis Z (n, n-1) of the vectors a with g . a = 0 (Householder)."""
    q, _ = np.linalg.qr(g.reshape(-1, 1), mode="complete")
    return q[:, 1:]
