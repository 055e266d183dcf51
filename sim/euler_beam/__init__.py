"""The quasi-linear Euler-beam model of the paper: statics, linear stability, dynamics."""

from sim.euler_beam.bifurcation import bifurcation
from sim.euler_beam.stability import Spectrum, is_stable, spectrum, spectrum_of
from sim.euler_beam.statics import (
    BeamError,
    Equilibrium,
    equilibria,
    equilibrium,
    euler_eigenvalues,
)
from sim.results import Bifurcation, BifurcationPoint

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
    "is_stable",
    "spectrum",
    "spectrum_of",
]
