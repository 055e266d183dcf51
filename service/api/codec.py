"""Signals at the door: validation of arrays, parsing of uploaded files, data downloads.

Formats: CSV with a header (units in brackets: ``time [s]``), NPY (1-D w, or 2 columns t, w),
NPZ and MATLAB .mat (variables ``w`` and ``t`` or ``dt``), WAV (``dt = 1 / rate``).
Every rejection is an :class:`ApiProblem` naming the field and echoing the value.
"""

from __future__ import annotations

import csv
import io
import math
import re
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from service.api.problems import ApiProblem, invalid, too_large

FORMATS = ("csv", "npy", "npz", "wav", "mat")
_TIME_NAMES = re.compile(r"^(t|time|times|timestamp|seconds|sec|s)$", re.IGNORECASE)
_VALUE_NAMES = re.compile(
    r"^(w|x|y|value|values|signal|position|deflection|displacement)$", re.IGNORECASE
)
_UNIT = re.compile(r"^\s*(?P<name>.*?)\s*[\[\(](?P<unit>[^\]\)]*)[\]\)]\s*$")


@dataclass
class CleanSignal:
    """A validated signal: ``w``, and ``t`` as given (or None), ``dt``, ``t0``."""

    w: np.ndarray
    t: np.ndarray | None
    dt: float
    t0: float
    unit: str | None = None
    value_unit: str | None = None
    source: str = "json"
    metadata: dict[str, Any] = field(default_factory=dict)


def _nonfinite_value(x: float) -> str:
    return "NaN" if math.isnan(x) else ("Infinity" if x > 0 else "-Infinity")


def check_finite(name: str, a: np.ndarray) -> None:
    bad = ~np.isfinite(a)
    if bad.any():
        i = int(np.argmax(bad))
        raise invalid(
            f"{name}[{i}]",
            _nonfinite_value(float(a[i])),
            f"must be finite ({int(bad.sum())} non-finite value(s) in {name})",
        )


def to_f64(name: str, values: Any) -> np.ndarray:
    """A 1-D float64 array from a list or array; 422 if ragged, nested or not numeric."""
    try:
        a = np.asarray(values)
    except (TypeError, ValueError) as exc:
        raise invalid(name, values, f"must be a flat list of numbers ({exc})") from None
    if a.dtype.kind == "c":
        raise invalid(name, str(a.dtype), "must be real, got complex values")
    if a.dtype.kind not in "biuf":
        raise invalid(name, str(a.dtype), "must hold numbers")
    if a.ndim != 1:
        raise invalid(name, list(a.shape), "must be one-dimensional")
    return a.astype(np.float64, copy=False)


def clean_signal(
    *,
    w: Any,
    t: Any = None,
    dt: float | None = None,
    t0: float | None = None,
    max_samples: int,
    uniform_rtol: float,
    w_name: str = "w",
    t_name: str = "t",
) -> tuple[np.ndarray, np.ndarray | None, float, float]:
    """Validate a signal; returns ``(w, t_or_None, dt, t0)`` with float64 arrays.

    Rejects (422) empty, non-finite, ragged, non-monotone and non-uniform input, and (413)
    more than ``max_samples`` samples.
    """
    n_hint = len(w) if hasattr(w, "__len__") else None
    if n_hint is not None and n_hint > max_samples:
        raise too_large(
            w_name,
            n_hint,
            f"{n_hint} samples exceed the limit of {max_samples} (setting SNAPWARN_MAX_SAMPLES)",
        )
    wa = to_f64(w_name, w)
    if wa.size < 2:
        raise invalid(w_name, wa.tolist(), f"must hold at least 2 samples, got {wa.size}")
    check_finite(w_name, wa)
    if t is not None:
        if dt is not None:
            raise invalid("dt", dt, "must not be given together with t (give one of them)")
        ta = to_f64(t_name, t)
        if ta.size != wa.size:
            raise invalid(
                t_name,
                f"{ta.size} samples",
                f"and {w_name} ({wa.size} samples) must have the same length",
            )
        check_finite(t_name, ta)
        d = np.diff(ta)
        if (d <= 0).any():
            i = int(np.argmax(d <= 0)) + 1
            raise invalid(
                f"{t_name}[{i}]",
                float(ta[i]),
                f"must be strictly increasing (previous {t_name}[{i - 1}] = {float(ta[i - 1])!r})",
            )
        step = (float(ta[-1]) - float(ta[0])) / (ta.size - 1)
        dev = np.abs(d - step) / step
        j = int(np.argmax(dev))
        if dev[j] > uniform_rtol:
            raise invalid(
                f"{t_name}[{j + 1}]",
                float(ta[j + 1]),
                f"is not uniformly sampled: step {float(d[j])!r} differs from the "
                f"mean step {step!r} by {float(dev[j]):.3g} (relative; tolerance "
                f"{uniform_rtol:g}, setting SNAPWARN_UNIFORM_RTOL)",
            )
        return wa, ta, step, float(ta[0])
    if dt is None:
        raise invalid("dt", None, f"is required when {t_name} is not given")
    dtf = float(dt)
    if not math.isfinite(dtf) or dtf <= 0:
        raise invalid(
            "dt",
            _nonfinite_value(dtf) if not math.isfinite(dtf) else dtf,
            "must be a finite number > 0",
        )
    t0f = 0.0 if t0 is None else float(t0)
    if not math.isfinite(t0f):
        raise invalid("t0", _nonfinite_value(t0f), "must be finite")
    return wa, None, dtf, t0f


