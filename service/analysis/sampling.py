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
- never more than :data:`MAX_SAMPLES` samples: the step is widened instead;
- when the records' time unit is known, :func:`mains_clear_dt` shortens the step a little
  (never lengthens it; the sweep policy applies it) so that no mains line (:data:`MAINS_HZ`
  and their harmonics) above the fundamental aliases onto it or below it: an aliased hum near
  zero frequency looks like a slow mode, the slowest line of the record.

:func:`service.analysis.pipeline.warn` samples its simulated records with it, and a live sweep
(:mod:`service.analysis.live`) advises the lab with it (``record_duration``, ``record_dt``).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, NamedTuple

if TYPE_CHECKING:
    from service.analysis.measurement import Measurement
    from service.analysis.predict import Prediction

__all__ = ["MAINS_HARMONICS", "MAINS_HZ", "MAX_SAMPLES", "PERIODS", "SAMPLES_PER_PERIOD",
           "RecordSampling", "mains_clear_dt", "next_record_sampling"]  # fmt: skip

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
#: Mains frequencies (Hz) a lab's records may hold, whichever grid the lab is on.
MAINS_HZ = (50.0, 60.0)
#: Harmonics of each mains frequency kept clear of the fundamental (1 = the line itself).
MAINS_HARMONICS = 5
#: No mains alias below this multiple of the fundamental's frequency.
MAINS_ALIAS_GUARD = 1.5
#: The sample step is shortened by at most this factor to clear the mains aliases.
MAINS_MAX_SHORTENING = 1.5


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


def mains_clear_dt(dt: float, duration: float, omega: float, seconds_per_unit: float) -> float:
    """The longest sample step <= ``dt`` whose mains aliases all lie clear of the fundamental.

    A line at ``f`` Hz sampled at ``fs`` appears at ``|f - k fs|`` (the nearest ``k``). Every
    mains line above :data:`MAINS_ALIAS_GUARD` times the fundamental's frequency must appear
    there too, so that it is never the record's slowest line, nor blended with the fundamental.
    Lines already below that band are real low lines the sampling cannot move. The step is
    shortened by at most :data:`MAINS_MAX_SHORTENING` and only while the record keeps
    <= :data:`MAX_SAMPLES` samples; ``dt`` itself when no such step exists.

    Parameters
    ----------
    dt, duration : float
        Proposed sample step and record length (the records' time unit).
    omega : float
        The fundamental's angular frequency (rad per time unit), the largest expected.
    seconds_per_unit : float
        Seconds in one time unit (> 0).

    Returns
    -------
    float
        The sample step (the records' time unit).
    """
    if not (seconds_per_unit > 0 and dt > 0 and omega > 0):
        return dt
    floor_hz = MAINS_ALIAS_GUARD * omega / (2 * math.pi) / seconds_per_unit
    lines = [m * f0 for f0 in MAINS_HZ for m in range(1, MAINS_HARMONICS + 1)]
    lines = [f for f in lines if f > floor_hz]
    if not lines:
        return dt
    steps = 200
    for i in range(steps + 1):
        trial = dt / (1.0 + (MAINS_MAX_SHORTENING - 1.0) * i / steps)
        if duration / trial > MAX_SAMPLES:
            break
        fs = 1.0 / (trial * seconds_per_unit)
        if all(abs(f - round(f / fs) * fs) > floor_hz for f in lines):
            return trial
    return dt
