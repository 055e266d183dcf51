"""The stored form of a live sweep's records: plain JSON types, read back exactly.

The API keeps each :class:`service.analysis.live.LiveRecord` as a JSON document (NaN kept as
a float); these functions are its only writer and reader.
"""

from __future__ import annotations

import math
from dataclasses import asdict
from typing import Any

from service.analysis.common import Flag
from service.analysis.live import LiveRecord
from service.analysis.measurement import Measurement

__all__ = ["measurement_from_dict", "record_from_dict", "record_to_dict"]


def measurement_from_dict(d: dict[str, Any] | None) -> Measurement | None:
    """Inverse of the stored measurement of :func:`record_to_dict` (None and missing numbers
    become NaN)."""
    if d is None:
        return None

    def num(k: str) -> float:
        v = d.get(k)
        return math.nan if v is None else float(v)

    return Measurement(
        mu=num("mu"),
        omega=num("omega"),
        sigma2=num("sigma2"),
        sigma2_std=num("sigma2_std"),
        w_static=num("w_static"),
        w_static_std=num("w_static_std"),
        regime=str(d.get("regime") or "underdamped"),
        duration=num("duration"),
        dt=num("dt"),
        flags=tuple(Flag(f["code"], f["message"]) for f in d.get("flags") or ()),
    )


def _measurement_dict(m: Measurement | None) -> dict[str, Any] | None:
    """A measurement's fields as stored (its flags as ``{code, message}``; NaN kept)."""
    if m is None:
        return None
    d = asdict(m)
    d["flags"] = list(d["flags"])
    return d


def record_to_dict(r: LiveRecord) -> dict[str, Any]:
    """The stored form of a :class:`LiveRecord` (plain JSON types; NaN kept as float)."""
    return {
        "seq": r.seq,
        "control": r.control,
        "measurement": _measurement_dict(r.measurement),
        "flags": [asdict(f) for f in r.flags],
        "interval": list(r.interval) if r.interval is not None else None,
        "next_control": r.next_control,
        "time_unit": r.time_unit,
        "name": r.name,
    }


def record_from_dict(d: dict[str, Any]) -> LiveRecord:
    """Inverse of :func:`record_to_dict` (None numbers become NaN)."""
    iv = d.get("interval")
    interval = None
    if iv is not None and all(v is not None for v in iv):
        interval = (float(iv[0]), float(iv[1]))
    nxt = d.get("next_control")
    return LiveRecord(
        seq=int(d["seq"]),
        control=float(d["control"]),
        measurement=measurement_from_dict(d.get("measurement")),
        flags=tuple(Flag(f["code"], f["message"]) for f in d.get("flags") or ()),
        interval=interval,
        next_control=math.nan if nxt is None else float(nxt),
        time_unit=d.get("time_unit"),
        name=d.get("name"),
    )
