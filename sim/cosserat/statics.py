"""Static equilibria of the planar Cosserat rod: Newton, continuation in mu, mu* location.

The static problem is grad E(z; mu) = 0 on the free dofs (a boundary-value problem of size
3n - 2). Branches are followed by Newton continuation in mu (tangent predictor), or, through
folds, with the midpoint deflection c = y(s = 1/2) as the continuation parameter and mu as an
unknown ("natural parametrisation by a state variable", regular at a saddle-node). The same
pinned problem, with y(1/2) held and mu fixed, is the released-indenter experiment's initial
state.

Stability: the smallest eigenvalue of the Hessian restricted to the free dofs (the rod has
no constraint left once the end nodes are removed). Frequencies: ``K phi = -sigma^2 M phi``
with the lumped mass matrix.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from scipy.optimize import brentq

from sim.errors import ParameterError, SimulationError

from .rod import Rod

_TOL = 1e-11


class ConvergenceError(SimulationError):
    """Newton or a continuation did not converge (e.g. the branch does not exist at this mu).

    A ``sim.errors.SimulationError`` whose parameter is "mu" (``.value``: the mu reached).
    """

    def __init__(self, message: str, mu: float | None = None) -> None:
        super().__init__("mu", mu, message)

    def __reduce__(self) -> tuple:
        return (type(self), (str(self), self.value))


def _dirichlet_band(rod: Rod, ab: np.ndarray, fixed: np.ndarray, diag: float = 1.0) -> np.ndarray:
    """Band matrix with the rows and columns of fixed dofs replaced by ``diag`` on the diagonal."""
    KU = (ab.shape[0] - 1) // 2
    N = ab.shape[1]
    for i in np.flatnonzero(fixed):
        ab[:, i] = 0.0
        for d in range(ab.shape[0]):
            col = i + KU - d
            if 0 <= col < N:
                ab[d, col] = 0.0
        ab[KU, i] = diag
    return ab


def _sparse(ab: np.ndarray) -> sp.csc_matrix:
    KU = (ab.shape[0] - 1) // 2
    N = ab.shape[1]
    return sp.dia_matrix((ab, KU - np.arange(ab.shape[0])), shape=(N, N)).tocsc()


def _anti_projector(rod: Rod) -> sp.csc_matrix:
    """(I - R) / 2 with R the linear part of the actuation's symmetry (sparse, N x N):
    node i <-> n - i, element e <-> n - 1 - e; x -> -x always; y -> y and theta -> -theta
    for the mirror (symmetric), y -> -y and theta -> theta for the half-turn."""
    n, N = rod.n, rod.N
    mirror = rod.actuation == "symmetric"
    if rod.actuation == "asymmetric":
        raise ValueError("the asymmetric actuation has no symmetry")
    i = np.arange(n + 1)
    e = np.arange(n)
    src = np.concatenate([3 * i, 3 * i + 1, 3 * e + 2])
    dst = np.concatenate([3 * (n - i), 3 * (n - i) + 1, 3 * (n - 1 - e) + 2])
    sy, st = (1.0, -1.0) if mirror else (-1.0, 1.0)
    sgn = np.concatenate([-np.ones(n + 1), sy * np.ones(n + 1), st * np.ones(n)])
    R = sp.csc_matrix((sgn, (dst, src)), shape=(N, N))
    return (0.5 * (sp.identity(N, format="csc") - R)).tocsc()


def newton(
    rod: Rod,
    z: np.ndarray,
    mu: float,
    *,
    pin: int | None = None,
    symmetric: bool = False,
    tol: float = _TOL,
    maxit: int = 40,
) -> tuple[np.ndarray, float]:
    """Solve grad E = 0 on the free dofs (sparse LU with pivoting).

    Parameters
    ----------
    rod : Rod
    z : ndarray (N,)
        Initial guess (copied).
    mu : float
        Control parameter; with ``pin`` it is the initial guess of an unknown.
    pin : int or None
        Index of a dof held at its value in ``z`` while mu becomes an unknown.
    symmetric : bool
        Project every iterate on the actuation's symmetric subspace (pitchfork branches).
    tol : float
        Convergence when max |dz| < tol (positions in units of L, angles in radians), or
        when |dz| < 1e-8 stops decreasing (round-off floor of a stiff, thin rod).

    Returns
    -------
    z, mu : the solution and the (possibly solved-for) control parameter.
    """
    z = rod.apply_bc(np.array(z, dtype=float), mu)
    fixed = rod.fixed_mask()
    if pin is not None and fixed[pin]:
        raise ParameterError("pin", pin, f"pin must index a free dof, got {pin!r}")
    dmax = math.inf
    P = _anti_projector(rod) if symmetric else None
    for _ in range(maxit):
        g = rod.gradient(z, mu)
        g[fixed] = 0.0
        ab = _dirichlet_band(rod, rod.hessian_band(z), fixed)
        J = _sparse(ab)
        if P is not None:
            # lift the symmetry-breaking directions (a pitchfork's null mode): the Newton
            # step of a symmetric residual is symmetric and does not see this term
            J = J + float(np.median(np.abs(ab[4]))) * P
        if pin is None:
            dz = spla.spsolve(J.tocsc(), -g)
        else:
            J = J.tolil()
            m = rod.dgrad_dmu(z)
            m[fixed] = 0.0
            J[:, pin] = m[:, None]
            dz = spla.spsolve(J.tocsc(), -g)
            mu += float(dz[pin])
            dz[pin] = 0.0
        z_old = z.copy()
        z += dz
        rod.apply_bc(z, mu)
        if symmetric:
            z = 0.5 * (z + rod.mirror(z))
        prev, dmax = dmax, float(np.max(np.abs(z - z_old)))
        if not np.all(np.isfinite(z)):
            break
        if dmax < tol or (dmax < 1e-8 and dmax > 0.5 * prev):
            return z, float(mu)
    raise ConvergenceError(f"Newton did not converge at mu={mu!r} (last |dz|={dmax:.3e})", mu)


def tangent_mu(rod: Rod, z: np.ndarray) -> np.ndarray:
    """dz/dmu along a branch parametrised by mu (N,), including the prescribed dofs."""
    fixed = rod.fixed_mask()
    ab = _dirichlet_band(rod, rod.hessian_band(z), fixed)
    db = rod.dbc_dmu(z)
    rhs = -rod.dgrad_dmu(z)
    rhs[fixed] = 0.0
    t = sla.solve_banded((4, 4), ab, rhs)
    t[fixed] = db[fixed]
    return t


def _free_sparse(rod: Rod, z: np.ndarray) -> tuple[sp.csc_matrix, np.ndarray]:
    fidx = np.flatnonzero(~rod.fixed_mask())
    H = _sparse(rod.hessian_band(z))[fidx][:, fidx].tocsc()
    return H, fidx


def min_eigenvalues(rod: Rod, z: np.ndarray, k: int = 1) -> np.ndarray:
    """The k eigenvalues of the free-dof Hessian nearest zero, ascending (stability: > 0).

    Shift-invert Lanczos about 0 (accurate for the soft eigenvalues even when the stretch
    stiffness 12 / h^2 makes the Hessian badly conditioned)."""
    H, _ = _free_sparse(rod, z)
    kk = max(k, 3)
    vals = spla.eigsh(H, k=kk, sigma=-1e-9, which="LM", return_eigenvectors=False,
                      tol=1e-14, v0=_start_vector(H.shape[0]))
    return np.sort(vals)[:k]


def _start_vector(n: int) -> np.ndarray:
    """A fixed, generic ARPACK start vector: without one ARPACK starts from a random vector and
    the same scene's mu* differs by ~1e-10 between calls (atlas cells must be reproducible)."""
    return np.cos(0.7 * np.arange(n) + 0.3) + 1.1


