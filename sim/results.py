"""Result types shared by every backend: the bifurcation and the resolution that produced it.

Frozen dataclasses of plain values (numpy arrays where a shape is returned); their wire
documents are built in one place, ``service.convert`` (the numerics know nothing of JSON).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass(frozen=True)
class Resolution:
    """The discretisation a result was computed with, and its estimated error.

    Attributes
    ----------
    model : str
        Backend ("euler-beam", "cosserat", "normal-form").
    size : int
        Elements of the Cosserat rod, Galerkin functions of the beam, 1 for the normal form.
    rtol : float or None
        Requested relative accuracy it was chosen from (None: given explicitly).
    mu_star_error : float
        Estimated discretisation error of mu* at this size (absolute, control units; > 0).
    method : str
        How ``mu_star_error`` was obtained (e.g. "Richardson from n = 24, 48 (order 2)").
    """

    model: str
    size: int
    rtol: float | None
    mu_star_error: float
    method: str


@dataclass(frozen=True)
class BifurcationPoint:
    """One bifurcation of the U_A branch: where it is and of which kind."""

    mu_star: float
    lambda_star: float
    transition: str
    branches: tuple[str, ...]


@dataclass(frozen=True)
class Bifurcation:
    """The shape transition of U_A for one actuation, whatever the backend.

    Attributes
    ----------
    actuation : str
    mu_star : float
        Control parameter at the transition (mu = alpha sqrt(L / dL)).
    lambda_star : float
        Lambda = sqrt(F L^2 / B) of the compression at mu* (NaN if in tension).
    transition : {"saddle-node", "subcritical-pitchfork", "supercritical-pitchfork"}
    branches : tuple of str
        Branches that meet there.
    secondary : tuple of BifurcationPoint
        Later bifurcations of U_A (symmetric: the fold U_A / W_B).
    model : str
        Backend that computed it.
    resolution : Resolution or None
        Discretisation used and its estimated error of mu*.
    end_shortening, slenderness : float or None
        The strip (Cosserat rod only; the beam is the dL/L -> 0 limit).
    w_star : ndarray
        Shape W(s) at mu* on the rod's nodes (empty for the beam).
    info : dict
        Diagnostics (eigenvalue at the root, Newton solves, notes).
    """

    actuation: str
    mu_star: float
    lambda_star: float
    transition: str
    branches: tuple[str, ...]
    secondary: tuple[BifurcationPoint, ...] = ()
    model: str = "euler-beam"
    resolution: Resolution | None = None
    end_shortening: float | None = None
    slenderness: float | None = None
    w_star: np.ndarray = field(default_factory=lambda: np.zeros(0), repr=False)
    info: dict = field(default_factory=dict, compare=False)

    @property
    def elements(self) -> int | None:
        """Elements of the rod (None for other backends)."""
        r = self.resolution
        return r.size if r is not None and self.model == "cosserat" else None

    @property
    def mu_star_error(self) -> float | None:
        """Estimated discretisation error of mu* (absolute)."""
        return None if self.resolution is None else self.resolution.mu_star_error


@dataclass(frozen=True)
class EquilibriumSummary:
    """One equilibrium as every backend reports it (shape details stay in the backend's type).

    ``lambda_`` is Lambda (negative: tension); ``w_half``, ``w_quarter`` are W(1/2), W(1/4)
    (units of sqrt(L dL)); ``energy`` the bending energy (beam only, else None).
    """

    model: str
    actuation: str
    mu: float
    branch: str
    lambda_: float
    w_half: float
    w_quarter: float
    stable: bool
    energy: float | None = None
    resolution: Resolution | None = None


@dataclass(frozen=True)
class SpectrumSummary:
    """Linear spectrum of one equilibrium: ``sigma2`` (modes,), ordered by |sigma^2|."""

    model: str
    actuation: str
    mu: float
    branch: str
    sigma2: np.ndarray
    lambda_: float | None = None
    resolution: Resolution | None = None
    sigma2_error: float | None = None  # relative, fundamental, Richardson (rod)

    @property
    def omega(self) -> np.ndarray:
        return np.sqrt(np.abs(self.sigma2))


@dataclass(frozen=True)
class ErrorEstimate:
    """Estimated relative error of mu* (and of the fundamental's sigma^2) a backend makes on a
    scene: ``model`` (its physics against the strip) + ``discretisation``; never 0.

    ``details`` names each term (e.g. "extensibility", "nonlinear_shift").
    """

    model: float
    discretisation: float
    details: dict = field(default_factory=dict)

    @property
    def total(self) -> float:
        return self.model + self.discretisation
