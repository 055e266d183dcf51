"""Recorded signals in: one reader, one set of rules, for the CLI and the REST API.

A recording is a record of the probe's position ``w`` sampled on a uniform time grid. Labs
write it in many layouts; this module reads them all into one :class:`Recording` and refuses
what it cannot read without guessing, with a :class:`RecordingError` that names the field and
echoes the value. It knows neither HTTP nor the command line: the API maps the errors to
problem documents (415 for :class:`UnsupportedFormat`, 413 for :class:`RecordingTooLarge`, 422
otherwise), the CLI to its one-line error.

Layouts
-------
CSV (``,``, ``;``, tab or blanks) with a header row
    The time column is recognised by its name (``t``, ``time``, ``timestamp``, ``seconds``...),
    with its unit kept from the header: ``t [ms]``, ``time (s)``, ``time_s``. The signal is the
    one other column (any name, e.g. ``accel_mV`` or ``w [mm]``), or among several the one with
    a signal's name (``w``, ``x``, ``signal``, ``displacement``...), or the one named by
    ``column``. A header that does not say which column is which is an error that lists the
    columns found, never a guess. A file without a time column needs ``dt``.
NPY
    1-D: the samples (give ``dt``). 2-D, two columns (or two rows): ``t`` then ``w``.
NPZ, MATLAB .mat
    Variables ``w`` (or ``signal``, ``x``, ``y``, ``value(s)``) and ``t`` (or ``time``) or
    ``dt``.
WAV
    ``dt = 1 / rate``; ``channel`` picks one channel of a multi-channel file.

Sampling
--------
Explicit times must increase strictly and be uniform. Timestamps written with a limited number
of significant digits (``%.9g``, ``%.6g``, a logger's fixed decimals) jitter by the rounding of
the written values: that is not non-uniform sampling. When the steps deviate from their mean by
more than the tolerance ``uniform_rtol`` (one setting, ``SNAPWARN_UNIFORM_RTOL``, default
1e-3, honoured by the CLI and the API alike), each deviating step is compared with the rounding
of its two written timestamps (half a unit in their last written digit): if the rounding
explains it, ``dt`` and ``t0`` are the least-squares line through the timestamps and the
recording carries the flag ``rounded_timestamps`` that says so. Steps the rounding cannot
explain (a dropped sample, a jittering clock) are an error naming the worst step, unless
``resample=True``, which interpolates the record linearly onto a uniform grid (flag
``resampled``).

``dt`` given by the caller supplies the step of a record that has no time of its own (1-D
NPY, a one-column CSV); given for a file that carries its own times (a time column, ``t`` or
``dt`` variables, a WAV rate), it is an error: the two could disagree, and silently preferring
one of them has turned an omega of 16 into 125.7.
"""

from __future__ import annotations

import csv
import io
import math
import os
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from service.analysis.common import Flag

FORMATS = ("csv", "npy", "npz", "wav", "mat")
DEFAULT_UNIFORM_RTOL = 1e-3
UNIFORM_RTOL_ENV = "SNAPWARN_UNIFORM_RTOL"

_TIME_NAMES = frozenset(
    ("t", "time", "times", "timestamp", "timestamps", "seconds", "sec", "secs", "s", "ms")
)
_VALUE_NAMES = frozenset(
    (
        "w", "x", "y", "z", "value", "values", "signal", "position", "deflection",
        "displacement", "disp", "amplitude", "response", "data",
    )
)  # fmt: skip
_BRACKET_UNIT = re.compile(r"^\s*(?P<name>.*?)\s*[\[\(\{](?P<unit>[^\]\)\}]*)[\]\)\}]\s*$")
_UNIT_TOKEN = re.compile(
    r"^(?:[munpkMµ]?(?:s|sec|m|V|g|N|Pa|Hz|A|rad)|min|h|deg|in|mil|um|us|ns|ms|mm|cm|nm|"
    r"mV|uV|µV|mg|kg|mN|kN|kPa|MPa|g0|m/s|m/s2|m/s\^2|mm/s|mm/s2|rad/s|deg/s|counts?|au|"
    r"percent|pct)$"
)
_MAX_DIGIT_CELLS = 20_000  # cells read to tell how many digits the timestamps were written with


