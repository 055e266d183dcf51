"""Linear stability of beam equilibria: the sigma^2 spectrum and mode shapes.

Perturbing W = W_eq + eps W_p e^{sigma T}, Lambda = Lambda_eq + eps Lambda_p e^{sigma T}
(paper, eq. smallperturbations_beameq):

    sigma^2 W_p + W_p'''' + Lambda^2 W_p'' = -2 Lambda Lambda_p W_eq'',   int W_eq' W_p' = 0,

with clamped homogeneous boundary conditions. In weak form with q = 2 Lambda Lambda_p as the
Lagrange multiplier of the linearised constraint this is the symmetric constrained pencil

    (K4 - Lambda^2 K2) a + sigma^2 M a = q g,   g . a = 0,   g_i = int W_eq' phi_i',

solved here on the null space of g (``method="galerkin"``, the default: spectral accuracy,
all modes at once). The paper's determinant method (``det M_p(sigma^2) = 0`` from the exact
solution of the ODE) is implemented independently in ``determinant`` / ``refine_by_determinant``
and is the reference the tests hold the Galerkin spectrum to.

With damping xi (paper eq. beam_equation_damping) each mode's poles solve
s^2 + xi s - sigma^2 = 0, so s1 s2 = -sigma^2 in the under- and the over-damped regime.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import scipy.linalg as sla
from scipy.optimize import brentq

from sim.errors import ParameterError
from sim.euler_beam import galerkin
from sim.euler_beam.statics import Equilibrium, equilibrium

DEFAULT_N = 32  # Galerkin functions: 10 lowest sigma^2 converged to ~1e-12 relative (tests)


@dataclass(frozen=True)
class Spectrum:
    """sigma^2 spectrum of an equilibrium, ordered by |sigma^2| ascending.

    Attributes
    ----------
    equilibrium : Equilibrium
    sigma2 : ndarray, shape (k,)
        Eigenvalues sigma^2 (negative: stable oscillation of angular frequency sqrt(-sigma^2)).
    coeffs : ndarray, shape (n, k)
        Galerkin coefficients of the mode shapes, M-orthonormal (int W_p^2 dX = 1).
    lambda_p : ndarray, shape (k,)
        Lambda_p of each (unit-mass) mode: the compression change it carries.
    n : int
        Galerkin basis size.
    """

    equilibrium: Equilibrium
    sigma2: np.ndarray
    coeffs: np.ndarray
    lambda_p: np.ndarray
    n: int

    @property
    def omega(self) -> np.ndarray:
        """sqrt(|sigma^2|): angular frequency of stable modes, growth rate of unstable ones."""
        return np.sqrt(np.abs(self.sigma2))

    def shape(self, X: np.ndarray, k: int = 0, derivative: int = 0) -> np.ndarray:
        """Mode shape k (or its derivative) at points X."""
        return galerkin.basis(self.n).eval(X, derivative) @ self.coeffs[:, k]


def _constraint_vector(eq: Equilibrium, B: galerkin.Basis) -> np.ndarray:
    return B.dphi.T @ (B.w * eq.shape(B.X, 1))


def spectrum_of(eq: Equilibrium, modes: int = 10, *, n: int = DEFAULT_N) -> Spectrum:
    """The ``modes`` smallest-|sigma^2| eigenpairs of an equilibrium (Legendre-Galerkin).

    Parameters
    ----------
    eq : Equilibrium
    modes : int
        How many (1 .. n - 1).
    n : int
        Galerkin basis size; accuracy is spectral in n (see tests for the convergence study).
    """
    if isinstance(modes, bool) or int(modes) != modes or not 1 <= modes <= n - 1:
        raise ParameterError("modes", modes, f"modes must be in 1..{n - 1}, got {modes!r}")
    B = galerkin.basis(n)
    g = _constraint_vector(eq, B)
    K = B.K4 - eq.lambda2 * B.K2
    # Diagonal scaling (K4 is diagonal in Shen's basis) and a shifted inverse pencil: the low
    # modes become the largest eigenvalues theta = 1 / (lambda + c) of (Mr, Kr + c Mr), which
    # LAPACK computes to round-off relative to theta_max (the direct pencil (Kr, Mr) loses
    # digits as n grows: 1e-9 at n = 40, 2e-8 at n = 60; this form stays at 1e-13).
    D = 1.0 / np.sqrt(np.diag(B.K4))
    Ks = K * np.outer(D, D)
    Ms = B.M * np.outer(D, D)
    Z = galerkin.constraint_null_space(D * g)
    Kr = Z.T @ Ks @ Z
    Mr = Z.T @ Ms @ Z
    Kr, Mr = 0.5 * (Kr + Kr.T), 0.5 * (Mr + Mr.T)
    rough = sla.eigh(Kr, Mr, eigvals_only=True)
    c = 1.5 * max(0.0, -rough.min()) + 0.5 * np.min(np.abs(rough)) + 1.0
    theta, vecs = sla.eigh(Mr, Kr + c * Mr)
    sigma2 = -(1.0 / theta - c)
    order = np.argsort(np.abs(sigma2), kind="stable")[:modes]
    V = vecs[:, order]
    V = V / np.sqrt(np.einsum("ik,ij,jk->k", V, Mr, V))
    A = D[:, None] * (Z @ V)
    s2 = sigma2[order]
    q = (g @ (K @ A + B.M @ A * s2)) / (g @ g)
    lam = math.sqrt(abs(eq.lambda2)) or 1.0
    return Spectrum(eq, s2, A, q / (2.0 * lam), n)


def is_stable(eq: Equilibrium, *, n: int = DEFAULT_N) -> bool:
    """True when every sigma^2 of the equilibrium's spectrum is negative."""
    return bool(np.all(spectrum_of(eq, modes=10, n=n).sigma2 < 0.0))


