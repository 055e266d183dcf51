"""Time units of recordings: seconds per unit, and one time base for the records of a sweep.

A sweep's records may be written by different instruments, one in seconds, another in
milliseconds. Their poles (1/time) can only be compared in one unit: records whose units differ
are brought to seconds when every unit is a known time unit, and refused otherwise (naming the
records and their units), never mixed.
"""

from __future__ import annotations

from collections.abc import Sequence

from service.recordings._errors import RecordingError

#: Seconds per unit, by the unit's name as headers write it (lower case; ``us``, ``µs`` and
#: ``μs`` all micro).
SECONDS_PER = {
    "s": 1.0, "sec": 1.0, "secs": 1.0, "second": 1.0, "seconds": 1.0,
    "ms": 1e-3, "msec": 1e-3, "millisecond": 1e-3, "milliseconds": 1e-3,
    "us": 1e-6, "µs": 1e-6, "μs": 1e-6, "usec": 1e-6, "microsecond": 1e-6,
    "microseconds": 1e-6,
    "ns": 1e-9, "nsec": 1e-9, "nanosecond": 1e-9, "nanoseconds": 1e-9,
    "min": 60.0, "minute": 60.0, "minutes": 60.0, "h": 3600.0, "hr": 3600.0, "hour": 3600.0,
    "hours": 3600.0,
}  # fmt: skip


def seconds_per(unit: str | None) -> float | None:
    """Seconds in one ``unit`` of time (``"ms"`` -> 1e-3); None for no unit or an unknown one."""
    if unit is None:
        return None
    return SECONDS_PER.get(unit.strip().lower())


def common_time_base(
    units: Sequence[str | None], names: Sequence[str]
) -> tuple[list[float], str | None]:
    """Factors that bring each record's time step to one unit, and that unit.

    Parameters
    ----------
    units : sequence of str or None
        Each record's time unit as read (``Recording.unit``).
    names : sequence of str
        The records' names (file names, signal ids), for the error.

    Returns
    -------
    factors : list of float
        Multiply each record's ``dt`` by its factor: all 1 when the units agree (or none is
        given), else seconds per unit.
    unit : str or None
        The common unit: the shared one, or ``"s"`` after conversion.

    Raises
    ------
    RecordingError
        ``records``: the units differ and one of them is missing or not a known time unit.
    """
    if len(set(units)) <= 1:
        return [1.0] * len(units), (units[0] if units else None)
    per = [seconds_per(u) for u in units]
    if all(p is not None for p in per):
        return [float(p) for p in per], "s"  # type: ignore[arg-type]
    listing = "(" + ", ".join(f"{n}: {u if u is not None else 'none given'}"
                              for n, u in zip(names, units)) + ")"  # fmt: skip
    raise RecordingError(
        "records",
        listing,
        "give their times in different units, not all of them known time units: write every "
        "record in one time unit, or name each one's in its header (e.g. 't [ms]')",
    )
