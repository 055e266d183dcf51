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
"""

from __future__ import annotations

import math
import threading
import time
from collections import OrderedDict
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, Any

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
from service.analysis.measurement import Measurement, measurement_from_detection
from service.analysis.predict import Prediction, bounded_by, predict
from service.analysis.predictor.sweep import group_mean
from service.analysis.sampling import PERIODS, mains_clear_dt, next_record_sampling

if TYPE_CHECKING:
    from service.analysis.detect import Detection

__all__ = [
    "MIN_RECORDS",
    "PolicyUpdate",
    "SetAside",
    "SweepPlan",
    "SweepPolicy",
    "SweepRecord",
    "evaluate",
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
#: Default control resolution: this fraction of the lab's step, unless the controls are
#: written with fewer decimals.
RESOLUTION_OF_STEP = 1e-4


@dataclass(frozen=True)
class SweepPlan:
    """How a sweep advises (control units throughout).

    Attributes
    ----------
    step : float or None
        The lab's step: the largest step before the interval is trusted, and the unit the
        alarm counts danger in. Default: the largest step between the records so far (and
        then a step grows at most ``max_step_growth`` times the last one).
    margin : float
        Distance kept below the safe bound on mu* (>= 0).
    target_width : float or None
        ``converged`` once the trusted interval is narrower after two records in a row;
        default :data:`TARGET_OF_SPAN` times the controls travelled.
    control_resolution : float or None
        The finest control step the lab can set: ``converged`` once the advised step is
        smaller, and no side of the interval is nearer mu* than half of it (flag
        ``resolution_floor``). Default: the decimals the controls are written with, at least
        ``1e-4 * step`` (:func:`resolution`).
    step_fraction : float
        Fraction of the room to the bound that a step takes, in (0, 1).
    max_step_growth : float or None
        A step is at most this multiple of the previous one. Default: none with ``step`` (the
        cap is the step), 2 without.
    method : str
        Detector method.
    level : float
        Confidence level of the interval.
    band : (lo, hi) or None
        The user's band for the fundamental's ``sqrt|sigma^2|`` (rad per time unit of the
        records): each record's fundamental is its slowest mode inside
        (:func:`service.analysis.reconcile.reconcile`).
    """

    step: float | None = None
    margin: float = 0.0
    target_width: float | None = None
    control_resolution: float | None = None
    step_fraction: float = 0.5
    max_step_growth: float | None = None
    method: str = "auto"
    level: float = 0.95
    band: tuple[float, float] | None = None

    def __post_init__(self) -> None:
        if self.band is not None:
            lo, hi = (float(v) for v in self.band)
            if not (math.isfinite(lo) and math.isfinite(hi) and 0 <= lo < hi):
                msg = f"band must be finite 0 <= lo < hi, got {self.band!r}"
                raise ParameterError("band", list(self.band), msg)
        for name in ("step", "target_width", "control_resolution"):
            v = getattr(self, name)
            if v is not None and not (math.isfinite(v) and v > 0):
                raise ParameterError(name, v, f"{name} must be > 0, got {name}={v!r}")
        if not (math.isfinite(self.margin) and self.margin >= 0):
            raise ParameterError(
                "margin", self.margin, f"margin must be finite and >= 0, got margin={self.margin!r}"
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
class SweepRecord:
    """One record of a sweep as the policy keeps it (a live sweep stores it).

    Attributes
    ----------
    seq : int
        Position in arrival order (1, 2, ...).
    control : float
        Control value the record was taken at (user unit).
    measurement : Measurement or None
        Its fundamental and static level; None when the detector found none, or it grew.
    flags : tuple of Flag
        Record flags (``past_transition``, ``no_mode``, ``out_of_order``, ``repeated_control``,
        ``past_safe_value``, ``record_set_aside``).
    interval : tuple of float or None
        The records' own interval of mu* after this record (``PolicyUpdate.fit_interval``,
        never a converged hull): the next update's trust test compares with it, as a batch
        compares with the interval of its records but the last.
    next_control : float
        The control advised after this record (NaN: none).
    time_unit : str or None
        The time unit of its measurement.
    name : str or None
        The record's name (file name) for the reasons a record is set aside.
    detection : Detection or None
        Its detection, for the sweep-wide choice of the fundamental (not stored).
    """

    seq: int
    control: float
    measurement: Measurement | None
    flags: tuple[Flag, ...] = ()
    interval: tuple[float, float] | None = None
    next_control: float = math.nan
    time_unit: str | None = None
    name: str | None = None
    detection: Detection | None = field(default=None, repr=False, compare=False)


@dataclass(frozen=True)
class SetAside:
    """A record left out of the prediction, with its reason."""

    seq: int
    control: float
    name: str | None
    reason: str


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


# ------------------------------------------------------------------------------ the records
def _label(r: SweepRecord) -> str:
    at = f"control {r.control:.6g}"
    return f"{r.name} ({at})" if r.name else f"the record at {at}"


def _reconciled(
    records: Sequence[SweepRecord], band: tuple[float, float] | None = None
) -> list[SweepRecord]:
    """The records with each fundamental chosen across the sweep
    (:func:`service.analysis.reconcile.reconcile`), when it exists and every record with a
    measurement kept its detection (a record set aside before detection has none); else the
    records as they are."""
    try:
        from service.analysis.reconcile import reconcile
    except ImportError:  # the sweep-wide choice has not landed: each record's own fundamental
        return list(records)
    # a record without a detection (a file that could not be read, a record stored without
    # it) keeps its own reading; the others are chosen together
    have = [r for r in records if r.detection is not None]
    if not have or any(r.detection is None and r.measurement is not None for r in records):
        return list(records)
    dets = reconcile(
        [r.detection for r in have],
        np.array([r.control for r in have], dtype=float),
        names=[r.name or f"#{r.seq}" for r in have],
        band=band,
    )
    chosen = dict(zip((id(r) for r in have), dets, strict=True))
    out = []
    for r in records:
        d = chosen.get(id(r))
        if d is None:
            out.append(r)
            continue
        if d is r.detection:
            out.append(r)
            continue
        m = r.measurement
        flags = tuple(f for f in d.flags if f.code == "record_set_aside")
        try:
            dur = m.duration if m is not None else (d.n_samples - 1) * d.dt
            dt = m.dt if m is not None else d.dt
            m = measurement_from_detection(r.control, d, dur, dt)
        except ValueError:
            m = None
        out.append(replace(r, measurement=m, flags=r.flags + flags, detection=d))
    return out


def _sort_out(
    records: Sequence[SweepRecord],
) -> tuple[list[SweepRecord], list[SetAside], float, list[float], int]:
    """(usable records, set aside, lowest control past the transition, its left-out controls,
    the number of records that grew with no stable record at or above their control)."""
    aside: list[SetAside] = []
    usable: list[SweepRecord] = []
    grew: list[SweepRecord] = []
    for r in records:
        m = r.measurement
        codes = {f.code for f in r.flags} | {f.code for f in (m.flags if m is not None else ())}
        why = next((f.message for f in (*r.flags, *(m.flags if m else ()))
                    if f.code == "record_set_aside"), None)  # fmt: skip
        if "past_transition" in codes:  # it grew: evidence of the transition, not a doubt
            grew.append(r)
        elif why is not None:
            aside.append(SetAside(r.seq, r.control, r.name, why))
        elif m is None:
            msg = next((f.message for f in r.flags if f.code == "no_mode"), "no fundamental found")
            aside.append(SetAside(r.seq, r.control, r.name, f"{_label(r)}: {msg}"))
        elif not (math.isfinite(m.sigma2) and m.sigma2 < 0):
            aside.append(SetAside(r.seq, r.control, r.name, (
                f"{_label(r)}: its fundamental has sigma2 = {m.sigma2:.4g} >= 0 (no stable mode) "
                "and the record does not grow: it cannot enter the sweep")))  # fmt: skip
        else:
            usable.append(r)
    top = max((r.control for r in usable), default=-math.inf)
    past = math.inf
    n_grew = 0
    for r in grew:  # a record that grew at or below a stable one is contradicted by it
        if r.control <= top:
            n = sum(u.control >= r.control for u in usable)
            aside.append(SetAside(r.seq, r.control, r.name, (
                f"{_label(r)} grows (flag unstable) but {n} stable record(s) lie at or above "
                "its control: it is not past the transition")))  # fmt: skip
        else:
            past = min(past, r.control)
            n_grew += 1
    beyond = [r.control for r in usable if r.control >= past]
    usable = [r for r in usable if r.control < past]
    aside.sort(key=lambda a: a.seq)
    return usable, aside, past, beyond, n_grew


def fit_points(records: Sequence[SweepRecord]) -> list[Measurement]:
    """The measurements of the usable records, one per control in increasing control: the
    records at one control averaged as the predictor averages a table's repeated rows
    (:func:`service.analysis.predictor.sweep.group_mean`: weights ``1/std^2`` when every record
    has its std, else plain means)."""
    ms = sorted((r.measurement for r in records if r.measurement is not None), key=lambda m: m.mu)
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


def _growth(
    pred: Prediction | None, ms: Sequence[Measurement], past: float, n_beyond: int,
    n_grew: int, flags: list[Flag],
) -> tuple[Prediction | None, bool]:  # fmt: skip
    """The prediction with the records that grew (``past``: the lowest of them) taken in, and
    whether that growth is unconfirmed.

    One record that grew below the lower end of the interval the stable records give is
    unconfirmed (one record must not derail a sweep: a detector can read a spurious growing
    pole): the interval spans both readings, from the last stable control to its upper end,
    and the lab records again at that control. Two records that grew, or one the interval does
    not contradict, confirm the transition: mu* and the interval end at ``past`` (between the
    last stable record and ``past`` when the interval lay wholly above it)."""
    if not math.isfinite(past):
        return pred, False
    has_pred = pred is not None and math.isfinite(pred.mu_star)
    if has_pred and n_grew == 1 and ms and pred.mu_star_interval[0] > past:
        lo, hi = pred.mu_star_interval
        flags.append(Flag(
            "growth_unconfirmed",
            f"the record at control {past:.6g} grows (flag unstable), but the stable records "
            f"put mu* in [{lo:.6g}, {hi:.6g}], above it: one record is not enough; record "
            f"again at {past:.6g} (a second record that grows confirms the transition, a "
            "stable one sets this one aside); meanwhile the interval spans both readings",
        ))  # fmt: skip
        return replace(pred, mu_star_interval=(ms[-1].mu, hi)), True
    flags.append(Flag(
        "past_transition",
        f"the record at control {past:.6g} grows (flag unstable): the strip is unstable "
        f"there, past its transition (mu* < {past:.6g}); it"
        + (f" and the {n_beyond} record(s) beyond it are" if n_beyond else " is")
        + " left out of the prediction",
    ))  # fmt: skip
    if not has_pred:
        return pred, False
    out = bounded_by(pred, past)
    if pred.mu_star_interval[0] >= past and ms:  # the bracket the records give, not a point
        out = replace(out, mu_star_interval=(ms[-1].mu, past))
    return out, False


# ------------------------------------------------------------------------------- the policy
def lab_step(ms: Sequence[Measurement], plan: SweepPlan) -> float:
    """The lab's step: the plan's, else the largest step between the usable controls."""
    if plan.step is not None:
        return float(plan.step)
    mu = [m.mu for m in ms]
    return float(np.max(np.diff(mu))) if len(mu) >= 2 else math.nan


def _decimals(controls: Iterable[float]) -> float:
    """The finest decimal the controls are written with (0 when more than 9 decimals)."""
    controls = list(controls)  # (read once per decimal: a generator would be spent)
    for k in range(10):
        q = 10.0**-k
        if all(abs(c / q - round(c / q)) < 1e-6 for c in controls):
            return q
    return 0.0


def resolution(ms: Sequence[Measurement], plan: SweepPlan, step: float) -> float:
    """The control resolution: the plan's, else the decimals of the controls, at least
    :data:`RESOLUTION_OF_STEP` times the lab's step."""
    if plan.control_resolution is not None:
        return float(plan.control_resolution)
    floor = RESOLUTION_OF_STEP * step if math.isfinite(step) else 0.0
    return max(_decimals(m.mu for m in ms), floor)


