"""The records of a sweep as the one sweep policy keeps them (:mod:`.sweep_policy`).

A record is its control, its measurement (the fundamental and static level), its flags, its
name and its detection. This module turns detections into records
(:func:`reduce_detection`, :func:`record_of`; :func:`unanalysed` for a record set aside before
detection), chooses each record's fundamental across the sweep
(:func:`service.analysis.reconcile.reconcile`), sorts the records into those the prediction
uses and those set aside with their reasons, and averages the records at one control into the
points of the fit (:func:`fit_points`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, Any

import numpy as np

from service.analysis.common import Flag
from service.analysis.measurement import Measurement, measurement_from_detection
from service.analysis.predictor.sweep import group_mean

if TYPE_CHECKING:
    from service.analysis.detect import Detection

__all__ = [
    "SetAside",
    "SweepRecord",
    "doubt_overdamped",
    "fit_points",
    "record_of",
    "reduce_detection",
    "file_unreadable",
    "samples_refused",
    "unanalysed",
]


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


def _reversed(ms: Sequence[Measurement]) -> bool:
    """The predictor refuses these points as a sweep that approaches its transition from above
    (:func:`service.analysis.predictor.sweep._check_direction`: the records slow down toward
    the lowest control); the same rule, so that the policy sees what the predictor would."""
    from service.analysis.errors import ParameterError
    from service.analysis.predictor.sweep import _check_direction

    if len(ms) < 2:
        return False
    try:
        _check_direction(np.array([m.mu for m in ms]), np.array([abs(m.sigma2) for m in ms]))
    except ParameterError:
        return True
    return False


def _odd_leading(
    usable: Sequence[SweepRecord],
) -> tuple[list[SweepRecord], list[SetAside]]:
    """The usable records without the few lowest controls that alone make the sweep read as
    one approached from above, with the reasons they are set aside.

    The predictor refuses a sweep whose records slow down toward its lowest control ("give
    -mu"). One odd first record (a heavily damped mode read as its fundamental) must not
    decide that for a sweep stepped up: the lowest ``k`` controls are set aside when every
    record at them is slower than every record above them, the records above soften toward
    the highest control (``|sigma^2|`` at the highest below its value at the lowest of them)
    and no longer read as approached from above, and the ``k`` controls are fewer than those
    above them. A sweep whose other records also slow down toward its lowest control is left
    to the predictor's refusal, which is then true."""
    ms = fit_points(usable)
    if not _reversed(ms):
        return list(usable), []
    y = [abs(m.sigma2) for m in ms]
    for k in range(1, len(ms)):
        rest = ms[k:]
        if len(rest) < 2 or k >= len(rest) or max(y[:k]) >= min(y[k:]):
            break
        if not y[-1] < y[k]:  # those above do not soften toward the top: no upward sweep
            break
        if _reversed(rest):  # the next lowest is as odd: try without it too
            continue
        odd = {m.mu for m in ms[:k]}
        a, b = rest[0], rest[-1]
        trend = (f"sqrt|sigma^2| {math.sqrt(y[k]):.6g} at control {a.mu:.6g} to "
                 f"{math.sqrt(y[-1]):.6g} at {b.mu:.6g}")  # fmt: skip
        aside = [
            SetAside(r.seq, r.control, r.name, (
                f"{_label(r)}: its fundamental (sqrt|sigma^2| = "
                f"{math.sqrt(abs(r.measurement.sigma2)):.6g}) is slower than every record at a "
                f"higher control, which soften toward the highest control ({trend}): it does "
                "not follow the sweep's line (another mode read as its fundamental, e.g. a "
                "heavily damped one) and does not decide the sweep's direction"))
            for r in usable if r.measurement.mu in odd
        ]  # fmt: skip
        return [r for r in usable if r.measurement.mu not in odd], aside
    return list(usable), []


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


#: An overdamped fundamental beside a ringing mode at least this many times stronger is in
#: doubt (the detector's own rule for a fundamental that does not ring beside a ringing mode
#: 3x stronger, ``detect._aside.AMBIG_WEAK``; it looks at ringing fundamentals only).
OVERDAMPED_DOUBT = 3.0


def doubt_overdamped(detection: Any) -> Any:
    """``detection`` with the flag ``fundamental_ambiguous`` when its fundamental is
    overdamped (a relaxation of two real poles: it does not oscillate) while a mode of the
    structure rings at least :data:`OVERDAMPED_DOUBT` times stronger: the structure's
    fundamental may be the ringing one (a heavily damped component, or the hammer's contact,
    read as the slowest mode). The flag is the detector's (every door reads it; the sweep-wide
    choice of the fundamental treats such a record first); unchanged otherwise."""
    f = getattr(detection, "fundamental", None)
    if f is None or f.mode.regime != "overdamped" or "fundamental_ambiguous" in {
            x.code for x in detection.flags}:  # fmt: skip
        return detection
    amp = f.mode.amplitude
    ring = [(j, m) for j, m in enumerate(detection.modes)
            if j != f.index and m.kind == "mode" and m.combination is None
            and m.regime == "underdamped" and m.amplitude >= OVERDAMPED_DOUBT * amp]  # fmt: skip
    if not ring:
        return detection
    j, m = max(ring, key=lambda jm: jm[1].amplitude)
    flag = Flag("fundamental_ambiguous", (
        f"the fundamental (sqrt|sigma^2| = {math.sqrt(abs(f.mode.sigma2)):.6g}) is overdamped "
        f"(two real poles: it does not oscillate) beside modes[{j}] (sqrt|sigma^2| = "
        f"{math.sqrt(abs(m.sigma2)):.6g}, {m.frequency:.6g} cycles/time) that rings "
        f"{m.amplitude / amp:.3g}x stronger: the structure's fundamental may be the ringing "
        "one. Check the record (a clean single kick), or give the band"))  # fmt: skip
    return replace(detection, flags=(*detection.flags, flag))


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


def file_unreadable(exc: Exception) -> str:
    """The reason a record is set aside when its file cannot be read (the reader's
    ``RecordingError``: a cell that is no number, an unknown format, a header that lies...);
    every door words it so (the batch sweep, ``snapwarn watch``, the live door)."""
    return f"its file cannot be read ({exc})"


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
