"""Planar discrete Cosserat rod (stretch, shear, bending; Gazzola et al. 2018 in the plane).

Public API
----------
simulate(scene) -> sim.scene.Signal
    The paper's impulse response: U_A (or U_B) at scene.mu by Newton continuation, kick at
    scene.kick_position, W(scene.probe, t) recorded (units of sqrt(L dL)).
equilibria(actuation, mu, *, end_shortening, slenderness, elements, branch="U_A")
    Static equilibrium (Newton continuation in mu from mu = 0).
spectrum(actuation, mu, *, ..., branch="U_A", modes=10)
    Linear spectrum sigma^2 (= -omega^2) of the equilibrium.
bifurcation(actuation, *, end_shortening=1e-2, slenderness=1e-3, elements=200)
    mu* of the rod (fold or loss of stability, root of the smallest Hessian eigenvalue).
snap_through(dmu, *, ...)
    Released-indenter snap-through past the asymmetric fold.

Non-dimensional as in the paper: L = 1, B = 1, rho b h = 1; time in sqrt(rho b h L^4 / B).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from . import statics as _S
from .bifurcation import Bifurcation, find_bifurcation
from .dynamics import SnapThrough, integrate, kick_velocity, simulate, snap_through
from .rod import CLAMPS, CosseratWarning, Rod
from .statics import ConvergenceError, Equilibrium

__all__ = [
    "Bifurcation", "CLAMPS", "ConvergenceError", "CosseratWarning", "Equilibrium", "Rod",
    "SnapThrough", "Spectrum", "bifurcation", "equilibria", "integrate", "kick_velocity",
    "simulate", "snap_through", "spectrum",
]


def equilibria(actuation: str, mu: float, *, end_shortening: float = 1e-2,
               slenderness: float = 1e-3, elements: int = 100, branch: str = "U_A",
               clamp: str = "node") -> Equilibrium:
    """Static equilibrium of the rod on ``branch`` at ``mu``.

    Parameters
    ----------
    actuation : {"asymmetric", "symmetric", "antisymmetric"}
    mu : float
        Control parameter mu = alpha sqrt(L / dL).
    end_shortening, slenderness : float
        dL / L and h / L.
    elements : int
        Number of elements (even).
    branch : {"U_A", "U_B"}
        U_A: buckled to negative w at mu = 0 (the left end slope +mu pushes it towards the
        transition); U_B: buckled to positive w.
    clamp : {"node", "element"}

    Returns
    -------
    Equilibrium
        Shape (x, y, theta, w = y / sqrt(L dL)), Lambda, smallest Hessian eigenvalue.

    Raises
    ------
    ConvergenceError
        When the branch does not reach ``mu`` (past the fold of U_A).
    """
    rod = Rod(elements=elements, end_shortening=end_shortening, slenderness=slenderness,
              actuation=actuation, clamp=clamp)
    z = _S.branch_state(rod, float(mu), branch)
    return _S.make_equilibrium(rod, z, mu, branch)


@dataclass(frozen=True)
class Spectrum:
    """Linear spectrum of an equilibrium: sigma2 = -omega^2 (ascending omega), shape (modes,),
    and the mode shapes' transverse component W_p (n+1, modes), normalised to max |W_p| = 1."""

    actuation: str
    mu: float
    branch: str
    sigma2: np.ndarray
    modes: np.ndarray
    elements: int
    end_shortening: float
    slenderness: float


def spectrum(actuation: str, mu: float, *, end_shortening: float = 1e-2,
             slenderness: float = 1e-3, elements: int = 100, branch: str = "U_A",
             modes: int = 10, clamp: str = "node") -> Spectrum:
    """Eigenvalues sigma^2 of the rod linearised about its equilibrium (paper eq.
    smallperturbations_beameq for the beam; here ``K phi = -sigma^2 M phi``)."""
    if int(modes) != modes or modes < 1:
        raise ValueError(f"modes must be an integer >= 1, got {modes!r}")
    rod = Rod(elements=elements, end_shortening=end_shortening, slenderness=slenderness,
              actuation=actuation, clamp=clamp)
    z = _S.branch_state(rod, float(mu), branch)
    s2, phi = _S.sigma2(rod, z, int(modes))
    wp = phi[1::3]
    wp = wp / np.max(np.abs(wp), axis=0, keepdims=True)
    return Spectrum(actuation=actuation, mu=float(mu), branch=branch, sigma2=s2, modes=wp,
                    elements=elements, end_shortening=end_shortening, slenderness=slenderness)


def bifurcation(actuation: str, *, end_shortening: float = 1e-2, slenderness: float = 1e-3,
                elements: int = 200, clamp: str = "node") -> Bifurcation:
    """mu* of the discrete Cosserat rod and the type of its transition.

    asymmetric: saddle-node (fold of U_A, continued through it with the midpoint deflection as
    parameter); symmetric: subcritical pitchfork (U_A loses stability; the secondary fold of
    U_A with W_B is in ``secondary``); antisymmetric: supercritical pitchfork (S_B gains
    stability where U_A and U_B end). mu* is the root of the smallest eigenvalue of the
    free-dof Hessian (Brent, xtol 1e-12). Discretisation error about 15 / n^2 (node clamp,
    asymmetric, dL/L = 1e-2): 4e-4 at the default n = 200.
    """
    rod = Rod(elements=elements, end_shortening=end_shortening, slenderness=slenderness,
              actuation=actuation, clamp=clamp)
    return find_bifurcation(rod)
