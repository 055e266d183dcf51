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
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

from service.analysis.alarm import Alarm, alarm_for, interval_trusted, next_measurement
from service.analysis.common import Flag
from service.analysis.detect import Detection, detect
from service.analysis.errors import ParameterError
from service.analysis.measurement import Measurement, measurement_from_detection
from service.analysis.predict import Prediction, bounded_by, paper_rule, predict
from service.analysis.sampling import PERIODS, next_record_sampling

Progress = Callable[[float, str], None]

# the kick scales with the expected rate cubed: the response amplitude (~ kick / omega) then
# stays a fixed fraction of the well's width (~ (mu* - mu)^(1/2) ~ omega^2 near a fold, wider
# near a pitchfork), so the nonlinear frequency shift of a kicked record does not grow as mu*
# nears (with a constant amplitude the normal-form sweeps were biased by -2e-6, 7-11 standard
# errors; the simulators' noise is relative to the response, so the SNR is unchanged)
KICK_POWER = 3.0


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


def _predict(
    ms: Sequence[Measurement], damping: float | None, *, strict: bool = False, least: int = 4
) -> Prediction | None:
    """The prediction from the measurements (None with fewer than ``least``); a table the
    predictor refuses gives None, or raises its ``ParameterError`` when ``strict`` (a lab's
    records: the user must hear why)."""
    if len({m.mu for m in ms}) < least:  # records repeating a control count once
        return None
    arr = lambda name: np.array([getattr(m, name) for m in ms])  # noqa: E731
    s2_std = arr("sigma2_std")
    try:
        return predict(
            arr("mu"),
            arr("sigma2"),
            sigma2_std=s2_std if np.all(np.isfinite(s2_std) & (s2_std > 0)) else None,
            w_static=arr("w_static"),
            w_static_std=np.maximum(arr("w_static_std"), 1e-15),
            damping=damping,
        )
    except ValueError:
        if strict:
            raise
        return None


def _t_ratio(ms: Sequence[Measurement]) -> float:
    return ms[0].omega / ms[-1].omega if ms[-1].omega > 0 else math.inf


def _alarm(ms: Sequence[Measurement], pred: Prediction | None) -> Alarm:
    """The alarm after the last measurement (:func:`service.analysis.alarm.alarm_for`)."""
    if pred is not None and math.isfinite(pred.mu_star):
        return alarm_for(ms[-1].mu, _t_ratio(ms), pred.mu_star, pred.mu_star_interval)
    return alarm_for(ms[-1].mu, _t_ratio(ms))


def _next_mu(
    ms: Sequence[Measurement], pred: Prediction | None, prev: Prediction | None, first_step: float
) -> tuple[float, bool]:
    """(next control value, whether the predictor's interval was trusted) by the one policy
    (:func:`service.analysis.alarm.next_measurement`): half the way to the safe bound, at most
    ``first_step``. The interval bounds the step once the slowdown has begun (T/T0 >= 2) and
    two consecutive intervals overlap; before that the model-free sigma^4 bound does (from four
    points and T/T0 >= 1.05: the first pairs, before the slowdown shows, can overshoot)."""
    last = ms[-1].mu
    trusted = (
        pred is not None and prev is not None
        and math.isfinite(pred.mu_star) and math.isfinite(prev.mu_star)
        and interval_trusted(pred.mu_star_interval, prev.mu_star_interval, last, _t_ratio(ms))
    )  # fmt: skip
    if len(ms) < 2:
        return last + first_step, False
    nxt = next_measurement(
        [m.mu for m in ms], [abs(m.sigma2) for m in ms],
        trusted_bound=pred.mu_star_interval[0] if (trusted and pred is not None) else None,
        step_fraction=0.5, max_step_growth=math.inf, max_step=first_step,
        min_t_ratio=1.05 if len(ms) >= 4 else math.inf, sigma4_when_trusted=False,
    )  # fmt: skip
    return nxt.mu, trusted


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
    ms: list[Measurement] = []
    alarm: list[Alarm] = []
    flags: list[Flag] = []
    pred: Prediction | None = None
    prev_pred: Prediction | None = None
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
            det = detect(sig.w, dt=sig.dt)
            m = measurement_from_detection(mu_next, det, sig.t[-1], sig.dt)
        except ValueError as exc:
            flags.append(Flag("no_mode", str(exc)))
            stopped = "no-mode"
            break
        ms.append(m)
        pred = _predict(ms, None)
        alarm.append(_alarm(ms, pred))
        if progress is not None:
            al = alarm[-1]
            msg = f"mu={m.mu:.6g} T/T0={al.t_ratio:.3g}"
            if math.isfinite(al.mu_star):
                lo, hi = al.mu_star_interval
                msg += f" mu*={al.mu_star:.8g} [{lo:.8g}, {hi:.8g}]"
            progress((k + 1) / max_measurements, msg)
        # next control value: a fraction of the way to a safe bound on mu*
        cand, trusted = _next_mu(ms, pred, prev_pred, first_step)
        prev_pred = pred
        if trusted and pred is not None:
            lo, hi = pred.mu_star_interval
            if hi - lo < rel_width:
                stopped = "converged"
                break
        if not cand > m.mu or cand - m.mu < 1e-12 * max(1.0, abs(m.mu)):
            stopped = "no-safe-step"
            break
        duration, dt = next_record_sampling(m, cand, pred)
        kick_k = kick * min(1.0, (2 * math.pi / duration * PERIODS) / ms[0].omega) ** KICK_POWER
        mu_next = cand
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
                      tuple(flags))  # fmt: skip


