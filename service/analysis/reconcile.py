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
  ``sqrt|sigma^2|`` (rad per time unit of the record) when no other mode of it lies inside;
* a record off the sweep's branch (:func:`_off_branch`) with no other mode on it.

The branch: the records sorted by control, the fundamental's ``r = sqrt|sigma^2|`` of a record
between two others lies (within :data:`BRANCH_TOL`) between theirs, or is no further from the
line through them (in ``log r`` against the control) than :data:`BRANCH_TOL`; an end record does
not go against the sweep's trend by more than that (the record nearest the transition may
drop: the slowdown). A record off the branch is treated: another mode of it on the branch
becomes its fundamental (flag ``fundamental_reconciled``), else it is set aside; first the one
whose treatment leaves the fewest records off the branch (so the repeats at one control that
agree define the branch against a single record beside them), a record whose detector doubts
its fundamental (flag ``fundamental_ambiguous``) before one it does not; then the next, until
every record is on the branch or :data:`MAX_OFF` of them were treated.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import replace

import numpy as np

from service.analysis.common import Flag
from service.analysis.detect import Detection, Fundamental, Mode
from service.analysis.errors import ParameterError

__all__ = ["SET_ASIDE", "reconcile", "set_aside"]

#: The flag code of a record left out of a sweep (its message gives the reason and the name).
SET_ASIDE = "record_set_aside"
#: Relative tolerance of the branch test on ``r = sqrt|sigma^2|`` (plus 4 standard errors).
BRANCH_TOL = 0.3
#: At most this fraction of the records is changed or set aside by the branch test.
MAX_OFF = 0.34


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
    idx = [k for k, m in enumerate(det.modes) if _candidate(m) and _in_band(m.sigma2, band)]
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
    c, band = _validate(detections, controls, names, band)
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
    return tuple(_branch(out, c, names))


def _usable(det: Detection) -> bool:
    return not any(f.code == SET_ASIDE for f in det.flags) and det.fundamental is not None


def _r(m: Mode) -> float:
    return math.sqrt(abs(m.sigma2))


def _spread(m: Mode) -> float:
    """The part of a mode's branch tolerance its own uncertainty gives: 4 standard errors of
    ``log r`` (``r = sqrt|sigma^2|``)."""
    if m.sigma2 == 0 or not math.isfinite(m.sigma2_std):
        return 0.0
    return 4.0 * 0.5 * m.sigma2_std / abs(m.sigma2)


def _tol(m: Mode) -> float:
    """The branch tolerance of a mode, in ``log r``."""
    return math.log1p(BRANCH_TOL) + _spread(m)


def _expected(i: int, idx: list[int], c: np.ndarray, logr: dict[int, float], trend: float,
              spread: dict[int, float] | None = None) -> tuple[float, float] | None:  # fmt: skip
    """The range of ``log r`` the branch allows at record ``idx[i]`` from its active neighbours
    (None: an end record whose trend allows anything on its side), widened by the neighbours'
    own uncertainty (``spread``: a neighbour read with a 150 % error constrains nothing)."""
    sp = spread or {}
    k = idx[i]
    left = [j for j in idx[:i] if c[j] < c[k]]
    right = [j for j in idx[i + 1 :] if c[j] > c[k]]
    if left and right:
        a, b = left[-1], right[0]
        t = (c[k] - c[a]) / (c[b] - c[a])
        line = logr[a] + t * (logr[b] - logr[a])
        u = max(sp.get(a, 0.0), sp.get(b, 0.0))
        lo = min(logr[a], logr[b], line) - u
        hi = max(logr[a], logr[b], line) + u
        return lo, hi
    if left:  # the last record: it may drop along the trend, not go against it
        a = left[-1]
        u = sp.get(a, 0.0)
        return (-math.inf, logr[a] + u) if trend < 0 else (logr[a] - u, math.inf)
    if right:  # the first record
        b = right[0]
        u = sp.get(b, 0.0)
        return (logr[b] - u, math.inf) if trend < 0 else (-math.inf, logr[b] + u)
    return None


