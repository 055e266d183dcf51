"""Times a logger writes as clock readings: ISO 8601 date-times (``2026-11-27T10:00:00.125``,
``2026-11-27 10:00:00.125+01:00``, ``...Z``) or times of day (``10:00:00.125``).

They are read as seconds since the first reading, written back as text with the readings' own
number of decimals: the sampling check then knows the quantum they were rounded to (a logger
writing milliseconds rounds to 0.5 ms), exactly as for a column of plain numbers.
"""

from __future__ import annotations

import datetime as _dt
import re

import numpy as np

from service.recordings._errors import RecordingError

_CLOCK = re.compile(r"^(?:\d{4}-\d{2}-\d{2}[T ])?\d{1,2}:\d{2}(?::\d{2}(?:[.,](?P<frac>\d+))?)?")


def _parse_one(cell: str) -> tuple[_dt.datetime | _dt.time, int]:
    """One reading and its number of decimals; ValueError if it is none."""
    m = _CLOCK.match(cell)
    if m is None:
        raise ValueError(cell)
    text = cell.replace(",", ".", 1) if m.group("frac") else cell
    decimals = len(m.group("frac") or "")
    if ":" in cell[:3]:  # a time of day: "10:00:00.125"
        return _dt.time.fromisoformat(text), decimals
    return _dt.datetime.fromisoformat(text), decimals


def _seconds(value: _dt.datetime | _dt.time) -> float:
    if isinstance(value, _dt.time):
        micro = ((value.hour * 60 + value.minute) * 60 + value.second) * 1_000_000
        return (micro + value.microsecond) / 1e6
    return value.timestamp() if value.tzinfo else value.replace(tzinfo=_dt.UTC).timestamp()


def is_clock(cell: str) -> bool:
    """Whether ``cell`` reads as a clock time (an ISO 8601 date-time or a time of day)."""
    try:
        _parse_one(cell.strip())
    except ValueError:
        return False
    return True


def clock_seconds(cells: list[str], where: list[str]) -> tuple[np.ndarray, list[str]]:
    """Seconds since the first reading, and the same as text with the readings' decimals.

    Parameters
    ----------
    cells : list of str
        The readings as written.
    where : list of str
        Each cell's place for errors (``"file: line 7, column 'time'"``).

    Raises
    ------
    RecordingError
        A cell that is not a clock reading, or readings that mix time zones with none.
    """
    seconds = np.empty(len(cells))
    most = 0
    aware = None
    for k, cell in enumerate(cells):
        try:
            value, decimals = _parse_one(cell.strip())
        except ValueError:
            raise RecordingError(where[k], cell, "is not a clock time like the first") from None
        has_zone = isinstance(value, _dt.datetime) and value.tzinfo is not None
        if aware is None:
            aware = has_zone
        elif has_zone != aware:
            raise RecordingError(where[k], cell, "mixes readings with and without a time zone")
        seconds[k] = _seconds(value)
        most = max(most, decimals)
    rel = seconds - seconds[0]
    if isinstance(_parse_one(cells[0].strip())[0], _dt.time):
        rel = np.where(rel < 0, rel + 86_400.0, rel)  # a time of day past midnight
    return rel, [f"{v:.{most}f}" for v in rel]
