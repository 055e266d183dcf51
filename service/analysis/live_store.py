"""The stored form of a live sweep's records: plain JSON types, read back exactly.

The API keeps each :class:`service.analysis.live.LiveRecord` as a JSON document (NaN kept as
a float); these functions are its only writer and reader. The record's detection is kept too,
so that a sweep read back from the store (a restarted server, another worker) still chooses
each record's fundamental across the whole sweep (:mod:`service.analysis.reconcile`); a
non-finite number in it reads back as NaN, and a record stored without it reads back without.
"""

from __future__ import annotations

import math
from dataclasses import asdict, fields
from typing import Any

from service.analysis.common import Flag
from service.analysis.detect import Detection, Fundamental, Mode
from service.analysis.live import LiveRecord
from service.analysis.measurement import Measurement

__all__ = [
    "detection_from_dict",
    "detection_to_dict",
    "measurement_from_dict",
    "record_from_dict",
    "record_to_dict",
]


def _flags(d: Any) -> tuple[Flag, ...]:
    return tuple(Flag(f["code"], f["message"]) for f in d or ())


def _fields_of(cls: type, d: dict[str, Any], skip: tuple[str, ...] = ()) -> dict[str, Any]:
    """The stored fields of dataclass ``cls`` (None floats back to NaN, lists to tuples)."""
    out: dict[str, Any] = {}
    for f in fields(cls):
        if f.name in skip or f.name not in d:
            continue
        v = d[f.name]
        if v is None and f.type == "float":
            v = math.nan
        elif isinstance(v, list):
            v = tuple(math.nan if x is None else x for x in v)
        out[f.name] = v
    return out


def _mode_from_dict(d: dict[str, Any]) -> Mode:
    return Mode(**_fields_of(Mode, d))


def detection_to_dict(det: Detection | None) -> dict[str, Any] | None:
    """A detection as plain JSON types (its modes, fundamental and flags)."""
    if det is None:
        return None
    d = asdict(det)
    d["flags"] = [asdict(f) for f in det.flags]
    return d


def detection_from_dict(d: dict[str, Any] | None) -> Detection | None:
    """Inverse of :func:`detection_to_dict` (None: no detection stored)."""
    if d is None:
        return None
    fund = d.get("fundamental")
    return Detection(
        modes=tuple(_mode_from_dict(m) for m in d.get("modes") or ()),
        fundamental=None if fund is None else Fundamental(_mode_from_dict(fund["mode"]),
                                                          int(fund["index"])),  # fmt: skip
        flags=_flags(d.get("flags")),
        **_fields_of(Detection, d, skip=("modes", "fundamental", "flags")),
    )


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
        "detection": detection_to_dict(r.detection),
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
        detection=detection_from_dict(d.get("detection")),
    )
