"""The CSV reader, streamed: memory bounded by the body and the sample limit, never by rows.

The bytes are read in blocks of about :data:`BLOCK` bytes cut at line ends; each block's lines
are split once and the two columns wanted are converted to float64 by numpy (C parsing of the
cells' bytes), so no Python object outlives its block. Before any parsing a vectorised count
of the lines that certainly hold data (a line start that is not blank, not a comment)
refuses a file with more rows than ``max_samples`` in milliseconds; while parsing, the rows
are counted and the reader stops at the limit. Peak memory: the body, the float64 columns
(bounded by the sample limit), the time column's text (for the rounding rules of
:mod:`service.recordings._sampling`) and one block's objects.

The text rules are those of :func:`service.recordings._formats.content_lines` (comments,
a header written as the last comment, ``sep=`` lines, units rows, decimal commas, clock
times); numbers are ASCII in every encoding read (UTF-8, UTF-16 with its BOM, Windows-1252).
"""

from __future__ import annotations

import codecs
import csv
import io
from collections.abc import Iterator
from operator import itemgetter
from typing import Any

import numpy as np

from service.recordings._clock import clock_seconds, is_clock
from service.recordings._errors import RecordingError, RecordingTooLarge

#: Bytes per block (cut at a line end); one block's Python objects are alive at a time.
BLOCK = 1 << 20
#: Lines before the data that are not data: a ``sep=`` line, the header, a units row.
_HEAD_LINES = 3

_NOT_DATA_START = np.zeros(256, dtype=bool)
for _c in b"#\r\n \t":
    _NOT_DATA_START[_c] = True


def ascii_text(data: bytes) -> tuple[bytes, str]:
    """The bytes with an ASCII-compatible encoding, and the encoding read.

    UTF-16 with its BOM is transcoded to UTF-8; UTF-8 (a BOM dropped) is checked in blocks,
    never decoded whole; anything else without NUL bytes is Windows-1252."""
    if data[:2] in (b"\xff\xfe", b"\xfe\xff"):
        try:
            return data.decode("utf-16").encode("utf-8"), "utf-16"
        except UnicodeDecodeError as exc:
            raise RecordingError("file", f"byte {exc.start}", "is not UTF-16 text") from None
    dec = codecs.getincrementaldecoder("utf-8")()
    try:
        for i in range(0, len(data), BLOCK):
            dec.decode(data[i : i + BLOCK])
        dec.decode(b"", final=True)
    except UnicodeDecodeError as exc:
        if data.find(b"\x00") >= 0:  # binary, or UTF-16 without a BOM: never 8-bit text
            raise RecordingError("file", f"byte {i + exc.start}", "is not UTF-8 text") from None
        return data, "cp1252"
    if data.startswith(codecs.BOM_UTF8):
        data = data[3:]
    return data, "utf-8"


def check_row_count(data: bytes, max_samples: int | None) -> None:
    """413 (:class:`RecordingTooLarge`) when the text certainly holds more than ``max_samples``
    data rows: the lines whose first byte is neither blank nor ``#`` are counted, vectorised,
    block by block (a lower bound of the data rows: the header, a units row and a ``sep=``
    line are allowed for)."""
    if max_samples is None or len(data) <= 2 * (max_samples + _HEAD_LINES):
        return  # too short to hold that many rows ("1\n" is the shortest)
    arr = np.frombuffer(data, dtype=np.uint8)
    count = 0 if _NOT_DATA_START[arr[0]] else 1
    for i in range(0, arr.size, BLOCK):
        seg = arr[i : i + BLOCK + 1]
        ends = np.flatnonzero((seg[:-1] == 10) | (seg[:-1] == 13))
        count += int(np.count_nonzero(~_NOT_DATA_START[seg[ends + 1]]))
        if count > max_samples + _HEAD_LINES:
            raise RecordingTooLarge(
                "file",
                f"{len(data)} bytes",
                f"holds more than {max_samples} rows, the limit of samples "
                "(setting SNAPWARN_MAX_SAMPLES)",
            )


def _blocks(data: bytes) -> Iterator[tuple[int, int, int, list[bytes]]]:
    """``(number of the first line, first byte, end byte, lines)`` of each block of about
    :data:`BLOCK` bytes, cut after a line end."""
    pos, line = 0, 1
    n = len(data)
    while pos < n:
        end = pos + BLOCK
        if end >= n:
            end = n
        else:
            cut = [k for k in (data.find(b"\n", end), data.find(b"\r", end)) if k >= 0]
            end = min(cut) + 1 if cut else n
            if end < n and data[end - 1] == 13 and data[end] == 10:
                end += 1
        lines = data[pos:end].splitlines()
        yield line, pos, end, lines
        line += len(lines)
        pos = end


