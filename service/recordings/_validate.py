"""From parsed arrays to a validated :class:`Recording` (the rules of the package docstring)."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from service.analysis.common import Flag
from service.recordings._errors import RecordingError, RecordingTooLarge
from service.recordings._record import (
    Recording,
    _positive_finite,
    _Raw,
    _representable_step,
    check_finite,
    to_f64,
    uniform_rtol_from_env,
)
from service.recordings._sampling import _uniform_grid


def from_arrays(
    w: Any,
    t: Any = None,
    dt: Any = None,
    t0: Any = None,
    *,
    uniform_rtol: float | None = None,
    resample: bool = False,
    max_samples: int | None = None,
    unit: str | None = None,
    value_unit: str | None = None,
    source: str = "arrays",
    w_name: str = "w",
    t_name: str = "t",
) -> Recording:
    """Validate samples given as arrays or lists: ``w`` with ``t`` (times) or ``dt`` (step).

    Parameters
    ----------
    w : array_like, shape (n,)
        Samples; finite numbers, at least 2.
    t : array_like, shape (n,), optional
        Sample times, strictly increasing, uniform within rounding (see the module notes).
    dt, t0 : float, optional
        Step and first time, when ``t`` is not given (``t0`` defaults to 0).
    uniform_rtol : float, optional
        Tolerance on the steps (relative); default :func:`uniform_rtol_from_env`.
    resample : bool
        Interpolate non-uniform times onto a uniform grid instead of refusing them.
    max_samples : int, optional
        Refuse more samples (:class:`RecordingTooLarge`).

    Raises
    ------
    RecordingError
        Naming the field (``w``, ``t[12]``, ``dt``...) and the value.
    """
    rtol = uniform_rtol_from_env() if uniform_rtol is None else float(uniform_rtol)
    return _validate(
        _Raw(w=w, t=t, unit=unit, value_unit=value_unit, source=source),
        dt=dt,
        t0=t0,
        rtol=rtol,
        resample=resample,
        max_samples=max_samples,
        w_name=w_name,
        t_name=t_name,
        dt_conflict=False,
    )


def _validate(
    raw: _Raw,
    *,
    dt: Any,
    t0: Any,
    rtol: float,
    resample: bool,
    max_samples: int | None,
    w_name: str = "w",
    t_name: str = "t",
    dt_conflict: bool = True,
) -> Recording:
    try:
        n_hint: int | None = len(raw.w)
    except TypeError:  # a scalar or an unsized object: to_f64 names it
        n_hint = None
    if max_samples is not None and n_hint is not None and n_hint > max_samples:
        raise RecordingTooLarge(
            w_name,
            n_hint,
            f"samples exceed the limit of {max_samples} (setting SNAPWARN_MAX_SAMPLES)",
        )
    wa = to_f64(w_name, raw.w)
    if wa.size < 2:
        raise RecordingError(w_name, wa.tolist(), f"must hold at least 2 samples, got {wa.size}")
    check_finite(w_name, wa)
    flags: tuple[Flag, ...] = _clipping(wa, w_name)
    if raw.t is not None:
        if dt is not None:
            why = (
                "must not be given: the file has its own sample times "
                f"({raw.metadata.get('time_column') or t_name}); drop dt or the time column"
                if dt_conflict
                else f"must not be given together with {t_name} (give one of them)"
            )
            raise RecordingError("dt", dt, why)
        ta = to_f64(t_name, raw.t)
        if ta.size != wa.size:
            raise RecordingError(
                t_name,
                f"{ta.size} samples",
                f"and {w_name} ({wa.size} samples) must have the same length",
            )
        check_finite(t_name, ta)
        wa, t_out, step, first, grid_flags = _uniform_grid(
            wa, ta, t_name=t_name, rtol=rtol, cells=raw.t_cells, resample=resample
        )
        flags += grid_flags
        if raw.dt is not None:  # a file with both t and dt: they must agree
            if abs(raw.dt - step) > max(rtol, 1e-9) * step and not grid_flags:
                raise RecordingError(
                    "file", f"dt={raw.dt!r}", f"disagrees with its own times (step {step!r})"
                )
        if t0 is not None:
            raise RecordingError("t0", t0, f"must not be given: the times come from {t_name}")
        _representable_step(f"{t_name} (its step)", step)
        return Recording(wa, t_out, step, first, raw.unit, raw.value_unit, raw.source, flags,
                         dict(raw.metadata))  # fmt: skip
    if raw.dt is not None:
        if dt is not None and dt_conflict:
            raise RecordingError(
                "dt", dt, f"must not be given: the file has its own step (dt = {raw.dt!r})"
            )
        step = _positive_finite("file: dt", raw.dt)
    elif dt is None:
        cols = raw.metadata.get("columns") or raw.metadata.get("variables")
        where = f" (found: {cols})" if cols else ""
        raise RecordingError(
            "dt", None, f"is required: the record has no sample times{where}; give its step dt"
        )
    else:
        step = _positive_finite("dt", dt)
    t0f = 0.0 if t0 is None else float(t0)
    if not math.isfinite(t0f):
        raise RecordingError("t0", t0f, "must be finite")
    return Recording(wa, None, step, t0f, raw.unit, raw.value_unit, raw.source, flags,
                     dict(raw.metadata))  # fmt: skip


#: A record is flagged ``clipped`` when its largest (or smallest) value is held in at least
#: this many separate runs: a decaying response reaches its extreme once; a saturated sensor
#: or ADC holds every clipped peak at the same value.
CLIP_RUNS = 3


def _clipping(w: np.ndarray, w_name: str) -> tuple[Flag, ...]:
    """The ``clipped`` flag when the record's extremes look saturated (see :data:`CLIP_RUNS`)."""
    if w.size < 3 * CLIP_RUNS or float(w.max()) == float(w.min()):
        return ()
    found = []
    for side, level in (("maximum", float(w.max())), ("minimum", float(w.min()))):
        at = w == level
        runs = int(np.count_nonzero(at[1:] & ~at[:-1])) + int(at[0])
        if runs >= CLIP_RUNS and int(at.sum()) >= 2 * runs:
            found.append(f"its {side} {level:.6g} is held in {runs} separate runs "
                         f"({int(at.sum())} samples)")  # fmt: skip
    if not found:
        return ()
    return (
        Flag(
            "clipped",
            f"{w_name} looks saturated: " + "; ".join(found) + ". A sensor or converter at the "
            "end of its range (or a very coarse quantisation) flattens the peaks, which shifts "
            "the fitted frequencies and damping; record with more range",
        ),
    )
