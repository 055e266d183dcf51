"""The one sweep policy: records in, the answer, the alarm and the next safe control out.

``warn`` (a simulated strip), the batch sweep of recorded signals and the live sweep all feed
their records to :class:`SweepPolicy` and read its :class:`PolicyUpdate`, so the same records
give the same alarm, advice and answer through every door. For the records so far it

1. chooses each record's fundamental consistently across the sweep
   (:func:`service.analysis.reconcile.reconcile`, when that module and every record's detection
   are at hand);
2. sets aside, with the reason and the record's name, the records that cannot be trusted (flag
   ``record_set_aside``), those without a fundamental, those whose fundamental cannot enter a
   sweep (``sigma^2 >= 0`` without the record growing), and a record that grew while stable
   records lie above it; a record that grew with none above it is past the transition: mu* and
   the advice stay below it;
3. averages the records at one control (:func:`service.analysis.predictor.sweep.group_mean`) and
   predicts once >= :data:`MIN_RECORDS` distinct controls remain
   (:func:`service.analysis.predict.predict`): one mu* and interval for the whole document;
4. raises the alarm (:func:`service.analysis.alarm.alarm_for`), advises the next control
   (:func:`service.analysis.alarm.next_measurement`) and the next record's length.

The records (steps 1-3's choosing, sorting and averaging) are :mod:`.sweep_records`'s; the
interval as the records bound it (a record that grew, the control resolution) is
:mod:`.sweep_interval`'s; their public names are also importable from here.
"""

from __future__ import annotations

import math
import threading
import time
from collections import OrderedDict
from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np

from service.analysis.alarm import (
    Alarm,
    NextMeasurement,
    alarm_for,
    interval_trusted,
    next_measurement,
)
from service.analysis.common import Flag, unique_flags
from service.analysis.errors import ParameterError
from service.analysis.measurement import Measurement
from service.analysis.predict import Prediction, bounded_by, predict
from service.analysis.reconcile import withhold_type
from service.analysis.sampling import PERIODS, mains_clear_dt, next_record_sampling
from service.analysis.sweep_interval import (
    _growth,
    _resolution_floor,
    lab_step,
    resolution,
)
from service.analysis.sweep_plan import SweepPlan
from service.analysis.sweep_records import (
    SetAside,
    SweepRecord,
    _odd_leading,
    _reconciled,
    _sort_out,
    doubt_overdamped,
    file_unreadable,
    fit_points,
    record_of,
    reduce_detection,
    samples_refused,
    unanalysed,
)

__all__ = [
    "MIN_RECORDS",
    "PolicyUpdate",
    "SetAside",
    "SweepPlan",
    "SweepPolicy",
    "SweepRecord",
    "doubt_overdamped",
    "evaluate",
    "file_unreadable",
    "fit_points",
    "record_of",
    "reduce_detection",
    "samples_refused",
    "unanalysed",
]

#: Distinct usable controls from which the sweep answers (a prediction).
MIN_RECORDS = 3
#: The model-free sigma^4 bound applies once the slowdown shows (T/T0 >= this) and four usable
#: controls exist (the first pairs, before the slowdown, can overshoot).
SIGMA4_MIN_T_RATIO = 1.05
SIGMA4_MIN_RECORDS = 4
#: The next record is at most this many times the 40-period length at the last frequency.
MAX_RECORD_GROWTH = 4.0
#: Default target width: this fraction of the controls travelled (ten times narrower than the
#: "narrow" of docs/lab-guide.md, an interval under 1 % of the distance travelled).
TARGET_OF_SPAN = 1e-3