def _content(first: int, lines: list[bytes]) -> tuple[list[int], list[bytes]]:
    """The data lines of a block and their numbers (blank lines and ``#`` comments dropped)."""
    nums, kept = [], []
    for k, ln in enumerate(lines, first):
        s = ln.lstrip()
        if s and not s.startswith(b"#") and s.strip():
            nums.append(k)
            kept.append(ln)
    return nums, kept


class _Where:
    """``where[k]``: the place of data row ``k`` for an error (built only when asked)."""

    def __init__(self, lines: list[int], column: str) -> None:
        self.lines, self.column = lines, column

    def __getitem__(self, k: int) -> str:
        return f"file: line {self.lines[k]}, column {self.column!r}"


class _Batch:
    """One block's data rows: where they are in the body and how many."""

    def __init__(self, lo: int, hi: int, first: int, rows: int) -> None:
        self.lo, self.hi, self.first, self.rows = lo, hi, first, rows


class _LazyCells:
    """The time column as written (``cells[k]`` -> str), read again from the body only when
    asked (the rounding rules of a non-uniform record look at a sample of the cells): one
    block split at a time, the last one kept."""

    def __init__(self, data: bytes, batches: list[_Batch], delim: bytes | None, encoding: str,
                 column: int, comma: bool) -> None:  # fmt: skip
        self.data, self.batches, self.delim, self.encoding = data, batches, delim, encoding
        self.column, self.comma = column, comma
        self.starts = np.cumsum([0] + [b.rows for b in batches])
        self._at: int | None = None
        self._cells: list[bytes] = []

    def __len__(self) -> int:
        return int(self.starts[-1])

    def __getitem__(self, k: int) -> str:
        j = int(np.searchsorted(self.starts, k, side="right")) - 1
        if j != self._at:
            b = self.batches[j]
            _, lines = _content(b.first, self.data[b.lo : b.hi].splitlines())
            rows = _split(lines, self.delim, self.encoding)
            self._cells = [r[self.column].strip() for r in rows]
            if self.comma:
                self._cells = [c.replace(b",", b".") for c in self._cells]
            self._at = j
        return self._cells[k - int(self.starts[j])].decode("latin-1")


def _split(lines: list[bytes], delim: bytes | None, encoding: str) -> list[list[bytes]]:
    """Each line's cells (bytes): ``csv`` rules where a quote appears, else a plain split."""
    if delim is None:
        return [ln.split() for ln in lines]
    if any(b'"' in ln for ln in lines):
        enc = "latin-1" if encoding == "cp1252" else "utf-8"
        rows = csv.reader([ln.decode(enc, "replace") for ln in lines], delimiter=delim.decode())
        return [[c.encode(enc, "replace") for c in r] for r in rows]
    return [ln.split(delim) for ln in lines]


def _floats(texts: list[bytes], where: _Where, k0: int) -> np.ndarray:
    """The cells as float64 (numpy's C conversion); an error names the first bad cell."""
    try:
        return np.array(texts, dtype=np.bytes_).astype(np.float64)
    except (ValueError, OverflowError):
        pass
    out = np.empty(len(texts))
    for k, cell in enumerate(texts):
        try:
            out[k] = float(cell)
        except ValueError:
            text = cell.decode("latin-1").strip()
            raise RecordingError(where[k0 + k], text, "is not a number") from None
    return out


def _fast(block: bytes, delim: bytes | None, ncol: int) -> np.ndarray | None:
    """The block's rows as float64 ``(rows, ncol)`` by numpy's C reader, or None where the
    block needs the careful path (quotes, comments, text cells, ragged rows: its errors)."""
    if b'"' in block or b"#" in block:
        return None
    try:
        a = np.loadtxt(io.StringIO(block.decode("latin-1")), dtype=np.float64, comments=None,
                       delimiter=None if delim is None else delim.decode(), ndmin=2)  # fmt: skip
    except ValueError:
        return None
    return a if a.shape[1] == ncol or a.shape[0] == 0 else None