# ------------------------------------------------------------------------------------- errors
def _show(value: Any) -> str:
    """A value as it is echoed in a message (short; NaN and infinities spelled out)."""
    if isinstance(value, float) and not math.isfinite(value):
        return repr("NaN" if math.isnan(value) else ("Infinity" if value > 0 else "-Infinity"))
    text = repr(value)
    return text if len(text) <= 200 else text[:200] + "..."


class RecordingError(ValueError):
    """A recording that cannot be read as it is: names the field and echoes the value.

    Parameters
    ----------
    field : str
        The offending input: ``"file"``, ``"dt"``, ``"column"``, ``"t[17]"``, ...
    value : Any
        The refused value (as given, or a short description of it).
    why : str
        What is wrong, in words; the message is ``"<field>: <value> <why>"``.

    Attributes
    ----------
    field, parameter : str
        The same name (``parameter`` as on the numerics' ``ParameterError``).
    value : Any
    """

    def __init__(self, field: str, value: Any, why: str) -> None:
        super().__init__(f"{field}: {_show(value)} {why}")
        self.field = field
        self.parameter = field
        self.value = value
        self.why = why


class UnsupportedFormat(RecordingError):
    """A file format this reader does not know (HTTP 415)."""


class RecordingTooLarge(RecordingError):
    """More samples than the caller allows (HTTP 413)."""


# ------------------------------------------------------------------------------------- result
@dataclass(frozen=True)
class Recording:
    """A validated recording.

    Attributes
    ----------
    w : ndarray, shape (n,)
        The samples, float64, finite (record units: ``value_unit``).
    t : ndarray, shape (n,), or None
        The sample times as written (None when the record is defined by ``dt``, or after
        resampling). They increase strictly and are uniform within the rounding of their
        written digits.
    dt : float
        Sampling step (time unit ``unit``); least-squares when the timestamps were rounded.
    t0 : float
        Time of the first sample.
    unit, value_unit : str or None
        Units of time and of ``w``, as the file or the caller gave them.
    source : str
        ``"json"``, ``"arrays"``, or the file format.
    flags : tuple of Flag
        ``rounded_timestamps`` (dt estimated by least squares), ``resampled``.
    metadata : dict
        What the reader learnt about the file (columns, variables, sample rate...).
    """

    w: np.ndarray
    t: np.ndarray | None
    dt: float
    t0: float
    unit: str | None = None
    value_unit: str | None = None
    source: str = "arrays"
    flags: tuple[Flag, ...] = ()
    metadata: dict[str, Any] = field(default_factory=dict)

    @property
    def n(self) -> int:
        """Number of samples."""
        return int(self.w.size)

    @property
    def duration(self) -> float:
        """``dt * (n - 1)``, time unit ``unit``."""
        return self.dt * (self.n - 1)

    def time(self) -> np.ndarray:
        """The sample times: ``t`` as written, else ``t0 + k dt``."""
        return time_axis(self.n, self.dt, self.t0, self.t)


@dataclass
class _Raw:
    """A parsed file before validation: arrays as found, and what the file says about them."""

    w: Any
    t: Any = None
    dt: float | None = None
    unit: str | None = None
    value_unit: str | None = None
    source: str = "arrays"
    t_cells: list[str] | None = None  # the time column as written (CSV)
    metadata: dict[str, Any] = field(default_factory=dict)


def uniform_rtol_from_env(default: float = DEFAULT_UNIFORM_RTOL) -> float:
    """The uniform-sampling tolerance: ``SNAPWARN_UNIFORM_RTOL`` if set, else ``default``."""
    text = os.environ.get(UNIFORM_RTOL_ENV)
    if text is None or not text.strip():
        return default
    try:
        v = float(text)
    except ValueError:
        raise RecordingError(UNIFORM_RTOL_ENV, text, "is not a number") from None
    if not (math.isfinite(v) and v > 0):
        raise RecordingError(UNIFORM_RTOL_ENV, text, "must be a finite number > 0")
    return v