@dataclass(frozen=True)
class PolicyUpdate:
    """The sweep after its records so far.

    Attributes
    ----------
    measurements : tuple of Measurement
        The points of the fit, one per control (repeats averaged), increasing control.
    n_records, n_used : int
        Records so far, and those in the fit.
    set_aside : tuple of SetAside
        Records left out, with their reasons (``n_set_aside`` counts them).
    past : float
        Lowest control of a record that grew with no stable record above it (inf: none).
    prediction : Prediction or None
        mu* and its interval (bounded by ``past``), with this alarm and advice; None below
        :data:`MIN_RECORDS` usable controls or when the predictor failed.
    alarm : Alarm
    next : NextMeasurement or None
        The advised next control (``next.mu``; NaN: no safe step); None without advice.
    trusted : bool
        The interval was trusted (the slowdown began and two consecutive intervals overlap):
        it alone bounds the step, which may then grow beyond the lab's step.
    converged : bool
        Trusted and narrower than the target width, or the next step is below the control
        resolution.
    record_duration, record_dt : float
        Suggested length and sample step of the next record (the last record's time unit).
    record_advice : str
        How the record length was chosen (and whether it was bounded).
    flags : tuple of Flag
        Sweep flags: the predictor's, ``record_set_aside``, ``past_transition``,
        ``no_safe_step``, ``predictor_failed``, ``too_few_records``.
    fit_interval : tuple of float or None
        The interval the records give by themselves: ``interval`` before a converged sweep
        joins it with the interval without its newest record (flag ``converged_hull``). It
        depends on the records alone, never on earlier updates, so the next record's trust
        test compares with the same interval in every door (a live sweep stores it with the
        record; a batch computes it from its records but the last).
    """

    measurements: tuple[Measurement, ...]
    n_records: int
    n_used: int
    set_aside: tuple[SetAside, ...]
    past: float
    prediction: Prediction | None
    alarm: Alarm
    next: NextMeasurement | None
    trusted: bool
    converged: bool
    record_duration: float = math.nan
    record_dt: float = math.nan
    record_advice: str = ""
    flags: tuple[Flag, ...] = ()
    fit_interval: tuple[float, float] | None = None

    @property
    def n_set_aside(self) -> int:
        """Records set aside."""
        return len(self.set_aside)

    @property
    def next_control(self) -> float:
        """The advised next control (NaN: none)."""
        return self.next.mu if self.next is not None else math.nan

    @property
    def interval(self) -> tuple[float, float] | None:
        """The interval of mu* (None without a prediction)."""
        p = self.prediction
        return tuple(p.mu_star_interval) if p is not None and math.isfinite(p.mu_star) else None


#: The last predictions, by their exact inputs (:func:`_predict`'s key): ``predict`` is
#: deterministic in them, and a sweep asks for the same one again: the converged hull
#: (:func:`_without_newest`) predicts the records but the newest, which the previous record's
#: update predicted (a live sweep's worker keeps them across requests), and a batch's
#: :meth:`SweepPolicy.result` assesses the records but the last first.
_PREDICTIONS: OrderedDict[tuple, Prediction] = OrderedDict()
_PREDICTIONS_MAX = 16
_PREDICTIONS_LOCK = threading.Lock()


def _predict(
    ms: Sequence[Measurement], level: float, strict: bool = False
) -> tuple[Prediction | None, list[Flag]]:
    if len(ms) < MIN_RECORDS:
        return None, []
    col = {k: np.array([getattr(m, k) for m in ms])
           for k in ("mu", "sigma2", "sigma2_std", "w_static", "w_static_std")}  # fmt: skip
    # exact: the columns' bytes (the arguments below are functions of them) and the level
    key = (level, *((col[k].dtype.str, col[k].tobytes()) for k in sorted(col)))
    with _PREDICTIONS_LOCK:
        hit = _PREDICTIONS.get(key)
        if hit is not None:
            _PREDICTIONS.move_to_end(key)
            return hit, []
    s2_std = col["sigma2_std"]
    # records of a velocity or an acceleration have no static level (NaN): the prediction
    # then reads the frequencies alone
    static = bool(np.all(np.isfinite(col["w_static"])))
    try:
        pred = predict(
            col["mu"],
            col["sigma2"],
            sigma2_std=s2_std if np.all(np.isfinite(s2_std) & (s2_std > 0)) else None,
            w_static=col["w_static"] if static else None,
            w_static_std=np.maximum(col["w_static_std"], 1e-15) if static else None,
            level=level,
        )
    except ParameterError:
        if strict:  # a batch of a lab's records: the user must hear why (e.g. swept from above)
            raise
        return _failed(ms)
    except (ValueError, ArithmeticError):  # LinAlgError, overflow
        return _failed(ms)
    with _PREDICTIONS_LOCK:
        _PREDICTIONS[key] = pred
        while len(_PREDICTIONS) > _PREDICTIONS_MAX:
            _PREDICTIONS.popitem(last=False)
    return pred, []


def _failed(ms: Sequence[Measurement]) -> tuple[None, list[Flag]]:
    import sys

    exc = sys.exception()
    return None, [Flag("predictor_failed", f"no prediction from {len(ms)} records: {exc}")]