def _advise(
    ms: Sequence[Measurement], pred: Prediction | None, trusted: bool, past: float,
    plan: SweepPlan,
) -> NextMeasurement | None:  # fmt: skip
    """The next control by :func:`service.analysis.alarm.next_measurement`: below the
    interval's lower end once the interval is evidence (no wider than the controls travelled),
    below the point estimate always, below a record that grew, below the sigma^4 bound until
    the interval is trusted; capped by the lab's step until then."""
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
        # stable there: repeat the record at that control (more evidence where it is needed)
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
    recs = _reconciled(records, plan.band)
    usable, aside, past, beyond, n_grew = _sort_out(recs)
    ms = fit_points(usable)
    t0, c0 = time.perf_counter(), time.process_time()
    pred, flags = _predict(ms, plan.level, strict)
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
    last = ms[-1] if ms else None
    t_ratio = ms[0].omega / last.omega if last is not None and last.omega > 0 else math.nan
    has_pred = pred is not None and math.isfinite(pred.mu_star)
    interval = tuple(pred.mu_star_interval) if has_pred else None
    fit_interval = interval  # the records' own (the hull below may join another to it)
    last_mu = last.mu if last is not None else (records[-1].control if records else math.nan)
    alarm = _alarm(ms, pred, last_mu, t_ratio, step, past)
    trusted = bool(
        has_pred and last is not None and previous_interval is not None
        and interval_trusted(interval, previous_interval, last.mu, t_ratio)
    )  # fmt: skip
    nxt = _advise(ms, pred if has_pred else None, trusted, past, plan)
    if unconfirmed:  # record again where the one record grew: it confirms or sets it aside
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
    # an interval of no width, or one reaching down to the last record, is no convergence: the
    # data say mu* may lie right there (a record read wrongly, or the lab at the transition)
    # ... nor is a newest record set aside: it added no evidence (the same interval again)
    newest_used = bool(recs) and any(r.seq == recs[-1].seq for r in usable)
    if trusted and newest_used and interval is not None and interval[1] > interval[0] > last.mu:
        width = plan.target_width
        if width is None:
            width = TARGET_OF_SPAN * (ms[-1].mu - ms[0].mu)
        small = nxt is not None and (not math.isfinite(nxt.mu) or nxt.mu - last.mu < res)
        # narrow twice in a row: one record that narrows the interval suddenly is not enough
        narrow = interval[1] - interval[0] < width and previous_interval is not None and (
            previous_interval[1] - previous_interval[0] < width)  # fmt: skip
        converged = bool(narrow or small)
        if narrow and not unconfirmed:
            # the sweep stops on this answer: it must not rest on the newest record alone
            hull = _without_newest(recs, usable, past, plan, interval, last.mu, flags)
            if hull != interval:
                pred = replace(pred, mu_star_interval=hull)
                alarm = _alarm(ms, pred, last_mu, t_ratio, step, past)
                nxt = _advise(ms, pred, trusted, past, plan)
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
            1 for r in usable if r.measurement is not None),
        set_aside=tuple(aside), past=past, prediction=pred, alarm=alarm, next=nxt,
        trusted=trusted, converged=converged, record_duration=duration, record_dt=dt,
        record_advice=why, flags=tuple(unique_flags(flags)), fit_interval=fit_interval,
    )  # fmt: skip


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


