"""The door of the detector: validation, normalisation, the method table, the result."""

from __future__ import annotations

import math
from dataclasses import replace
from typing import Any

import numpy as np

from service.analysis.common import Flag
from service.analysis.detect import _aside, _censored, _lab, _uncertainty
from service.analysis.detect._flags import _record_flags
from service.analysis.detect._methods import (
    ALIASES,
    METHOD_TABLE,
    METHODS,
    Options,
    Outcome,
    Record,
    _fit_parametric,
)
from service.analysis.detect._modes import (
    _as_fundamental,
    _combinations,
    _fundamental,
    _scaled,
    _trends,
    _waveform,
)
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
    return (
        arr[start:],
        start,
        Flag(
            "pretrigger",
            f"the record is quiet for its first {start} samples (to t = {start * dt:.6g} from its "
            "first sample) before the response: a pre-trigger, or the strip at rest before the "
            "kick; analysed from there (amplitudes and phases at that sample)",
        ),
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
        unit = math.ldexp(1.0, math.frexp(peak)[1] - 1)  # 2^1023 at most: never inf
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


QUANTITIES = ("displacement", "velocity", "acceleration")


def _validate_lab(
    quantity: Any, start: Any, notch: Any, n: int, dt: float
) -> tuple[str | None, float | None, np.ndarray]:
    """Check the lab options of :func:`detect`; notch frequencies as rad per sample."""
    if quantity is not None and quantity not in QUANTITIES:
        raise ParameterError(
            "quantity", quantity,
            f"quantity={quantity!r}: unknown, expected one of {', '.join(QUANTITIES)} or None",
        )  # fmt: skip
    if start is not None:
        ok = not isinstance(start, bool) and isinstance(start, (int, float, np.integer,
                                                                np.floating))  # fmt: skip
        if not ok or not (math.isfinite(float(start)) and 0 <= float(start)):
            raise ParameterError("start", start, f"start={start!r}: expected a time >= 0")
        if float(start) / dt > n - 4 * MIN_SAMPLES:
            raise ParameterError(
                "start", start, f"start={float(start)!r}: leaves fewer than {4 * MIN_SAMPLES} "
                f"samples of the record (duration {(n - 1) * dt:.6g})"
            )  # fmt: skip
        start = float(start)
    if notch is None:
        return quantity, start, np.zeros(0)
    try:
        f = np.atleast_1d(np.asarray(notch, dtype=float))
    except (TypeError, ValueError):
        raise ParameterError("notch", notch, f"notch={notch!r}: expected frequencies") from None
    nyq = 0.5 / dt
    if f.ndim != 1 or f.size > 16 or not np.all(np.isfinite(f) & (f > 0) & (f < nyq)):
        raise ParameterError(
            "notch", notch, f"notch={notch!r}: expected up to 16 frequencies in (0, {nyq:.6g}) "
            "(cycles per time unit of dt, below Nyquist)"
        )  # fmt: skip
    return quantity, start, 2 * math.pi * f * dt


def _window(
    arr: np.ndarray, dt: float, kind: str, start: float | None
) -> tuple[_lab.Window | None, int, Flag | None]:
    """The lab window of an impulse record (None: the record is read as before, from the
    pre-trigger cut :func:`_pretrigger`, which is returned with its flag)."""
    if kind != "impulse":
        return None, 0, None
    old = _pretrigger(arr) if start is None else 0
    win = _lab.locate(arr, dt, start=start)
    if old:
        win.start = win.lead = old
        win.quiet = True
        if win.stop <= old + 4 * MIN_SAMPLES:
            win.stop = arr.size
    if not (win.lead or win.kicks or win.n_clipped or win.user_start):
        return None, 0, None
    if win.lead and not win.user_start:
        win.flags.insert(
            0,
            Flag(
                "pretrigger",
                f"the record is quiet for its first {win.lead} samples (to t = "
                f"{win.lead * dt:.6g} from its first sample) before the response: a "
                "pre-trigger, or the strip at rest before the kick; analysed from "
                f"sample {win.start} (amplitudes and phases at that sample)",
            ),
        )
    if win.user_start:
        win.flags.insert(0, Flag("start_given", f"analysed from t = {win.start * dt:.6g} "
                                                "(the start given by the user)"))  # fmt: skip
    return win, win.start, None


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
    quantity: str | None = None,
    start: float | None = None,
    notch: Any = None,
) -> Detection:
    """Detect the modes (poles) of a uniformly sampled record.

    Parameters
    ----------
    w : array_like, shape (N,)
        The record: absolute position, including the static offset (or a velocity or an
        acceleration, see ``quantity``). ``N >= 16``; any finite magnitude (the record is
        normalised inside, so the result is equivariant under ``w -> k w``).
    dt : float
        Sample step (> 0), in the record's own time unit; every output rate is per that unit
        (equivariant under ``t -> c t``: rates scale as ``1/c``).
    method : {"auto", "varpro", "esprit", "fft", "fft-parabolic"}
        See the package documentation; ``"auto"`` is ``"varpro"``.
    kind : {"impulse", "ambient"}
        Free decay after a kick, or a noise-driven record (its autocorrelation is analysed).
    max_modes : int or None
        Largest number of modes (pole pairs) kept, 1 to 20 (default 6); stationary lines seen
        before the kick or given in ``notch`` come on top.
    common_damping : bool
        Impose one decay rate ``gamma = xi/2`` on every mode (the beam model); parametric
        methods only.
    check_linearity : bool
        Refit the two halves of the record and flag a drift of the fundamental (varpro only).
    max_iter : int
        Levenberg-Marquardt iteration cap (>= 0).
    quantity : {"displacement", "velocity", "acceleration"} or None
        What the sensor measures. Poles (frequencies, damping) come from any; the static level
        only from a displacement: for a velocity or an acceleration it is NaN (flag
        ``no_static_level``). None: a displacement, as before.
    start : float or None
        Time (from the first sample, time unit of ``dt``) where the free response starts,
        overriding the located kick (flag ``start_given``).
    notch : sequence of float or None
        Frequencies (cycles per time unit of ``dt``) of stationary lines (mains hum and its
        harmonics): fitted as lines (flag ``stationary_line``), never the fundamental.

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
    quantity, start, notch_w = _validate_lab(quantity, start, notch, arr.size, dt)
    resolved = ALIASES.get(method, method)
    win, first, _ = _window(arr, dt, kind, start)
    lead = arr[: win.lead] if win is not None and win.lead and not win.user_start else None
    hi = lo = None
    if win is None:
        arr, first, lead = _cut_pretrigger(arr, dt, kind)
        pre = [] if lead is None else [lead]
        seeds_w = notch_w
    else:
        seeds_w = np.concatenate((notch_w, _lab.lead_lines(arr, win.lead)))
        hi, lo = _lab.clipped_edges(arr, win)
        arr = arr[win.start : win.stop]
        pre = win.flags
    n_seeds = seeds_w.size if kind == "impulse" else 0
    seeds = (np.zeros(n_seeds), seeds_w[:n_seeds] ** 2) if n_seeds else None
    mm = min(20, max_modes + n_seeds)
    opts = Options(mm, bool(common_damping), int(max_iter), bool(check_linearity), seeds)
    # a lab's record (a lead-in with hum or drift on it, a second kick, clipping) is read with
    # its slope removed (the drift's ramp); a quiet lead-in alone is not
    detrend = win is not None and kind == "impulse" and not win.quiet
    if resolved != "varpro" or win is None:
        hi = lo = None
    raw = arr

    def fit(detrend: bool) -> tuple[np.ndarray, Record, Outcome]:
        """The window as fitted (its clipped samples censored: replaced by their expected
        values at the EM fit's convergence, module _censored) and its fit."""
        if hi is None or lo is None:
            return (raw, *_fit(raw, dt, kind, mm, resolved, opts, detrend))
        a, _ = _censored.fit_censored(
            raw, hi, lo, detrend=_detrended if detrend else (lambda v: v),
            first=lambda y: _fit_parametric(
                y, _spectrum(y), max_modes=mm, common=opts.common, refine=True,
                max_iter=opts.max_iter, seeds=opts.seeds)[0],
            max_modes=mm, max_iter=opts.max_iter,
        )  # fmt: skip
        return (a, *_fit(a, dt, kind, mm, resolved, opts, detrend))

    arr, rec, out = fit(detrend)
    cens = None if hi is None or lo is None else hi | lo
    lab = kind == "impulse" and (win is not None or resolved == "varpro")
    if not detrend and lab and _suspect(out.modes, arr.size * dt):
        # a growing or slow fundamental that is not kicked beside a ringing mode: refit with
        # the record's slope (a drift of the baseline) taken out, and use that fit
        detrend = True
        arr, rec, out = fit(detrend)
    if win is not None and resolved == "varpro" and rec.scale > 0 and out.modes:
        skip = _lab.forced_head(_residual(rec, out, dt), out.noise_std)
        if skip and arr.size - skip >= max(4 * MIN_SAMPLES, arr.size // 2):
            arr = arr[skip:]
            first += skip
            cens = None if cens is None else cens[skip:]
            rec, out = _fit(arr, dt, kind, mm, resolved, opts, detrend)
            pre = [*pre, Flag(
                "forced_part",
                f"the first {skip} samples after the kick are a forced response (the "
                "hammer's contact: the free-decay model misfits them, the rest fits); "
                f"analysed from sample {first}",
            )]  # fmt: skip
    rec.flags[:0] = pre
    base = (arr, lead) if win is not None and rec.scale > 0 else None
    lead_T = lead.size * dt if lead is not None else 0.0
    return _result(rec, out, arr.size, dt, kind, resolved, first, quantity, seeds_w / dt, lab,
                   base, lead_T, cens)


def _suspect(modes: list, T: float) -> bool:
    """Whether the slowest mode of a fit may be a drift rather than the fundamental: it grows
    (``sigma^2 >= 0`` or a growing envelope) beside a faster ringing mode
    (:func:`_aside._rings`)."""
    if len(modes) < 2:
        return False
    m0 = modes[0]
    if not (m0.sigma2 >= 0 or m0.damping < 0):
        return False
    if m0.regime == "overdamped" and _aside._from_rest(m0, T):
        return False  # a kicked growing mode (past the transition): the physics
    return any(_aside._rings(m, T) and abs(m.sigma2) > abs(m0.sigma2) for m in modes[1:])


def _detrended(arr: np.ndarray) -> np.ndarray:
    """The record with its least-squares slope removed (its mean kept): a drift's ramp."""
    n = arr.size
    u = np.arange(n, dtype=float) - 0.5 * (n - 1)
    slope = float(np.sum(u * (arr - arr.mean()))) / float(np.sum(u * u))
    return arr - slope * u


def _fit(
    arr: np.ndarray, dt: float, kind: str, max_modes: int, resolved: str, opts: Options,
    detrend: bool = False,
) -> tuple[Record, Outcome]:  # fmt: skip
    """Prepare the record (``detrend``: its slope removed first) and run the method."""
    rec = _prepare(_detrended(arr) if detrend else arr, kind, max_modes)
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
    return rec, out


def _residual(rec: Record, out: Outcome, dt: float) -> np.ndarray:
    """The record minus its fitted model (units of ``rec.x`` plus its mean)."""
    n = rec.x.size
    r = rec.x + rec.mean - out.static
    for m in out.modes:
        r = r - _waveform(m, n, dt)
    return r


def _result(
    rec: Record, out: Outcome, n: int, dt: float, kind: str, resolved: str, start: int,
    quantity: str | None, seeds: np.ndarray, lab: bool = True,
    base: tuple[np.ndarray, np.ndarray | None] | None = None, lead_T: float = 0.0,
    censored: np.ndarray | None = None,
) -> Detection:  # fmt: skip
    """The Detection of a fit: lines, drift and trends set aside, the fundamental, flags.
    ``lab``: tell lines, drift, transients and negligible growth (varpro, or a lab window:
    the initialisation-only and FFT methods on a plain record read as before); ``base``: a
    record read through a lab window (a lead-in, a later kick, clipped samples, the user's
    start): the window as given (no slope removed) and the lead-in before the kick (None:
    none), where the fundamental is checked for ambiguity and the baseline for drift;
    ``lead_T``: the duration of the lead-in before the kick (lines are looked for there);
    ``censored``: the window's clipped samples read as censored (None: none). On a lab
    window the standard errors are the sandwich's where larger (:mod:`._uncertainty`)."""
    trend = frozenset()
    lines = drift = tiny = transient = quiet = frozenset()
    if kind == "impulse":
        trend = _trends(out.modes, n=n, dt=dt, noise_std=out.noise_std)
        combos = frozenset(_combinations(out.modes))
        if lab:
            peak = float(np.max(np.abs(rec.x))) if rec.x.size else math.inf
            lines, drift, transient = _aside.lines_and_drift(out.modes, n * dt, seeds,
                                                           trend | combos, lead_T,
                                                           peak, base is not None)  # fmt: skip
            # the combination tones as the result lists them (stationary lines are no
            # parents): a component the first pass took for one (a hum line its parent) is
            # told from lines, drift and transients like any other
            final = frozenset(_combinations(out.modes, lines))
            if final != combos:
                lines, drift, transient = _aside.lines_and_drift(
                    out.modes, n * dt, seeds, trend | final, lead_T, peak, base is not None)
            quiet = _aside.quiet_lines(out.modes, n * dt, trend | final | lines | drift
                                       | transient)  # fmt: skip
            lines = lines | quiet
            if base is not None and base[1] is not None:
                # a slow component the lead-in already holds was not kicked: a drift
                before = _aside.before_kick(out.modes, n * dt, base[1] / rec.unit - rec.mean,
                                          start, dt, trend | lines | drift | transient,
                                          lines)  # fmt: skip
                drift = drift | before
            tiny = _aside.negligible_growth(out.modes, n * dt)
    # on a lab window, a slower component the fit cannot tell from nothing is no fundamental
    # beside a ringing mode the record shows (it stays a mode; the record is flagged)
    undet = frozenset()
    if base is not None and kind == "impulse":
        undet = _aside.undetermined(out.modes, n * dt,
                                    trend | lines | drift | transient | tiny
                                    | frozenset(_combinations(out.modes, lines)))  # fmt: skip
    side, bound = {}, None
    if base is not None and kind == "impulse":
        side, bound = _aside.sidebands(out.modes, n * dt, trend | lines | drift | transient | tiny
                                       | frozenset(_combinations(out.modes, lines)))  # fmt: skip
        undet = undet - set(side)
    modes, order = _fundamental(out.modes, n=n, dt=dt,
                                trend=trend | lines | drift | transient | undet, aside=lines,
                                sidebands=side)  # fmt: skip
    split_at = None
    if base is not None and modes:
        factors = _uncertainty.inflation(out.modes, _residual(rec, out, dt), dt,
                                         out.noise_std, censored)  # fmt: skip
        modes = [_uncertainty.inflated(m, factors[k]) for m, k in zip(modes, order)]
        if side and order[0] == next(iter(side.values()))[0]:
            modes[0] = _aside.comb_bounded(modes[0], None if bound is None else
                                           out.modes[bound])  # fmt: skip
        else:
            # a weak fundamental beside a much stronger line close to it (one line split in
            # several): the line lies between them
            rival = _aside.split_rival(out.modes, order[0], set(order[1:]) - (
                trend | lines | drift | transient | undet | set(side)))  # fmt: skip
            if rival is not None:
                modes[0] = _aside.comb_bounded(modes[0], out.modes[rival])
                split_at = order.index(rival)
    growth = None if out.growth is None else [out.growth[k] for k in order]
    at = {k: i for i, k in enumerate(order)}
    trend_at = frozenset(at[k] for k in trend)
    lines_at = frozenset(at[k] for k in lines)
    drift_at = frozenset(at[k] for k in drift)
    tiny_at = frozenset(at[k] for k in tiny)
    trans_at = frozenset(at[k] for k in transient)
    aside = trend_at | lines_at | drift_at | trans_at
    found = bool(modes) and 0 not in aside  # every mode set aside: no fundamental
    snr_db = _snr_db(modes if found else [], out, kind)
    f = rec.unit * rec.unit if kind == "ambient" else rec.unit
    modes = [_scaled(m, f) for m in modes]
    modes = [replace(m, kind="line") if i in lines_at else
             replace(m, kind="drift") if i in drift_at else
             replace(m, kind="transient") if i in trans_at else
             replace(m, kind="trend") if i in trend_at else m
             for i, m in enumerate(modes)]  # fmt: skip
    fund = _as_fundamental(modes) if found else None
    flags = rec.flags + out.flags
    u = rec.unit
    noise_std = out.noise_std * u
    if fund is None and rec.scale > 0:
        flags.append(
            Flag(
                "no_mode",
                f"no mode rises above the noise (noise std {noise_std:.3g}, "
                f"{n} samples): the record looks like noise"
                + (" plus a slow trend (see the flag 'trend')" if trend_at else "")
                + (" plus stationary lines" if lines_at else "")
                + (" plus a drift" if drift_at else ""),
            )
        )
    flags += _record_flags(
        modes, n=n, dt=dt, spec=rec.spec, static=out.static, static_std=out.static_std,
        growth=growth, trend=trend_at, aside=aside | tiny_at,
    )  # fmt: skip
    flags += _aside.aside_flags(modes, lines_at, drift_at, tiny_at, trans_at)
    doubt = _aside.ambiguity(modes, n * dt) if base is not None and fund is not None else None
    if side and fund is not None and order[0] == next(iter(side.values()))[0]:
        doubt = _aside.with_sidebands(doubt, modes, sorted(at[k] for k in side),
                                      None if bound is None else at[bound])  # fmt: skip
    if split_at is not None and fund is not None and doubt is not None:
        head, sep, tail = doubt.message.partition(". Check the record")
        doubt = Flag(doubt.code, f"{head}; its sigma^2 error is at least half its difference "
                                 f"from the stronger modes[{split_at}]{sep}{tail}")
    quiet_at = sorted(at[k] for k in quiet if fund is not None
                      and abs(out.modes[k].sigma2) < abs(fund.mode.sigma2))  # fmt: skip
    if quiet_at and fund is not None:
        doubt = _aside.with_quiet_lines(doubt, modes, quiet_at)
    undet_at = sorted(at[k] for k in undet if fund is not None
                      and abs(out.modes[k].sigma2) < abs(fund.mode.sigma2))  # fmt: skip
    if undet_at and fund is not None:
        doubt = _aside.with_undetermined(doubt, modes, undet_at)
    if doubt is not None:
        flags.append(doubt)
    static, static_std = out.static * u, out.static_std * u
    moved = None
    if base is not None and kind == "impulse" and quantity in (None, "displacement"):
        raw, lead = base
        r = raw / u - out.static
        for m in out.modes:
            r = r - _waveform(m, n, dt)
        peak = float(np.max(np.abs(raw / u - out.static))) if raw.size else 0.0
        peak = max(peak, abs(float(out.static)))
        moved = _lab.baseline_drift(r, out.noise_std, out.static, out.static_std,
                                    None if lead is None else lead / u, len(drift),
                                    peak)  # fmt: skip
    if moved is not None:
        flags.append(
            Flag(
                "baseline_drift",
                f"the record's baseline moves ({moved}): a sensor's offset, ramp or wobble "
                f"cannot be told from the static deflection (the level read, {static:.6g}, "
                "holds the sensor's offset too); static_level is NaN",
            )
        )
        static = static_std = math.nan
    if quantity in ("velocity", "acceleration"):
        static = static_std = math.nan
        flags.append(
            Flag(
                "no_static_level",
                f"the record is a {quantity}: its poles are the structure's, but it has no "
                "static level (the equilibrium deflection is read from a displacement "
                "only); static_level is NaN",
            )
        )
    return Detection(
        modes=tuple(modes),
        fundamental=fund,
        static_level=static,
        static_level_std=static_std,
        flags=tuple(flags),
        method=resolved,
        noise_std=noise_std,
        snr_db=snr_db,
        n_samples=n,
        dt=dt,
        kind=kind,
        iterations=out.iterations,
        start=start,
        quantity=quantity or "displacement",
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