# ------------------------------------------------------------------------------- the policy
def _advise(
    ms: Sequence[Measurement], pred: Prediction | None, trusted: bool, past: float,
    plan: SweepPlan, repeats: int = 1, res: float = 0.0,
) -> NextMeasurement | None:  # fmt: skip
    """The next control by :func:`service.analysis.alarm.next_measurement`: below the
    interval's lower end once the interval is evidence (no wider than the controls travelled),
    below the point estimate always, below a record that grew, below the sigma^4 bound until
    the interval is trusted; capped by the lab's step until then.

    When no step up is safe (the interval reaches down to the last record, which was stable)
    the record is repeated there; once it was (``repeats`` usable records at the last
    control) and the interval still reaches down to it, the next record fills in halfway
    between the last two controls (``fill_in``; stable ground, more than the control
    resolution ``res`` from both): repeats narrow the noise of one point, not the law's
    shape near the transition, which a point between them constrains."""
    if not ms:
        return None
    lo = None
    if pred is not None and math.isfinite(pred.mu_star):
        lo, hi = pred.mu_star_interval
        if not (trusted or hi - lo <= ms[-1].mu - ms[0].mu):  # too little evidence: mu* bounds
            lo = pred.mu_star
    step = plan.step if plan.step is not None else math.inf
    growth = plan.max_step_growth
    if growth is None:
        growth = math.inf if plan.step is not None else 2.0
    if trusted and plan.step is not None and plan.max_step_growth is not None:
        step = math.inf  # a trusted bound lets steps grow beyond the lab's step
    if len(ms) == 1:
        if plan.step is None:
            return None
        nxt = ms[0].mu + plan.step
        if past < math.inf or (lo is not None and nxt >= lo):
            return NextMeasurement(math.nan, min(past, lo or math.inf), "interval", "no_safe_step")
        return NextMeasurement(nxt, math.inf, "none", "max_step")
    nxt = next_measurement(
        [m.mu for m in ms],
        [abs(m.sigma2) for m in ms],
        trusted_bound=lo if trusted else None,
        lower_bound=None if trusted else lo,
        past=past,
        margin=plan.margin,
        step_fraction=plan.step_fraction,
        max_step_growth=growth,
        max_step=step,
        min_t_ratio=SIGMA4_MIN_T_RATIO if len(ms) >= SIGMA4_MIN_RECORDS else math.inf,
        sigma4_when_trusted=False,
    )
    last = ms[-1].mu
    if not math.isfinite(nxt.mu) and nxt.source == "interval" and past == math.inf:
        # the interval reaches down to the last record: no step up is safe, but the strip was
        # stable there: repeat the record at that control (more evidence where it is needed),
        # then fill in between the last two controls when a repeat did not lift it
        fill = 0.5 * (ms[-2].mu + ms[-1].mu)
        if repeats >= 2 and min(fill - ms[-2].mu, last - fill) > res:
            return NextMeasurement(fill, nxt.bound, nxt.source, "fill_in")
        return NextMeasurement(last, nxt.bound, nxt.source, "repeat")
    return nxt


def _record_advice(
    last: Measurement | None,
    nxt: NextMeasurement | None,
    pred: Prediction | None,
    time_unit: str | None = None,
) -> tuple[float, float, str]:
    """Length and step of the next record (:func:`service.analysis.sampling.next_record_sampling`)
    at most :data:`MAX_RECORD_GROWTH` times 40 periods of the last frequency; NaN without a time
    scale. With a known ``time_unit`` the step keeps mains aliases clear of the fundamental."""
    if last is None or not (last.omega > 0 and math.isfinite(last.omega)):
        return math.nan, math.nan, "no advice: the last record gives no time scale"
    target = nxt.mu if nxt is not None and math.isfinite(nxt.mu) else last.mu
    from service.recordings._time_units import seconds_per

    try:
        duration, dt = next_record_sampling(last, target, pred)
    except (ArithmeticError, ValueError):
        return math.nan, math.nan, "no advice: the last record gives no time scale"
    period = 2 * math.pi / last.omega
    cap = MAX_RECORD_GROWTH * PERIODS * period if last.regime != "overdamped" else math.inf
    why = (f"{PERIODS} periods of the fundamental expected at the next control "
           f"(last period {period:.4g})")  # fmt: skip
    if duration > cap:
        duration = cap
        why += f", bounded to {MAX_RECORD_GROWTH:g} x {PERIODS} periods of the last one"
    if last.regime == "overdamped":
        why = "the last overdamped record's length grown by the expected slowdown (at most 4x)"
    spu = seconds_per(time_unit)
    if spu is not None and last.regime != "overdamped":
        cleared = mains_clear_dt(dt, duration, last.omega, spu)
        if cleared < dt:
            why += (f"; step shortened {dt / cleared:.3g}x so that 50/60 Hz mains and harmonics "
                    "do not alias onto or below the fundamental")  # fmt: skip
            dt = cleared
    return float(duration), float(dt), why