def time_axis(n: int, dt: float, t0: float, t: np.ndarray | None) -> np.ndarray:
    return t if t is not None else t0 + dt * np.arange(n, dtype=np.float64)


# --- uploads ---------------------------------------------------------------------------------
def guess_format(filename: str | None, content_type: str | None, fmt: str | None) -> str:
    if fmt:
        f = fmt.lower().lstrip(".")
        if f not in FORMATS:
            raise ApiProblem(
                415, f"format {fmt!r} is not one of {FORMATS}", field="format", value=fmt
            )
        return f
    name = (filename or "").lower()
    for ext, f in (
        (".csv", "csv"),
        (".tsv", "csv"),
        (".txt", "csv"),
        (".npy", "npy"),
        (".npz", "npz"),
        (".wav", "wav"),
        (".mat", "mat"),
    ):
        if name.endswith(ext):
            return f
    ct = (content_type or "").lower()
    for key, f in (
        ("csv", "csv"),
        ("text/plain", "csv"),
        ("x-npy", "npy"),
        ("npz", "npz"),
        ("wav", "wav"),
        ("matlab", "mat"),
    ):
        if key in ct:
            return f
    raise ApiProblem(
        415,
        f"cannot tell the format of file {filename!r} ({content_type}); use an extension "
        f"{['.' + f for f in FORMATS]} or the 'format' field",
        field="file",
        value=filename,
    )


def _split_unit(header: str) -> tuple[str, str | None]:
    m = _UNIT.match(header)
    if m:
        return m.group("name").strip(), (m.group("unit").strip() or None)
    return header.strip(), None


def _pick(
    names: list[str], wanted: str | None, pattern: re.Pattern, what: str, exclude: int | None = None
) -> int | None:
    if wanted is not None:
        for i, n in enumerate(names):
            if n == wanted or _split_unit(n)[0] == wanted:
                return i
        raise invalid(what, wanted, f"is not a column of the file (columns: {names})")
    for i, n in enumerate(names):
        if i != exclude and pattern.match(_split_unit(n)[0]):
            return i
    return None


def parse_csv(data: bytes, *, column: str | None, time_column: str | None) -> CleanSignal:
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise invalid("file", f"byte {exc.start}", "is not UTF-8 text") from None
    lines = [ln for ln in text.splitlines() if ln.strip() and not ln.lstrip().startswith("#")]
    if not lines:
        raise invalid("file", "", "is empty (a CSV needs a header and at least 2 rows)")
    head = lines[0]
    delim = max((",", ";", "\t"), key=head.count)
    if head.count(delim) == 0:
        delim = None
    rows = list(csv.reader(lines, delimiter=delim)) if delim else [ln.split() for ln in lines]
    header = [h.strip() for h in rows[0]]

    def _is_number(s: str) -> bool:
        try:
            float(s)
            return True
        except ValueError:
            return False

    if all(_is_number(h) for h in header):
        raise invalid(
            "file",
            ",".join(header)[:80],
            "has no header row (first line must name the columns, e.g. 't,w')",
        )
    body = rows[1:]
    if len(body) < 2:
        raise invalid("file", f"{len(body)} rows", "must hold at least 2 data rows")
    ncol = len(header)
    for k, r in enumerate(body):
        if len(r) != ncol:
            raise invalid(
                f"file: line {k + 2}",
                f"{len(r)} cells",
                f"is ragged: the header has {ncol} columns",
            )
    ti = _pick(header, time_column, _TIME_NAMES, "time_column")
    wi = _pick(header, column, _VALUE_NAMES, "column", exclude=ti)
    if wi is None:
        others = [i for i in range(ncol) if i != ti]
        if not others:
            raise invalid("file", header, "has no value column")
        wi = others[0]
    cols = {}
    for idx in ([ti] if ti is not None else []) + [wi]:
        vals = np.empty(len(body))
        for k, r in enumerate(body):
            cell = r[idx].strip()
            try:
                vals[k] = float(cell)
            except ValueError:
                raise invalid(
                    f"file: line {k + 2}, column {header[idx]!r}", cell, "is not a number"
                ) from None
        cols[idx] = vals
    wname, wunit = _split_unit(header[wi])
    tunit = _split_unit(header[ti])[1] if ti is not None else None
    return CleanSignal(
        w=cols[wi],
        t=cols[ti] if ti is not None else None,
        dt=math.nan,
        t0=0.0,
        unit=tunit,
        value_unit=wunit,
        source="csv",
        metadata={
            "columns": header,
            "value_column": header[wi],
            "time_column": header[ti] if ti is not None else None,
        },
    )


