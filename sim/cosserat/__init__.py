"""Planar discrete Cosserat rod (stretch, shear, bending; Gazzola et al. 2018 in the plane).

Public API
----------
simulate(scene) -> sim.scene.Signal
    The paper's impulse response: U_A (or U_B) at scene.mu by Newton continuation, kick at
    scene.kick_position, W(scene.probe, t) recorded (units of sqrt(L dL)).
equilibria(actuation, mu, *, end_shortening, slenderness, elements=None, rtol=None, ...)
    Static equilibrium (Newton continuation in mu from mu = 0).
spectrum(actuation, mu, *, ..., branch="U_A", modes=10)
    Linear spectrum sigma^2 (= -omega^2) of the equilibrium.
bifurcation(actuation, *, end_shortening=1e-2, slenderness=1e-3, elements=None, rtol=None)
    mu* of the rod (fold or loss of stability, root of the smallest Hessian eigenvalue).

The number of elements is chosen from a requested accuracy ``rtol`` (``sim.resolution``)
unless given; every result carries that ``Resolution`` (elements and estimated mu* error).
snap_through(dmu, *, ...)
    Released-indenter snap-through past the asymmetric fold.

Non-dimensional as in the paper: L = 1, B = 1, rho b h = 1; time in sqrt(rho b h L^4 / B).
"""

from __future__ import annotations

from sim.results import Bifurcation

from .api import Spectrum, bifurcation, equilibria, make_rod, spectrum
from .dynamics import SnapThrough, integrate, kick_velocity, simulate, snap_through
from .rod import CLAMPS, CosseratWarning, Rod
from .statics import ConvergenceError, Equilibrium

__all__ = [
    "Bifurcation", "CLAMPS", "ConvergenceError", "CosseratWarning", "Equilibrium", "Rod",
    "SnapThrough", "Spectrum", "bifurcation", "equilibria", "integrate", "kick_velocity",
    "make_rod", "simulate", "snap_through", "spectrum",
]