@dataclass
class _Answer:
    """The records' answer before the alarm and the advice (:func:`_answer`)."""

    recs: list[SweepRecord]
    usable: list[SweepRecord]
    aside: list[SetAside]
    past: float
    ms: list[Measurement]
    pred: Prediction | None
    flags: list[Flag]
    unconfirmed: bool
    step: float
    res: float


def _answer(
    records: Sequence[SweepRecord], plan: SweepPlan,
    timings: dict[str, tuple[float, float]] | None, strict: bool,
) -> _Answer:  # fmt: skip
    """The records chosen, sorted and predicted: the prediction with its interval bounded by a
    record that grew and floored at the control resolution, and the sweep's flags so far."""
    recs = _reconciled(records, plan.band)
    usable, aside, past, beyond, n_grew = _sort_out(recs)
    usable, odd = _odd_leading(usable)  # one odd first record does not turn the sweep round
    if odd:
        aside = sorted([*aside, *odd], key=lambda a: a.seq)
    ms = fit_points(usable)
    t0, c0 = time.perf_counter(), time.process_time()
    pred, flags = _predict(ms, plan.level, strict)
    pred = withhold_type(pred, [r.measurement for r in usable], flags)  # reconcile's doubt
    if timings is not None:
        timings["predict"] = (time.perf_counter() - t0, time.process_time() - c0)
    if len(ms) < len(usable):
        flags.append(Flag(
            "repeated_points_averaged",
            f"{len(usable)} usable records at {len(ms)} distinct controls: the records at one "
            "control are averaged into one point (inverse-variance weights when every record "
            "has its std)",
        ))  # fmt: skip
    no_mode = next((f for r in recs for f in r.flags if f.code == "no_mode"), None)
    if no_mode is not None:
        flags.append(no_mode)
    if aside:
        flags.append(Flag("record_set_aside", f"{len(aside)} record(s) set aside: "
                          + "; ".join(a.reason for a in aside)))  # fmt: skip
    pred, unconfirmed = _growth(pred, ms, past, len(beyond), n_grew, flags)
    step = lab_step(ms, plan)
    res = resolution(ms, plan, step)
    pred = _resolution_floor(pred, ms, res, past, flags)
    if len(ms) < MIN_RECORDS:
        flags.append(Flag(
            "too_few_records",
            f"{len(ms)} usable control(s) below the transition ({len(aside)} record(s) set "
            f"aside): a prediction needs at least {MIN_RECORDS}",
        ))  # fmt: skip
    return _Answer(recs, usable, aside, past, ms, pred, flags, unconfirmed, step, res)


