"""One analysed record of a sweep: its control, fundamental, static level and flags.

:class:`Measurement` is what the early-warning sweep (:mod:`service.analysis.pipeline`) and a
live sweep (:mod:`service.analysis.live`) keep of each record, and what the sampling policy
(:mod:`service.analysis.sampling`) reads to size the next one;
:func:`measurement_from_detection` reduces the pole detector's result to it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

from service.analysis.common import Flag
from service.analysis.errors import ParameterError

if TYPE_CHECKING:
    from service.analysis.detect import Detection

__all__ = ["Measurement", "measurement_from_detection"]


@dataclass(frozen=True)
class Measurement:
    """One analysed record of the sweep.

    Attributes
    ----------
    mu : float
        Control value (user unit).
    omega, sigma2, sigma2_std : float
        sqrt|sigma^2| (rad/time), the fundamental's undamped eigenvalue (1/time^2) and its error.
    w_static, w_static_std : float
        Static level of the record (the equilibrium's deflection at the probe).
    regime : str
        "underdamped" or "overdamped".
    duration, dt : float
        Record length and step used.
    flags : tuple of Flag
        The detector's flags for this record.
    """

    mu: float
    omega: float
    sigma2: float
    sigma2_std: float
    w_static: float
    w_static_std: float
    regime: str
    duration: float
    dt: float
    flags: tuple[Flag, ...] = ()


def measurement_from_detection(
    mu: float, det: Detection, duration: float, dt: float
) -> Measurement:
    """Reduce a detection to the sweep's measurement (fundamental, static level, flags)."""
    f = det.fundamental
    if f is None or not math.isfinite(f.sigma2):
        raise ParameterError(
            "record", float(mu), f"record at mu={mu!r}: no fundamental mode found in it"
        )
    return Measurement(
        mu=float(mu),
        omega=math.sqrt(abs(f.sigma2)),
        sigma2=float(f.sigma2),
        sigma2_std=float(f.sigma2_std) if f.sigma2_std is not None else math.nan,
        w_static=float(det.static_level),
        w_static_std=float(det.static_level_std),
        regime=f.regime,
        duration=float(duration),
        dt=float(dt),
        flags=tuple(det.flags),
    )