# ------------------------------------------------------------------------------------- arrays
def check_finite(name: str, a: np.ndarray) -> None:
    """Raise naming the first non-finite element ``name[i]``."""
    bad = ~np.isfinite(a)
    if bad.any():
        i = int(np.argmax(bad))
        raise RecordingError(
            f"{name}[{i}]",
            float(a[i]),
            f"must be finite ({int(bad.sum())} non-finite value(s) in {name})",
        )


def to_f64(name: str, values: Any) -> np.ndarray:
    """A 1-D float64 array from a list or an array; refuses ragged, nested, boolean, text."""
    try:
        a = np.asarray(values)
    except (TypeError, ValueError) as exc:
        raise RecordingError(name, values, f"must be a flat list of numbers ({exc})") from None
    if a.dtype.kind == "c":
        raise RecordingError(name, str(a.dtype), "must be real, got complex values")
    if a.dtype.kind == "b":
        raise RecordingError(name, str(a.dtype), "must hold numbers, not booleans")
    if a.dtype.kind not in "iuf":
        raise RecordingError(name, str(a.dtype), "must hold numbers")
    if a.ndim != 1:
        raise RecordingError(name, list(a.shape), "must be one-dimensional")
    return a.astype(np.float64, copy=False)


def _positive_finite(name: str, value: Any) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise RecordingError(name, value, "must be a number") from None
    if not (math.isfinite(v) and v > 0):
        raise RecordingError(name, v, "must be a finite number > 0")
    return _representable_step(name, v)


#: A step whose square (or inverse square) is not a normal float64 cannot give a finite
#: eigenvalue (``sigma^2`` is in 1/time^2): about 3e-154 <= dt <= 3.4e153 (any time unit).
_STEP_MIN = math.sqrt(2.0**-1022) * 2.0
_STEP_MAX = 1.0 / _STEP_MIN


def _representable_step(name: str, v: float) -> float:
    if not _STEP_MIN <= v <= _STEP_MAX:
        raise RecordingError(
            name,
            v,
            f"is out of the representable range [{_STEP_MIN:.3g}, {_STEP_MAX:.3g}]: rates in "
            "1/time^2 would under- or overflow; write the record in another time unit",
        )
    return v


def time_axis(n: int, dt: float, t0: float, t: np.ndarray | None) -> np.ndarray:
    """``t`` if given, else ``t0 + k dt`` for ``k = 0..n-1``."""
    return t if t is not None else t0 + dt * np.arange(n, dtype=np.float64)


# ----------------------------------------------------------------------- rounding of timestamps
def _sig_digits(cell: str) -> tuple[int, int | None]:
    """(significant digits, decimals or None with an exponent) of a written number."""
    s = cell.strip().lstrip("+-")
    mant, _, exp = s.partition("e") if "e" in s else s.partition("E")
    decimals = len(mant.split(".", 1)[1]) if "." in mant and not exp else None
    digits = mant.replace(".", "").lstrip("0")
    return max(len(digits), 1), decimals