def evaluate(
    records: Sequence[SweepRecord],
    plan: SweepPlan | None = None,
    *,
    previous_interval: tuple[float, float] | None = None,
    timings: dict[str, tuple[float, float]] | None = None,
    strict: bool = False,
) -> PolicyUpdate:
    """The sweep after ``records`` (arrival order).

    Parameters
    ----------
    records : sequence of SweepRecord
    plan : SweepPlan, optional
    previous_interval : tuple of float, optional
        The interval after the records but the last (the trust test's second interval).
    timings : dict, optional
        Gets ``"predict"``: (wall, CPU) seconds of the prediction.
    strict : bool
        Raise the predictor's ``ParameterError`` (a batch of records: the user must hear why)
        instead of flagging ``predictor_failed`` (a live sweep goes on).
    """
    plan = plan or SweepPlan()
    a = _answer(records, plan, timings, strict)
    ms, pred, past, flags = a.ms, a.pred, a.past, a.flags
    last = ms[-1] if ms else None
    t_ratio = ms[0].omega / last.omega if last is not None and last.omega > 0 else math.nan
    has_pred = pred is not None and math.isfinite(pred.mu_star)
    interval = tuple(pred.mu_star_interval) if has_pred else None
    last_mu = last.mu if last is not None else (records[-1].control if records else math.nan)
    alarm = _alarm(ms, pred, last_mu, t_ratio, a.step, past)
    trusted = bool(
        has_pred and last is not None and previous_interval is not None
        and interval_trusted(interval, previous_interval, last.mu, t_ratio)
    )  # fmt: skip
    repeats = sum(1 for r in a.usable if last is not None and r.measurement.mu == last.mu)
    nxt = _advise(ms, pred if has_pred else None, trusted, past, plan, repeats, a.res)
    if a.unconfirmed:  # record again where the one record grew: it confirms or sets it aside
        nxt = NextMeasurement(past, past, "past_transition", "confirm")
        alarm = replace(alarm, reason=(
            f"the record at {past:.6g} grows, but the stable records put mu* above it: "
            f"record again at {past:.6g} to confirm (only the advised control, or stop)"))
    if nxt is not None and not math.isfinite(nxt.mu):
        flags.append(Flag(
            "no_safe_step",
            f"no control beyond {last_mu:.6g} stays below the safe bound {nxt.bound:.6g} "
            f"({nxt.source}) minus the margin {plan.margin:g}",
        ))  # fmt: skip
    converged = False
    if trusted:
        converged, hull = _converged(a, plan, interval, previous_interval, nxt)
        if hull is not None:  # the answer the sweep stops on: not the newest record's alone
            pred = replace(pred, mu_star_interval=hull)
            alarm = _alarm(ms, pred, last_mu, t_ratio, a.step, past)
            nxt = _advise(ms, pred, trusted, past, plan, repeats, a.res)
    unit = next((r.time_unit for r in reversed(records) if r.measurement is not None), None)
    duration, dt, why = _record_advice(last, nxt, pred, unit)
    if pred is not None:
        flags.extend(pred.flags)
        cls = pred.classification
        if cls is not None:  # one mu* per document: the classification names the prediction's
            cls = replace(cls, mu_star=pred.mu_star, mu_star_std=pred.mu_star_std)
        pred = replace(pred, alarm=alarm, next_safe_mu=nxt.mu if nxt is not None else math.nan,
                       classification=cls)  # fmt: skip
    return PolicyUpdate(
        measurements=tuple(ms), n_records=len(records), n_used=sum(
            1 for r in a.usable if r.measurement is not None),
        set_aside=tuple(a.aside), past=past, prediction=pred, alarm=alarm, next=nxt,
        trusted=trusted, converged=converged, record_duration=duration, record_dt=dt,
        record_advice=why, flags=tuple(unique_flags(flags)), fit_interval=interval,
    )  # fmt: skip


def _converged(
    a: _Answer, plan: SweepPlan, interval: tuple[float, float] | None,
    previous_interval: tuple[float, float] | None, nxt: NextMeasurement | None,
) -> tuple[bool, tuple[float, float] | None]:  # fmt: skip
    """Whether a trusted sweep converged, and the interval it converged on when that is not
    the records' own (the hull with the interval without the newest record; None: its own).

    An interval of no width, or one reaching down to the last record, is no convergence: the
    data say mu* may lie right there (a record read wrongly, or the lab at the transition);
    nor is a newest record set aside: it added no evidence (the same interval again)."""
    ms, recs = a.ms, a.recs
    last = ms[-1] if ms else None
    newest_used = bool(recs) and any(r.seq == recs[-1].seq for r in a.usable)
    if not (newest_used and interval is not None and interval[1] > interval[0] > last.mu):
        return False, None
    width = plan.target_width
    if width is None:
        width = TARGET_OF_SPAN * (ms[-1].mu - ms[0].mu)
    small = nxt is not None and (not math.isfinite(nxt.mu) or nxt.mu - last.mu < a.res)
    # narrow twice in a row: one record that narrows the interval suddenly is not enough
    narrow = interval[1] - interval[0] < width and previous_interval is not None and (
        previous_interval[1] - previous_interval[0] < width)  # fmt: skip
    hull = None
    if narrow and not a.unconfirmed:
        # the sweep stops on this answer: it must not rest on the newest record alone
        joined = _without_newest(recs, a.usable, a.past, plan, interval, last.mu, a.flags)
        hull = joined if joined != interval else None
    return bool(narrow or small), hull


