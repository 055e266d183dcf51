"""The early-warning pipeline: sweep the control upward, measure, classify, predict mu*.

``warn`` runs the paper's protocol (Discussion) on a simulator, as an experimenter would on a
strip: measure the impulse response at mu = 0, then at increasing mu, each record analysed by
the pole detector (sigma^2 = -s1 s2 of the fundamental, its error, the static level). As soon
as four points exist the predictor gives mu* with a 95 % interval; the next mu goes a fraction
of the way to the interval's lower end (never at or beyond it), so the steps shrink
geometrically as the alarm rises. It stops when the interval is narrow enough, the budget of
measurements is spent, or no safe step is left. The paper's rule is evaluated on the same
measurements for comparison.

The pipeline only sees what a sensor records: the record length and sampling of each
measurement are chosen from the previous detection
(:func:`service.analysis.sampling.next_record_sampling`: 40 periods, 50 samples per period of
the expected fundamental), never from the simulator's knowledge. ``sweep_from_signals`` is the
same analysis for records a lab uploads (any time unit, any control unit).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from service.analysis.alarm import Alarm, alarm_for
from service.analysis.common import Flag, unique_flags
from service.analysis.detect import Detection, detect
from service.analysis.errors import ParameterError
from service.analysis.measurement import Measurement
from service.analysis.predict import Prediction, paper_rule
from service.analysis.reconcile import set_aside
from service.analysis.sampling import PERIODS
from service.analysis.sweep_policy import (
    PolicyUpdate,
    SetAside,
    SweepPlan,
    SweepPolicy,
    doubt_overdamped,
    record_of,
    reduce_detection,
    samples_refused,
    unanalysed,
)

Progress = Callable[[float, str], None]

# the kick scales with the expected rate cubed: the response amplitude (~ kick / omega) then
# stays a fixed fraction of the well's width (~ (mu* - mu)^(1/2) ~ omega^2 near a fold, wider
# near a pitchfork), so the nonlinear frequency shift of a kicked record does not grow as mu*
# nears (with a constant amplitude the normal-form sweeps were biased by -2e-6, 7-11 standard
# errors; the simulators' noise is relative to the response, so the SNR is unchanged)
KICK_POWER = 3.0
#: The control resolution of a simulated sweep: a simulator sets any control, so ``warn``
#: converges only by the interval's width (a lab loop that wants ``warn``'s sweep gives the
#: same plan: ``step=first_step``, ``target_width=rel_width`` and this resolution)
SIMULATED_RESOLUTION = 1e-12


@dataclass(frozen=True)
class WarnResult:
    """Outcome of an early-warning sweep.

    Attributes
    ----------
    measurements : tuple of Measurement
    prediction : Prediction
        The final prediction (with its classification and the paper's rule).
    alarm : tuple of Alarm
        After each measurement: level, mu, T/T0, and (once predicted) mu*, the interval, and
        the distance to mu* in units of the interval half-width.
    stopped : str
        "converged" (interval narrow enough), "budget" (max measurements), "no-safe-step",
        or "snapped" (a measurement found no equilibrium: the sweep crossed mu*).
    truth : dict or None
        For simulated sweeps: the model's own mu* and transition (and the ``Resolution`` it
        was computed at), and the errors.
    flags : tuple of Flag
    detections : tuple of (Detection, float, str or None)
        Recorded sweeps: each record's detection, its control value and its name.
    set_aside : tuple of SetAside
        Records left out of the prediction, each with its reason and name.
    next_control : float
        The next safe control after the last record (NaN: none).
    record_duration, record_dt : float
        Suggested length and sample step of the next record (the records' time unit; NaN:
        no advice), as a live sweep advises them after the same records.
    record_advice : str
        How the record length was chosen (and whether it was bounded).
    """

    actuation: str | None
    model: str | None
    measurements: tuple[Measurement, ...]
    prediction: Prediction | None
    alarm: tuple[Alarm, ...]
    stopped: str
    truth: dict | None = None
    flags: tuple[Flag, ...] = ()
    detections: tuple[tuple[Detection, float, str | None], ...] = field(default=(), repr=False)
    set_aside: tuple[SetAside, ...] = ()
    next_control: float = math.nan
    record_duration: float = math.nan
    record_dt: float = math.nan
    record_advice: str = ""

    @property
    def n_set_aside(self) -> int:
        """Records set aside (``set_aside`` lists them with their reasons)."""
        return len(self.set_aside)


def result_of(
    u: PolicyUpdate,
    *,
    alarms: Sequence[Alarm | dict] = (),
    stopped: str = "done",
    detections: Sequence[tuple[Detection, float, str | None]] = (),
    extra_flags: Sequence[Flag] = (),
    actuation: str | None = None,
    model: str | None = None,
) -> WarnResult:
    """The sweep document's result from the policy's last update (the one prediction, alarm and
    advice of every door): ``alarms`` the alarm after each record, the last being ``u.alarm``."""
    return WarnResult(actuation, model, u.measurements, u.prediction, tuple(alarms) or (u.alarm,),
                      stopped, None, tuple(unique_flags([*u.flags, *extra_flags])),
                      tuple(detections), u.set_aside, u.next_control, u.record_duration,
                      u.record_dt, u.record_advice)  # fmt: skip


def warn(
    actuation: str,
    *,
    model: str = "euler-beam",
    damping: float = 2e-4,
    snr_db: float | None = 40.0,
    seed: int | None = None,
    max_measurements: int = 30,
    kick: float = 1e-2,
    first_step: float = 0.2,
    first_dt: float = 1e-3,
    first_duration: float = 2.0,
    rel_width: float = 2e-6,
    scene_options: dict | None = None,
    progress: Progress | None = None,
) -> WarnResult:
    """Run the early-warning sweep on a simulated strip.

    Parameters
    ----------
    actuation : {"asymmetric", "symmetric", "antisymmetric"}
    model : str
        Simulator backend (``sim.simulate``).
    damping : float
        xi of the simulated strip (the pipeline does not use it: it measures).
    snr_db : float or None
        Noise of every record (dB relative to the response power).
    seed : int or None
        Base seed; measurement k uses seed + k.
    max_measurements : int
        Budget of impulse responses (>= 5).
    kick : float
        Impulse at mu = 0; later kicks scale with the expected frequency cubed so that the
        response stays a fixed fraction of the shrinking well (see ``KICK_POWER``).
    first_step : float
        Control step while no prediction exists (control units).
    first_dt, first_duration : float
        Sampling of the first record (the calibration measurement at mu = 0).
    rel_width : float
        Stop when the 95 % interval is narrower than this (control units).
    scene_options : dict, optional
        Extra ``Scene`` fields (e.g. end_shortening for the Cosserat rod).
    progress : callable(fraction, message), optional
        Called after each measurement.
    """
    from sim import simulate
    from sim.scene import Scene

    if max_measurements < 5:
        raise ParameterError(
            "max_measurements",
            max_measurements,
            f"max_measurements must be >= 5, got max_measurements={max_measurements!r}",
        )
    if not (math.isfinite(first_step) and first_step > 0):
        raise ParameterError(
            "first_step", first_step, f"first_step must be > 0, got first_step={first_step!r}"
        )
    base = Scene(actuation=actuation, mu=0.0, damping=damping, kick=kick, snr_db=snr_db,
                 **(scene_options or {}))  # fmt: skip
    policy = SweepPolicy(SweepPlan(step=first_step, target_width=rel_width,
                                   control_resolution=SIMULATED_RESOLUTION))  # fmt: skip
    alarm: list[Alarm] = []
    flags: list[Flag] = []
    u: PolicyUpdate | None = None
    omega0 = math.nan
    stopped = "budget"
    mu_next, duration, dt, kick_k = 0.0, first_duration, first_dt, kick
    for k in range(max_measurements):
        scene = base.with_(mu=mu_next, duration=duration, dt=dt, kick=kick_k,
                           seed=None if seed is None else seed + k)  # fmt: skip
        try:
            sig = simulate(scene, model)
        except ValueError as exc:  # no stable equilibrium left: the strip snapped
            flags.append(Flag("snapped", f"no stable U_A equilibrium at mu={mu_next!r}: {exc}"))
            stopped = "snapped"
            break
        try:
            det = doubt_overdamped(detect(sig.w, dt=sig.dt))
        except ValueError as exc:
            flags.append(Flag("no_mode", str(exc)))
            stopped = "no-mode"
            break
        m, rflags = reduce_detection(det, mu_next, sig.t[-1], sig.dt)
        u = policy.add(record_of(mu_next, det, m, rflags))
        alarm.append(u.alarm)
        if m is not None and not math.isfinite(omega0):
            omega0 = m.omega
        if progress is not None:
            al = alarm[-1]
            msg = f"mu={mu_next:.6g} T/T0={al.t_ratio:.3g} alarm={al.level}"
            if math.isfinite(al.mu_star):
                lo, hi = al.mu_star_interval
                msg += f" mu*={al.mu_star:.8g} [{lo:.8g}, {hi:.8g}]"
            progress((k + 1) / max_measurements, msg)
        if u.converged:
            stopped = "converged"
            break
        cand = u.next_control
        # the advice may repeat the control just recorded (a record set aside there, or the
        # interval reaching down to it: more evidence where it is needed) or fill in below it
        # (repeats did not lift the interval), never go back otherwise
        back = u.next is not None and u.next.limited_by == "fill_in"
        if not (cand >= mu_next or back) or not math.isfinite(u.record_duration):
            stopped = "no-safe-step"
            break
        duration, dt = u.record_duration, u.record_dt
        kick_k = kick * min(1.0, (2 * math.pi / duration * PERIODS) / omega0) ** KICK_POWER
        mu_next = cand
    ms = list(u.measurements) if u is not None else []
    pred = u.prediction if u is not None else None
    if u is not None:
        flags = [*u.flags, *flags]
    truth = None
    try:  # the bifurcation of exactly the backend and resolution that were simulated
        from sim.backends import BACKENDS

        try:
            simulated = sig.model  # model="auto": the backend it picked
        except NameError:
            simulated = model
        b = BACKENDS[simulated].bifurcation(base)
        truth = {
            "mu_star": b.mu_star,
            "transition": b.transition,
            "model": b.model,
            "mu_star_error": b.mu_star_error,
            "resolution": b.resolution,
        }
    except Exception:  # noqa: BLE001 - the truth is a comparison, never a failure
        truth = None
    if truth is not None and pred is not None:
        truth["error"] = pred.mu_star - truth["mu_star"]
        lo, hi = pred.mu_star_interval
        truth["covered"] = bool(lo <= truth["mu_star"] <= hi)
        truth["transition_correct"] = pred.transition == truth["transition"]
        truth["max_mu_measured"] = max(m.mu for m in ms)
        if pred.baseline is not None:
            truth["baseline_error"] = pred.baseline.mu_star - truth["mu_star"]
    return WarnResult(actuation, model, tuple(ms), pred, tuple(alarm), stopped, truth,
                      tuple(unique_flags(flags)), (), u.set_aside if u is not None else (),
                      u.next_control if u is not None else math.nan,
                      *((u.record_duration, u.record_dt, u.record_advice) if u is not None
                        else ()))  # fmt: skip


def sweep_from_signals(
    records: Sequence[tuple[np.ndarray, float, float]],
    *,
    names: Sequence[str] | None = None,
    method: str = "auto",
    progress: Progress | None = None,
    plan: SweepPlan | None = None,
    options: Sequence[Mapping[str, Any] | None] | None = None,
    time_unit: str | None = None,
) -> WarnResult:
    """Detect every recorded signal, then classify and predict (the lab-data path).

    Parameters
    ----------
    records : sequence of (w, dt, control)
        Each record's samples (any length unit), its sample step (its own time unit) and its
        control value (any unit: degrees, newtons, volts...). Sorted by control here; records
        sharing a control value are averaged into one point by the predictor (flag
        ``repeated_points_averaged``).
    names : sequence of str, optional
        Labels for the per-record detections (e.g. file names).
    method : str
        Detector method.
    plan : SweepPlan, optional
        The sweep policy's options (the lab's step, margin, control resolution, the
        fundamental's band).
    options : sequence of mapping, optional
        Per record (the order of ``records``), the detector's lab options (``quantity``,
        ``start``, ``notch``) and ``exclude`` (True: the user leaves the record out; it is
        listed as set aside with that reason); ``unreadable`` (the reason a record's file could
        not be read: its ``w`` is None, it is set aside with that reason). A record whose
        samples the detector refuses (parameter ``w``: non-finite, too short, constant) is
        set aside with the detector's reason; the sweep goes on with the others.
    time_unit : str, optional
        The records' common time unit (their ``dt``'s), for the next record's advice as a
        live sweep gives it.
    """
    if options is not None and len(options) != len(records):
        raise ParameterError(
            "options", len(options), f"options must hold one entry per record ({len(records)}), "
            f"got {len(options)}"
        )  # fmt: skip
    if len(records) < 3:
        raise ParameterError(
            "records", len(records), f"records must hold at least 3 signals, got {len(records)}"
        )
    plan = plan or SweepPlan()
    order = np.argsort([float(r[2]) for r in records], kind="stable")
    policy = SweepPolicy(plan)
    dets: list[tuple[Detection, float, str | None]] = []
    for i, j in enumerate(order):
        w, dt, control = records[j]
        name = names[j] if names is not None else None
        opts = dict((options[j] or {}) if options is not None else {})
        exclude = bool(opts.pop("exclude", False))
        label = name or f"at control {control!r}"
        why = opts.pop("unreadable", None)
        if why is None:
            w = np.asarray(w, dtype=float)
            try:
                det = doubt_overdamped(detect(w, dt=float(dt), method=method, **opts))
            except ParameterError as exc:  # say which record; its samples: set it aside
                if exc.parameter != "w":
                    where = f"{name} (control {control!r})" if name else label
                    raise ParameterError(exc.parameter, exc.value,
                                         f"record {where}: {exc}") from None  # fmt: skip
                why = samples_refused(exc)
        if why is not None:
            policy.append(unanalysed(float(control), name, why))
            if progress is not None:
                progress((i + 1) / len(records), f"detected {i + 1}/{len(records)}")
            continue
        if exclude:
            det = set_aside(det, name or f"at control {control!r}", "excluded by the user")
        dets.append((det, float(control), name))
        m, rflags = reduce_detection(det, float(control), (w.size - 1) * float(dt), float(dt))
        policy.append(record_of(control, det, m, rflags, name=name, time_unit=time_unit))
        if progress is not None:
            progress((i + 1) / len(records), f"detected {i + 1}/{len(records)}")
    u = policy.result(strict=True)
    # after each record its slowdown; after the last, the policy's alarm (the alarm a user
    # reads is the one of warn and of a live sweep fed the same records)
    ms = u.measurements
    alarms = [alarm_for(m.mu, ms[0].omega / m.omega if m.omega > 0 else math.inf)
              for m in ms[:-1]]  # fmt: skip
    return result_of(u, alarms=[*alarms, u.alarm], stopped="done", detections=dets)


__all__ = ["SIMULATED_RESOLUTION", "WarnResult", "paper_rule", "result_of", "sweep_from_signals",
           "warn"]
