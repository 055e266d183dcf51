"""A live sweep: a lab adds one record at a time and asks where it may go next.

This is :func:`service.analysis.pipeline.warn` turned inside out. ``warn`` drives a simulator;
here the experiment drives itself and every record arrives with its control value. Each update

1. detects the new record (:func:`service.analysis.detect.detect`): its fundamental
   ``sigma^2 = -s1 s2``, its error and the static level, with the detector's flags;
2. classifies and predicts over every record measured so far
   (:func:`service.analysis.predict.predict`, once four records with a fundamental exist):
   the transition with its probabilities, ``mu*`` with its 95 % interval;
3. raises the alarm (:func:`service.analysis.alarm.alarm_for`) and chooses the next safe control
   value with the one policy of the project (:func:`service.analysis.alarm.next_measurement`):
   a fraction of the way to the interval's lower end once the predictor can be trusted
   (:func:`service.analysis.alarm.interval_trusted`: the slowdown has begun and two consecutive
   intervals overlap), the model-free two-point ``sigma^4`` bound before that, minus the
   sweep's margin. The value is never at or beyond ``mu*`` minus the margin.

The lab may do something else than advised: a record at or below a control already measured
(``out_of_order``, ``repeated_control``) or beyond the last advised value (``past_safe_value``)
is accepted and flagged, never reordered in the record list. The fit uses the records with a
fundamental in increasing control order; records at one control are averaged into one point
(:func:`_fit_set`), as a batch sweep of the same records averages them.

The module is pure numerics (numpy, the detector and the predictor); storing records, streaming
updates and the HTTP door live in ``service.api``.
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from service.analysis.alarm import (
    Alarm,
    NextMeasurement,
    alarm_for,
    interval_trusted,
    next_measurement,
)
from service.analysis.common import Flag, unique_flags
from service.analysis.detect import Detection, detect
from service.analysis.errors import ParameterError
from service.analysis.measurement import Measurement, measurement_from_detection
from service.analysis.pipeline import WarnResult
from service.analysis.predict import Prediction, bounded_by, predict
from service.analysis.predictor.sweep import group_mean
from service.analysis.sampling import next_record_sampling

__all__ = [
    "LivePlan",
    "LiveRecord",
    "LiveUpdate",
    "assess",
    "finish",
    "measure",
    "update",
]

#: Records with a fundamental needed before the predictor runs (as in ``warn``).
MIN_PREDICT = 4
#: The sigma^4 bound applies once the slowdown shows (T/T0 >= this) and MIN_PREDICT records exist
#: (the first pairs, before the slowdown, can overshoot; as in ``warn``).
SIGMA4_MIN_T_RATIO = 1.05
#: Relative tolerance when comparing a control value with the advised one.
_RTOL = 1e-12


@dataclass(frozen=True)
class LivePlan:
    """How a live sweep advises (the sweep's options; control units throughout).

    Attributes
    ----------
    step : float or None
        Largest step of the control (the first steps, before any bound on mu* exists). Without
        it the step never exceeds ``max_step_growth`` times the last one (the lab's own
        spacing), and after the first record no advice can be given.
    margin : float
        Distance kept below the safe bound on mu* (>= 0).
    target_width : float or None
        The sweep has converged once the trusted interval is narrower than this; default
        ``1e-6 * max(|mu*|, span of the controls)``.
    step_fraction : float
        Fraction of the room to the bound that a step takes, in (0, 1).
    max_step_growth : float or None
        A step is at most this multiple of the previous one (trust region). Default: none when
        ``step`` caps the steps (as ``warn``), 2 without ``step``.
    method : str
        Detector method.
    level : float
        Confidence level of the interval.
    """

    step: float | None = None
    margin: float = 0.0
    target_width: float | None = None
    step_fraction: float = 0.5
    max_step_growth: float | None = None
    method: str = "auto"
    level: float = 0.95

    def __post_init__(self) -> None:
        if self.step is not None and not (math.isfinite(self.step) and self.step > 0):
            raise ParameterError("step", self.step, f"step must be > 0, got step={self.step!r}")
        if not (math.isfinite(self.margin) and self.margin >= 0):
            raise ParameterError(
                "margin", self.margin, f"margin must be finite and >= 0, got margin={self.margin!r}"
            )
        tw = self.target_width
        if tw is not None and not (math.isfinite(tw) and tw > 0):
            raise ParameterError(
                "target_width", tw, f"target_width must be > 0, got target_width={tw!r}"
            )
        if not 0 < self.step_fraction < 1:
            raise ParameterError(
                "step_fraction",
                self.step_fraction,
                f"step_fraction must be in (0, 1), got step_fraction={self.step_fraction!r}",
            )
        if self.max_step_growth is not None and not self.max_step_growth > 0:
            raise ParameterError(
                "max_step_growth",
                self.max_step_growth,
                f"max_step_growth must be > 0, got max_step_growth={self.max_step_growth!r}",
            )
        if not 0 < self.level < 1:
            raise ParameterError(
                "level", self.level, f"level must be in (0, 1), got level={self.level!r}"
            )


@dataclass(frozen=True)
class LiveRecord:
    """What a live sweep keeps of one record (enough to assess the next one).

    Attributes
    ----------
    seq : int
        Position in arrival order (1, 2, ...).
    control : float
        Control value the record was taken at (user unit).
    measurement : Measurement or None
        The record's fundamental and static level; None when the detector found no mode.
    flags : tuple of Flag
        Record flags (``out_of_order``, ``repeated_control``, ``past_safe_value``, ``no_mode``).
    interval : tuple of float or None
        The 95 % interval of mu* after this record (None without a prediction): the next
        update's trust test compares its interval with it.
    next_control : float
        The control advised after this record (NaN: none).
    time_unit : str or None
        The time unit its measurement is in: the sweep's (its first record's), a record
        written in another known unit being converted to it.
    """

    seq: int
    control: float
    measurement: Measurement | None
    flags: tuple[Flag, ...] = ()
    interval: tuple[float, float] | None = None
    next_control: float = math.nan
    time_unit: str | None = None


@dataclass(frozen=True)
class LiveUpdate:
    """The warning after one more record.

    Attributes
    ----------
    record : LiveRecord
        The new record as kept (its flags, interval and advice included).
    detection : Detection
        The new record's detection.
    n_records, n_used : int
        Records so far, and those in the fit (a fundamental, distinct increasing controls).
    prediction : Prediction or None
        Classification (transition, probabilities) and mu* with its interval; None until
        :data:`MIN_PREDICT` records with a fundamental exist or when the predictor fails.
    alarm : Alarm
        Level, T/T0, mu* and the distance to it in half-widths.
    next : NextMeasurement or None
        The advised next control value (``next.mu``; NaN when no safe step is left); None
        when no advice is possible (one record and no ``step``).
    trusted : bool
        Whether the predictor's interval bounded the advice (else the model-free bound did).
    converged : bool
        The trusted interval is narrower than the plan's target width: the lab may stop.
    record_duration, record_dt : float
        Suggested length and sample step of the next record (the new record's time unit):
        40 periods of the expected fundamental, 50 samples per period of the last one (as
        ``warn`` samples); NaN without a fundamental.
    flags : tuple of Flag
        Flags of the update: the predictor's, ``no_safe_step``, ``predictor_failed``.
    """

    record: LiveRecord
    detection: Detection
    n_records: int
    n_used: int
    prediction: Prediction | None
    alarm: Alarm
    next: NextMeasurement | None
    trusted: bool
    converged: bool
    record_duration: float = math.nan
    record_dt: float = math.nan
    flags: tuple[Flag, ...] = field(default=())

    @property
    def next_control(self) -> float:
        """The advised next control value (NaN: none)."""
        return self.record.next_control

    @property
    def used_in_fit(self) -> bool:
        """The record has a fundamental (a repeated control is averaged with the others)."""
        return self.record.measurement is not None


# ----------------------------------------------------------------------------------- steps
def measure(
    w: Any, *, dt: float, control: float, method: str = "auto"
) -> tuple[Detection, Measurement | None, tuple[Flag, ...]]:
    """Detect one record and reduce it to the sweep's measurement.

    Parameters
    ----------
    w : array_like, shape (N,)
        The record (absolute position, any length unit), uniformly sampled.
    dt : float
        Sample step (the record's time unit).
    control : float
        Control value of the record (user unit), finite.
    method : str
        Detector method.

    Returns
    -------
    detection, measurement, flags
        ``measurement`` is None (flag ``no_mode``) when the detector found no fundamental.
    """
    c = float(control)
    if not math.isfinite(c):
        raise ParameterError("control", control, f"control must be finite, got {control!r}")
    arr = np.asarray(w, dtype=float)
    det = detect(arr, dt=float(dt), method=method)
    if "unstable" in det.flag_codes:  # the record grows: past the transition, not a point of it
        return det, None, (
            Flag(
                "past_transition",
                f"the record at control={c!r} grows (flag unstable): the strip is unstable "
                "there, past its transition; it is left out of the fit",
            ),
        )
    try:
        m = measurement_from_detection(c, det, (arr.size - 1) * float(dt), float(dt))
    except ValueError as exc:
        return det, None, (Flag("no_mode", str(exc)),)
    return det, m, ()


def _past(records: Sequence[LiveRecord]) -> float:
    """The lowest control of a record that grew (flag ``past_transition``); inf if none."""
    return min(
        (r.control for r in records if any(f.code == "past_transition" for f in r.flags)),
        default=math.inf,
    )


def _fit_records(records: Sequence[LiveRecord]) -> list[Measurement]:
    """The records' measurements the fit uses: a fundamental, below any record that grew (past
    the transition), in increasing control (arrival order within one control)."""
    past = _past(records)
    out = [r.measurement for r in records if r.measurement is not None and r.control < past]
    out.sort(key=lambda m: m.mu)  # stable
    return out


def _fit_set(records: Sequence[LiveRecord]) -> list[Measurement]:
    """Measurements of the fit, one per control: the records at one control averaged as the
    predictor averages a table's repeated rows (:func:`service.analysis.predictor.sweep.group_mean`:
    weights ``1/std^2`` when every record has its std, else plain means), so that a live sweep
    and a batch sweep of the same records fit the same points."""
    ms = _fit_records(records)
    if len({m.mu for m in ms}) == len(ms):
        return ms
    mu = np.array([m.mu for m in ms])
    starts = np.flatnonzero(np.r_[True, np.diff(mu) != 0])

    def mean(name: str, std: str) -> tuple[np.ndarray, np.ndarray]:
        v, sd = np.array([getattr(m, name) for m in ms]), np.array([getattr(m, std) for m in ms])
        ok = bool(np.all(np.isfinite(sd) & (sd > 0)))
        avg, avg_sd = group_mean(v, sd if ok else None, starts)
        return avg, (avg_sd if avg_sd is not None else np.full(starts.size, np.nan))

    s2, s2_sd = mean("sigma2", "sigma2_std")
    w, w_sd = mean("w_static", "w_static_std")
    return [
        replace(ms[i], sigma2=float(s2[g]), sigma2_std=float(s2_sd[g]),
                omega=math.sqrt(abs(float(s2[g]))), w_static=float(w[g]),
                w_static_std=float(w_sd[g]))  # fmt: skip
        for g, i in enumerate(starts)
    ]


def _predict(ms: Sequence[Measurement], level: float) -> tuple[Prediction | None, list[Flag]]:
    if len(ms) < MIN_PREDICT:
        return None, []
    names = ("mu", "sigma2", "sigma2_std", "w_static", "w_static_std")
    col = {k: np.array([getattr(m, k) for m in ms]) for k in names}
    s2_std = col["sigma2_std"]
    try:
        pred = predict(
            col["mu"],
            col["sigma2"],
            sigma2_std=s2_std if np.all(np.isfinite(s2_std) & (s2_std > 0)) else None,
            w_static=col["w_static"],
            w_static_std=np.maximum(col["w_static_std"], 1e-15),
            level=level,
        )
    except (ValueError, ArithmeticError) as exc:  # ParameterError, LinAlgError, overflow
        return None, [Flag("predictor_failed", f"no prediction from {len(ms)} records: {exc}")]
    return pred, []


def _record_flags(
    previous: Sequence[LiveRecord], control: float, m: Measurement | None, det_flags: tuple
) -> tuple[Flag, ...]:
    flags = list(det_flags)
    done = [r.control for r in previous]
    if control in done:
        k = done.index(control) + 1
        flags.append(
            Flag(
                "repeated_control",
                f"control {control!r} was already measured (record {k}); the fit averages "
                "the records at this control into one point",
            )
        )
    elif done and control < max(done):
        flags.append(
            Flag(
                "out_of_order",
                f"control {control!r} is below the largest already measured ({max(done)!r}); "
                "the record is kept in arrival order and the fit sorts by control",
            )
        )
    if previous:
        advised = previous[-1].next_control
        if math.isfinite(advised) and control > advised + _RTOL * max(1.0, abs(advised)):
            flags.append(
                Flag(
                    "past_safe_value",
                    f"control {control!r} is beyond the advised safe value {advised!r}",
                )
            )
    return tuple(flags)


def assess(
    previous: Sequence[LiveRecord],
    detection: Detection,
    measurement: Measurement | None,
    control: float,
    *,
    plan: LivePlan | None = None,
    detection_flags: tuple[Flag, ...] = (),
    timings: dict[str, tuple[float, float]] | None = None,
    time_unit: str | None = None,
) -> LiveUpdate:
    """The warning after adding one measured record to ``previous`` (in arrival order).

    Parameters
    ----------
    previous : sequence of LiveRecord
        The sweep's records so far, in arrival order.
    detection, measurement : Detection, Measurement or None
        The new record, from :func:`measure`.
    control : float
        Its control value.
    plan : LivePlan, optional
        The sweep's options.
    detection_flags : tuple of Flag
        Flags :func:`measure` returned (``no_mode``).
    timings : dict, optional
        Gets ``"predict"``: the (wall, CPU) seconds of the classification and prediction (the
        rest is the alarm, the advice and the sampling policy).
    time_unit : str, optional
        The time unit of the record's measurement (kept with it, :class:`LiveRecord`).

    Returns
    -------
    LiveUpdate
    """
    plan = plan or LivePlan()
    control = float(control)
    rflags = _record_flags(previous, control, measurement, detection_flags)
    seq = len(previous) + 1
    provisional = LiveRecord(seq, control, measurement, rflags)
    ms = _fit_set([*previous, provisional])
    t0, c0 = time.perf_counter(), time.process_time()
    pred, uflags = _predict(ms, plan.level)
    if timings is not None:
        timings["predict"] = (time.perf_counter() - t0, time.process_time() - c0)
    last = ms[-1] if ms else None
    t_ratio = ms[0].omega / last.omega if last is not None and last.omega > 0 else math.nan
    has_pred = pred is not None and math.isfinite(pred.mu_star)
    interval = tuple(pred.mu_star_interval) if has_pred else None
    alarm = alarm_for(
        last.mu if last is not None else control,
        t_ratio,
        pred.mu_star if has_pred else math.nan,
        interval or (math.nan, math.nan),
    )
    past = _past([*previous, provisional])
    if math.isfinite(past) and pred is not None:  # mu* lies below the record that grew
        pred = bounded_by(pred, past)
        interval = tuple(pred.mu_star_interval) if has_pred else None
    if math.isfinite(past):  # a record grew: the strip is past its transition there
        alarm = Alarm(
            "critical",
            f"the record at mu={past:.6g} grows: the strip is past its transition there",
            past, alarm.t_ratio, pred.mu_star if has_pred else math.nan,
            interval or (math.nan, math.nan), math.nan,
        )  # fmt: skip
    prev_interval = previous[-1].interval if previous else None
    trusted = bool(
        has_pred
        and prev_interval is not None
        and interval_trusted(interval, prev_interval, last.mu, t_ratio)
    )
    nxt = _advise(ms, pred if trusted else None, plan)
    if nxt is not None and not math.isfinite(nxt.mu):
        uflags.append(
            Flag(
                "no_safe_step",
                f"no control value beyond {last.mu!r} stays below the safe bound "
                f"{nxt.bound!r} minus the margin {plan.margin!r}",
            )
        )
    converged = trusted and _narrow(interval, pred.mu_star, ms, plan)
    if pred is not None:
        uflags.extend(pred.flags)
    duration, dt = _record_advice(last, nxt, pred)
    record = LiveRecord(
        seq, control, measurement, rflags, interval, nxt.mu if nxt is not None else math.nan,
        time_unit,
    )  # fmt: skip
    return LiveUpdate(
        record=record,
        detection=detection,
        n_records=seq,
        n_used=len(_fit_records([*previous, provisional])),
        prediction=pred,
        alarm=alarm,
        next=nxt,
        trusted=trusted,
        converged=converged,
        record_duration=duration,
        record_dt=dt,
        flags=tuple(unique_flags(uflags)),
    )


def _narrow(
    interval: tuple[float, float], mu_star: float, ms: Sequence[Measurement], plan: LivePlan
) -> bool:
    """The interval is narrower than the plan's target width (default ``1e-6 * max(|mu*|,
    span of the controls)``)."""
    width = plan.target_width
    if width is None:
        width = 1e-6 * max(abs(mu_star), ms[-1].mu - ms[0].mu)
    return bool(interval[1] - interval[0] < width)


def _record_advice(
    last: Measurement | None, nxt: NextMeasurement | None, pred: Prediction | None
) -> tuple[float, float]:
    """Length and step of the next record
    (:func:`service.analysis.sampling.next_record_sampling`, as ``warn`` samples); NaN when the
    last record gives no time scale."""
    if last is None or not (last.omega > 0 and math.isfinite(last.omega)):
        return math.nan, math.nan
    target = nxt.mu if nxt is not None and math.isfinite(nxt.mu) else last.mu
    try:
        duration, dt = next_record_sampling(last, target, pred)
    except (ArithmeticError, ValueError):  # a degenerate record: no advice on sampling
        return math.nan, math.nan
    return float(duration), float(dt)


def _advise(
    ms: Sequence[Measurement], trusted: Prediction | None, plan: LivePlan
) -> NextMeasurement | None:
    """The next control value by :func:`service.analysis.alarm.next_measurement`, with the
    parameters of ``warn``: a sequential sweep, whose trusted interval alone bounds the step
    (near a pitchfork the sigma^4 bound lands about halfway to mu* and would halve every
    step)."""
    max_step = plan.step if plan.step is not None else math.inf
    growth = plan.max_step_growth
    if growth is None:
        growth = math.inf if plan.step is not None else 2.0
    if not ms:
        return None
    if len(ms) == 1:
        if plan.step is None:
            return None
        return NextMeasurement(ms[0].mu + plan.step, math.inf, "none", "max_step")
    return next_measurement(
        [m.mu for m in ms],
        [abs(m.sigma2) for m in ms],
        trusted_bound=trusted.mu_star_interval[0] if trusted is not None else None,
        margin=plan.margin,
        step_fraction=plan.step_fraction,
        max_step_growth=growth,
        max_step=max_step,
        min_t_ratio=SIGMA4_MIN_T_RATIO if len(ms) >= MIN_PREDICT else math.inf,
        sigma4_when_trusted=False,
    )


def update(
    previous: Sequence[LiveRecord],
    w: Any,
    *,
    dt: float,
    control: float,
    plan: LivePlan | None = None,
) -> LiveUpdate:
    """Detect a new record and assess the sweep with it (:func:`measure` then :func:`assess`)."""
    plan = plan or LivePlan()
    det, m, fl = measure(w, dt=dt, control=control, method=plan.method)
    return assess(previous, det, m, control, plan=plan, detection_flags=fl)


def finish(records: Sequence[LiveRecord], *, plan: LivePlan | None = None,
           alarms: Sequence[dict] = (), stopped: str = "closed",
           prediction: Prediction | None = None) -> WarnResult:  # fmt: skip
    """The sweep's final result, in the shape of :func:`~service.analysis.pipeline.warn`'s.

    Parameters
    ----------
    records : sequence of LiveRecord
        All records, arrival order.
    plan : LivePlan, optional
    alarms : sequence of dict
        The alarm after each record (as stored with each update).
    stopped : str
        Why the sweep ended: ``"closed"`` (by the lab) or ``"budget"``.
    prediction : Prediction, optional
        The prediction over these same records (the last update's), kept instead of fitting
        again; without it the records are fitted here.
    """
    plan = plan or LivePlan()
    ms = _fit_set(records)
    if prediction is not None:
        pred, flags = prediction, []
    else:
        pred, flags = _predict(ms, plan.level)
    for r in records:
        flags.extend(f for f in r.flags if f.code != "no_mode")
    return WarnResult(None, None, tuple(ms), pred, tuple(alarms), stopped, None,
                      tuple(unique_flags(flags)))  # fmt: skip