def sigma2(rod: Rod, z: np.ndarray, modes: int = 10) -> tuple[np.ndarray, np.ndarray]:
    """Linear spectrum about an equilibrium: sigma^2 = -omega^2 (paper eq. smallperturbations).

    Solves ``H phi = lam M phi`` on the free dofs with the lumped mass M (shift-invert Lanczos
    about 0, the modes nearest zero); returns ``sigma2 = -lam`` (shape (modes,), by increasing
    lam) and the mode shapes (N, modes), zero on the fixed dofs.
    """
    H, fidx = _free_sparse(rod, z)
    M = sp.diags(rod.mass()[fidx]).tocsc()
    lam, V = spla.eigsh(
        H, k=modes, M=M, sigma=-1e-9, which="LM", tol=1e-14, v0=_start_vector(H.shape[0])
    )
    order = np.argsort(lam)
    phi = np.zeros((rod.N, modes))
    phi[fidx] = V[:, order]
    return -lam[order], phi


def follow_mu(
    rod: Rod,
    z: np.ndarray,
    mu0: float,
    mu1: float,
    *,
    symmetric: bool = False,
    max_step: float = 0.05,
    min_step: float = 1e-7,
) -> np.ndarray:
    """Newton continuation in mu from an equilibrium ``z`` at mu0 to mu1 (tangent predictor).

    A step is refused (and retried 4x shorter) when Newton fails, or when its correction is
    larger than the predictor's own move (max |z - z_pred| > step max |dz/dmu|): Newton has
    then left the branch, e.g. jumped over a fold onto another state.
    """
    mu = mu0
    h = max_step
    direction = 1.0 if mu1 >= mu0 else -1.0
    while direction * (mu1 - mu) > 1e-15:
        step = min(h, abs(mu1 - mu))
        t = tangent_mu(rod, z)
        pred = z + direction * step * t
        try:
            zn, _ = newton(rod, pred, mu + direction * step, symmetric=symmetric)
            if np.max(np.abs(zn - pred)) > step * np.max(np.abs(t)) + 1e-12:
                raise ConvergenceError("left the branch", mu)
        except (ConvergenceError, np.linalg.LinAlgError):
            h = step / 4.0
            if h < min_step:
                raise ConvergenceError(
                    f"continuation in mu stalled at mu={mu!r} (the branch may end here)", mu
                ) from None
            continue
        z, mu = zn, mu + direction * step
        h = min(max_step, 2.0 * step)
    return z


