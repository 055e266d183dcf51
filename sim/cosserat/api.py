"""The rod's static commands with the resolution policy: equilibria, spectrum, bifurcation.

Each takes the strip (actuation, dL/L, h/L, Poisson ratio, clamp) and either ``elements`` or a
requested accuracy ``rtol`` (``sim.resolution.rod_resolution``), so that the commands of one
scene use one discretisation; each result carries its ``Resolution``.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from sim.errors import ParameterError
from sim.resolution import rod_resolution
from sim.results import Bifurcation, Resolution

from . import statics as _S
from .bifurcation import find_bifurcation
from .rod import Rod
from .statics import Equilibrium


def make_rod(actuation: str, *, end_shortening: float = 1e-2, slenderness: float = 1e-3,
             elements: int | None = None, rtol: float | None = None, poisson: float = 0.5,
             clamp: str = "node") -> tuple[Rod, Resolution]:
    """The rod of a strip at the resolution the policy picks (or ``elements``)."""
    res = rod_resolution(actuation, end_shortening=end_shortening, slenderness=slenderness,
                         poisson=poisson, clamp=clamp, rtol=rtol, elements=elements)
    rod = Rod(elements=res.size, end_shortening=end_shortening, slenderness=slenderness,
              actuation=actuation, clamp=clamp, poisson=poisson)
    return rod, res


def equilibria(actuation: str, mu: float, *, end_shortening: float = 1e-2,
               slenderness: float = 1e-3, elements: int | None = None,
               rtol: float | None = None, poisson: float = 0.5, branch: str = "U_A",
               clamp: str = "node") -> Equilibrium:
    """Static equilibrium of the rod on ``branch`` at ``mu``.

    Parameters
    ----------
    actuation : {"asymmetric", "symmetric", "antisymmetric"}
    mu : float
        Control parameter mu = alpha sqrt(L / dL).
    end_shortening, slenderness, poisson : float
        dL / L, h / L and the Poisson ratio of the rectangular strip.
    elements, rtol : int or None, float or None
        Resolution (see ``sim.resolution``).
    branch : {"U_A", "U_B"}
        U_A: buckled to negative w at mu = 0 (the left end slope +mu pushes it towards the
        transition); U_B: buckled to positive w.
    clamp : {"node", "element"}

    Returns
    -------
    Equilibrium
        Shape (x, y, theta, w = y / sqrt(L dL)), Lambda, smallest Hessian eigenvalue;
        ``info["resolution"]`` is the Resolution used.

    Raises
    ------
    sim.errors.SimulationError
        (a ConvergenceError) when the branch does not reach ``mu`` (past the fold of U_A).
    """
    rod, res = make_rod(actuation, end_shortening=end_shortening, slenderness=slenderness,
                        elements=elements, rtol=rtol, poisson=poisson, clamp=clamp)
    z = _S.branch_state(rod, float(mu), branch)
    return _S.make_equilibrium(rod, z, mu, branch, {"resolution": res})


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
    resolution: Resolution | None = None


def spectrum(actuation: str, mu: float, *, end_shortening: float = 1e-2,
             slenderness: float = 1e-3, elements: int | None = None,
             rtol: float | None = None, poisson: float = 0.5, branch: str = "U_A",
             modes: int = 10, clamp: str = "node") -> Spectrum:
    """Eigenvalues sigma^2 of the rod linearised about its equilibrium (paper eq.
    smallperturbations_beameq for the beam; here ``K phi = -sigma^2 M phi``)."""
    if isinstance(modes, bool) or int(modes) != modes or modes < 1:
        raise ParameterError("modes", modes, f"modes must be an integer >= 1, got {modes!r}")
    rod, res = make_rod(actuation, end_shortening=end_shortening, slenderness=slenderness,
                        elements=elements, rtol=rtol, poisson=poisson, clamp=clamp)
    z = _S.branch_state(rod, float(mu), branch)
    s2, phi = _S.sigma2(rod, z, int(modes))
    wp = phi[1::3]
    wp = wp / np.max(np.abs(wp), axis=0, keepdims=True)
    return Spectrum(actuation=actuation, mu=float(mu), branch=branch, sigma2=s2, modes=wp,
                    elements=rod.n, end_shortening=end_shortening, slenderness=slenderness,
                    resolution=res)


def bifurcation(actuation: str, *, end_shortening: float = 1e-2, slenderness: float = 1e-3,
                elements: int | None = None, rtol: float | None = None, poisson: float = 0.5,
                clamp: str = "node") -> Bifurcation:
    """mu* of the discrete Cosserat rod and the type of its transition.

    asymmetric: saddle-node (fold of U_A, continued through it with the midpoint deflection as
    parameter); symmetric: subcritical pitchfork (U_A loses stability; the secondary fold of
    U_A with W_B is in ``secondary``); antisymmetric: supercritical pitchfork (S_B gains
    stability where U_A and U_B end). mu* is the root of the smallest eigenvalue of the
    free-dof Hessian (Brent, xtol 1e-12). The number of elements follows the resolution
    policy (``sim.resolution``) unless given; ``resolution.mu_star_error`` estimates the
    discretisation error of the mu* returned (second order in n with the node clamp).
    """
    rod, res = make_rod(actuation, end_shortening=end_shortening, slenderness=slenderness,
                        elements=elements, rtol=rtol, poisson=poisson, clamp=clamp)
    return replace(find_bifurcation(rod), resolution=res)
