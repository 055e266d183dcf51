"""File layouts: CSV headers, NPY, NPZ, MAT, WAV; parsing before validation."""

from __future__ import annotations

import csv
import io
import os
import re
from pathlib import Path
from typing import Any

import numpy as np

from service.recordings._errors import (
    RecordingError,
    RecordingTooLarge,
    UnsupportedFormat,
)
from service.recordings._record import FORMATS, Recording, _Raw, uniform_rtol_from_env
from service.recordings._validate import _validate

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
    elif (fast := _mat5_unpacked_size(data)) is not None:
        total = fast
    else:  # not plain MAT v5 (v4, odd headers): scipy reads the variables' headers
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


_MAT_NUMERIC = frozenset({4, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15})  # char, double... uint64


def _mat5_unpacked_size(data: bytes) -> int | None:
    """Bytes the variables of a MAT v5 file hold once unpacked and read as float64, from the
    element tags and the first 64 inflated bytes of each compressed element (the rest is never
    inflated); None when the file is not plain MAT v5 (the caller asks scipy then)."""
    import struct
    import zlib

    if len(data) < 136 or data[126:128] not in (b"IM", b"MI"):
        return None
    end = "<" if data[126:128] == b"IM" else ">"
    total, pos = 0, 128
    while pos + 8 <= len(data):
        dtype, nbytes = struct.unpack(end + "II", data[pos : pos + 8])
        start = pos
        pos += 8 + nbytes + (-nbytes % 8 if dtype != 15 else 0)
        if dtype == 15:  # miCOMPRESSED: a miMATRIX element, deflated
            try:
                head = zlib.decompressobj().decompress(data[start + 8 : pos], 64)
            except zlib.error:
                return None
        elif dtype == 14:  # miMATRIX, with its tag
            head = data[start : start + 64]
        else:
            continue
        if len(head) < 40 or struct.unpack(end + "I", head[:4])[0] != 14:
            return None
        inner_bytes = struct.unpack(end + "I", head[4:8])[0]
        cls = struct.unpack(end + "I", head[16:20])[0] & 0xFF
        dims_type, dims_bytes = struct.unpack(end + "II", head[24:32])
        if cls not in _MAT_NUMERIC or dims_type != 5 or dims_bytes % 4 or 32 + dims_bytes > 64:
            total += 8 * inner_bytes  # cells, structs, sparse: their bytes, counted as doubles
            continue
        count = 1
        for d in struct.unpack(end + f"{dims_bytes // 4}i", head[32 : 32 + dims_bytes]):
            count *= max(0, d)
        total += 8 * count
    return total


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