@dataclass(frozen=True)
class Equilibrium:
    """A static equilibrium of the rod.

    Attributes
    ----------
    mu : float
        Control parameter.
    branch : str
    s : ndarray (n+1,)
        Reference arclength of the nodes, s = X in [0, 1].
    x, y : ndarray (n+1,)
        Node positions (units of L).
    theta : ndarray (n,)
        Element angles (rad).
    w : ndarray (n+1,)
        Transverse deflection y / sqrt(L dL) (the paper's W).
    lambda_ : float
        Lambda = sqrt(compressive end force L^2 / B) (the beam's Lambda).
    min_eigenvalue : float
        Smallest eigenvalue of the free-dof Hessian (> 0: stable).
    z : ndarray (3n+2,)
        The raw state vector.
    info : dict
    """

    mu: float
    branch: str
    s: np.ndarray
    x: np.ndarray
    y: np.ndarray
    theta: np.ndarray
    w: np.ndarray
    lambda_: float
    min_eigenvalue: float
    z: np.ndarray
    info: dict = field(default_factory=dict)

    @property
    def stable(self) -> bool:
        return self.min_eigenvalue > 0.0


def make_equilibrium(
    rod: Rod, z: np.ndarray, mu: float, branch: str, info: dict[str, Any] | None = None
) -> Equilibrium:
    x, y, th = (a.copy() for a in rod.unpack(z))
    P = -rod.axial_force(z)
    return Equilibrium(
        mu=float(mu),
        branch=branch,
        s=rod.s_nodes,
        x=x,
        y=y,
        theta=th,
        w=y / math.sqrt(rod.end_shortening),
        lambda_=math.sqrt(P) if P > 0 else -math.sqrt(-P),
        min_eigenvalue=float(min_eigenvalues(rod, z)[0]),
        z=z.copy(),
        info=dict(info or {}),
    )