def _resolution_floor(
    pred: Prediction | None, ms: Sequence[Measurement], res: float, past: float,
    flags: list[Flag],
) -> Prediction | None:  # fmt: skip
    """The prediction with each side of its interval at least half the control resolution
    ``res`` (:func:`resolution`: the lab's, else its controls' grid) from mu*: a lab that sets
    its control to that resolution knows each control only to half of it, and so mu* (never
    below the last stable control, never above a record that grew: ``past``). Flag
    ``resolution_floor`` when it widens a side."""
    if not (res > 0) or pred is None or not math.isfinite(pred.mu_star) or not ms:
        return pred
    lo, hi = pred.mu_star_interval
    m, half = pred.mu_star, 0.5 * float(res)
    new = (max(min(lo, m - half), min(lo, ms[-1].mu)), max(hi, min(m + half, past)))
    if new == (lo, hi):
        return pred
    flags.append(Flag(
        "resolution_floor",
        f"the interval [{lo:.6g}, {hi:.6g}] is finer than the control resolution {res:.3g} "
        f"allows: each side is at least half of it from mu* (now [{new[0]:.6g}, "
        f"{new[1]:.6g}]); give control_resolution when your control is set more finely",
    ))  # fmt: skip
    return replace(pred, mu_star_interval=new)


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


