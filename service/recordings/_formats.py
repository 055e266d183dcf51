"""File layouts: CSV headers, NPY, NPZ, MAT, WAV; parsing before validation."""

from __future__ import annotations

import csv
import io
import os
import re
from pathlib import Path
from typing import Any

import numpy as np

from service.recordings._csv import _blocks, _is_number, ascii_text, check_row_count, read_csv_body
from service.recordings._errors import RecordingError, UnsupportedFormat
from service.recordings._guards import check_unpacked_size, load_failed
from service.recordings._record import FORMATS, Recording, _Raw, uniform_rtol_from_env
from service.recordings._time_units import seconds_per
from service.recordings._validate import _validate

_TIME_NAMES = frozenset(
    (
        "t",
        "time",
        "times",
        "timestamp",
        "timestamps",
        "datetime",
        "seconds",
        "sec",
        "secs",
        "s",
        "ms",
    )
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


def _decode(data: bytes) -> tuple[str, str]:
    """The text of a CSV and the encoding read: UTF-8 (BOM or not), UTF-16 with its BOM (a
    spreadsheet's "Unicode text" export), else Windows-1252 (a spreadsheet's legacy export:
    the numbers are ASCII in every one of them; only names such as ``µm`` differ)."""
    if data[:2] in (b"\xff\xfe", b"\xfe\xff"):
        try:
            return data.decode("utf-16"), "utf-16"
        except UnicodeDecodeError as exc:
            raise RecordingError("file", f"byte {exc.start}", "is not UTF-16 text") from None
    try:
        return data.decode("utf-8-sig"), "utf-8"
    except UnicodeDecodeError as exc:
        if b"\x00" in data:  # binary, or UTF-16 without a BOM: never read as 8-bit text
            raise RecordingError("file", f"byte {exc.start}", "is not UTF-8 text") from None
        return data.decode("cp1252", errors="replace"), "cp1252"


_SEP_LINE = re.compile(r'^\s*"?sep=(.)"?\s*$', re.IGNORECASE)


def _sep_hint(numbered: list[tuple[int, str]]) -> tuple[list[tuple[int, str]], str | None]:
    """Drop a spreadsheet's ``sep=;`` first line and return the delimiter it names."""
    if numbered and (m := _SEP_LINE.match(numbered[0][1])):
        return numbered[1:], m.group(1)
    return numbered, None


def _cells_of(line: str, delim: str | None) -> list[str]:
    return next(csv.reader([line], delimiter=delim)) if delim else line.split()


def content_lines(text: str) -> list[tuple[int, str]]:
    """The lines that hold the table, numbered as a text editor shows them: blank lines and
    ``#`` comments dropped, except a header written as the last comment before numbers
    (``numpy.savetxt(..., header="t,w")`` writes ``# t,w``), taken when it names as many
    columns as the first data row has and is not itself numbers."""
    return content_lines_of(text.splitlines())


def content_lines_of(lines: list[str]) -> list[tuple[int, str]]:
    """:func:`content_lines` of a text already split into lines."""
    numbered: list[tuple[int, str]] = []
    comment: tuple[int, str] | None = None
    for k, ln in enumerate(lines):
        if not ln.strip():
            continue
        if ln.lstrip().startswith("#"):
            if not numbered:
                comment = (k + 1, ln.lstrip().lstrip("#").strip())
            continue
        numbered.append((k + 1, ln))
    if not numbered or comment is None or not comment[1] or _SEP_LINE.match(numbered[0][1]):
        return numbered
    first = numbered[0][1]
    delim: str | None = max((",", ";", "\t"), key=first.count)
    if first.count(delim) == 0:
        delim = None
    data, head = _cells_of(first, delim), _cells_of(comment[1], delim)
    if (
        all(_is_number(c) for c in data)
        and len(head) == len(data)
        and not all(_is_number(c) for c in head)
    ):
        numbered.insert(0, comment)
    return numbered


def _time_unit(name: str) -> str | None:
    """The time column's unit: from the header (``t [ms]``, ``time_s``), or the name itself
    when it is one (``ms``, ``seconds``)."""
    base, unit = split_unit(name)
    if unit is None and seconds_per(base) is not None:
        return base.strip()
    return unit


def _is_units_row(cells: list[str]) -> bool:
    """A row of units under the header (``s,mm``, ``(ms),(V)``, ``[s];[mm]``): no number in it,
    every non-empty cell a short unit, and at least one cell given."""
    texts = [c.strip().strip("()[]{}").strip() for c in cells]
    if not any(texts) or any(_is_number(c) for c in cells if c.strip()):
        return False
    return all(not t or (len(t) <= 12 and " " not in t) for t in texts)


def _csv_head(data: bytes, encoding: str) -> list[tuple[int, str]]:
    """The first content lines of a CSV (a ``sep=`` line, the header, a units row and the
    first data row: :func:`content_lines` of the leading blocks), decoded."""
    enc = "cp1252" if encoding == "cp1252" else "utf-8"
    lines: list[str] = []
    numbered: list[tuple[int, str]] = []
    for _, _, _, block in _blocks(data):
        lines.extend(ln.decode(enc, "replace") for ln in block)
        numbered = content_lines_of(lines)
        if len(numbered) >= 4:
            break
    return numbered


def _parse_csv(
    data: bytes,
    *,
    column: str | None,
    time_column: str | None,
    has_dt: bool,
    max_samples: int | None = None,
) -> _Raw:
    data, encoding = ascii_text(data)
    check_row_count(data, max_samples)  # a vectorised count: too many rows refused at once
    numbered, hint = _sep_hint(_csv_head(data, encoding))
    if not numbered:
        raise RecordingError("file", "", "is empty (a CSV needs a header and at least 2 rows)")
    head = numbered[0][1]
    delim: str | None = hint or max((",", ";", "\t"), key=head.count)
    if head.count(delim) == 0:
        delim = None
    rows = [_cells_of(ln, delim) for _, ln in numbered[:2]]
    header = [h.strip() for h in rows[0]]
    if all(_is_number(h) for h in header):
        raise RecordingError(
            "file",
            ",".join(header)[:80],
            "has no header row (the first line must name the columns, e.g. 't [s],w [mm]')",
        )
    first = 1
    if len(rows) > 1 and len(rows[1]) == len(header) and _is_units_row(rows[1]):
        units = [c.strip().strip("()[]{}").strip() for c in rows[1]]
        header = [h if split_unit(h)[1] or not u else f"{h} [{u}]" for h, u in zip(header, units)]
        first = 2
    if len(numbered) <= first:
        raise RecordingError("file", "0 rows", "must hold at least 2 data rows")
    ti, wi = _choose_columns(header, column, time_column, has_dt)
    w, t, t_cells, clock = read_csv_body(
        data, encoding, first_line=numbered[first][0], delim=None if delim is None else
        delim.encode(), header=header, columns=(ti, wi), max_samples=max_samples,
    )  # fmt: skip
    time_unit = "s" if clock else (_time_unit(header[ti]) if ti is not None else None)
    return _Raw(
        w=w,
        t=t,
        unit=time_unit,
        value_unit=split_unit(header[wi])[1],
        source="csv",
        t_cells=t_cells,
        metadata={
            "columns": header,
            "value_column": header[wi],
            "time_column": header[ti] if ti is not None else None,
            **({} if encoding == "utf-8" else {"encoding": encoding}),
        },
    )


_RATE_NAMES = ("fs", "sample_rate", "sampling_rate", "samplerate", "srate", "sr", "rate")
_STEP_NAMES = ("dt", "ts", "sample_period", "sampling_period")


def _scalar(arrs: dict[str, Any], options: tuple[str, ...]) -> tuple[str | None, float | None]:
    """The first variable named one of ``options`` (any case) holding one number."""
    for key in arrs:
        if key.lower() in options:
            a = np.asarray(arrs[key])
            if np.size(a) != 1:
                raise RecordingError(f"file: {key}", list(np.shape(a)), "must be one number")
            if a.dtype.kind not in "iuf":
                raise RecordingError(f"file: {key}", str(a.dtype), "must be a number")
            return key, float(a.reshape(()))
    return None, None


def _is_scalar_number(v: Any) -> bool:
    a = np.asarray(v)
    return a.size == 1 and a.dtype.kind in "iuf"


def _pick(
    arrs: dict[str, Any], names: list[str], role: str, preferred: tuple[str, ...]
) -> str | None:
    """The variable with a name of ``role`` (the CSV's names, any case; ``preferred`` first)."""
    for n in preferred:
        if n in arrs:
            return n
    found = [n for n in names if _role(n.rsplit(".", 1)[-1]) == role]  # struct fields: rec.t
    if len(found) > 1:
        raise RecordingError(
            "file",
            names,
            f"has several {role} variables ({found}); name one with "
            + ("column" if role == "value" else "time_column"),
        )
    return found[0] if found else None


def _struct_fields(arrs: dict[str, Any]) -> dict[str, Any]:
    """MATLAB structs (one level) opened into their fields, named ``struct.field`` (not a
    struct named as a signal or a time: ``w`` must be numbers, and its error says so)."""
    out: dict[str, Any] = {}
    for k, v in arrs.items():
        a = np.asarray(v)
        if a.dtype.names and a.size == 1 and _role(k) is None:
            for f in a.dtype.names:
                out[f"{k}.{f}"] = a[f].reshape(-1)[0]
        else:
            out[k] = v
    return out


def _from_mapping(
    arrs: dict[str, Any], source: str, column: str | None, time_column: str | None
) -> _Raw:
    names = sorted(arrs)
    arrays = {k: v for k, v in arrs.items() if not _is_scalar_number(v)}
    if source == "npz" and len(arrs) == 1 and column is None and time_column is None:
        only = np.squeeze(np.asarray(next(iter(arrs.values()))))
        if only.ndim == 2 and 2 in only.shape:  # np.savez(f, table): one unnamed (n, 2) table
            a2 = only if only.shape[1] == 2 else only.T
            return _Raw(w=a2[:, 1], t=a2[:, 0], source=source,
                        metadata={"variables": names, "time_column": f"{names[0]}[:, 0]",
                                  "value_column": f"{names[0]}[:, 1]"})  # fmt: skip
    if time_column is not None:
        if time_column not in arrs:
            raise RecordingError(
                "time_column", time_column, f"is not a variable of the file ({names})"
            )
        tn: str | None = time_column
    else:
        tn = _pick(arrays, sorted(arrays), "time", ("t", "time"))
    if column is not None:
        if column not in arrs:
            raise RecordingError("column", column, f"is not a variable of the file ({names})")
        wn: str | None = column
    else:
        wn = _pick(arrays, sorted(arrays), "value", ("w", "signal", "x", "y", "value", "values"))
        others = [n for n in sorted(arrays) if n != tn]
        timed = tn is not None or any(k.lower() in _STEP_NAMES + _RATE_NAMES for k in arrs)
        if wn is None and len(others) == 1 and timed:
            wn = others[0]  # the one array besides the time (or the step): the signal
    if wn is None:
        raise RecordingError(
            "file",
            names,
            f"has no signal variable (one of {sorted(_VALUE_NAMES)}, or a single array "
            "besides a time or a step); name it with column",
        )
    w = np.squeeze(np.asarray(arrs[wn]))
    t = None if tn is None else np.squeeze(np.asarray(arrs[tn]))
    dn, dt = _scalar(arrs, _STEP_NAMES)
    rn, rate = _scalar(arrs, _RATE_NAMES)
    meta: dict[str, Any] = {"variables": names, "value_column": wn, "time_column": tn}
    if rate is not None:
        if not (np.isfinite(rate) and rate > 0):
            raise RecordingError(f"file: {rn}", rate, "must be a sample rate > 0")
        if dt is not None and abs(dt * rate - 1.0) > 1e-9:
            raise RecordingError(f"file: {rn}", rate, f"disagrees with {dn} = {dt!r} (1/{rn})")
        dt = 1.0 / rate if dt is None else dt
        meta["sample_rate"] = rate
    # units in the variables' names, as in a CSV header: t_ms, time_s, w_mm
    unit = _time_unit(tn.rsplit(".", 1)[-1]) if tn is not None else None
    value_unit = split_unit(wn.rsplit(".", 1)[-1])[1]
    return _Raw(w=w, t=t, dt=dt, source=source, metadata=meta, unit=unit, value_unit=value_unit)


def _parse(
    data: bytes,
    fmt: str,
    *,
    column: str | None,
    time_column: str | None,
    channel: Any,
    has_dt: bool,
    max_decompressed_bytes: int | None = None,
    max_samples: int | None = None,
) -> _Raw:
    if not data:
        raise RecordingError("file", "", "is empty")
    if fmt == "npy" and data[:4] == b"PK\x03\x04":
        fmt = "npz"  # an NPZ archive named .npy: read as what it is
    if fmt == "mat" and (b"MATLAB 7.3" in data[:128] or data[512:520] == b"\x89HDF\r\n\x1a\n"):
        raise RecordingError(
            "file", f"{len(data)} bytes", "is a MATLAB v7.3 (HDF5) file, which this reader "
            "cannot open: save it with save(name, '-v7'), or as CSV",
        )  # fmt: skip
    if fmt != "csv":  # one guard for every binary format, from the headers, before reading
        check_unpacked_size(data, fmt, max_decompressed_bytes)
    buf = io.BytesIO(data)
    if fmt == "csv":
        return _parse_csv(data, column=column, time_column=time_column, has_dt=has_dt,
                          max_samples=max_samples)  # fmt: skip
    if fmt == "npy":
        try:
            a = np.load(buf, allow_pickle=False)
        except Exception as exc:  # noqa: BLE001 - any parse failure is the file's fault
            raise load_failed(".npy", data, exc) from None
        if a.ndim == 2 and 1 in a.shape:
            a = a.reshape(-1)
        if a.ndim == 1:
            return _Raw(w=a, source="npy")
        if a.ndim == 2 and 2 in a.shape:
            a2 = a if a.shape[1] == 2 else a.T
            return _Raw(w=a2[:, 1], t=a2[:, 0], source="npy", metadata={"time_column": "t"})
        raise RecordingError("file", list(a.shape), "must be a 1-D array (w) or 2 columns (t, w)")
    if fmt == "npz":
        try:
            with np.load(buf, allow_pickle=False) as z:
                arrs = {k: z[k] for k in z.files}
        except Exception as exc:  # noqa: BLE001
            raise load_failed(".npz", data, exc) from None
        return _from_mapping(arrs, "npz", column, time_column)
    if fmt == "mat":
        from scipy.io import loadmat

        try:
            arrs = {k: v for k, v in loadmat(buf).items() if not k.startswith("__")}
        except Exception as exc:  # noqa: BLE001
            raise load_failed(".mat", data, exc) from None
        return _from_mapping(_struct_fields(arrs), "mat", column, time_column)
    if fmt == "wav":
        from scipy.io import wavfile

        try:
            rate, a = wavfile.read(buf)
        except Exception as exc:  # noqa: BLE001
            raise load_failed("WAV", data, exc) from None
        if not rate > 0:
            raise RecordingError("file: sample rate", rate, "must be > 0 (the WAV's fmt chunk)")
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
                 has_dt=dt is not None, max_decompressed_bytes=max_decompressed_bytes,
                 max_samples=max_samples)  # fmt: skip
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