def branch_state(rod: Rod, mu: float, branch: str = "U_A") -> np.ndarray:
    """Equilibrium state z on ``branch`` (U_A or U_B) at ``mu``, by continuation from mu = 0.

    U_A is the first-mode state buckled to negative w at mu = 0 (the left end slope +mu then
    pushes it towards the transition); U_B the one buckled to positive w.
    """
    if branch not in ("U_A", "U_B"):
        raise ParameterError("branch", branch,
                             f"branch must be 'U_A' or 'U_B' for the Cosserat rod, got {branch!r}")
    sym = rod.actuation == "symmetric"
    z0, _ = newton(rod, rod.guess(branch), 0.0, symmetric=sym)
    if mu == 0.0:
        return z0
    try:
        return follow_mu(rod, z0, 0.0, float(mu), symmetric=sym)
    except ConvergenceError:
        if branch == "U_A" and rod.actuation != "symmetric" and mu > 0.0:  # towards its fold
            return _u_a_near_fold(rod, z0, float(mu))
        raise


def _pinned_path(rod: Rod, z0: np.ndarray, mu0: float, c_stop: float, nsteps: int,
                 symmetric: bool = False):
    """Yield (c, z, mu) along the branch with c = y(1/2) from z0's value to c_stop."""
    k = 3 * (rod.n // 2) + 1
    c0 = float(z0[k])
    z, mu = z0.copy(), mu0
    prev = None
    for c in np.linspace(c0, c_stop, nsteps + 1)[1:]:
        if prev is None:  # tangent predictor from the mu-parametrised branch
            t = tangent_mu(rod, z)
            dmu = (c - float(z[k])) / t[k]
            zg = z + dmu * t
            mug = mu + dmu
        else:  # secant predictor
            zp, mup, cp = prev
            f = (c - float(z[k])) / (float(z[k]) - cp)
            zg = z + f * (z - zp)
            mug = mu + f * (mu - mup)
        zg[k] = c
        zn, mun = newton(rod, zg, mug, pin=k, symmetric=symmetric)
        prev = (z, mu, float(z[k]))
        z, mu = zn, mun
        yield float(c), z, mu


def _u_a_near_fold(rod: Rod, z0: np.ndarray, mu: float) -> np.ndarray:
    """U_A at mu close to a fold, where natural continuation in mu stalls."""
    k = 3 * (rod.n // 2) + 1
    pts = []
    for c, z, m in _pinned_path(rod, z0, 0.0, 0.0, 80):
        pts.append((c, z, m))
        if m >= mu:
            break
        if len(pts) > 2 and m < pts[-2][2]:
            raise ConvergenceError(
                f"no U_A equilibrium at mu={mu!r}: past the rod's fold at mu* ~ "
                f"{pts[-2][2]:.6f} ({rod.elements} elements)", mu
            )
    else:
        raise ConvergenceError(f"no U_A equilibrium at mu={mu!r}", mu)
    if len(pts) < 2:
        raise ConvergenceError(f"no U_A equilibrium at mu={mu!r} near a fold", mu)
    (ca, za, ma), (cb, zb, mb) = pts[-2], pts[-1]
    cache: dict[float, tuple[np.ndarray, float]] = {}

    def f(c: float) -> float:
        zg = za + (c - ca) / (cb - ca) * (zb - za)
        zg[k] = c
        zn, mn = newton(rod, zg, ma + (c - ca) / (cb - ca) * (mb - ma), pin=k)
        cache[c] = (zn, mn)
        return mn - mu

    c_root = brentq(f, ca, cb, xtol=1e-14)
    zr, _ = cache.get(c_root) or (None, None)
    if zr is None:
        f(c_root)
        zr = cache[c_root][0]
    return newton(rod, zr, mu)[0]
