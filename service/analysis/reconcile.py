"""The fundamental across a sweep: each record's choice made consistent with its neighbours.

A detection alone picks its fundamental as the slowest significant mode of its record. Across a
sweep the critical mode is the one whose ``sigma^2`` moves continuously with the control (and
softens towards the transition); :func:`reconcile` checks each record's choice against that and
sets aside (flag ``record_set_aside``, with the reason and the record's name) the records that
cannot be trusted, so that the sweep policy leaves them out and goes on with the others.

Set aside:

* a record with no fundamental (flag ``no_mode``), a non-finite one, or one with
  ``sigma^2 >= 0`` (no stable mode to follow: the strip grows, is driven, or the detector
  read a drift);
* (with ``band``) a record whose fundamental lies outside the user's band ``[lo, hi]`` of
  ``sqrt|sigma^2|`` (rad per time unit of the record) when no other mode of it lies inside.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import replace

import numpy as np

from service.analysis.common import Flag
from service.analysis.detect import Detection, Fundamental
from service.analysis.errors import ParameterError

__all__ = ["SET_ASIDE", "reconcile", "set_aside"]

#: The flag code of a record left out of a sweep (its message gives the reason and the name).
SET_ASIDE = "record_set_aside"


def set_aside(det: Detection, name: str, reason: str) -> Detection:
    """``det`` with the flag ``record_set_aside`` added: ``"<name>: <reason>"`` (once)."""
    if any(f.code == SET_ASIDE for f in det.flags):
        return det
    flag = Flag(SET_ASIDE, f"record {name} set aside: {reason}")
    return replace(det, flags=(*det.flags, flag))


def _validate(
    detections: Sequence[Detection],
    controls: np.ndarray,
    names: Sequence[str],
    band: tuple[float, float] | None,
) -> tuple[np.ndarray, tuple[float, float] | None]:
    n = len(detections)
    c = np.asarray(controls, dtype=float)
    if c.ndim != 1 or c.size != n:
        raise ParameterError(
            "controls", list(np.shape(c)), f"controls: expected {n} values (one per detection), "
            f"got shape {np.shape(c)}"
        )  # fmt: skip
    if not np.all(np.isfinite(c)):
        i = int(np.flatnonzero(~np.isfinite(c))[0])
        raise ParameterError("controls", float(c[i]), f"controls[{i}] = {c[i]!r}: not finite")
    if len(names) != n:
        raise ParameterError(
            "names", len(names), f"names: expected {n} names (one per detection), got {len(names)}"
        )
    if band is None:
        return c, None
    try:
        lo, hi = (float(v) for v in band)
    except (TypeError, ValueError):
        msg = f"band={band!r}: expected two numbers (lo, hi)"
        raise ParameterError("band", band, msg) from None
    if not (math.isfinite(lo) and math.isfinite(hi) and 0 <= lo < hi):
        raise ParameterError(
            "band", [lo, hi], f"band=({lo!r}, {hi!r}): expected finite 0 <= lo < hi"
        )
    return c, (lo, hi)


def _stable(det: Detection) -> str | None:
    """Why ``det`` has no stable fundamental to follow (None: it has one)."""
    f = det.fundamental
    if f is None:
        return "no mode found in it (flag no_mode)"
    if not math.isfinite(f.sigma2):
        return f"its fundamental's sigma^2 is not finite ({f.sigma2!r})"
    if f.sigma2 >= 0:
        return (
            f"its fundamental has sigma^2 = {f.sigma2:.6g} >= 0 (a growing pole: the strip is "
            "past its transition or driven there, or a drift was read as a mode)"
        )
    return None


def _in_band(sigma2: float, band: tuple[float, float]) -> bool:
    return band[0] <= math.sqrt(abs(sigma2)) <= band[1]


def _choose_in_band(det: Detection, band: tuple[float, float]) -> Detection | None:
    """``det`` with its fundamental moved to the slowest stable mode inside ``band`` (None when
    no mode is there). Combination tones are never chosen."""
    idx = [
        k for k, m in enumerate(det.modes)
        if m.combination is None and math.isfinite(m.sigma2) and m.sigma2 < 0
        and _in_band(m.sigma2, band)
    ]  # fmt: skip
    if not idx:
        return None
    k = min(idx, key=lambda j: abs(det.modes[j].sigma2))
    if det.fundamental is not None and det.fundamental.index == k:
        return det
    old = det.fundamental
    was = f"sqrt|sigma^2| = {math.sqrt(abs(old.sigma2)):.6g}" if old is not None else "none"
    flag = Flag(
        "fundamental_band",
        f"the fundamental is modes[{k}] (sqrt|sigma^2| = "
        f"{math.sqrt(abs(det.modes[k].sigma2)):.6g}), the slowest mode in the band "
        f"[{band[0]:.6g}, {band[1]:.6g}] given for it (the record's slowest mode: {was})",
    )
    return replace(det, fundamental=Fundamental(det.modes[k], k), flags=(*det.flags, flag))


def reconcile(
    detections: Sequence[Detection],
    controls: np.ndarray,
    *,
    names: Sequence[str],
    band: tuple[float, float] | None = None,
) -> tuple[Detection, ...]:
    """The detections of a sweep with each record's fundamental chosen consistently.

    Parameters
    ----------
    detections : sequence of Detection
        One per record, in any order.
    controls : array_like, shape (n,)
        Each record's control value (user unit).
    names : sequence of str
        Each record's name (a file name); set-aside messages give it, never an index.
    band : (lo, hi) or None
        The user's band for the fundamental's ``sqrt|sigma^2|`` (rad per time unit of the
        records); a record's fundamental is the slowest stable mode inside it.

    Returns
    -------
    tuple of Detection
        Same order as given; a record that cannot be trusted carries the flag
        ``record_set_aside`` (the reason and its name); the others are unchanged or carry the
        flag saying which mode was chosen instead of the record's own.

    Raises
    ------
    ParameterError
        ``controls`` or ``names`` of the wrong length, a non-finite control, a bad ``band``.
    """
    _, band = _validate(detections, controls, names, band)
    out: list[Detection] = []
    for det, name in zip(detections, names, strict=True):
        if band is not None and det.fundamental is not None:
            moved = _choose_in_band(det, band)
            if moved is None:
                out.append(set_aside(det, name, f"no stable mode in the band "
                                                f"[{band[0]:.6g}, {band[1]:.6g}] given for the "
                                                "fundamental"))  # fmt: skip
                continue
            det = moved
        why = _stable(det)
        out.append(det if why is None else set_aside(det, name, why))
    return tuple(out)
