"""How long to record the next measurement, and how finely: the one sampling policy.

An experimenter stepping the control towards a transition records an impulse response at each
step. Near ``mu*`` the fundamental slows down (``omega ~ (mu* - mu)^a``), so a record of fixed
length holds fewer and fewer periods and the detector loses it. :func:`next_record_sampling`
chooses the next record's length and sample step from what the previous record measured, never
from a model of the strip:

- an underdamped fundamental: :data:`PERIODS` periods of the frequency *expected* at the next
  control (``omega_next = omega_prev * r^a``, with ``r = (mu* - mu_next) / (mu* - mu_prev)``
  from the latest prediction; ``r = 1`` without one), sampled with :data:`SAMPLES_PER_PERIOD`
  samples per period of the *previous* fundamental;
- an overdamped one (the slow pole sets the time scale, its rate ``~ (mu* - mu)^(2a)``): the
  previous length grown by ``r^(-2a)`` (at most 4x a step; 2x when no slowdown is expected), the
  previous sample step kept (the fast pole needs it);
- never more than :data:`MAX_SAMPLES` samples: the step is widened instead.

:func:`service.analysis.pipeline.warn` samples its simulated records with it, and a live sweep
(:mod:`service.analysis.live`) advises the lab with it (``record_duration``, ``record_dt``).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, NamedTuple

if TYPE_CHECKING:
    from service.analysis.measurement import Measurement
    from service.analysis.predict import Prediction

__all__ = ["MAX_SAMPLES", "PERIODS", "SAMPLES_PER_PERIOD", "RecordSampling",
           "next_record_sampling"]  # fmt: skip

#: Fundamental periods (at the expected next frequency) in a record.
PERIODS = 40
#: Samples per period of the previous record's fundamental.
SAMPLES_PER_PERIOD = 50
#: Most samples in one record (the step is widened beyond).
MAX_SAMPLES = 20_000
#: Most growth of an overdamped record's length in one step.
MAX_OVERDAMPED_GROWTH = 4.0
#: Growth of an overdamped record's length when no slowdown is expected (``r = 1``).
OVERDAMPED_GROWTH_DEFAULT = 2.0


class RecordSampling(NamedTuple):
    """Length and sample step of the next record (the previous record's time unit).

    Attributes
    ----------
    duration : float
        Record length (time unit of the previous record).
    dt : float
        Sample step (same unit); ``duration / dt <= MAX_SAMPLES``.
    """

    duration: float
    dt: float


def next_record_sampling(
    last: Measurement, mu_next: float, prediction: Prediction | None = None
) -> RecordSampling:
    """Length and sample step of the record to take at ``mu_next``.

    Parameters
    ----------
    last : Measurement
        The previous record's measurement: its control ``mu`` (control unit), fundamental
        ``omega`` (rad per time unit), ``regime`` (``"underdamped"`` or ``"overdamped"``),
        ``duration`` and ``dt`` (its time unit).
    mu_next : float
        Control value of the next record (control unit).
    prediction : Prediction, optional
        The latest prediction: its ``mu_star`` (control unit) and exponent ``a`` give the
        expected slowdown between ``last.mu`` and ``mu_next``. Ignored when absent, not finite
        or not beyond ``mu_next`` (then the previous frequency is expected again, ``a = 1/2``).

    Returns
    -------
    RecordSampling
        ``(duration, dt)`` in the previous record's time unit.

    Raises
    ------
    ZeroDivisionError
        When ``last.omega`` is zero (a record without a time scale gives no advice).
    """
    ratio = 1.0  # expected (mu* - mu_next) / (mu* - mu_prev): unknown without a prediction
    a = 0.5
    p = prediction
    if p is not None and math.isfinite(p.mu_star) and p.mu_star > mu_next:
        ratio = min((p.mu_star - mu_next) / max(p.mu_star - last.mu, 1e-300), 1.0)
        a = p.a
    if last.regime == "overdamped":
        growth = ratio ** (-2.0 * a) if ratio < 1.0 else OVERDAMPED_GROWTH_DEFAULT
        duration = last.duration * min(growth, MAX_OVERDAMPED_GROWTH)
        return RecordSampling(duration, max(last.dt, duration / MAX_SAMPLES))
    omega_next = last.omega * ratio**a
    t_prev = 2 * math.pi / last.omega
    t_next = 2 * math.pi / max(omega_next, 1e-12)
    duration = PERIODS * t_next
    dt = t_prev / SAMPLES_PER_PERIOD
    if duration / dt > MAX_SAMPLES:
        dt = duration / MAX_SAMPLES
    return RecordSampling(duration, dt)
