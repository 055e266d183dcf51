"""Scene and Signal: what a simulator is asked to do, and what it records.

Everything here is non-dimensional with the paper's scales (eq. nonDimensionnalization):
length by L, transverse deflection by sqrt(L dL), time by sqrt(rho b h L^4 / B).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from sim.errors import ParameterError

#: The one actuation table (paper eq. BC): end rotations (left, right) per unit alpha, i.e.
#: W_X(0) = mu * left and W_X(1) = mu * right. The beam's slope ratio is ``right``; the rod's
#: end angles are ``alpha * (left, right)``.
ACTUATION_ENDS: dict[str, tuple[float, float]] = {
    "asymmetric": (1.0, 0.0),
    "symmetric": (1.0, -1.0),
    "antisymmetric": (1.0, 1.0),
}
ACTUATIONS = tuple(ACTUATION_ENDS)
BRANCHES = ("U_A", "U_B", "S_A", "S_B", "W_A", "W_B")
MODELS = ("normal-form", "euler-beam", "cosserat", "auto")
DEFAULT_RTOL = 2e-4  # requested relative accuracy of mu* and of the fundamental's sigma^2


class SceneError(ParameterError):
    """A scene parameter is out of its domain (``.parameter``, ``.value``; message names both)."""


def check_actuation(actuation: str, error: type[ParameterError] = ParameterError) -> str:
    """``actuation`` if it is one of ACTUATIONS, else ``error("actuation", ...)``."""
    if actuation not in ACTUATION_ENDS:
        raise error("actuation", actuation,
                    f"actuation must be one of {ACTUATIONS}, got {actuation!r}")  # fmt: skip
    return actuation


#: Largest damping ratio a scene may have (every mode is then far overdamped; beyond, the
#: integrators' time scales overflow).
MAX_DAMPING = 1e3
#: Thinnest strip (h/L) a scene may have: 12/h^2 and its eigenproblems stay well scaled.
MIN_SLENDERNESS = 1e-8


def _check_finite(
    name: str, value: float, *, positive: bool = False, nonneg: bool = False
) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise SceneError(name, value, f"{name} must be a number, got {value!r}") from None
    if not math.isfinite(v):
        raise SceneError(name, value, f"{name} must be finite, got {value!r}")
    if positive and v <= 0:
        raise SceneError(name, value, f"{name} must be > 0, got {value!r}")
    if nonneg and v < 0:
        raise SceneError(name, value, f"{name} must be >= 0, got {value!r}")
    return v


@dataclass(frozen=True)
class Scene:
    """One impulse-response experiment on a clamped-clamped buckled strip.

    Parameters
    ----------
    actuation : {"asymmetric", "symmetric", "antisymmetric"}
        How the ends are rotated (paper eq. BC): W_X(0) = mu and W_X(1) = 0, -mu or +mu.
    mu : float
        Control parameter mu = alpha sqrt(L / dL) (non-dimensional end rotation).
    branch : str
        Equilibrium about which the strip is kicked (U_A, U_B, S_A, S_B, W_A, W_B).
    damping : float
        Non-dimensional viscous damping xi (paper eq. beam_equation_damping), >= 0.
    kick : float
        Transverse impulse per unit mass, in units of sqrt(L dL) / time scale: the velocity
        field just after the kick is ``kick * delta(X - kick_position)``.
    kick_position, probe : float
        Where the impulse is applied and where the sensor records, in X = x / L in (0, 1).
        Both default to X = 1/4 (s = -L/4 in the paper's centred coordinate).
    duration, dt : float or None
        Record length and sampling step (time units). ``None`` lets the backend choose
        (a number of fundamental periods, and a step resolving the fundamental well).
    snr_db : float or None
        If given, white Gaussian noise is added with power = response power / 10^(snr/10)
        (response = record minus its static level).
    seed : int or None
        Seed of the noise generator.
    end_shortening : float
        dL/L.
    slenderness, width : float
        Thickness h/L and width b/L of the rectangular strip (b >= h). The planar models use
        h (stretch and shear stiffness 12/h^2 relative to bending, rotary inertia h^2/12);
        b scales out of the non-dimensional equations and is kept for the record.
    poisson : float
        Poisson ratio nu in [0, 0.5]: shear modulus E / (2 (1 + nu)) and the rectangle's shear
        coefficient 10 (1 + nu) / (12 + 11 nu) (Cowper 1966) of the Cosserat rod.
    rtol : float
        Requested relative accuracy of mu* and of the fundamental's sigma^2, in (0, 0.1):
        picks the discretisation (``sim.resolution``) and, for model="auto", the backend.
    elements : int or None
        Number of elements of the Cosserat rod; None: chosen from ``rtol``.
    """

    actuation: str = "asymmetric"
    mu: float = 0.0
    branch: str = "U_A"
    damping: float = 2e-4
    kick: float = 1e-2
    kick_position: float = 0.25
    probe: float = 0.25
    duration: float | None = None
    dt: float | None = None
    snr_db: float | None = None
    seed: int | None = None
    end_shortening: float = 1e-2
    slenderness: float = 1e-3
    width: float = 1e-1
    poisson: float = 0.5
    rtol: float = DEFAULT_RTOL
    elements: int | None = None

    def __post_init__(self) -> None:
        check_actuation(self.actuation, SceneError)
        if self.branch not in BRANCHES:
            raise SceneError("branch", self.branch,
                             f"branch must be one of {BRANCHES}, got {self.branch!r}")
        _check_finite("mu", self.mu)
        if _check_finite("damping", self.damping, nonneg=True) > MAX_DAMPING:
            raise SceneError("damping", self.damping, f"damping must be <= {MAX_DAMPING:g} (a "
                             f"ratio to the bending time scale), got {self.damping!r}")
        _check_finite("kick", self.kick)
        for name in ("kick_position", "probe"):
            v = _check_finite(name, getattr(self, name))
            if not 0.0 < v < 1.0:
                raise SceneError(name, v, f"{name} must lie in (0, 1), got {v!r}")
        if self.duration is not None:
            _check_finite("duration", self.duration, positive=True)
        if self.dt is not None:
            _check_finite("dt", self.dt, positive=True)
        if self.duration is not None and self.dt is not None and self.dt >= self.duration:
            raise SceneError("dt", self.dt, f"dt must be smaller than duration, got dt={self.dt!r}")
        if self.snr_db is not None:
            _check_finite("snr_db", self.snr_db)
        _check_finite("end_shortening", self.end_shortening, positive=True)
        if _check_finite("slenderness", self.slenderness, positive=True) < MIN_SLENDERNESS:
            raise SceneError("slenderness", self.slenderness,
                             f"slenderness must be >= {MIN_SLENDERNESS:g} (the rod's stretch "
                             f"stiffness 12/h^2 is then finite in double precision), got "
                             f"{self.slenderness!r}")  # fmt: skip
        if _check_finite("width", self.width, positive=True) < self.slenderness:
            raise SceneError("width", self.width, f"width must be >= the thickness "
                             f"(slenderness={self.slenderness!r}), got width={self.width!r}")
        if not 0.0 <= _check_finite("poisson", self.poisson) <= 0.5:
            raise SceneError("poisson", self.poisson,
                             f"poisson must lie in [0, 0.5], got {self.poisson!r}")
        if not 0.0 < _check_finite("rtol", self.rtol) < 0.1:
            raise SceneError("rtol", self.rtol, f"rtol must lie in (0, 0.1), got {self.rtol!r}")
        e = self.elements
        if e is not None and (isinstance(e, bool) or not isinstance(e, (int, np.integer))
                              or e < 4 or e % 2):
            raise SceneError("elements", e, f"elements must be an even integer >= 4, got {e!r}")

    def with_(self, **changes: Any) -> Scene:
        """A copy with some fields changed (validated again)."""
        return replace(self, **changes)


@dataclass(frozen=True)
class Signal:
    """A uniformly sampled record of the transverse position at the probe.

    Attributes
    ----------
    t : ndarray, shape (n,)
        Sample times (time units), ``t[k] = k * dt``.
    w : ndarray, shape (n,)
        Absolute transverse position W(probe, t) = static deflection + response.
    w_static : float
        Static deflection of the equilibrium at the probe (what the record settles to).
    model : str
        Backend that produced it.
    scene : Scene
        The scene simulated.
    info : dict
        Backend details (e.g. the equilibrium's Lambda, the modes used, warnings).
    """

    t: np.ndarray
    w: np.ndarray
    w_static: float
    model: str
    scene: Scene
    info: dict = field(default_factory=dict)

    @property
    def dt(self) -> float:
        return float(self.t[1] - self.t[0])


def add_noise(w: np.ndarray, w_static: float, snr_db: float | None, seed: int | None) -> np.ndarray:
    """Add white Gaussian noise at ``snr_db`` relative to the response power (w - w_static)."""
    if snr_db is None:
        return w
    resp = w - w_static
    power = float(np.mean(resp**2))
    sigma = math.sqrt(power / 10.0 ** (snr_db / 10.0)) if power > 0 else 0.0
    rng = np.random.default_rng(seed)
    return w + sigma * rng.standard_normal(w.shape)