def spectrum(
    actuation: str, mu: float, branch: str = "U_A", modes: int = 10, *, n: int = DEFAULT_N
) -> Spectrum:
    """sigma^2 spectrum of the equilibrium on ``branch`` at ``mu`` (see ``spectrum_of``)."""
    return spectrum_of(equilibrium(actuation, mu, branch), modes, n=n)


# --------------------------------------------------------------------------------------------
# The paper's determinant method (independent reference)
# --------------------------------------------------------------------------------------------
_DQ = 200
_DX, _DW = np.polynomial.legendre.leggauss(_DQ)
_DX = 0.5 * (_DX + 1.0)
_DW = 0.5 * _DW


def _fundamental_solutions(lam: float, sigma2: float) -> list:
    """Real fundamental solutions of sigma^2 y + y'''' + lam y'' = 0, bounded by 1 on [0, 1].

    From the roots r of r^4 + lam r^2 + sigma^2 = 0, each exp(r (X - x_r)) with x_r = 1 when
    Re r > 0 (no basis function exceeds 1, so the determinant stays well scaled for high
    modes); a complex pair gives the real and imaginary parts of one member.
    Returns a list of callables f(X, derivative) -> ndarray.
    """
    roots = np.roots([1.0, 0.0, lam, 0.0, sigma2])
    funcs = []
    tol = 1e-12 * max(1.0, np.abs(roots).max())
    for r in sorted(roots, key=lambda z: (z.real, z.imag)):
        x0 = 1.0 if r.real > 0 else 0.0
        if abs(r.imag) <= tol:
            rr = r.real
            funcs.append(lambda X, d, rr=rr, x0=x0: rr**d * np.exp(rr * (X - x0)))
        elif r.imag > 0:
            funcs.append(lambda X, d, r=r, x0=x0: (r**d * np.exp(r * (X - x0))).real)
            funcs.append(lambda X, d, r=r, x0=x0: (r**d * np.exp(r * (X - x0))).imag)
    return funcs


def determinant(eq: Equilibrium, sigma2: float) -> float:
    """det M_p(sigma^2) (the paper's method): zero exactly at the eigenvalues sigma^2 of ``eq``.

    The perturbation is written W_p = sum_j c_j y_j(X) + p W_eq''(X): y_j are the exact
    fundamental solutions of sigma^2 y + y'''' + Lambda^2 y'' = 0 (exponentials of the
    characteristic roots, scaled to stay bounded) and p W_eq'' is the particular solution for
    the forcing -2 Lambda Lambda_p W_eq'' (W_eq'' solves y'''' + Lambda^2 y'' = 0, hence
    sigma^2 W_eq'' + L W_eq'' = sigma^2 W_eq''). The five conditions W_p(0) = W_p'(0) =
    W_p(1) = W_p'(1) = 0 and int W_eq' W_p' = 0 form the 5 x 5 matrix M_p.
    """
    funcs = _fundamental_solutions(eq.lambda2, sigma2)
    if len(funcs) != 4:  # a repeated root (a measure-zero set): nudge off it
        funcs = _fundamental_solutions(eq.lambda2, sigma2 * (1 + 1e-12) + 1e-12)
    ends = np.array([0.0, 1.0])
    dWeq = eq.shape(_DX, 1)
    Mp = np.empty((5, 5))
    for j, f in enumerate(funcs):
        v0, v1 = f(ends, 0), f(ends, 1)
        Mp[:, j] = (v0[0], v1[0], v0[1], v1[1], np.sum(_DW * dWeq * f(_DX, 1)))
    P, dP = eq.shape(ends, 2), eq.shape(ends, 3)
    Mp[:, 4] = (P[0], dP[0], P[1], dP[1], np.sum(_DW * dWeq * eq.shape(_DX, 3)))
    Mp /= np.maximum(np.abs(Mp).max(axis=0, keepdims=True), 1e-300)
    # At sigma^2 = 0 the particular column W_eq'' is itself a homogeneous solution, so det M_p
    # vanishes there for every equilibrium: divide that spurious simple root out.
    return float(np.linalg.det(Mp)) / (sigma2 if sigma2 != 0.0 else 1e-300)


def refine_by_determinant(eq: Equilibrium, guess: float, rel: float = 1e-3) -> float:
    """The root of det M_p nearest ``guess`` (bracketed in guess*(1 +- rel), then Brent)."""
    lo, hi = sorted((guess * (1 - rel), guess * (1 + rel)))
    f = lambda s2: determinant(eq, s2)  # noqa: E731
    flo, fhi = f(lo), f(hi)
    if flo * fhi > 0:
        raise ValueError(f"no sign change of det M_p in [{lo!r}, {hi!r}]")
    return brentq(f, lo, hi, xtol=1e-14 * abs(guess), rtol=1e-15, maxiter=200)


def roots_by_determinant(eq: Equilibrium, lo: float, hi: float, num: int = 400) -> np.ndarray:
    """Every sign change of det M_p on a grid of ``num`` points in [lo, hi], refined by Brent."""
    grid = np.linspace(lo, hi, num)
    vals = np.array([determinant(eq, s) for s in grid])
    roots = []
    for a, b, fa, fb in zip(grid[:-1], grid[1:], vals[:-1], vals[1:]):
        if fa == 0.0:
            roots.append(a)
        elif fa * fb < 0:
            roots.append(brentq(lambda s: determinant(eq, s), a, b, xtol=1e-13 * max(abs(a), 1.0)))
    return np.array(roots)