def _offs(out: list[Detection], idx: list[int], c: np.ndarray
          ) -> dict[int, tuple[float, tuple[float, float]]]:  # fmt: skip
    """Each record of ``idx`` (usable, sorted by control) off the branch: how far (in ``log r``,
    beyond its tolerance) and the range its neighbours allow."""
    if len(idx) < 3:
        return {}
    logr = {k: math.log(_r(out[k].fundamental.mode)) for k in idx}
    spread = {k: _spread(out[k].fundamental.mode) for k in idx}
    trend = _trend(idx, c, logr)
    offs = {}
    for i, k in enumerate(idx):
        e = _expected(i, idx, c, logr, trend, spread)
        if e is None:
            continue
        tol = _tol(out[k].fundamental.mode)
        off = max(e[0] - tol - logr[k], logr[k] - e[1] - tol, 0.0)
        if off > 0:
            offs[k] = (off, e)
    return offs


def _branch(dets: list[Detection], c: np.ndarray, names: Sequence[str]) -> list[Detection]:
    """The branch test (module docstring) on the usable records of ``dets``.

    Of the records off the branch, the one treated first is the one whose treatment (another
    mode of it, or setting it aside) leaves the fewest records off the branch: one wrong
    record makes its neighbours look off too, and repeats at one control that agree outvote a
    single record beside them (the majority defines the branch). Ties go to a record whose
    detector doubts its fundamental (flag ``fundamental_ambiguous``), then to one with another
    mode on the branch (no record lost), then to the farthest off."""
    out = list(dets)
    idx = [k for k in np.argsort(c, kind="stable") if _usable(out[k])]
    budget = int(MAX_OFF * len(idx))
    while budget > 0:
        offs = _offs(out, idx, c)
        if not offs:
            break
        best, choice = None, None
        for k, (off, rng) in offs.items():
            new = _rechoose(out[k], names[k], rng)
            trial = [*out[:k], new, *out[k + 1 :]]
            kept = idx if _usable(new) else [j for j in idx if j != k]
            left = len(_offs(trial, kept, c))
            ambiguous = any(f.code == "fundamental_ambiguous" for f in out[k].flags)
            key = (left, not ambiguous, not _usable(new), -off)
            if best is None or key < best:
                best, choice = key, (k, new, kept)
        assert choice is not None
        k, out[k], idx = choice
        budget -= 1
    return out


def _trend(idx: list[int], c: np.ndarray, logr: dict[int, float]) -> float:
    """The sweep's trend: the Theil-Sen slope (median of the pairwise slopes, robust to a
    third of outliers) of ``log r`` against the control; -1 when the controls are equal."""
    slopes = [(logr[b] - logr[a]) / (c[b] - c[a])
              for i, a in enumerate(idx) for b in idx[i + 1 :] if c[b] != c[a]]  # fmt: skip
    return float(np.median(slopes)) if slopes else -1.0


def _rechoose(det: Detection, name: str, rng: tuple[float, float]) -> Detection:
    """``det`` with its fundamental moved to another mode on the branch (``log r`` in
    ``rng`` within the tolerance), or set aside when none is."""
    old = det.fundamental
    best, bk = math.inf, -1
    mid = 0.5 * (rng[0] + rng[1]) if all(map(math.isfinite, rng)) else None
    for k, m in enumerate(det.modes):
        if k == old.index or not _candidate(m):
            continue
        lr = math.log(_r(m))
        tol = _tol(m)
        if rng[0] - tol <= lr <= rng[1] + tol:
            d = abs(lr - mid) if mid is not None else abs(lr - math.log(_r(old.mode)))
            if d < best:
                best, bk = d, k
    lo, hi = (math.exp(v) if math.isfinite(v) else v for v in rng)
    if bk < 0:
        return set_aside(
            det, name,
            f"its fundamental (sqrt|sigma^2| = {_r(old.mode):.6g}) is off the branch that its "
            f"neighbours in the sweep follow (expected {lo:.6g} to {hi:.6g}) and no other mode "
            "of it is on it",
        )  # fmt: skip
    m = det.modes[bk]
    flag = Flag(
        "fundamental_reconciled",
        f"the fundamental is modes[{bk}] (sqrt|sigma^2| = {_r(m):.6g}), on the branch its "
        f"neighbours in the sweep follow (expected {lo:.6g} to {hi:.6g}), not the record's "
        f"own choice (sqrt|sigma^2| = {_r(old.mode):.6g})",
    )
    return replace(det, fundamental=Fundamental(m, bk), flags=(*det.flags, flag))


def _candidate(m: Mode) -> bool:
    """A mode that may be a fundamental: stable, finite, neither a combination tone nor set
    aside by the detector (a line, a drift, a trend, a transient)."""
    return (
        m.combination is None and getattr(m, "kind", "mode") == "mode"
        and math.isfinite(m.sigma2) and m.sigma2 < 0
    )  # fmt: skip