def reduce_detection(
    detection: Any, control: float, duration: float, dt: float
) -> tuple[Measurement | None, tuple[Flag, ...]]:
    """A record's measurement and flags from its detection: a record that grows (flag
    ``unstable``) is past the transition, not a point of the sweep; one without a fundamental
    gets ``no_mode``; the detector's ``record_set_aside`` is kept as a record flag."""
    c = float(control)
    own = tuple(f for f in detection.flags if f.code == "record_set_aside")
    if "unstable" in {f.code for f in detection.flags}:
        return None, (*own, Flag(
            "past_transition",
            f"the record at control={c!r} grows (flag unstable): the strip is unstable there, "
            "past its transition; it is left out of the fit",
        ))  # fmt: skip
    try:
        m = measurement_from_detection(c, detection, duration, dt)
    except ValueError as exc:
        return None, (*own, Flag("no_mode", str(exc)))
    return m, own


def samples_refused(exc: Exception) -> str:
    """The reason a record is set aside when the detector refuses its samples (its
    ``ParameterError`` on ``w``: too short, non-finite)."""
    return f"its samples cannot be analysed ({exc})"


def unanalysed(control: float, name: str | None, why: str) -> SweepRecord:
    """A record set aside before detection (its file cannot be read, or the detector refuses
    its samples): flag ``record_set_aside`` naming it (its file's name) with ``why``; it has no
    measurement and no detection, and the other records answer (every door alike)."""
    label = name or f"at control {float(control)!r}"
    flag = Flag("record_set_aside", f"record {label} set aside: {why}")
    return SweepRecord(0, float(control), None, (flag,), name=name)


def record_of(
    control: float, detection: Any, measurement: Measurement | None, flags: Sequence[Flag] = (),
    *, name: str | None = None, time_unit: str | None = None,
) -> SweepRecord:  # fmt: skip
    """A record for the policy from one detection and its measurement."""
    return SweepRecord(0, float(control), measurement, tuple(flags), name=name,
                       time_unit=time_unit, detection=detection)  # fmt: skip