def sweep_from_signals(
    records: Sequence[tuple[np.ndarray, float, float]],
    *,
    names: Sequence[str] | None = None,
    method: str = "auto",
    progress: Progress | None = None,
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
    """
    if len(records) < 3:
        raise ParameterError(
            "records", len(records), f"records must hold at least 3 signals, got {len(records)}"
        )
    order = np.argsort([float(r[2]) for r in records], kind="stable")
    controls = [float(records[j][2]) for j in order]  # repeated: averaged by the predictor
    ms: list[Measurement] = []
    dets: list[tuple[Detection, float, str | None]] = []
    flags: list[Flag] = []
    past: list[float] = []  # controls of records that grow (the strip is unstable there)
    for i, j in enumerate(order):
        w, dt, control = records[j]
        w = np.asarray(w, dtype=float)
        name = names[j] if names is not None else None
        try:
            det = detect(w, dt=float(dt), method=method)
        except ParameterError as exc:  # say which record
            label = f"{name} (control {control!r})" if name else f"at control {control!r}"
            raise ParameterError(exc.parameter, exc.value, f"record {label}: {exc}") from None
        dets.append((det, float(control), name))
        if any(f.code == "unstable" for f in det.flags):
            past.append(float(control))
        elif not past:  # records beyond a growing one are past the transition too
            try:
                ms.append(measurement_from_detection(float(control), det, (w.size - 1) * dt, dt))
            except ValueError as exc:
                flags.append(Flag("no_mode", str(exc)))
        if progress is not None:
            progress((i + 1) / len(records), f"detected {i + 1}/{len(records)}")
    pred = _predict(ms, None, strict=True, least=3)
    if pred is None:
        flags.append(
            Flag(
                "too_few_records",
                f"{len(ms)} record(s) with a stable fundamental below the transition: a "
                "prediction needs at least 3",
            )
        )
    # after each record its slowdown; after the last, the final prediction as well (the
    # alarm a user reads is the one of warn and of a live sweep fed the same records)
    alarm = [_alarm(ms[: k + 1], pred if k == len(ms) - 1 else None) for k in range(len(ms))]
    if past:
        if pred is not None:
            pred = bounded_by(pred, past[0])
        flags.append(_past_flag(past, controls))
        alarm.append(_past_alarm(past[0], ms, pred))
    return WarnResult(None, None, tuple(ms), pred, tuple(alarm), "done", None, tuple(flags),
                      tuple(dets))  # fmt: skip


def _past_flag(past: Sequence[float], controls: Sequence[float]) -> Flag:
    """The sweep's flag for records that grow: the strip is unstable there (past mu*)."""
    beyond = [c for c in controls if c > past[0]]
    return Flag(
        "past_transition",
        f"the record at control={past[0]:.6g} grows (flag unstable): the strip is unstable "
        f"there, past its transition (mu* < {past[0]:.6g}); it"
        + (f" and the {len(beyond)} record(s) beyond it are" if beyond else " is")
        + " left out of the prediction",
    )


def _past_alarm(mu: float, ms: Sequence[Measurement], pred: Prediction | None) -> Alarm:
    """The alarm at a record that grows: critical, whatever the slowdown says."""
    t_ratio = _t_ratio(ms) if ms else math.nan  # (T has no meaning in a growing record)
    mu_star = pred.mu_star if pred is not None else math.nan
    interval = pred.mu_star_interval if pred is not None else (math.nan, math.nan)
    return Alarm(
        "critical",
        f"the record at mu={mu:.6g} grows: the strip is past its transition there",
        float(mu), float(t_ratio), float(mu_star), interval, math.nan,
    )  # fmt: skip


__all__ = ["WarnResult", "paper_rule", "sweep_from_signals", "warn"]