def _from_mapping(
    arrs: dict[str, Any], source: str, column: str | None, time_column: str | None
) -> CleanSignal:
    def get(names: tuple[str, ...]) -> Any:
        for n in names:
            if n in arrs:
                return np.asarray(arrs[n])
        return None

    w = get((column,)) if column else get(("w", "signal", "x", "y", "value", "values"))
    if w is None:
        raise invalid("file", sorted(arrs), f"has no variable {column or 'w'!r}")
    t = get((time_column,)) if time_column else get(("t", "time"))
    dt = get(("dt",))
    sq = np.squeeze
    return CleanSignal(
        w=sq(w),
        t=sq(t) if t is not None else None,
        dt=float(sq(dt)) if dt is not None and np.size(dt) == 1 else math.nan,
        t0=0.0,
        source=source,
        metadata={"variables": sorted(arrs)},
    )


def parse_upload(
    data: bytes,
    fmt: str,
    *,
    column: str | None = None,
    time_column: str | None = None,
    channel: int = 0,
) -> CleanSignal:
    """Parse an uploaded file (not yet validated: pass the arrays to :func:`clean_signal`)."""
    if not data:
        raise invalid("file", "", "is empty")
    buf = io.BytesIO(data)
    if fmt == "csv":
        return parse_csv(data, column=column, time_column=time_column)
    if fmt == "npy":
        try:
            a = np.load(buf, allow_pickle=False)
        except Exception as exc:  # noqa: BLE001
            raise invalid(
                "file", f"{len(data)} bytes", f"is not a valid .npy file ({exc})"
            ) from None
        if a.ndim == 1:
            return CleanSignal(w=a, t=None, dt=math.nan, t0=0.0, source="npy")
        if a.ndim == 2 and 2 in a.shape:
            a2 = a if a.shape[1] == 2 else a.T
            return CleanSignal(w=a2[:, 1], t=a2[:, 0], dt=math.nan, t0=0.0, source="npy")
        raise invalid("file", list(a.shape), "must be a 1-D array (w) or 2 columns (t, w)")
    if fmt == "npz":
        try:
            with np.load(buf, allow_pickle=False) as z:
                arrs = {k: z[k] for k in z.files}
        except Exception as exc:  # noqa: BLE001
            raise invalid(
                "file", f"{len(data)} bytes", f"is not a valid .npz file ({exc})"
            ) from None
        return _from_mapping(arrs, "npz", column, time_column)
    if fmt == "mat":
        from scipy.io import loadmat

        try:
            arrs = {k: v for k, v in loadmat(buf).items() if not k.startswith("__")}
        except Exception as exc:  # noqa: BLE001
            raise invalid(
                "file", f"{len(data)} bytes", f"is not a valid .mat file ({exc})"
            ) from None
        return _from_mapping(arrs, "mat", column, time_column)
    if fmt == "wav":
        from scipy.io import wavfile

        try:
            rate, a = wavfile.read(buf)
        except Exception as exc:  # noqa: BLE001
            raise invalid(
                "file", f"{len(data)} bytes", f"is not a valid WAV file ({exc})"
            ) from None
        if a.ndim == 2:
            if not 0 <= channel < a.shape[1]:
                raise invalid("channel", channel, f"must be in [0, {a.shape[1]})")
            a = a[:, channel]
        return CleanSignal(
            w=a,
            t=None,
            dt=1.0 / float(rate),
            t0=0.0,
            unit="s",
            source="wav",
            metadata={"sample_rate": int(rate), "sample_dtype": str(a.dtype)},
        )
    raise ApiProblem(415, f"unsupported format {fmt!r}", field="format", value=fmt)


# --- downloads -------------------------------------------------------------------------------
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