def _alarm(
    ms: Sequence[Measurement], pred: Prediction | None, last_mu: float, t_ratio: float,
    step: float, past: float,
) -> Alarm:  # fmt: skip
    """The alarm of :func:`service.analysis.alarm.alarm_for` for the prediction so far."""
    has_pred = pred is not None and math.isfinite(pred.mu_star)
    return alarm_for(
        last_mu, t_ratio,
        pred.mu_star if has_pred else math.nan,
        tuple(pred.mu_star_interval) if has_pred else (math.nan, math.nan),
        step=step, span=(ms[-1].mu - ms[0].mu) if ms else math.nan,
        transition=pred.transition if pred is not None else None,
        past=past if math.isfinite(past) else math.nan,
    )  # fmt: skip


def _without_newest(
    recs: Sequence[SweepRecord], usable: Sequence[SweepRecord], past: float, plan: SweepPlan,
    interval: tuple[float, float], last_mu: float, flags: list[Flag],
) -> tuple[float, float]:  # fmt: skip
    """The converged interval: the hull of ``interval`` and the interval of the same usable
    records without the newest one (above the last stable control).

    The nearest record decides an extrapolated mu* almost alone (its leverage is close to 1):
    one record read a few standard errors off moves the answer by a few half-widths, and the
    sweep stops on that answer (docs/lab-guide.md, "The advice rule": measured on the 60
    sessions of bench/lab_session.py's lab)."""
    newest = recs[-1].seq if recs else None
    rest = [r for r in usable if r.seq != newest]
    ms = fit_points(rest)
    if len(ms) < MIN_RECORDS:
        return interval
    pred, _ = _predict(ms, plan.level)
    if pred is None or not math.isfinite(pred.mu_star):
        return interval
    lo, hi = bounded_by(pred, past).mu_star_interval
    if not (math.isfinite(lo) and math.isfinite(hi)):
        return interval
    hull = (max(min(interval[0], lo), last_mu), max(interval[1], hi))
    if hull != interval:
        flags.append(Flag(
            "converged_hull",
            f"converged: the interval [{interval[0]:.6g}, {interval[1]:.6g}] joined with "
            f"[{lo:.6g}, {hi:.6g}] from the records without the newest one, so that the answer "
            "does not rest on one record alone",
        ))  # fmt: skip
    return hull


class SweepPolicy:
    """The accumulator every door feeds: ``add(record) -> PolicyUpdate``, ``result()``.

    Parameters
    ----------
    plan : SweepPlan, optional
    records : sequence of SweepRecord, optional
        Records already in the sweep (a live sweep's stored ones: the last one's ``interval``
        is the trust test's previous interval).
    """

    def __init__(self, plan: SweepPlan | None = None, records: Sequence[SweepRecord] = ()) -> None:
        self.plan = plan or SweepPlan()
        self.records: list[SweepRecord] = list(records)
        self._last: PolicyUpdate | None = None
        self._stored = True  # every record's interval is the one assessed after it
        self._prev: tuple[float, float] | None | bool = (
            self.records[-1].interval if self.records else None
        )

    def append(self, record: SweepRecord) -> None:
        """Add a record without assessing the sweep (a batch's records; see :meth:`result`)."""
        self.records.append(replace(record, seq=len(self.records) + 1))
        self._last = None
        self._stored = False
        self._prev = False  # unknown: result() assesses the records but the last

    def add(
        self, record: SweepRecord, *, timings: dict[str, tuple[float, float]] | None = None
    ) -> PolicyUpdate:
        """Add one record and assess the sweep with it."""
        if self._prev is False:
            self._prev = self._interval_before_last() if self.records else None
        prev = self._prev
        self.records.append(replace(record, seq=len(self.records) + 1))
        u = evaluate(self.records, self.plan, previous_interval=prev, timings=timings)  # type: ignore[arg-type]
        self.records[-1] = replace(self.records[-1], interval=u.fit_interval,
                                   next_control=u.next_control)  # fmt: skip
        self._last, self._prev = u, u.fit_interval
        return u

    def _interval_before_last(self) -> tuple[float, float] | None:
        return evaluate(self.records, self.plan).fit_interval

    def result(self, *, strict: bool = False) -> PolicyUpdate:
        """The sweep after every record added (the last :meth:`add`'s update, or assessed
        here: the records but the last give the trust test's previous interval)."""
        if self._last is not None:
            return self._last
        prev = None
        if len(self.records) > 1:
            prev = (self.records[-2].interval if self._stored
                    else evaluate(self.records[:-1], self.plan).fit_interval)  # fmt: skip
        self._last = evaluate(self.records, self.plan, previous_interval=prev, strict=strict)
        return self._last


