"""Tables of numbers a lab writes by hand or by spreadsheet (a sweep, a manifest of records).

The same text rules as the recordings' CSV (:mod:`service.recordings._formats`): UTF-8 with or
without a BOM, UTF-16 with its BOM, else Windows-1252; ``#`` comment lines and blank lines
skipped (a header written as the last comment before numbers, as ``numpy.savetxt`` writes
it, is read as the header); ``,``, ``;``, tab or blanks between cells; a unit in the header
(``mu [deg]``, ``omega (Hz)``, ``mu_deg``) or in a row of units under it; decimal commas with
``;`` or tab.
Errors name the line a text editor shows and the column.
"""

from __future__ import annotations

import csv
import math
from dataclasses import dataclass, field

import numpy as np

from service.recordings._errors import RecordingError
from service.recordings._formats import (
    _decode,
    _is_number,
    _is_units_row,
    _sep_hint,
    content_lines,
    split_unit,
)


@dataclass(frozen=True)
class Table:
    """A table read from text: cells by column, with the header's names and units.

    Attributes
    ----------
    names : list of str
        The columns' names without their units, as written (``"mu"`` for ``"mu [deg]"``).
    units : dict
        ``name -> unit`` (None when the header gives none).
    cells : dict
        ``name -> list of str``: the cells as written (stripped).
    lines : list of int
        The line of the file each row comes from (1-based).
    """

    names: list[str]
    units: dict[str, str | None]
    cells: dict[str, list[str]]
    lines: list[int] = field(default_factory=list)

    def find(self, *options: str) -> str | None:
        """The first column named one of ``options`` (any case), or None."""
        low = {n.lower(): n for n in self.names}
        for o in options:
            if o.lower() in low:
                return low[o.lower()]
        return None

    def floats(self, name: str, what: str = "file") -> np.ndarray:
        """Column ``name`` as finite float64; an error names the line, the column, the cell."""
        out = np.empty(len(self.lines))
        for k, cell in enumerate(self.cells[name]):
            where = f"{what}: line {self.lines[k]}, column {name!r}"
            try:
                v = float(cell)
            except ValueError:
                raise RecordingError(where, cell, "is not a number") from None
            if not math.isfinite(v):
                raise RecordingError(
                    where, cell, "must be a finite number (remove the row, or fill the cell)"
                )
            out[k] = v
        return out


def read_table(data: bytes, *, what: str = "file") -> Table:
    """Read a table with a header row (the module's rules); ``what`` names the input in errors.

    Rows whose cells are all empty (a spreadsheet's trailing ``,,``) are skipped.
    """
    text, _ = _decode(data)
    numbered = content_lines(text)
    numbered, hint = _sep_hint(numbered)
    if not numbered:
        raise RecordingError(what, "", "is empty (a table needs a header row and data rows)")
    head = numbered[0][1]
    delim = hint or max((",", ";", "\t"), key=head.count)
    lines = [ln for _, ln in numbered]
    if head.count(delim):
        rows = list(csv.reader(lines, delimiter=delim))
    else:
        delim, rows = " ", [ln.split() for ln in lines]
    header = [h.strip() for h in rows[0]]
    if all(_is_number(h) for h in header):
        raise RecordingError(
            what, ",".join(header)[:80], "has no header row (the first line must name the columns)"
        )
    first = 1
    units_row: list[str | None] = [None] * len(header)
    if len(rows) > 1 and len(rows[1]) == len(header) and _is_units_row(rows[1]):
        units_row = [c.strip().strip("()[]{}").strip() or None for c in rows[1]]
        first = 2
    names, units = [], {}
    for h, u in zip(header, units_row):
        name, unit = split_unit(h)
        if name in units:
            raise RecordingError(what, header, f"names the column {name!r} twice")
        names.append(name)
        units[name] = unit or u
    cells: dict[str, list[str]] = {n: [] for n in names}
    kept: list[int] = []
    decimal_commas = delim in (";", "\t")
    for (line, _), row in zip(numbered[first:], rows[first:]):
        if all(not c.strip() for c in row):
            continue
        if len(row) != len(names):
            raise RecordingError(
                f"{what}: line {line}", f"{len(row)} cells", f"is ragged: the header has "
                f"{len(names)} columns ({header})",
            )  # fmt: skip
        for n, c in zip(names, row):
            c = c.strip()
            cells[n].append(c.replace(",", ".") if decimal_commas else c)
        kept.append(line)
    if not kept:
        raise RecordingError(what, header, "has no data rows")
    return Table(names, units, cells, kept)


#: Names of a manifest's column of record files (any case).
PATH_NAMES = ("path", "file", "filename", "file_name", "record", "recording")


def manifest_columns(table: Table, control: str | None = None) -> tuple[str, str]:
    """The columns of a manifest of records: the files (named one of :data:`PATH_NAMES`) and
    the control (named ``control``, or ``control`` given). An error lists the columns found."""
    path_col = table.find(*PATH_NAMES)
    control_col = table.find(control or "control")
    if path_col is None or control_col is None:
        raise RecordingError(
            "file", table.names,
            f"needs the header 'path,{control or 'control'}' (the files' column may also be "
            f"named {', '.join(PATH_NAMES[1:])}; columns found: {table.names}; name the "
            "control column if it is not 'control')",
        )  # fmt: skip
    return path_col, control_col