def _quanta(t: np.ndarray, cells: list[str] | None, idx: np.ndarray) -> tuple[np.ndarray, str]:
    """Half a unit in the last written digit of ``t[idx]``, and how the column was written.

    The column is read as fixed decimals (the largest values written with as many decimals as
    any: ``%.6f``, a logger's format) or as significant digits (``%.9g``; the most digits of any
    sampled cell, so that stripped trailing zeros do not widen the rounding). Binary arrays are
    read through their shortest round-trip text (``repr``), so exact float64 times get a
    rounding near 1e-16 and nothing is excused.
    """
    n = t.size
    step = max(1, n // _MAX_DIGIT_CELLS)
    sample = np.unique(np.concatenate([np.arange(0, n, step), idx]))
    if cells is not None:
        texts = [cells[i] for i in sample]
    else:
        texts = [repr(float(t[i])) for i in sample]
    info = [_sig_digits(c) for c in texts]
    decimals = [d for _, d in info]
    if None not in decimals:
        # fixed decimals: the largest values carry as many decimals as any value (with %g the
        # decimals fall as the magnitude grows; stripped trailing zeros only lower a few)
        top = np.argsort(np.abs(t[sample]))[-max(1, len(sample) // 10) :]
        nd = max(decimals)  # type: ignore[type-var]
        if max(decimals[i] for i in top) == nd:  # type: ignore[type-var]
            return np.full(idx.size, 0.5 * 10.0 ** (-nd)), f"{nd} decimals"
    digits = max(d for d, _ in info)
    mag = np.abs(t[idx])
    with np.errstate(divide="ignore"):
        e = np.where(mag > 0, np.floor(np.log10(np.where(mag > 0, mag, 1.0))), -np.inf)
    return 0.5 * 10.0 ** (e - digits + 1), f"{digits} significant digits"


def _least_squares_line(t: np.ndarray) -> tuple[float, float]:
    """``(dt, t0)`` of the least-squares line ``t_k = t0 + k dt``."""
    n = t.size
    k = np.arange(n, dtype=np.float64)
    kc = k - (n - 1) / 2.0
    tm = float(np.mean(t))
    dt = float(np.dot(kc, t - tm) / np.dot(kc, kc))
    return dt, tm - dt * (n - 1) / 2.0


def _uniform_grid(
    w: np.ndarray,
    t: np.ndarray,
    *,
    t_name: str,
    rtol: float,
    cells: list[str] | None,
    resample: bool,
) -> tuple[np.ndarray, np.ndarray | None, float, float, tuple[Flag, ...]]:
    """Check that ``t`` is uniform (within rounding); ``(w, t, dt, t0, flags)``."""
    d = np.diff(t)
    if (d <= 0).any():
        i = int(np.argmax(d <= 0)) + 1
        raise RecordingError(
            f"{t_name}[{i}]",
            float(t[i]),
            f"must be strictly increasing (previous {t_name}[{i - 1}] = {float(t[i - 1])!r})",
        )
    n = t.size
    mean_step = (float(t[-1]) - float(t[0])) / (n - 1)
    if float(np.max(np.abs(d - mean_step))) <= rtol * mean_step:
        return w, t, mean_step, float(t[0]), ()
    dt, t0 = _least_squares_line(t)
    dev = np.abs(d - dt)
    bad = np.flatnonzero(dev > rtol * dt)
    q, written = _quanta(t, cells, np.concatenate([bad, bad + 1]))
    rounding = q[: bad.size] + q[bad.size :]
    allowed = np.where(rounding < 0.5 * dt, rounding * (1 + 1e-9) + rtol * dt, rtol * dt)
    excess = dev[bad] - allowed
    if (excess <= 0).all():
        worst = float(np.max(dev[bad]))
        flag = Flag(
            "rounded_timestamps",
            f"the {t_name} column is written with {written}: its steps deviate from the "
            f"least-squares step {dt:.9g} by up to {worst / dt:.2g} of a step, within the "
            f"rounding of the written values (+-{float(np.max(q)):.2g}); dt and t0 are the "
            f"least-squares line through the {n} timestamps",
        )
        return w, t, dt, t0, (flag,)
    j = int(bad[int(np.argmax(excess))])
    if resample:
        step = float(np.median(d))
        m = int(math.floor((float(t[-1]) - float(t[0])) / step * (1 + 1e-12))) + 1
        grid = float(t[0]) + step * np.arange(m, dtype=np.float64)
        wr = np.interp(grid, t, w)
        flag = Flag(
            "resampled",
            f"the {t_name} column is not uniform (worst step {t_name}[{j + 1}] - "
            f"{t_name}[{j}] = {float(d[j]):.6g} against a median step {step:.6g}): the record "
            f"was interpolated linearly onto {m} uniform samples",
        )
        return wr, None, step, float(t[0]), (flag,)
    raise RecordingError(
        f"{t_name}[{j + 1}]",
        float(t[j + 1]),
        f"is not uniformly sampled: the step {t_name}[{j + 1}] - {t_name}[{j}] = "
        f"{float(d[j])!r} differs from the least-squares step {dt!r} by "
        f"{float(dev[j]) / dt:.3g} of a step, more than the rounding of the written "
        f"timestamps ({written}, +-{float(rounding[int(np.argmax(excess))]):.2g}) and the "
        f"tolerance {rtol:g} explain (setting {UNIFORM_RTOL_ENV}); resample it onto a uniform "
        "grid with resample=true (CLI: --resample)",
    )


# ------------------------------------------------------------------------------- validation
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
    flags: tuple[Flag, ...] = ()
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
        wa, t_out, step, first, flags = _uniform_grid(
            wa, ta, t_name=t_name, rtol=rtol, cells=raw.t_cells, resample=resample
        )
        if raw.dt is not None:  # a file with both t and dt: they must agree
            if abs(raw.dt - step) > max(rtol, 1e-9) * step and not flags:
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


# ------------------------------------------------------------------------------------ formats
def guess_format(
    filename: str | None, content_type: str | None = None, fmt: str | None = None
) -> str:
    """The format from ``fmt``, else the file extension, else the content type."""
    if fmt:
        f = fmt.lower().lstrip(".")
        if f not in FORMATS:
            raise UnsupportedFormat("format", fmt, f"is not one of {FORMATS}")
        return f
    name = (filename or "").lower()
    for ext, f in ((".csv", "csv"), (".tsv", "csv"), (".txt", "csv"), (".dat", "csv"),
                   (".npy", "npy"), (".npz", "npz"), (".wav", "wav"), (".mat", "mat")):  # fmt: skip
        if name.endswith(ext):
            return f
    ct = (content_type or "").lower()
    for key, f in (("csv", "csv"), ("text/plain", "csv"), ("x-npy", "npy"), ("npz", "npz"),
                   ("wav", "wav"), ("matlab", "mat")):  # fmt: skip
        if key in ct:
            return f
    raise UnsupportedFormat(
        "file",
        filename,
        f"has a format this reader cannot tell ({content_type}); use an extension "
        f"{['.' + f for f in FORMATS]} or name the format",
    )


def split_unit(header: str) -> tuple[str, str | None]:
    """``"t [ms]"`` -> ``("t", "ms")``; ``"time_s"`` -> ``("time", "s")``; else no unit."""
    m = _BRACKET_UNIT.match(header)
    if m and m.group("name").strip():
        return m.group("name").strip(), (m.group("unit").strip() or None)
    h = header.strip()
    if "_" in h:
        head, _, tail = h.rpartition("_")
        if head and _UNIT_TOKEN.match(tail):
            return head, tail
    return h, None


def _role(name: str) -> str | None:
    key = split_unit(name)[0].strip().lower()
    if key in _TIME_NAMES:
        return "time"
    if key in _VALUE_NAMES:
        return "value"
    return None


def _find(names: list[str], wanted: str, what: str) -> int:
    for i, n in enumerate(names):
        if n == wanted or split_unit(n)[0] == wanted:
            return i
    raise RecordingError(what, wanted, f"is not a column of the file (columns found: {names})")


def _choose_columns(
    header: list[str], column: str | None, time_column: str | None, has_dt: bool
) -> tuple[int | None, int]:
    """(time index or None, value index) by the rules of the module docstring."""
    if time_column is not None:
        ti: int | None = _find(header, time_column, "time_column")
    else:
        times = [i for i, h in enumerate(header) if _role(h) == "time"]
        if len(times) > 1:
            raise RecordingError(
                "file",
                header,
                f"has several time columns ({[header[i] for i in times]}); name one with "
                "time_column",
            )
        ti = times[0] if times else None
    if column is not None:
        wi = _find(header, column, "column")
        if wi == ti:
            raise RecordingError("column", column, "is the time column")
        return ti, wi
    others = [i for i in range(len(header)) if i != ti]
    if not others:
        raise RecordingError("file", header, "has no signal column besides the time column")
    if ti is None and len(others) > 1 and not has_dt:
        raise RecordingError(
            "file",
            header,
            f"has no recognised time column among the columns found ({header}); name it "
            f"(one of {sorted(_TIME_NAMES)}, units allowed: 't [ms]', 'time_s'), or give "
            "time_column, or column with dt",
        )
    if len(others) == 1:
        return ti, others[0]
    values = [i for i in others if _role(header[i]) == "value"]
    if len(values) == 1:
        return ti, values[0]
    raise RecordingError(
        "file",
        header,
        f"has several columns that could hold the signal ({[header[i] for i in others]}); "
        "name it with column",
    )


def _is_number(s: str) -> bool:
    try:
        float(s)
    except ValueError:
        return False
    return True


def _parse_csv(
    data: bytes, *, column: str | None, time_column: str | None, has_dt: bool
) -> _Raw:
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise RecordingError("file", f"byte {exc.start}", "is not UTF-8 text") from None
    lines = [ln for ln in text.splitlines() if ln.strip() and not ln.lstrip().startswith("#")]
    if not lines:
        raise RecordingError("file", "", "is empty (a CSV needs a header and at least 2 rows)")
    head = lines[0]
    delim = max((",", ";", "\t"), key=head.count)
    if head.count(delim) == 0:
        delim = None
    rows = list(csv.reader(lines, delimiter=delim)) if delim else [ln.split() for ln in lines]
    header = [h.strip() for h in rows[0]]
    if all(_is_number(h) for h in header):
        raise RecordingError(
            "file",
            ",".join(header)[:80],
            "has no header row (the first line must name the columns, e.g. 't [s],w [mm]')",
        )
    body = rows[1:]
    if len(body) < 2:
        raise RecordingError("file", f"{len(body)} rows", "must hold at least 2 data rows")
    ncol = len(header)
    for k, r in enumerate(body):
        if len(r) != ncol:
            raise RecordingError(
                f"file: line {k + 2}",
                f"{len(r)} cells",
                f"is ragged: the header has {ncol} columns",
            )
    ti, wi = _choose_columns(header, column, time_column, has_dt)
    cols: dict[int, np.ndarray] = {}
    cells: dict[int, list[str]] = {}
    for idx in ([ti] if ti is not None else []) + [wi]:
        texts = [r[idx].strip() for r in body]
        if delim in (";", "\t") and any("," in c for c in texts[:50]):
            texts = [c.replace(",", ".") for c in texts]  # decimal commas (spreadsheet exports)
        vals = np.empty(len(body))
        for k, cell in enumerate(texts):
            try:
                vals[k] = float(cell)
            except ValueError:
                raise RecordingError(
                    f"file: line {k + 2}, column {header[idx]!r}", cell, "is not a number"
                ) from None
        cols[idx], cells[idx] = vals, texts
    return _Raw(
        w=cols[wi],
        t=cols[ti] if ti is not None else None,
        unit=split_unit(header[ti])[1] if ti is not None else None,
        value_unit=split_unit(header[wi])[1],
        source="csv",
        t_cells=cells[ti] if ti is not None else None,
        metadata={
            "columns": header,
            "value_column": header[wi],
            "time_column": header[ti] if ti is not None else None,
        },
    )


def _from_mapping(
    arrs: dict[str, Any], source: str, column: str | None, time_column: str | None
) -> _Raw:
    names = sorted(arrs)

    def get(options: tuple[str, ...]) -> tuple[str | None, Any]:
        for n in options:
            if n in arrs:
                return n, np.squeeze(np.asarray(arrs[n]))
        return None, None

    if column is not None:
        wn, w = get((column,))
        if w is None:
            raise RecordingError("column", column, f"is not a variable of the file ({names})")
    else:
        wn, w = get(("w", "signal", "x", "y", "value", "values"))
        if w is None:
            raise RecordingError(
                "file",
                names,
                "has no signal variable (w, signal, x, y, value); name it with column",
            )
    if time_column is not None:
        tn, t = get((time_column,))
        if t is None:
            raise RecordingError(
                "time_column", time_column, f"is not a variable of the file ({names})"
            )
    else:
        tn, t = get(("t", "time"))
    _, dt = get(("dt",))
    if dt is not None and np.size(dt) != 1:
        raise RecordingError("file: dt", list(np.shape(dt)), "must be one number")
    return _Raw(
        w=w,
        t=t,
        dt=float(dt) if dt is not None and np.asarray(dt).dtype.kind in "iuf" else None,
        source=source,
        metadata={"variables": names, "value_column": wn, "time_column": tn},
    )


def _check_unpacked_size(data: bytes, fmt: str, limit: int) -> None:
    """Refuse an NPZ or MAT file whose arrays unpack beyond ``limit`` bytes, from their
    headers alone (zip directory sizes; MAT variable shapes), before inflating anything."""
    total = 0
    if fmt == "npz":
        import zipfile

        try:
            with zipfile.ZipFile(io.BytesIO(data)) as z:
                infos = z.infolist()
        except Exception as exc:  # noqa: BLE001 - not a zip: np.load names the failure
            raise _load_failed(".npz", data, exc) from None
        if len(infos) > 256:
            raise RecordingTooLarge("file", len(infos), "holds more than 256 arrays")
        total = sum(i.file_size for i in infos)
    else:
        from scipy.io import whosmat

        try:
            for _name, shape, cls in whosmat(io.BytesIO(data)):
                size = int(np.prod([int(d) for d in shape], dtype=object))
                total += size * (16 if "complex" in cls else 8)
        except RecordingError:
            raise
        except Exception as exc:  # noqa: BLE001
            raise _load_failed(".mat", data, exc) from None
    if total > limit:
        raise RecordingTooLarge(
            "file",
            f"{len(data)} bytes",
            f"unpacks to {total} bytes, over the limit of {limit} "
            "(setting SNAPWARN_MAX_DECOMPRESSED_BYTES)",
        )


def _load_failed(fmt: str, data: bytes, exc: Exception) -> RecordingError:
    return RecordingError("file", f"{len(data)} bytes", f"is not a valid {fmt} file ({exc})")


def _parse(
    data: bytes,
    fmt: str,
    *,
    column: str | None,
    time_column: str | None,
    channel: Any,
    has_dt: bool,
    max_decompressed_bytes: int | None = None,
) -> _Raw:
    if not data:
        raise RecordingError("file", "", "is empty")
    buf = io.BytesIO(data)
    if fmt == "csv":
        return _parse_csv(data, column=column, time_column=time_column, has_dt=has_dt)
    if fmt == "npy":
        try:
            a = np.load(buf, allow_pickle=False)
        except Exception as exc:  # noqa: BLE001 - any parse failure is the file's fault
            raise _load_failed(".npy", data, exc) from None
        if a.ndim == 2 and 1 in a.shape:
            a = a.reshape(-1)
        if a.ndim == 1:
            return _Raw(w=a, source="npy")
        if a.ndim == 2 and 2 in a.shape:
            a2 = a if a.shape[1] == 2 else a.T
            return _Raw(w=a2[:, 1], t=a2[:, 0], source="npy", metadata={"time_column": "t"})
        raise RecordingError("file", list(a.shape), "must be a 1-D array (w) or 2 columns (t, w)")
    if fmt == "npz":
        if max_decompressed_bytes is not None:
            _check_unpacked_size(data, fmt, max_decompressed_bytes)
        try:
            with np.load(buf, allow_pickle=False) as z:
                arrs = {k: z[k] for k in z.files}
        except Exception as exc:  # noqa: BLE001
            raise _load_failed(".npz", data, exc) from None
        return _from_mapping(arrs, "npz", column, time_column)
    if fmt == "mat":
        from scipy.io import loadmat

        if max_decompressed_bytes is not None:
            _check_unpacked_size(data, fmt, max_decompressed_bytes)
        try:
            arrs = {k: v for k, v in loadmat(buf).items() if not k.startswith("__")}
        except Exception as exc:  # noqa: BLE001
            raise _load_failed(".mat", data, exc) from None
        return _from_mapping(arrs, "mat", column, time_column)
    if fmt == "wav":
        from scipy.io import wavfile

        try:
            rate, a = wavfile.read(buf)
        except Exception as exc:  # noqa: BLE001
            raise _load_failed("WAV", data, exc) from None
        if a.ndim == 2:
            try:
                ch = int(channel)
            except (TypeError, ValueError, OverflowError):
                raise RecordingError("channel", channel, "must be an integer") from None
            if not 0 <= ch < a.shape[1] or ch != channel:
                raise RecordingError("channel", channel, f"must be an integer in [0, {a.shape[1]})")
            a = a[:, ch]
        return _Raw(
            w=a,
            dt=1.0 / float(rate),
            unit="s",
            source="wav",
            metadata={"sample_rate": int(rate), "sample_dtype": str(a.dtype)},
        )
    raise UnsupportedFormat("format", fmt, f"is not one of {FORMATS}")


def read_bytes(
    data: bytes,
    fmt: str,
    *,
    dt: Any = None,
    t0: Any = None,
    column: str | None = None,
    time_column: str | None = None,
    channel: Any = 0,
    uniform_rtol: float | None = None,
    resample: bool = False,
    max_samples: int | None = None,
    max_decompressed_bytes: int | None = None,
) -> Recording:
    """Read and validate a file's bytes (``fmt``: one of :data:`FORMATS`).

    ``dt`` supplies the step of a record without times of its own and is an error for a file
    that has them; ``column``/``time_column`` name the columns (CSV) or variables (NPZ, MAT);
    ``channel`` picks a WAV channel. See the module notes for the rest.
    """
    if fmt not in FORMATS:
        raise UnsupportedFormat("format", fmt, f"is not one of {FORMATS}")
    rtol = uniform_rtol_from_env() if uniform_rtol is None else float(uniform_rtol)
    raw = _parse(data, fmt, column=column, time_column=time_column, channel=channel,
                 has_dt=dt is not None,
                 max_decompressed_bytes=max_decompressed_bytes)  # fmt: skip
    return _validate(raw, dt=dt, t0=t0, rtol=rtol, resample=resample, max_samples=max_samples)


def read_file(path: str | os.PathLike[str], *, fmt: str | None = None, **options: Any) -> Recording:
    """Read and validate a recording from a file (the format from ``fmt`` or its extension).

    Takes the options of :func:`read_bytes`; the file's name goes into ``metadata``.
    """
    p = Path(path)
    if not p.is_file():
        raise RecordingError("file", str(path), "is not a readable file")
    rec = read_bytes(p.read_bytes(), guess_format(p.name, None, fmt), **options)
    return Recording(rec.w, rec.t, rec.dt, rec.t0, rec.unit, rec.value_unit, rec.source,
                     rec.flags, {**rec.metadata, "filename": p.name})  # fmt: skip


# ---------------------------------------------------------------------------------- downloads
def to_csv(t: np.ndarray, w: np.ndarray, unit: str | None, value_unit: str | None) -> bytes:
    """CSV with a header; 17 significant digits, so float64 values round-trip exactly."""
    out = io.StringIO()
    th = f"t [{unit}]" if unit else "t"
    wh = f"w [{value_unit}]" if value_unit else "w"
    out.write(f"{th},{wh}\n")
    np.savetxt(out, np.column_stack([t, w]), delimiter=",", fmt="%.17g")
    return out.getvalue().encode()


def to_npy(t: np.ndarray, w: np.ndarray) -> bytes:
    """A (n, 2) float64 .npy array with columns t, w."""
    out = io.BytesIO()
    np.save(out, np.column_stack([t, w]).astype("<f8"), allow_pickle=False)
    return out.getvalue()


__all__ = [
    "DEFAULT_UNIFORM_RTOL",
    "FORMATS",
    "UNIFORM_RTOL_ENV",
    "Recording",
    "RecordingError",
    "RecordingTooLarge",
    "UnsupportedFormat",
    "check_finite",
    "from_arrays",
    "guess_format",
    "read_bytes",
    "read_file",
    "split_unit",
    "time_axis",
    "to_csv",
    "to_f64",
    "to_npy",
    "uniform_rtol_from_env",
]
