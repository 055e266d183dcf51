"""The alarm after a measurement and the one rule that chooses the next measurement.

The sweep policy (:mod:`service.analysis.sweep_policy`), used by ``warn``, the batch sweep and
the live sweep, and the predictor (:func:`service.analysis.predict.predict`) use the objects of
this module, so that the alarm a user reads and the step the lab takes follow one rule.

Alarm levels say what the lab must do (``rank`` orders them, 0 lowest). ``lo, hi`` is the
interval of mu*, ``mu`` the last usable control, ``gap = lo - mu``, ``step`` the lab's step (its
plan's step, else the largest step between its records) and ``span`` the controls travelled:

============  ====  =====================================================================
level         rank  when (and what to do)
============  ====  =====================================================================
insufficient  0     no prediction yet, or its interval is wider than ``span`` with its
                    lower end more than 4 steps ahead or not ahead of ``mu``: too little
                    evidence to judge; step by the advice (the model-free bound guards)
clear         1     ``gap > 4 step``, or the type is ``none`` (no loss of stability): go on
watch         2     ``2 step < gap <= 4 step``: the interval is a few steps ahead; the
                    advice now shortens the steps
warning       3     ``step < gap <= 2 step``: within two steps; record only at the advice
critical      4     ``gap <= step`` (the next step would reach the interval), or a record
                    grew (past the transition): only the advised, smaller steps, or stop
============  ====  =====================================================================

The width decides whether there is evidence (``insufficient``); danger is counted in the lab's
steps, so a wide interval alone never raises the top level: an interval wider than ``span``
whose lower end lies ahead within 4 steps is ``watch`` or ``warning`` by the steps to that end
(its lower end is still a bound the lab must respect), never ``critical``. ``T/T0`` (``T =
1/sqrt|sigma^2|``, ``T0`` at the first point) is kept in the alarm as information.

The next measurement (:func:`next_measurement`) advances a fraction of the way to the safe
bound: the interval's lower end, any record past the transition, and (until the interval is
trusted) the model-free two-point ``sigma^4`` bound; a step never exceeds a multiple of the last
step (trust region) nor an absolute cap, so steps grow when far and shrink near.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from service.analysis.errors import ParameterError

__all__ = [
    "ALARM_LEVELS",
    "ALARM_RANK",
    "Alarm",
    "NextMeasurement",
    "alarm_for",
    "interval_trusted",
    "next_measurement",
    "sigma4_bound",
]

ALARM_LEVELS = ("insufficient", "clear", "watch", "warning", "critical")
ALARM_RANK = {name: i for i, name in enumerate(ALARM_LEVELS)}
#: The interval's lower end within this many lab steps: watch, warning, critical.
WATCH_STEPS, WARNING_STEPS, CRITICAL_STEPS = 4.0, 2.0, 1.0


@dataclass(frozen=True)
class Alarm:
    """The alarm after the last measurement of a sweep.

    Attributes
    ----------
    level : str
        One of :data:`ALARM_LEVELS`.
    reason : str
        One sentence with the numbers that set the level.
    mu : float
        Last usable control value (unit of ``mu``); the control of a record that grew when one
        did.
    t_ratio : float
        ``T / T0 = sqrt(sigma^2(0) / sigma^2(mu))`` at the last point (dimensionless).
    mu_star : float
        Predicted transition point (unit of ``mu``); NaN without a prediction.
    mu_star_interval : tuple of float
        Its interval ``(lo, hi)`` (95 % by default); ``(nan, nan)`` without a prediction.
    distance : float
        ``(mu* - mu) / half-width`` of the interval; NaN without a prediction.
    rank : int
        Position of ``level`` in :data:`ALARM_LEVELS` (0 lowest).
    step : float
        The lab's step the danger is counted in (unit of ``mu``; NaN when unknown).
    steps_left : float
        ``(lo - mu) / step``: lab steps left to the interval's lower end.
    widths_left : float
        ``(lo - mu) / (hi - lo)``: the same distance in widths of the interval.
    """

    level: str
    reason: str
    mu: float
    t_ratio: float
    mu_star: float = math.nan
    mu_star_interval: tuple[float, float] = (math.nan, math.nan)
    distance: float = math.nan
    rank: int = 0
    step: float = math.nan
    steps_left: float = math.nan
    widths_left: float = math.nan

    def __post_init__(self) -> None:
        if self.level not in ALARM_RANK:
            raise ParameterError("level", self.level, f"unknown alarm level {self.level!r}")
        object.__setattr__(self, "rank", ALARM_RANK[self.level])  # the level's, always


def _num(x: float, u: float = math.nan) -> str:
    """A control value for a reason: rounded to ``u`` (the interval's half-width) when given."""
    from service.numfmt import fmt

    return fmt(x, u if math.isfinite(u) and u > 0 else None, digits=4)


def alarm_for(
    mu: float,
    t_ratio: float,
    mu_star: float = math.nan,
    interval: tuple[float, float] = (math.nan, math.nan),
    *,
    step: float = math.nan,
    span: float = math.nan,
    transition: str | None = None,
    past: float = math.nan,
) -> Alarm:
    """The alarm at the last usable control ``mu`` (the scale of the module docstring).

    Parameters
    ----------
    mu : float
        Last usable control value.
    t_ratio : float
        ``T / T0`` at ``mu`` (>= 0; information only).
    mu_star : float, optional
        Predicted transition point (NaN: no prediction yet).
    interval : tuple of float, optional
        Its interval ``(lo, hi)``.
    step : float, optional
        The lab's step (unit of ``mu``); without it danger is counted in interval widths.
    span : float, optional
        Controls travelled by the usable records (``mu - first``); an interval wider than it
        is too little evidence. NaN: not checked.
    transition : str, optional
        The predicted type; ``"none"`` (no loss of stability) is never a snap alarm.
    past : float, optional
        Lowest control of a record that grew (past the transition); NaN if none.

    Returns
    -------
    Alarm
    """
    lo, hi = float(interval[0]), float(interval[1])
    mu, mu_star = float(mu), float(mu_star)
    width = hi - lo
    has_pred = math.isfinite(mu_star) and math.isfinite(width) and width >= 0
    dist = (mu_star - mu) / (0.5 * width) if has_pred and width > 0 else math.nan
    gap = lo - mu if has_pred else math.nan
    step = float(step) if math.isfinite(step) and step > 0 else math.nan
    steps_left = gap / step if math.isfinite(step) else math.nan
    widths_left = gap / width if has_pred and width > 0 else math.nan

    def make(level: str, reason: str, at: float = mu) -> Alarm:
        return Alarm(level, reason, at, float(t_ratio), mu_star, (lo, hi), float(dist),
                     ALARM_RANK[level], step, float(steps_left), float(widths_left))  # fmt: skip

    if math.isfinite(past):
        return make("critical", f"the record at {_num(past)} grows: the strip is past its "
                    "transition there", at=float(past))  # fmt: skip
    if transition == "none":
        return make("clear", "the predictor finds no loss of stability (type none): no snap "
                    "is expected")  # fmt: skip
    if not has_pred:
        return make("insufficient", f"no prediction yet (T/T0 = {t_ratio:.3g}): too little "
                    "evidence to judge")  # fmt: skip
    n = steps_left if math.isfinite(steps_left) else widths_left
    unit = f"steps of {_num(step)}" if math.isfinite(steps_left) else "interval widths"
    where = (f"the interval's lower end {_num(lo, 0.5 * width)} is {n:.3g} {unit} above the "
             f"last control {_num(mu, 0.5 * width)}")  # fmt: skip
    if math.isfinite(span) and width > span:
        wide = (f"the interval [{_num(lo, 0.5 * width)}, {_num(hi, 0.5 * width)}] is wider "
                f"({_num(width)}) than the controls travelled ({_num(span)})")  # fmt: skip
        if not (math.isfinite(steps_left) and 0 < steps_left <= WATCH_STEPS):
            return make("insufficient", f"{wide}: too little evidence to judge")
        # its lower end, ahead of the records, is still a bound the lab must respect: danger by
        # the steps to it, but never the top level on a wide interval (one that reaches down to
        # the last record bounds nothing the records do not show: insufficient)
        level = "warning" if steps_left <= WARNING_STEPS else "watch"
        return make(level, f"{wide}, but its lower end is {steps_left:.3g} {unit} above the "
                    f"last control: {level} (never critical on so wide an interval)")  # fmt: skip
    if not n > CRITICAL_STEPS:
        return make("critical", f"{where}: the next step would reach the interval")
    if n <= WARNING_STEPS:
        return make("warning", f"{where}: record only at the advised controls")
    if n <= WATCH_STEPS:
        return make("watch", f"{where}: the advice now shortens the steps")
    return make("clear", f"{where}: far from the transition")


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
        What set ``bound``: ``"interval"`` (the predictor's lower end), ``"sigma4"`` (the
        model-free two-point bound), ``"past_transition"`` (a record that grew) or ``"none"``.
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
    lower_bound: float | None = None,
    past: float = math.inf,
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
        The predictor's trusted lower bound on mu* (its interval's lower end); one not beyond
        ``mu[-1]`` leaves no safe step.
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
    lower_bound : float, optional
        An untrusted interval's lower end: it bounds the step too (the advice stays strictly
        below every interval's lower end) but leaves the sigma^4 bound in charge as well.
    past : float
        Lowest control of a record that grew (past the transition): a bound as well.
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
    if trusted_bound is not None and math.isfinite(trusted_bound):
        bound, source = float(trusted_bound), "interval"
    b4 = sigma4_bound(m, y, min_t_ratio=min_t_ratio)
    if source == "interval" and not sigma4_when_trusted:
        b4 = math.inf
    if lower_bound is not None and math.isfinite(lower_bound) and lower_bound < bound:
        bound, source = float(lower_bound), "interval"
    if b4 < bound:
        bound, source = b4, "sigma4"
    if past < bound:
        bound, source = float(past), "past_transition"
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
