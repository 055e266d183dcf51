"""The quasi-linear Euler-beam model of the paper: statics, linear stability, dynamics."""

from sim.euler_beam.stability import Spectrum, spectrum, spectrum_of
from sim.euler_beam.statics import (
    BeamError,
    Bifurcation,
    BifurcationPoint,
    Equilibrium,
    bifurcation,
    equilibria,
    equilibrium,
    euler_eigenvalues,
)

__all__ = [
    "BeamError",
    "Bifurcation",
    "BifurcationPoint",
    "Equilibrium",
    "Spectrum",
    "bifurcation",
    "equilibria",
    "equilibrium",
    "euler_eigenvalues",
    "spectrum",
    "spectrum_of",
]
