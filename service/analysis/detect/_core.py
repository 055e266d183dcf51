"""The door of the detector: validation, normalisation, the method table, the result."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from service.analysis.common import Flag
from service.analysis.detect._flags import _record_flags
from service.analysis.detect._methods import (
    ALIASES,
    METHOD_TABLE,
    METHODS,
    Options,
    Outcome,
    Record,
)
from service.analysis.detect._modes import _as_fundamental, _fundamental, _scaled, _trends
from service.analysis.detect._results import KINDS, MIN_SAMPLES, Detection
from service.analysis.detect._spectral import _spectrum, _welch_peaks
from service.analysis.errors import ParameterError


def _validate(
    w: Any, dt: Any, method: Any, kind: Any, max_modes: Any, common_damping: Any, max_iter: Any
) -> tuple[np.ndarray, float, str, str, int]:
    """Check every argument of :func:`detect`; raise :class:`ParameterError` naming it."""
    if not (isinstance(method, str) and method.lower() in METHODS):
        raise ParameterError(
            "method", method, f"method={method!r}: unknown, expected one of {', '.join(METHODS)}"
        )
    if kind not in KINDS:
        raise ParameterError(
            "kind", kind, f"kind={kind!r}: unknown, expected one of {', '.join(KINDS)}"
        )
    try:
        arr = np.asarray(w)
    except Exception as exc:  # pragma: no cover - numpy raises on ragged input
        raise ParameterError("w", None, f"w: cannot be read as an array ({exc})") from None
    if arr.dtype.kind not in "biuf":
        raise ParameterError(
            "w", str(arr.dtype), f"w: expected real numbers, got dtype {arr.dtype}"
        )
    arr = arr.astype(float, copy=False)
    if arr.ndim != 1:
        raise ParameterError("w", arr.shape, f"w: expected a 1-D array, got shape {arr.shape}")
    if arr.size < MIN_SAMPLES:
        raise ParameterError(
            "w", arr.size, f"w: too short ({arr.size} samples), need at least {MIN_SAMPLES}"
        )
    bad = ~np.isfinite(arr)
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise ParameterError(
            "w",
            float(arr[i]),
            f"w: {int(bad.sum())} non-finite sample(s), first at index {i} (value {arr[i]!r})",
        )
    if isinstance(dt, bool) or not isinstance(dt, (int, float, np.integer, np.floating)):
        raise ParameterError("dt", dt, f"dt={dt!r}: expected a positive number")
    if not (math.isfinite(float(dt)) and float(dt) > 0):
        raise ParameterError("dt", dt, f"dt={float(dt)!r}: must be finite and > 0")
    if max_modes is None:
        max_modes = 6
    if (
        isinstance(max_modes, bool)
        or not isinstance(max_modes, (int, np.integer))
        or not 1 <= int(max_modes) <= 20
    ):
        raise ParameterError(
            "max_modes",
            max_modes,
            f"max_modes={max_modes!r}: expected an integer from 1 to 20 or None",
        )
    if not isinstance(common_damping, (bool, np.bool_)):
        raise ParameterError(
            "common_damping", common_damping, f"common_damping={common_damping!r}: expected "
            "True or False"
        )  # fmt: skip
    if isinstance(max_iter, bool) or not isinstance(max_iter, (int, np.integer)) or max_iter < 0:
        raise ParameterError(
            "max_iter", max_iter, f"max_iter={max_iter!r}: expected an integer >= 0"
        )
    return arr, float(dt), method.lower(), kind, int(max_modes)


#: A pre-trigger: the record's first samples quiet (below ``_QUIET`` of the amplitude that
#: follows) for at least ``_LEAD`` of the record (and 16 samples) before the response rises
#: past ``_ONSET`` of its largest deviation.
_ONSET, _QUIET, _LEAD = 0.2, 0.05, 0.02
_SHARP = 4.0  # the lead-in at least this many times longer than the rise from _QUIET to _ONSET


def _pretrigger(arr: np.ndarray) -> int:
    """Index where the response starts after a quiet lead-in (a scope's pre-trigger, a strip
    at rest before the kick or a release), 0 when the record starts with it.

    ``d = |w - b|`` with ``b`` the median of the first samples. The response has begun at the
    first sample ``i0`` with ``d > _ONSET max(d)``; the lead-in is the samples before the first
    one above ``_QUIET`` times the largest ``d`` over ``[i0, 2 i0)``. A lead-in of at least
    ``_LEAD`` of the record, and ``_SHARP`` times longer than the rise, makes a pre-trigger;
    the analysis starts at ``i0`` (past the kick's rise). A record that starts with its
    response, drifts or rises smoothly has no such lead-in."""
    n = arr.size
    m = max(MIN_SAMPLES, int(_LEAD * n))
    if n < 4 * m:
        return 0
    d = np.abs(arr - float(np.median(arr[:m])))
    peak = float(d.max())
    if not peak > 0:
        return 0
    i0 = int(np.argmax(d > _ONSET * peak))
    if i0 < m or n - i0 < 2 * m:
        return 0
    after = float(d[i0 : min(n, 2 * i0)].max())
    quiet = int(np.argmax(d > _QUIET * after))  # samples before the rise
    # a kick rises from _QUIET to _ONSET within a few samples after a long quiet lead-in; a
    # record that starts smoothly (d from its first value growing as t or t^2) spends
    # about as long below _QUIET as rising past it
    return i0 if quiet >= m and quiet >= _SHARP * (i0 - quiet) else 0


def _cut_pretrigger(arr: np.ndarray, dt: float, kind: str) -> tuple[np.ndarray, int, Flag | None]:
    """The record from its kick on (an impulse record's pre-trigger cut, :func:`_pretrigger`),
    the index it starts at, and the flag that says so (None: nothing cut)."""
    start = _pretrigger(arr) if kind == "impulse" else 0
    if not start:
        return arr, 0, None
    return arr[start:], start, Flag(
        "pretrigger",
        f"the record is quiet for its first {start} samples (to t = {start * dt:.6g} from its "
        "first sample) before the response: a pre-trigger, or the strip at rest before the "
        "kick; analysed from there (amplitudes and phases at that sample)",
    )


_SAFE = (2.0**-400, 2.0**400)  # magnitudes whose squares summed over any record stay finite


def _prepare(arr: np.ndarray, kind: str, max_modes: int) -> Record | None:
    """Normalise the record: outside ``2^-400 .. 2^400`` divide it by a power of two (exact, so
    that no square overflows or underflows at any finite magnitude), remove the mean, and for
    ambient records take the autocorrelation; ``y`` has rms 1. A constant record gets
    ``scale = 0``."""
    peak = max(float(arr.max()), -float(arr.min()))
    unit = 1.0
    if peak > 0 and not _SAFE[0] < peak < _SAFE[1]:
        unit = math.ldexp(1.0, math.frexp(peak)[1])
    a = arr / unit if unit != 1.0 else arr
    N0 = a.size
    mean = float(np.mean(a))
    x = a - mean
    flags: list[Flag] = []
    static_std = None
    acf0 = 0.0
    if kind == "ambient":
        n_l = N0 // 2
        nfft = 1 << int(math.ceil(math.log2(2 * N0)))
        F = np.fft.rfft(x, nfft)
        acf = np.fft.irfft(F * np.conj(F), nfft)[: n_l + 1] / N0
        acf0 = float(acf[0])
        # keep the informative lags: up to 1.5x the last one above 5x the tail's rms
        tail = acf[n_l // 2 :]
        tail_rms = float(np.sqrt(np.mean(tail * tail))) if tail.size else 0.0
        loud = np.flatnonzero(np.abs(acf[1:]) > 5.0 * tail_rms)
        n_cut = int(1.5 * (loud[-1] + 1)) if loud.size else MIN_SAMPLES
        n_cut = int(min(max(n_cut, 4 * MIN_SAMPLES), n_l))
        y_raw = acf[1 : n_cut + 1]
        # the estimation errors of an autocorrelation are correlated: cap the model order at
        # the number of resolved peaks of the record's averaged (Welch) spectrum
        max_modes = min(max_modes, max(_welch_peaks(x), 1))
        nb = 16
        bm = x[: (N0 // nb) * nb].reshape(nb, -1).mean(axis=1)
        static_std = float(np.std(bm, ddof=1) / math.sqrt(nb))
        n_seg = int(min(8, N0 // (4 * n_cut)))
        flags.append(
            Flag(
                "ambient",
                f"modes fitted to the autocorrelation (lags 1 to {n_cut}); amplitudes are in "
                f"variance units; standard errors from the scatter over {max(n_seg, 0)} "
                "segments of the record" + (" (too few: rough)" if n_seg < 4 else ""),
            )
        )
    else:
        y_raw = x
    scale = float(np.sqrt(np.mean(y_raw * y_raw)))
    tiny = np.finfo(float).tiny * 1e6
    if not math.isfinite(scale) or scale <= tiny or scale <= 1e-14 * max(abs(mean), tiny):
        return Record(x, x, 0.0, mean, unit, kind, max_modes, _spectrum(0.0 * x), flags=flags)
    y = y_raw / scale
    return Record(x, y, scale, mean, unit, kind, max_modes, _spectrum(y), acf0, static_std, flags)


def detect(
    w: Any,
    *,
    dt: float,
    method: str = "auto",
    kind: str = "impulse",
    max_modes: int | None = None,
    common_damping: bool = False,
    check_linearity: bool = True,
    max_iter: int = 50,
) -> Detection:
    """Detect the modes (poles) of a uniformly sampled record.

    Parameters
    ----------
    w : array_like, shape (N,)
        The record: absolute position, including the static offset. ``N >= 16``; any finite
        magnitude (the record is normalised inside, so the result is equivariant under
        ``w -> k w``).
    dt : float
        Sample step (> 0), in the record's own time unit; every output rate is per that unit
        (equivariant under ``t -> c t``: rates scale as ``1/c``).
    method : {"auto", "varpro", "esprit", "fft", "fft-parabolic"}
        See the package documentation; ``"auto"`` is ``"varpro"``.
    kind : {"impulse", "ambient"}
        Free decay after a kick, or a noise-driven record (its autocorrelation is analysed).
    max_modes : int or None
        Largest number of modes (pole pairs) kept, 1 to 20 (default 6).
    common_damping : bool
        Impose one decay rate ``gamma = xi/2`` on every mode (the beam model); parametric
        methods only.
    check_linearity : bool
        Refit the two halves of the record and flag a drift of the fundamental (varpro only).
    max_iter : int
        Levenberg-Marquardt iteration cap (>= 0).

    Returns
    -------
    Detection
        Frozen result; ``service.convert.detection`` gives its wire document.

    Raises
    ------
    service.analysis.errors.ParameterError
        On a bad argument (a ``ValueError``); ``.parameter`` names it, ``.value`` echoes it.
    """
    arr, dt, method, kind, max_modes = _validate(
        w, dt, method, kind, max_modes, common_damping, max_iter
    )
    resolved = ALIASES.get(method, method)
    arr, start, lead = _cut_pretrigger(arr, dt, kind)
    rec = _prepare(arr, kind, max_modes)
    if lead is not None:
        rec.flags.append(lead)
    opts = Options(max_modes, bool(common_damping), int(max_iter), bool(check_linearity))
    if rec.scale == 0.0:
        rec.flags.append(
            Flag(
                "no_mode",
                f"the record is constant (value {rec.mean * rec.unit:.6g}): no mode to detect",
            )
        )
        out = Outcome([], 0.0, rec.mean, 0.0)
    else:
        out = METHOD_TABLE[resolved](rec, dt, opts)
    if rec.static_std is not None:
        out.static, out.static_std = rec.mean, rec.static_std
    trend = frozenset()
    if kind == "impulse":
        trend = _trends(out.modes, n=arr.size, dt=dt, noise_std=out.noise_std)
    modes, order = _fundamental(out.modes, n=arr.size, dt=dt, trend=trend)
    growth = None if out.growth is None else [out.growth[k] for k in order]
    trend_at = frozenset(i for i, k in enumerate(order) if k in trend)
    found = bool(modes) and 0 not in trend_at  # every mode a trend: no fundamental
    snr_db = _snr_db(modes if found else [], out, kind)
    f = rec.unit * rec.unit if kind == "ambient" else rec.unit
    modes = [_scaled(m, f) for m in modes]
    fund = _as_fundamental(modes) if found else None
    flags = rec.flags + out.flags
    u = rec.unit
    noise_std = out.noise_std * u
    if fund is None and rec.scale > 0:
        flags.append(
            Flag(
                "no_mode",
                f"no mode rises above the noise (noise std {noise_std:.3g}, "
                f"{arr.size} samples): the record looks like noise"
                + (" plus a slow trend (see the flag 'trend')" if trend_at else ""),
            )
        )
    flags += _record_flags(
        modes, n=arr.size, dt=dt, spec=rec.spec, static=out.static, static_std=out.static_std,
        growth=growth, trend=trend_at,
    )  # fmt: skip
    return Detection(
        modes=tuple(modes),
        fundamental=fund,
        static_level=out.static * u,
        static_level_std=out.static_std * u,
        flags=tuple(flags),
        method=resolved,
        noise_std=noise_std,
        snr_db=snr_db,
        n_samples=arr.size,
        dt=dt,
        kind=kind,
        iterations=out.iterations,
        start=start,
    )


def _snr_db(modes: list, out: Outcome, kind: str) -> float:
    """Per-sample SNR of the fundamental at the first sample, ``10 log10(A^2 / (2 s^2))``
    (ambient: response variance over measurement-noise variance); NaN without modes."""
    if not modes:
        return math.nan
    if kind == "ambient":
        power, npow = out.ambient_var, out.noise_std**2
    else:
        power, npow = 0.5 * modes[0].amplitude ** 2, out.noise_std**2
    if npow > 0 and power > 0:
        return float(np.clip(10 * math.log10(power / npow), -300.0, 300.0))
    return 300.0 if power > 0 else -300.0
