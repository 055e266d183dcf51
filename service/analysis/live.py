"""A live sweep: a lab adds one record at a time and asks where it may go next.

This is :func:`service.analysis.pipeline.warn` turned inside out: the experiment drives itself
and every record arrives with its control value. Each update detects the new record
(:func:`service.analysis.detect.detect`) and feeds it, with the records so far, to the one sweep
policy (:mod:`service.analysis.sweep_policy`, the one ``warn`` and the batch sweep use): records
that cannot be trusted are set aside with their reason (the sweep recovers at the next good
record), the rest are averaged per control and predicted from three distinct controls on; the
alarm and the next safe control follow (:mod:`service.analysis.alarm`).

The lab may do something else than advised: a record at or below a control already measured
(``out_of_order``, ``repeated_control``) or beyond the last advised value (``past_safe_value``)
is accepted and flagged, never reordered in the record list.

The module is pure numerics (numpy, the detector and the predictor); storing records, streaming
updates and the HTTP door live in ``service.api``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from service.analysis import sweep_policy
from service.analysis.alarm import Alarm, NextMeasurement
from service.analysis.common import Flag
from service.analysis.detect import Detection, detect
from service.analysis.errors import ParameterError
from service.analysis.measurement import Measurement
from service.analysis.pipeline import WarnResult
from service.analysis.predict import Prediction
from service.analysis.reconcile import set_aside
from service.analysis.sweep_policy import (
    SIGMA4_MIN_T_RATIO,
    PolicyUpdate,
    SetAside,
    SweepPlan,
    SweepPolicy,
    SweepRecord,
    fit_points,
)

__all__ = [
    "LivePlan",
    "LiveRecord",
    "LiveUpdate",
    "assess",
    "finish",
    "measure",
    "sweep_time_unit",
    "unreadable",
    "update",
    "update_unreadable",
]

#: How a live sweep advises: the sweep policy's plan.
LivePlan = SweepPlan
#: What a live sweep keeps of one record: the sweep policy's record.
LiveRecord = SweepRecord
#: Distinct usable controls before the predictor runs (the policy's).
MIN_PREDICT = sweep_policy.MIN_RECORDS
__all__ += ["MIN_PREDICT", "NOT_ANALYSED", "SIGMA4_MIN_T_RATIO"]
#: Relative tolerance when comparing a control value with the advised one.
_RTOL = 1e-12


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
        Records so far, and those in the fit.
    prediction : Prediction or None
        Classification and mu* with its interval; None below three usable controls or when
        the predictor fails.
    alarm : Alarm
    next : NextMeasurement or None
        The advised next control value (``next.mu``; NaN when no safe step is left); None
        when no advice is possible (one record and no ``step``).
    trusted : bool
        Whether the predictor's interval alone bounded the advice.
    converged : bool
        The lab may stop (:class:`service.analysis.sweep_policy.PolicyUpdate`).
    record_duration, record_dt : float
        Suggested length and sample step of the next record (the new record's time unit).
    flags : tuple of Flag
        Flags of the update (the policy's).
    set_aside : tuple of SetAside
        Records left out of the prediction, with their reasons.
    record_advice : str
        How the record length was chosen.
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
    set_aside: tuple[SetAside, ...] = ()
    record_advice: str = ""
    policy: PolicyUpdate | None = field(default=None, repr=False, compare=False)

    @property
    def next_control(self) -> float:
        """The advised next control value (NaN: none)."""
        return self.record.next_control

    @property
    def used_in_fit(self) -> bool:
        """The record is in the fit (not set aside, below any record that grew)."""
        return self.record.seq not in {a.seq for a in self.set_aside} and (
            self.record.measurement is not None
            and self.record.control < (self.policy.past if self.policy else math.inf)
        )

    @property
    def n_set_aside(self) -> int:
        """Records set aside."""
        return len(self.set_aside)


# ----------------------------------------------------------------------------------- steps
def measure(
    w: Any, *, dt: float, control: float, method: str = "auto",
    options: Mapping[str, Any] | None = None, name: str | None = None,
) -> tuple[Detection, Measurement | None, tuple[Flag, ...]]:  # fmt: skip
    """Detect one record and reduce it to the sweep's measurement
    (:func:`service.analysis.sweep_policy.reduce_detection`).

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
    options : mapping, optional
        The detector's lab options (``quantity``, ``start``, ``notch``) and ``exclude``
        (True: the user leaves the record out; it is set aside with that reason).
    name : str, optional
        The record's name (in the set-aside reason).

    Returns
    -------
    detection, measurement, flags
        ``measurement`` is None (flag ``no_mode``, ``past_transition`` or
        ``record_set_aside``) when the record gives no point of the sweep. A record whose
        samples the detector refuses (``w``: too short, non-finite) is set aside by name
        (flag ``record_set_aside`` with the reason) and its detection has no mode and method
        :data:`NOT_ANALYSED`; any other parameter the detector refuses raises.
    """
    c = float(control)
    if not math.isfinite(c):
        raise ParameterError("control", control, f"control must be finite, got {control!r}")
    arr = np.asarray(w, dtype=float)
    opts = dict(options or {})
    exclude = bool(opts.pop("exclude", False))
    try:
        det = sweep_policy.doubt_overdamped(detect(arr, dt=float(dt), method=method, **opts))
    except ParameterError as exc:
        if exc.parameter != "w":  # the request is wrong (dt, an option): the caller hears it
            raise
        # samples the detector refuses (too short, non-finite): set aside by name, as a batch
        # sweep sets them aside; the sweep goes on with the other records
        flag = sweep_policy.unanalysed(c, name, sweep_policy.samples_refused(exc)).flags
        return _not_analysed(arr.size, float(dt), method, flag), None, flag
    if exclude:
        det = set_aside(det, name or f"at control {c:.6g}", "excluded by the user")
    m, flags = sweep_policy.reduce_detection(det, c, (arr.size - 1) * float(dt), float(dt))
    return det, m, flags


def unreadable(
    control: float, why: str, *, name: str | None = None
) -> tuple[Detection, None, tuple[Flag, ...]]:
    """What :func:`measure` gives for a record whose file cannot be read at all: no
    measurement, flag ``record_set_aside`` naming the record (its file's name) with ``why``
    (:func:`service.analysis.sweep_policy.file_unreadable`), a detection without modes (method
    :data:`NOT_ANALYSED`, no samples). The sweep goes on with the other records, as a batch
    sweep sets such a file aside."""
    c = float(control)
    if not math.isfinite(c):
        raise ParameterError("control", control, f"control must be finite, got {control!r}")
    flag = sweep_policy.unanalysed(c, name, why).flags
    return _not_analysed(0, math.nan, NOT_ANALYSED, flag), None, flag


def sweep_time_unit(records: Sequence[LiveRecord], unit: str | None = None) -> str | None:
    """The sweep's time unit: its first record's that was read (a record whose file could not
    be read has none, and is skipped); ``unit`` (the new record's) before any."""
    return next((r.time_unit for r in records
                 if r.measurement is not None or r.time_unit is not None), unit)  # fmt: skip


#: The method of a record's detection when the detector refused its samples (no mode).
NOT_ANALYSED = "none"


def _not_analysed(n: int, dt: float, method: str, flags: tuple[Flag, ...]) -> Detection:
    """The detection document of a record whose samples could not be analysed: no mode, the
    reason in its flags."""
    nan = math.nan
    return Detection(modes=(), fundamental=None, static_level=nan, static_level_std=nan,
                     flags=flags, method=NOT_ANALYSED, noise_std=nan, snr_db=nan,
                     n_samples=int(n), dt=dt)  # fmt: skip


def _advised(previous: Sequence[LiveRecord], control: float) -> bool:
    """``control`` is the control advised after the last record (a fill-in below the largest
    control measured is the advice, not a lab going its own way)."""
    advised = previous[-1].next_control if previous else math.nan
    return math.isfinite(advised) and abs(control - advised) <= _RTOL * max(1.0, abs(advised))


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
    elif done and control < max(done) and not _advised(previous, control):
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
    name: str | None = None,
) -> LiveUpdate:
    """The warning after adding one measured record to ``previous`` (in arrival order): the
    sweep policy (:class:`service.analysis.sweep_policy.SweepPolicy`) fed the stored records
    and this one.

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
        Flags :func:`measure` returned (``no_mode``, ``past_transition``).
    timings : dict, optional
        Gets ``"predict"``: the (wall, CPU) seconds of the prediction.
    time_unit : str, optional
        The time unit of the record's measurement.
    name : str, optional
        The record's name (file name), for the reason it may be set aside.

    Returns
    -------
    LiveUpdate
    """
    plan = plan or LivePlan()
    control = float(control)
    rflags = _record_flags(previous, control, measurement, detection_flags)
    policy = SweepPolicy(plan, previous)
    # a record set aside before detection carries none into the sweep (as in a batch)
    kept = None if detection.method == NOT_ANALYSED else detection
    u = policy.add(
        LiveRecord(0, control, measurement, rflags, time_unit=time_unit, name=name,
                   detection=kept),
        timings=timings,
    )  # fmt: skip
    return LiveUpdate(
        record=policy.records[-1],
        detection=detection,
        n_records=u.n_records,
        n_used=u.n_used,
        prediction=u.prediction,
        alarm=u.alarm,
        next=u.next,
        trusted=u.trusted,
        converged=u.converged,
        record_duration=u.record_duration,
        record_dt=u.record_dt,
        flags=u.flags,
        set_aside=u.set_aside,
        record_advice=u.record_advice,
        policy=u,
    )


def update(
    previous: Sequence[LiveRecord],
    w: Any,
    *,
    dt: float,
    control: float,
    plan: LivePlan | None = None,
    options: Mapping[str, Any] | None = None,
    name: str | None = None,
    time_unit: str | None = None,
) -> LiveUpdate:
    """Detect a new record and assess the sweep with it (:func:`measure` then :func:`assess`):
    ``options`` the detector's lab options and ``exclude``, ``name`` the record's (file) name
    for the reasons it may be set aside, ``time_unit`` its time unit."""
    plan = plan or LivePlan()
    det, m, fl = measure(w, dt=dt, control=control, method=plan.method, options=options,
                         name=name)  # fmt: skip
    return assess(previous, det, m, control, plan=plan, detection_flags=fl, name=name,
                  time_unit=time_unit)  # fmt: skip


def update_unreadable(
    previous: Sequence[LiveRecord],
    control: float,
    why: str,
    *,
    plan: LivePlan | None = None,
    name: str | None = None,
    time_unit: str | None = None,
) -> LiveUpdate:
    """Assess the sweep with a record whose file cannot be read (:func:`unreadable`): it is
    kept, set aside by name with ``why``, and the other records answer."""
    det, m, fl = unreadable(control, why, name=name)
    return assess(previous, det, m, control, plan=plan, detection_flags=fl, name=name,
                  time_unit=time_unit)  # fmt: skip


def finish(records: Sequence[LiveRecord], *, plan: LivePlan | None = None,
           alarms: Sequence[dict] = (), stopped: str = "closed",
           update: LiveUpdate | None = None) -> WarnResult:  # fmt: skip
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
    update : LiveUpdate, optional
        The update after these same records (kept instead of assessing them again).
    """
    from service.analysis.pipeline import result_of

    u = update.policy if update is not None and update.policy is not None else None
    if u is None:
        u = SweepPolicy(plan, records).result()
    extra = [f for r in records for f in r.flags
             if f.code in ("out_of_order", "repeated_control", "past_safe_value")]  # fmt: skip
    return result_of(u, alarms=tuple(alarms) or (u.alarm,), stopped=stopped, extra_flags=extra)


def _fit_set(records: Sequence[LiveRecord]) -> list[Measurement]:
    """The points of the fit of these records (one per control; the policy's)."""
    return fit_points(sweep_policy._sort_out(records)[0])
