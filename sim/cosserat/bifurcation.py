"""mu* of the discrete Cosserat rod, located by a root of the smallest Hessian eigenvalue.

- asymmetric (saddle-node): U_A is followed with the midpoint deflection c = y(1/2) as the
  parameter (mu unknown, regular through the fold); the fold is the root in c of the
  smallest eigenvalue of the free-dof Hessian (equivalently d mu / d c = 0).
- symmetric (subcritical pitchfork): U_A, kept mirror-symmetric, is followed in mu; mu* is
  the root in mu of its smallest eigenvalue (the antisymmetric mode); the secondary fold of
  U_A (with W_B) is then found as in the asymmetric case, within the symmetric subspace.
- antisymmetric (supercritical pitchfork): U_A and U_B meet S_B (the half-turn symmetric
  state); S_B is followed in mu and mu* is the root of its smallest eigenvalue.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import scipy.sparse.linalg as spla
from scipy.optimize import brentq

from sim.results import Bifurcation, BifurcationPoint, Resolution

from . import statics as S
from .rod import Rod

TRANSITIONS = {
    "asymmetric": ("saddle-node", ("U_A", "S_B")),
    "symmetric": ("subcritical-pitchfork", ("U_A", "S_A", "S_B")),
    "antisymmetric": ("supercritical-pitchfork", ("U_A", "U_B", "S_B")),
}


def _lam_min(rod: Rod, z: np.ndarray) -> float:
    return float(S.min_eigenvalues(rod, z)[0])


def _fold_by_pin(
    rod: Rod, z0: np.ndarray, mu0: float, c_stop: float, nsteps: int, xtol: float,
    symmetric: bool = False,
) -> tuple[float, np.ndarray, float, int]:
    """First root of the smallest Hessian eigenvalue along the branch through (z0, mu0),
    parametrised by c = y(1/2) (a fold, or a symmetry-breaking bifurcation of a symmetric
    branch): (mu*, z*, c*, solves)."""
    k = 3 * (rod.n // 2) + 1
    prev = (float(z0[k]), z0, mu0, _lam_min(rod, z0))
    solves = 0
    bracket = None
    for c, z, mu in S._pinned_path(rod, z0, mu0, c_stop, nsteps, symmetric=symmetric):
        solves += 1
        lam = _lam_min(rod, z)
        if lam < 0.0 <= prev[3]:
            bracket = (prev, (c, z, mu, lam))
            break
        prev = (c, z, mu, lam)
    if bracket is None:
        raise S.ConvergenceError(f"no fold of U_A found along the branch ({rod.n} elements)")
    (ca, za, ma, _), (cb, zb, mb, _) = bracket
    cache: dict[float, tuple[np.ndarray, float]] = {}

    def f(c: float) -> float:
        t = (c - ca) / (cb - ca)
        zg = za + t * (zb - za)
        zg[k] = c
        zn, mn = S.newton(rod, zg, ma + t * (mb - ma), pin=k, symmetric=symmetric)
        cache[c] = (zn, mn)
        return _lam_min(rod, zn)

    c_star = brentq(f, ca, cb, xtol=xtol, rtol=1e-15)
    if c_star not in cache:
        f(c_star)
    z_star, mu_star = cache[c_star]
    return mu_star, z_star, c_star, solves + len(cache)


def _critical_mode_is_symmetric(rod: Rod, z: np.ndarray) -> bool:
    """Whether the Hessian's eigenvector nearest zero is invariant under the actuation's
    symmetry (a fold of the symmetric branch) or reversed by it (symmetry breaking)."""
    H, fidx = S._free_sparse(rod, z)
    _, V = spla.eigsh(H, k=1, sigma=-1e-9, which="LM", tol=1e-12, v0=S._start_vector(H.shape[0]))
    phi = np.zeros(rod.N)
    phi[fidx] = V[:, 0]
    img = rod.mirror(phi) - rod.mirror(np.zeros(rod.N))
    return float(phi @ img) > 0.0


def _root_in_mu(
    rod: Rod, z: np.ndarray, mu: float, step: float, mu_max: float, xtol: float
) -> tuple[float, np.ndarray, int]:
    """Follow a symmetric branch in mu until its smallest eigenvalue changes sign; root."""
    lam0 = _lam_min(rod, z)
    k = 3 * (rod.n // 2) + 1
    solves = 0
    slope = None
    while True:
        h = step
        if slope is not None and slope * lam0 < 0.0:  # approaching a root: secant guess
            h = min(step, max(1e-6, 1.3 * abs(lam0 / slope)))
        mu1 = mu + h
        if mu1 > mu_max:
            raise S.ConvergenceError(f"no sign change of the smallest eigenvalue below {mu_max}")
        z1 = S.follow_mu(rod, z, mu, mu1, symmetric=True, max_step=h)
        solves += 1
        if abs(z1[k] - z[k]) > 0.2 * math.sqrt(rod.end_shortening):
            raise S.ConvergenceError(f"the branch was lost between mu={mu!r} and {mu1!r}")
        lam1 = _lam_min(rod, z1)
        if np.sign(lam1) != np.sign(lam0):
            break
        slope = (lam1 - lam0) / h
        z, mu, lam0 = z1, mu1, lam1
    za, ma = z, mu
    cache: dict[float, np.ndarray] = {}

    def f(m: float) -> float:
        zn, _ = S.newton(rod, za + (m - ma) * S.tangent_mu(rod, za), m, symmetric=True)
        cache[m] = zn
        return _lam_min(rod, zn)

    m_star = brentq(f, ma, mu1, xtol=xtol, rtol=1e-15)
    if m_star not in cache:
        f(m_star)
    return m_star, cache[m_star], solves + len(cache)


def find_bifurcation(rod: Rod, *, xtol: float = 1e-12,
                     resolution: Resolution | None = None) -> Bifurcation:
    """Locate the transition of U_A for ``rod`` (see the module docstring).

    ``resolution`` (the discretisation's error estimate, ``sim.resolution``) is attached to
    the result as given.
    """
    act = rod.actuation
    transition, branches = TRANSITIONS[act]
    k = 3 * (rod.n // 2) + 1
    sym = act == "symmetric"
    z0, _ = S.newton(rod, rod.guess("U_A"), 0.0, symmetric=sym)
    c0 = float(z0[k])
    secondary: list[dict] = []
    info: dict[str, Any] = {}
    if act == "asymmetric":
        mu_star, z_star, c_star, solves = _fold_by_pin(rod, z0, 0.0, 0.05 * c0, 95, xtol * abs(c0))
        info["c_star"] = c_star / math.sqrt(rod.end_shortening)
    elif act == "symmetric":
        # U_A (mirror-symmetric) by the midpoint parametrisation, through folds; the first
        # zero of the smallest eigenvalue is either the pitchfork (antisymmetric critical
        # mode: S_A and S_B meet U_A) or a fold of U_A (symmetric mode), which for thick
        # or strongly shortened strips comes first.
        mu_star, z_star, c_star, solves = _fold_by_pin(
            rod, z0, 0.0, 0.05 * c0, 95, xtol * abs(c0), symmetric=True)
        if _critical_mode_is_symmetric(rod, z_star):
            transition, branches = "saddle-node", ("U_A", "W_B")
            info["note"] = "the fold of U_A comes before the pitchfork with S_A, S_B"
        else:
            try:
                mu2, z2, c2, s2 = _fold_by_pin_sym(rod, z_star, mu_star, c0, xtol)
                P2 = -rod.axial_force(z2)
                secondary.append(BifurcationPoint(mu2, math.sqrt(max(P2, 0.0)), "saddle-node",
                                                  ("U_A", "W_B")))
                solves += s2
            except S.ConvergenceError as e:  # pragma: no cover - reported, not fatal
                info["secondary_error"] = str(e)
    else:
        # U_A by the midpoint parametrisation almost to the pitchfork, then S_B.
        # (w(1/2) is even in mu here, so start the midpoint parametrisation at mu = 1)
        z1 = S.follow_mu(rod, z0, 0.0, 1.0)
        *_, (c, z, mu) = list(S._pinned_path(rod, z1, 1.0, 0.1 * c0, 40))
        zs, _ = S.newton(rod, 0.5 * (z + rod.mirror(z)), mu, symmetric=True)
        if _lam_min(rod, zs) >= 0.0:
            raise S.ConvergenceError("S_B is already stable where U_A was left: refine the path")
        mu_star, z_star, solves = _root_in_mu(rod, zs, mu, 0.01, 3.0, xtol)
        solves += 41
    P = -rod.axial_force(z_star)
    info["min_eigenvalue_at_root"] = _lam_min(rod, z_star)
    info["newton_solves"] = solves
    info["z_star"] = z_star.copy()  # the state at mu* (snap-through initial condition)
    info["clamp"] = rod.clamp
    return Bifurcation(
        actuation=act,
        mu_star=float(mu_star),
        lambda_star=math.sqrt(P) if P > 0 else math.nan,
        transition=transition,
        branches=branches,
        secondary=tuple(secondary),
        model="cosserat",
        resolution=resolution if resolution is not None else Resolution(
            "cosserat", rod.n, None, math.nan, "not estimated"),
        end_shortening=rod.end_shortening,
        slenderness=rod.slenderness,
        w_star=z_star[1::3] / math.sqrt(rod.end_shortening),
        info=info,
    )


def _fold_by_pin_sym(rod: Rod, z: np.ndarray, mu: float, c0: float, xtol: float):
    """Secondary fold of the symmetric U_A past the pitchfork (max of mu along y(1/2)),
    inside the mirror-symmetric subspace: d mu / d c = 0 by a bracketed root of the secant
    slope of mu(c)."""
    k = 3 * (rod.n // 2) + 1
    pts = [(float(z[k]), z, mu)]
    zc, m = z, mu
    for c in np.linspace(float(z[k]), 0.0, 60)[1:]:
        zg = zc.copy()
        zg[k] = c
        zc, m = _pinned_sym(rod, zg, m, k)
        pts.append((c, zc, m))
        if len(pts) >= 3 and pts[-1][2] < pts[-2][2]:
            break
    else:
        raise S.ConvergenceError("no secondary fold found")
    # maximise mu(c) by golden-section on the bracket pts[-3] .. pts[-1]
    (ca, za, ma), (cb, zb, mb) = pts[-3], pts[-1]
    gr = (math.sqrt(5.0) - 1.0) / 2.0
    cache: dict[float, float] = {}
    solves = len(pts)

    def g(c: float) -> float:
        t = (c - ca) / (cb - ca)
        zg = za + t * (zb - za)
        zg[k] = c
        cache[c] = _pinned_sym(rod, zg, ma + t * (mb - ma), k)[1]
        return cache[c]

    a, b = ca, cb
    x1, x2 = b - gr * (b - a), a + gr * (b - a)
    f1, f2 = g(x1), g(x2)
    while abs(b - a) > max(xtol * abs(c0), 1e-13) * 10:
        if f1 > f2:
            b, x2, f2 = x2, x1, f1
            x1 = b - gr * (b - a)
            f1 = g(x1)
        else:
            a, x1, f1 = x1, x2, f2
            x2 = a + gr * (b - a)
            f2 = g(x2)
    cm = 0.5 * (a + b)
    t = (cm - ca) / (cb - ca)
    zg = za + t * (zb - za)
    zg[k] = cm
    z2, m2 = _pinned_sym(rod, zg, ma + t * (mb - ma), k)
    return m2, z2, cm, solves + len(cache)


def _pinned_sym(rod: Rod, zg: np.ndarray, mu: float, k: int) -> tuple[np.ndarray, float]:
    return S.newton(rod, zg, mu, pin=k, symmetric=True)
