"""The alarm after a measurement and the one rule that chooses the next measurement.

Both the predictor (:func:`service.analysis.predict.predict`, its ``alarm`` and
``next_safe_mu``) and the early-warning sweep (:func:`service.analysis.pipeline.warn`) use the
objects of this module, so that the alarm a user reads and the step the pipeline takes follow
the same rule.

Alarm levels (``T = 1/sqrt|sigma^2|`` the time scale of the fundamental, ``T0`` at the first
point of the sweep; paper, Discussion: the slowdown ``T ~ (mu* - mu)^(-a)`` announces the
transition):

==========  =====================================================================
level       when
==========  =====================================================================
none        ``T / T0 <= 3`` and no interval near the last point
watch       ``T / T0 > 3``
warning     ``T / T0 > 10`` (the paper's threshold)
critical    the interval's lower end lies within one half-width of the last point
==========  =====================================================================

The next measurement (:func:`next_measurement`) advances a fraction of the way to a safe bound
on mu*: the smaller of the predictor's trusted bound (its interval's lower end) and the
model-free two-point ``sigma^4`` bound; the step never exceeds a multiple of the last step
(trust region) nor an absolute cap.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from service.analysis.errors import ParameterError

__all__ = [
    "ALARM_LEVELS",
    "Alarm",
    "NextMeasurement",
    "alarm_for",
    "interval_trusted",
    "next_measurement",
    "sigma4_bound",
]

ALARM_LEVELS = ("none", "watch", "warning", "critical")
WATCH_RATIO = 3.0
WARNING_RATIO = 10.0  # the paper's T > 10 T0


@dataclass(frozen=True)
class Alarm:
    """The alarm after the last measurement of a sweep.

    Attributes
    ----------
    level : str
        One of :data:`ALARM_LEVELS`: ``"none"``, ``"watch"``, ``"warning"``, ``"critical"``.
    reason : str
        One sentence with the numbers that set the level.
    mu : float
        Last measured control value (unit of ``mu``).
    t_ratio : float
        ``T / T0 = sqrt(sigma^2(0) / sigma^2(mu))`` at the last point (dimensionless).
    mu_star : float
        Predicted transition point (unit of ``mu``); NaN without a prediction.
    mu_star_interval : tuple of float
        Its interval ``(lo, hi)`` (95 % by default); ``(nan, nan)`` without a prediction.
    distance : float
        ``(mu* - mu) / half-width`` of the interval: how many half-widths remain; NaN without a
        prediction.
    """

    level: str
    reason: str
    mu: float
    t_ratio: float
    mu_star: float = math.nan
    mu_star_interval: tuple[float, float] = (math.nan, math.nan)
    distance: float = math.nan


def alarm_for(
    mu: float,
    t_ratio: float,
    mu_star: float = math.nan,
    interval: tuple[float, float] = (math.nan, math.nan),
) -> Alarm:
    """The alarm at the last measured ``mu``.

    Parameters
    ----------
    mu : float
        Last measured control value.
    t_ratio : float
        ``T / T0`` at ``mu`` (>= 0).
    mu_star : float, optional
        Predicted transition point (NaN: no prediction yet).
    interval : tuple of float, optional
        Its interval ``(lo, hi)``.

    Returns
    -------
    Alarm
    """
    lo, hi = float(interval[0]), float(interval[1])
    half = 0.5 * (hi - lo)
    has_pred = math.isfinite(mu_star) and math.isfinite(half) and half > 0
    dist = (mu_star - mu) / half if has_pred else math.nan
    if has_pred and lo - mu <= half:
        level = "critical"
        reason = (
            f"the interval's lower end {lo:.6g} is within one half-width ({half:.3g}) of the "
            f"last point mu={mu:.6g}"
        )
    elif t_ratio > WARNING_RATIO:
        level, reason = "warning", f"T/T0 = {t_ratio:.3g} > {WARNING_RATIO:g}"
    elif t_ratio > WATCH_RATIO:
        level, reason = "watch", f"T/T0 = {t_ratio:.3g} > {WATCH_RATIO:g}"
    else:
        level, reason = "none", f"T/T0 = {t_ratio:.3g} <= {WATCH_RATIO:g}"
    return Alarm(level, reason, float(mu), float(t_ratio), float(mu_star), (lo, hi), float(dist))


@dataclass(frozen=True)
class NextMeasurement:
    """The suggested next control value.

    Attributes
    ----------
    mu : float
        Next control value (unit of ``mu``); NaN when no safe step is left.
    bound : float
        The safe bound on mu* the step respects (``inf`` when none applies).
    source : str
        What set ``bound``: ``"interval"`` (the predictor's trusted lower end), ``"sigma4"``
        (the model-free two-point bound) or ``"none"``.
    limited_by : str
        What set the step: ``"bound"``, ``"growth"`` (trust region), ``"max_step"`` or
        ``"no_safe_step"``.
    """

    mu: float
    bound: float
    source: str
    limited_by: str


def sigma4_bound(
    mu: Sequence[float] | np.ndarray, y: Sequence[float] | np.ndarray, *, min_t_ratio: float = 1.0
) -> float:
    """Model-free bound on mu*: ``sigma^4`` extrapolated linearly to zero through the last two
    points.

    Exact at leading order near a fold (``sigma^4 ~ mu* - mu``, paper eq. saddleGrowthRate);
    near a pitchfork (``sigma^2 ~ mu* - mu``) it lands short of mu*, hence a conservative bound.

    Parameters
    ----------
    mu : array_like, shape (n,)
        Control values, increasing, n >= 2.
    y : array_like, shape (n,)
        ``|sigma^2|`` (1/time^2) at ``mu``.
    min_t_ratio : float
        The bound applies only once ``T/T0 = sqrt(y[0]/y[-1])`` reached this (the first pairs,
        before the slowdown shows, can overshoot).

    Returns
    -------
    float
        The bound (unit of ``mu``), ``inf`` when ``|sigma^2|`` does not decrease or the
        slowdown is below ``min_t_ratio``.
    """
    m = np.asarray(mu, dtype=float)
    yy = np.asarray(y, dtype=float)
    if m.size < 2 or yy.size != m.size:
        return math.inf
    y1, y2 = float(yy[-2]), float(yy[-1])
    if not (y1 > y2 > 0) or math.sqrt(float(yy[0]) / y2) < min_t_ratio:
        return math.inf
    return float(m[-1] + y2**2 * (m[-1] - m[-2]) / (y1**2 - y2**2))


def interval_trusted(
    interval: tuple[float, float],
    previous: tuple[float, float] | None,
    last_mu: float,
    t_ratio: float,
    *,
    min_t_ratio: float = 2.0,
) -> bool:
    """Whether the predictor's interval may bound the next step: the slowdown has begun
    (``T/T0 >= min_t_ratio``), the interval lies beyond the last point and (when a previous
    interval exists) overlaps it."""
    lo, hi = interval
    if not (math.isfinite(lo) and math.isfinite(hi) and lo > last_mu and t_ratio >= min_t_ratio):
        return False
    if previous is None:
        return True
    plo, phi = previous
    return bool(lo <= phi and plo <= hi)


def _positive(
    name: str, value: float, *, allow_inf: bool = False, open_unit: bool = False
) -> float:
    v = float(value)
    ok = v > 0 and (math.isfinite(v) or (allow_inf and v == math.inf))
    if open_unit:
        ok = ok and v < 1
    if not ok:
        dom = "in (0, 1)" if open_unit else "> 0"
        raise ParameterError(name, value, f"{name} must be {dom}, got {name}={value!r}")
    return v


def next_measurement(
    mu: Sequence[float] | np.ndarray,
    y: Sequence[float] | np.ndarray,
    *,
    trusted_bound: float | None = None,
    margin: float = 0.0,
    step_fraction: float = 0.5,
    max_step_growth: float = 2.0,
    max_step: float = math.inf,
    min_t_ratio: float = 1.0,
    sigma4_when_trusted: bool = True,
) -> NextMeasurement:
    """The next control value of an upward sweep.

    ``mu_next = mu[-1] + min(step_fraction * (bound - margin - mu[-1]),
    max_step_growth * (mu[-1] - mu[-2]), max_step)`` with ``bound`` the smaller of
    ``trusted_bound`` and :func:`sigma4_bound`; without any bound the step is the cap alone.

    Parameters
    ----------
    mu : array_like, shape (n,)
        Measured control values, increasing, n >= 2.
    y : array_like, shape (n,)
        ``|sigma^2|`` (1/time^2) at ``mu``.
    trusted_bound : float, optional
        The predictor's trusted lower bound on mu* (its interval's lower end); ignored when not
        beyond ``mu[-1]``.
    margin : float
        Distance (unit of ``mu``) kept below the bound, >= 0.
    step_fraction : float
        Fraction of the room to the bound that the step takes, in (0, 1).
    max_step_growth : float
        The step is at most this multiple of the last one (trust region), > 0 (``inf``: none).
    max_step : float
        Absolute cap on the step (unit of ``mu``), > 0 (``inf``: none).
    min_t_ratio : float
        Slowdown ``T/T0`` from which the sigma^4 bound applies (see :func:`sigma4_bound`).
    sigma4_when_trusted : bool
        Whether the sigma^4 bound also caps a step that a trusted bound already limits (True:
        the smaller of both, a single prediction; False: a sequential sweep whose intervals
        were checked against each other, since near a pitchfork the sigma^4 bound lands about
        halfway to mu* and would halve every step).

    Returns
    -------
    NextMeasurement
        ``mu`` is NaN (``limited_by == "no_safe_step"``) when the bound is not beyond the last
        point, or when no step is bounded at all (no bound, no cap).
    """
    m = np.asarray(mu, dtype=float)
    if m.ndim != 1 or m.size < 2:
        raise ParameterError("mu", mu, f"mu needs at least 2 points, got {m.size}")
    if not (math.isfinite(margin) and margin >= 0):
        raise ParameterError("margin", margin, f"margin must be finite and >= 0, got {margin!r}")
    step_fraction = _positive("step_fraction", step_fraction, open_unit=True)
    max_step_growth = _positive("max_step_growth", max_step_growth, allow_inf=True)
    max_step = _positive("max_step", max_step, allow_inf=True)
    last = float(m[-1])
    bound, source = math.inf, "none"
    if trusted_bound is not None and math.isfinite(trusted_bound) and trusted_bound > last:
        bound, source = float(trusted_bound), "interval"
    b4 = sigma4_bound(m, y, min_t_ratio=min_t_ratio)
    if source == "interval" and not sigma4_when_trusted:
        b4 = math.inf
    if b4 < bound:
        bound, source = b4, "sigma4"
    cap, why = max_step, "max_step"
    growth = max_step_growth * (last - float(m[-2]))
    if growth < cap:
        cap, why = growth, "growth"
    room = bound - margin - last
    if not room > 0:
        return NextMeasurement(math.nan, bound, source, "no_safe_step")
    step = step_fraction * room
    if step <= cap:
        return NextMeasurement(last + step, bound, source, "bound")
    if not math.isfinite(cap):
        return NextMeasurement(math.nan, bound, source, "no_safe_step")
    return NextMeasurement(last + cap, bound, source, why)