def read_csv_body(
    data: bytes,
    encoding: str,
    *,
    first_line: int,
    delim: bytes | None,
    header: list[str],
    columns: tuple[int | None, int],
    max_samples: int | None,
) -> tuple[np.ndarray, np.ndarray | None, Any, bool]:
    """The data rows of a CSV from line ``first_line`` on (the line after the header or its
    units row): ``(w, t, the time cells as written, whether t is a clock)``; ``columns``: (time
    index or None, value index). Stops at ``max_samples`` rows (:class:`RecordingTooLarge`).

    Each block is read by numpy's C reader where it is plain numbers; else (quotes, comments,
    text in other columns, decimal commas, clock times, an error to name) cell by cell."""
    ti, wi = columns
    ncol = len(header)
    parts: dict[int, list[np.ndarray]] = {i: [] for i in (ti, wi) if i is not None}
    batches: list[_Batch] = []
    clock: list[str] | None = None
    clock_lines: list[int] = []
    comma: dict[int, bool] = {}
    count = 0
    for first, lo, hi, lines in _data_blocks(data, first_line):
        block = data[lo:hi]
        if not comma:  # decimal commas: decided once, on the first data block
            nums, kept = _content(first, lines)
            rows = _split(kept[:50], delim, encoding)
            for idx in parts:
                comma[idx] = delim in (b";", b"\t") and any(b"," in r[idx] for r in rows
                                                              if len(r) == ncol)  # fmt: skip
            if ti is not None and rows and len(rows[0]) == ncol:
                cell = rows[0][ti].strip().decode("latin-1")
                if not _is_number(cell) and is_clock(cell):
                    clock = []
        a = None
        if clock is None and not any(comma.values()):
            a = _fast(block, delim, ncol)
        if a is not None:
            n = a.shape[0]
            for idx in parts:
                parts[idx].append(np.ascontiguousarray(a[:, idx]))
        else:
            nums, kept = _content(first, lines)
            rows = _split(kept, delim, encoding)
            for k, r in enumerate(rows):
                if len(r) != ncol:
                    raise RecordingError(
                        f"file: line {nums[k]}", f"{len(r)} cells",
                        f"is ragged: the header has {ncol} columns",
                    )  # fmt: skip
            n = len(rows)
            for idx in parts:
                texts = [c.strip() for c in map(itemgetter(idx), rows)]
                if idx == ti and clock is not None:
                    clock.extend(c.decode("latin-1") for c in texts)
                    clock_lines.extend(nums)
                    continue
                if comma[idx]:
                    texts = [c.replace(b",", b".") for c in texts]
                parts[idx].append(_floats(texts, _Where(nums, header[idx]), 0))
        count += n
        if max_samples is not None and count > max_samples:
            raise RecordingTooLarge(
                "file",
                f"more than {max_samples} rows",
                f"samples exceed the limit of {max_samples} (setting SNAPWARN_MAX_SAMPLES)",
            )
        batches.append(_Batch(lo, hi, first, n))
    if count < 2:
        raise RecordingError("file", f"{count} rows", "must hold at least 2 data rows")
    w = np.concatenate(parts[wi])
    if ti is None:
        return w, None, None, False
    if clock is not None:
        t, texts = clock_seconds(clock, _Where(clock_lines, header[ti]))  # type: ignore[arg-type]
        return w, t, texts, True
    cells = _LazyCells(data, batches, delim, encoding, ti, comma.get(ti, False))
    return w, np.concatenate(parts[ti]), cells, False


def _data_blocks(data: bytes, first_line: int) -> Iterator[tuple[int, int, int, list[bytes]]]:
    """The blocks (as :func:`_blocks`) from line ``first_line`` on."""
    for start, lo, hi, lines in _blocks(data):
        if start + len(lines) <= first_line:
            continue
        if start < first_line:
            skip = first_line - start
            for ln in lines[:skip]:  # the bytes of the lines skipped, with their line ends
                lo += len(ln)
                while lo < hi and data[lo] in (10, 13):
                    lo += 1
                    if data[lo - 1] == 13 and lo < hi and data[lo] == 10:
                        lo += 1
                    break
            lines, start = lines[skip:], first_line
        if lines:
            yield start, lo, hi, lines


def _is_number(s: str) -> bool:
    """A number as a file writes it: ``1.5``, ``-2e-3``, or with a decimal comma (``0,0035``:
    a spreadsheet's export under a ``;`` or tab separator)."""
    for text in (s, s.replace(",", ".", 1)):
        try:
            float(text)
        except ValueError:
            continue
        return True
    return False
