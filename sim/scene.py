"""Scene and Signal: what a simulator is asked to do, and what it records.

Everything here is non-dimensional with the paper's scales (eq. nonDimensionnalization):
length by L, transverse deflection by sqrt(L dL), time by sqrt(rho b h L^4 / B).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

ACTUATIONS = ("asymmetric", "symmetric", "antisymmetric")
BRANCHES = ("U_A", "U_B", "S_A", "S_B", "W_A", "W_B")
MODELS = ("normal-form", "euler-beam", "cosserat", "auto")


class SceneError(ValueError):
    """A scene parameter is out of its domain; the message names the parameter and value."""


def _check_finite(
    name: str, value: float, *, positive: bool = False, nonneg: bool = False
) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise SceneError(f"{name} must be a number, got {value!r}") from None
    if not math.isfinite(v):
        raise SceneError(f"{name} must be finite, got {value!r}")
    if positive and v <= 0:
        raise SceneError(f"{name} must be > 0, got {value!r}")
    if nonneg and v < 0:
        raise SceneError(f"{name} must be >= 0, got {value!r}")
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
    end_shortening, slenderness, elements : float, float, int
        dL/L, h/L and the number of elements: used by the Cosserat backend only.
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
    elements: int = 50

    def __post_init__(self) -> None:
        if self.actuation not in ACTUATIONS:
            raise SceneError(f"actuation must be one of {ACTUATIONS}, got {self.actuation!r}")
        if self.branch not in BRANCHES:
            raise SceneError(f"branch must be one of {BRANCHES}, got {self.branch!r}")
        _check_finite("mu", self.mu)
        _check_finite("damping", self.damping, nonneg=True)
        _check_finite("kick", self.kick)
        for name in ("kick_position", "probe"):
            v = _check_finite(name, getattr(self, name))
            if not 0.0 < v < 1.0:
                raise SceneError(f"{name} must lie in (0, 1), got {v!r}")
        if self.duration is not None:
            _check_finite("duration", self.duration, positive=True)
        if self.dt is not None:
            _check_finite("dt", self.dt, positive=True)
        if self.duration is not None and self.dt is not None and self.dt >= self.duration:
            raise SceneError(f"dt must be smaller than duration, got dt={self.dt!r}")
        if self.snr_db is not None:
            _check_finite("snr_db", self.snr_db)
        _check_finite("end_shortening", self.end_shortening, positive=True)
        _check_finite("slenderness", self.slenderness, positive=True)
        if int(self.elements) != self.elements or self.elements < 4:
            raise SceneError(f"elements must be an integer >= 4, got {self.elements!r}")

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
