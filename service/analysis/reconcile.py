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

__all__ = ["SET_ASIDE", "SWEEP_DOUBT", "reconcile", "set_aside", "withhold_type"]

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
    out = _critical_line(out, c, names)
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


# ------------------------------------------------------------------ the critical line of a sweep
#: A record's own fundamental that continues no line of the sweep while the sweep's line goes
#: on in the record at least this many times stiffer (``|sigma^2|``) is a stray, not the line
#: softening (:func:`_strays`).
STRAY_JUMP = 4.0
#: The message of the sweep-level ``fundamental_ambiguous`` flag starts with this (the
#: detector's own flag of that code concerns one record and does not withhold the type).
SWEEP_DOUBT = "across the sweep"
#: A line is followed from one record to the next when its ``r = sqrt|sigma^2|`` lies within
#: this relative distance of the value its track expects there (a second pass allows
#: :data:`TRACK_TOL_SOFT` for a line that went softer than expected: the critical one).
TRACK_TOL = 0.15
TRACK_TOL_SOFT = 0.45
#: ... only for a track whose last step softened its ``|sigma^2|`` by at least this fraction
#: (a line that stays put does not jump onto a softer one).
SOFT_STEP = 0.02
#: Two tracks may share one mode where their lines meet (a crossing read as one line): when it
#: lies within this relative distance of what each track expects.
MEET_TOL = 0.07
#: The most a mode's own uncertainty widens those tolerances (in ``log r``).
MAX_TRACK_SPREAD = 0.05
#: A line that reaches ``sigma^2 = 0`` within this fraction of the distance the records' own
#: line needs replaces it without doubt; up to the records' own distance it replaces it with
#: the flag ``fundamental_ambiguous`` (two lines plausible, the type withheld).
CLEARLY = 0.5
#: ... and below this fraction it is no rival at all: lines proportional to one another (a
#: harmonic, a mode shape's overtone) reach zero together.
AGREE = 0.9
#: A line must soften by at least this fraction of its ``|sigma^2|`` across the records it is
#: seen in to be a candidate (a sensor's or a rig's line stays put).
MIN_SOFTENING = 0.1
#: A line is a candidate for the sweep's critical line once seen at this many controls (a
#: quadratic continuation needs them; three records cannot tell a line's bend).
MIN_CONTROLS = 4
#: ... and its quadratic continuation must fit its points within this fraction (rms) of their
#: range (a track that stays put and then drops has jumped onto other lines).
MAX_BEND_MISFIT = 0.05


def _tracks(out: list[Detection], idx: list[int], c: np.ndarray) -> list[dict[int, int]]:
    """The lines of the usable records ``idx`` (sorted by control) followed by continuity:
    each track maps a record to the index of its mode on the line. A track expects at the next
    record the ``sigma^2`` its last two points (distinct controls) extrapolate to (its last
    value otherwise); modes are matched one to one, nearest first (in ``log r``), within
    :data:`TRACK_TOL` (plus the mode's own 4 standard errors), then within
    :data:`TRACK_TOL_SOFT` for a mode softer than expected on a track that softens
    (:data:`SOFT_STEP`) or is seen at one control so far; where two lines meet and the record
    shows one mode, both tracks take it (:data:`MEET_TOL`). A track missing one record goes on;
    one missing two ends. Only a candidate mode (:func:`_candidate`) starts a track; a
    transient (:func:`_continues`) may continue one within :data:`TRACK_TOL`."""
    tracks: list[dict[int, int]] = []
    ends: list[int] = []  # position in idx of each track's last record
    for pos, k in enumerate(idx):
        cands = [j for j, m in enumerate(out[k].modes) if _candidate(m) or _continues(m)]
        live = [t for t in range(len(tracks)) if pos - ends[t] <= 2]
        expect = {}
        softening: set[int] = set()  # tracks whose last step softened: they may drop faster
        trended: set[int] = set()  # tracks whose expectation continues their last step
        for t in live:
            ks = list(tracks[t])
            s_last = out[ks[-1]].modes[tracks[t][ks[-1]]].sigma2
            s_exp = s_last
            prev = [a for a in ks[:-1] if c[a] != c[ks[-1]]]
            if not prev:  # a line seen at one control: its trend is not known yet
                softening.add(t)
            if prev and c[k] != c[ks[-1]]:
                a = prev[-1]
                s_a = out[a].modes[tracks[t][a]].sigma2
                slope = (s_last - s_a) / (c[ks[-1]] - c[a])
                guess = s_last + slope * (c[k] - c[ks[-1]])
                if s_last - s_a > SOFT_STEP * abs(s_a):
                    softening.add(t)
                trended.add(t)
                s_exp = guess if guess < 0 else s_last
            expect[t] = 0.5 * math.log(abs(s_exp))
        pairs = []
        for t in live:
            for j in cands:
                m = out[k].modes[j]
                d = math.log(_r(m)) - expect[t]
                pairs.append((abs(d), d, t, j))
        pairs.sort()
        dist = {(t, j): d for _ad, d, t, j in pairs}
        modes = out[k].modes
        took: dict[int, int] = {}  # track -> mode
        for soft in (False, True):
            for _ad, d, t, j in pairs:
                if (t not in took and j not in took.values()
                        and _joins(modes[j], d, soft, t in softening)):  # fmt: skip
                    took[t] = j
        _untangle(took, dist, modes, softening, trended)
        used_t: set[int] = set(took)
        used_j: set[int] = set(took.values())
        owner_cost: dict[int, float] = {}
        for t, j in took.items():
            tracks[t][k] = j
            ends[t] = pos
            owner_cost[j] = abs(dist[t, j])
        # two lines that meet (a crossing) may be read as one mode: both tracks take it when
        # it lies within MEET_TOL of what each expects
        for ad, _d, t, j in pairs:
            if t in used_t or j not in owner_cost:
                continue
            if ad <= math.log1p(MEET_TOL) and owner_cost[j] <= math.log1p(MEET_TOL):
                tracks[t][k] = j
                ends[t] = pos
                used_t.add(t)
        for j in cands:
            if j not in used_j and _candidate(out[k].modes[j]):
                tracks.append({k: j})
                ends.append(pos)
    _untangle_starts(tracks, out, c)
    return tracks


def _untangle_starts(tracks: list[dict[int, int]], out: list[Detection], c: np.ndarray) -> None:
    """Exchange (in place) the first-control modes of two tracks that start at the same
    control where each lies nearer to what the other track expects there, continued backward
    from its next two controls, than to what its own track expects (each within
    :data:`TRACK_TOL_SOFT`; measured: foundation lab 1's scattered second line, continued
    backward, lies nearer to the critical mode than to its own, and must not take it). At its
    first step a line expects its last value (its trend is not
    known yet), so two close lines that both soften may be joined crosswise there (measured:
    blind arch_pitchfork lab 100, 6.94 and 7.66 Hz at 0 N, the critical line's first point
    taken at 7.66 Hz)."""

    def back(t: dict[int, int], c0: float) -> float | None:
        later = sorted((c[k], k) for k in t if c[k] > c0)
        pts = []
        for x, k in later:
            if not pts or x != pts[-1][0]:
                pts.append((x, out[k].modes[t[k]].sigma2))
            if len(pts) == 2:
                break
        if len(pts) < 2:
            return None
        (x1, s1), (x2, s2) = pts
        s0 = s1 + (s1 - s2) / (x2 - x1) * (x1 - c0)
        return 0.5 * math.log(abs(s0 if s0 < 0 else s1))

    firsts: dict[float, list[int]] = {}
    for i, t in enumerate(tracks):
        firsts.setdefault(min(c[k] for k in t), []).append(i)
    for c0, ts in firsts.items():
        exp = {i: back(tracks[i], c0) for i in ts}
        ts = [i for i in ts if exp[i] is not None]
        for a_i, a in enumerate(ts):
            for b in ts[a_i + 1 :]:
                ta, tb = tracks[a], tracks[b]
                for k in [k for k in ta if c[k] == c0 and k in tb]:
                    ma, mb = out[k].modes[ta[k]], out[k].modes[tb[k]]
                    if ta[k] == tb[k]:
                        continue
                    la, lb = math.log(_r(ma)), math.log(_r(mb))
                    # both prefer the other's mode (a backward continuation of a line with
                    # scattered points says little: only the two together decide)
                    both = (abs(lb - exp[a]) < abs(la - exp[a])
                            and abs(la - exp[b]) < abs(lb - exp[b]))  # fmt: skip
                    ok = (abs(lb - exp[a]) <= math.log1p(TRACK_TOL_SOFT) + _track_spread(mb)
                          and abs(la - exp[b]) <= math.log1p(TRACK_TOL_SOFT) + _track_spread(ma))
                    if both and ok:
                        ta[k], tb[k] = tb[k], ta[k]


def _joins(m: Mode, d: float, soft: bool, softens: bool) -> bool:
    """Whether mode ``m``, at ``d`` (``log r``) from what a track expects, may join it: within
    :data:`TRACK_TOL`, or (``soft`` pass) softer within :data:`TRACK_TOL_SOFT` for a track
    that ``softens`` (each plus the mode's own spread, :func:`_track_spread`)."""
    return abs(d) <= math.log1p(TRACK_TOL) + _track_spread(m) or (
        soft and d < 0 and _candidate(m) and softens
        and -d <= math.log1p(TRACK_TOL_SOFT) + _track_spread(m))  # fmt: skip


def _untangle(took: dict[int, int], dist: dict[tuple[int, int], float], modes: Sequence[Mode],
              softening: set[int], trended: set[int]) -> None:  # fmt: skip
    """Exchange the modes of two tracks (in place) where each may join the other's mode and
    the exchange brings both nearer to what they expect (sum of squared ``log r`` distances).
    Only between tracks whose expectation continues a step of theirs (``trended``): a line
    seen at one control expects its last value, which says nothing of where it goes (measured:
    foundation lab 1's critical line, -1218 at 0 N, exchanged with a spurious -1043 +- 177 at
    its first step).

    The greedy match (nearest pair first) can swap two lines that both soften faster than their
    straight continuations: near a transition the critical line drops onto where its neighbour
    was expected, and the neighbour is then pushed onto the critical line's mode by the soft
    pass (measured: a noise-free Euler-beam sweep's lowest two lines, exchanged at its last
    record, made a kinked line that looked critical first)."""
    changed = True
    while changed:
        changed = False
        ts = sorted(t for t in took if t in trended)
        for a_i, a in enumerate(ts):
            for b in ts[a_i + 1 :]:
                ja, jb = took[a], took[b]
                now = dist[a, ja] ** 2 + dist[b, jb] ** 2
                swapped = dist[a, jb] ** 2 + dist[b, ja] ** 2
                if (swapped < now and _joins(modes[jb], dist[a, jb], True, a in softening)
                        and _joins(modes[ja], dist[b, ja], True, b in softening)):  # fmt: skip
                    took[a], took[b] = jb, ja
                    changed = True


def _track_spread(m: Mode) -> float:
    """A mode's own part of the tracking tolerance: its 4 standard errors of ``log r``, at most
    :data:`MAX_TRACK_SPREAD` (a mode read with a 100 % error would otherwise join any line)."""
    return min(_spread(m), MAX_TRACK_SPREAD)


def _continues(m: Mode) -> bool:
    """A mode the detector set aside as a transient (heavily damped, gone early in the record)
    may continue a line that ringing modes began: a critical mode whose damping grows as it
    softens ends so (it is never the start of a line)."""
    return getattr(m, "kind", "mode") == "transient" and math.isfinite(m.sigma2) and m.sigma2 < 0


def _zero(track: dict[int, int], out: list[Detection], c: np.ndarray, *, fold: bool = False
          ) -> float:  # fmt: skip
    """The control where the line's ``sigma^2``, continued by a quadratic in the control
    fitted to all its points (least squares), first reaches 0 beyond its last control; inf for
    a line seen at fewer than :data:`MIN_CONTROLS` controls, one that does not soften by
    :data:`MIN_SOFTENING` of its level, one the quadratic does not fit
    (:data:`MAX_BEND_MISFIT`), or one whose continuation does not reach 0. The
    quadratic tells a line that bends toward zero (the critical mode near a pitchfork) from one
    whose softening slows down (a line that a straight continuation of its first records would
    wrongly take to zero first).

    ``fold``: the quadratic continues ``(sigma^2)^2`` instead, the law of a line near a fold
    (``sigma^2 ~ -sqrt(mu* - mu)``), which a quadratic in ``sigma^2`` continues too far
    (measured: 2.24 for a fold at 2.0 seen from 0 to 1.95)."""
    ks = list(track)
    s = np.array([out[k].modes[track[k]].sigma2 for k in ks])
    x = np.array([c[k] for k in ks])
    if np.unique(x).size < MIN_CONTROLS or (s[-1] - s[0]) < MIN_SOFTENING * abs(s[0]):
        return math.inf
    last = float(x.max())
    scale = float(np.ptp(x))
    u, v = (x - last) / scale, s / abs(s[0])
    if fold:
        v = -(v**2)  # negative while stable, like sigma^2
    p = np.polyfit(u, v, 2)
    rms = float(np.sqrt(np.mean((np.polyval(p, u) - v) ** 2)))
    if rms > MAX_BEND_MISFIT * float(np.ptp(v)):  # not one smooth line: a jump onto another
        return math.inf
    if np.polyval(p, 0.0) >= 0:  # the fit is at zero already at the line's last control
        return last
    roots = [r.real for r in np.roots(p) if abs(r.imag) <= 1e-9 * max(1.0, abs(r.real))]
    ahead = [r for r in roots if r > 0]
    return last + scale * min(ahead) if ahead else math.inf


def _earliest(track: dict[int, int], out: list[Detection], c: np.ndarray) -> float:
    """The earlier of the line's two continuations to ``sigma^2 = 0`` (:func:`_zero`: a
    quadratic in ``sigma^2``, a pitchfork's, or in ``(sigma^2)^2``, a fold's)."""
    return min(_zero(track, out, c), _zero(track, out, c, fold=True))


def _critical_line(out: list[Detection], c: np.ndarray, names: Sequence[str]) -> list[Detection]:
    """Each usable record's fundamental on the sweep's critical line: the line (followed from
    record to record, :func:`_tracks`) whose ``sigma^2`` reaches zero first (:func:`_zero`),
    seen in at least :data:`MIN_CONTROLS` records and half of them. Nothing changes when that
    line is the one the records' own fundamentals mostly follow, or reaches zero with it
    (:data:`AGREE`).
    Otherwise the records take their mode on it (flag ``fundamental_reconciled``) and those
    without one are set aside, when it reaches zero clearly first (:data:`CLEARLY`); when only
    somewhat first, the same, and every record carries the flag ``fundamental_ambiguous``
    (message starting :data:`SWEEP_DOUBT`): two lines are plausible and lead to different
    answers, so the type is withheld (:func:`withhold_type`)."""
    idx = [k for k in np.argsort(c, kind="stable") if _usable(out[k])]
    if np.unique(c[idx]).size < MIN_CONTROLS:
        return out
    tracks = _tracks(out, idx, c)
    need = max(MIN_CONTROLS, math.ceil(0.5 * len(idx)))
    seen = [t for t in tracks if len(t) >= need]
    if not seen:
        return out
    own = max(seen, key=lambda t: sum(out[k].fundamental.index == j for k, j in t.items()))
    n_own = sum(out[k].fundamental.index == j for k, j in own.items())
    zeros = [_earliest(t, out, c) for t in seen]
    i_c = int(np.argmin(zeros))
    crit = seen[i_c]
    if crit is own or not math.isfinite(zeros[i_c]):
        return _strays(out, own, tracks, c) if n_own * 2 >= len(idx) else out
    last = max(c[k] for k in idx)
    d_c = max(zeros[i_c] - last, 0.0)
    # each line continued both ways (a fold's, or a pitchfork's quadratic): the earliest
    z_own = _earliest(own, out, c) if n_own * 2 >= len(idx) else math.inf
    d_own = z_own - last
    if not d_c < AGREE * d_own:
        return _strays(out, own, tracks, c) if n_own * 2 >= len(idx) else out
    doubt = not d_c < CLEARLY * d_own
    lo_c, hi_c = min(c[k] for k in crit), max(c[k] for k in crit)
    r_c = [_r(out[k].modes[j]) for k, j in crit.items()]
    r_o = [_r(out[k].modes[j]) for k, j in own.items()]
    line = (f"the line softening toward sigma^2 = 0 first across the sweep (sqrt|sigma^2| "
            f"{r_c[0]:.6g} to {r_c[-1]:.6g}, reaching 0 near control {zeros[i_c]:.6g}) rather "
            f"than the records' slowest line ({r_o[0]:.6g} to {r_o[-1]:.6g}, "
            + (f"near {z_own:.6g}" if math.isfinite(z_own) else "not softening toward 0")
            + ")")  # fmt: skip
    res = list(out)
    for k in idx:
        det = res[k]
        j = crit.get(k)
        if j is None and not lo_c <= c[k] <= hi_c:
            j = _beyond(crit, out, k, c)
        if j is None:
            res[k] = set_aside(det, names[k], (
                f"the sweep's critical line (the one softening toward sigma^2 = 0 first, seen "
                f"from control {lo_c:.6g} to {hi_c:.6g}) is not found in it"
                if lo_c <= c[k] <= hi_c else
                f"the sweep's critical line is seen from control {lo_c:.6g} to {hi_c:.6g} "
                "only, not in it"))  # fmt: skip
            continue
        flags = list(det.flags)
        if det.fundamental.index != j:
            flags.append(Flag("fundamental_reconciled", (
                f"the fundamental is modes[{j}] (sqrt|sigma^2| = {_r(det.modes[j]):.6g}), on "
                f"{line}, not the record's own choice (sqrt|sigma^2| = "
                f"{_r(det.fundamental.mode):.6g})")))  # fmt: skip
        if doubt:
            flags.append(Flag("fundamental_ambiguous", (
                f"{SWEEP_DOUBT}: two lines are plausible and lead to different answers: "
                f"{line}; their controls of sigma^2 = 0 differ by less than a factor "
                f"{1 / CLEARLY:.3g} in distance from the last record: the type is withheld")))
        res[k] = replace(det, fundamental=Fundamental(det.modes[j], j), flags=tuple(flags))
    return res


def _beyond(line: dict[int, int], out: list[Detection], k: int, c: np.ndarray) -> int | None:
    """The mode of record ``k``, outside the controls ``line`` is seen at, that lies within
    :data:`TRACK_TOL` (plus its spread) of the line continued straight from its two nearest
    controls (None: none does). The tracks follow lines forward from the first record, where
    no line's trend is known yet: a first step that took a line too far for it to follow
    (measured: blind arch_fold lab 100 with a rig mode, -1278 at 0 N then -871 at 58.65 N:
    the critical line seen from the second record on, the first set aside) is recovered so."""
    side = [(abs(c[a] - c[k]), c[a], a) for a in line]
    side.sort()
    pts: list[tuple[float, float]] = []
    for _d, x, a in side:
        if not pts or x != pts[-1][0]:
            pts.append((x, out[a].modes[line[a]].sigma2))
        if len(pts) == 2:
            break
    if len(pts) < 2:
        return None
    (x1, s1), (x2, s2) = pts
    s_k = s1 + (s1 - s2) / (x1 - x2) * (c[k] - x1)
    if s_k >= 0:
        return None
    want = 0.5 * math.log(-s_k)
    best, bj = math.inf, None
    for j, m in enumerate(out[k].modes):
        if not _candidate(m):
            continue
        d = abs(math.log(_r(m)) - want)
        if d <= math.log1p(TRACK_TOL) + _track_spread(m) and d < best:
            best, bj = d, j
    return bj


def _strays(out: list[Detection], line: dict[int, int], tracks: list[dict[int, int]],
            c: np.ndarray) -> list[Detection]:  # fmt: skip
    """The records on ``line`` (the one most records' own fundamentals follow, kept as the
    sweep's) whose own fundamental is another mode, :data:`STRAY_JUMP` times softer than the
    line's there or more, that continues no line of the sweep (its track holds no other
    record): their mode on the line becomes the fundamental (flag ``fundamental_reconciled``).
    Such a mode is no softening of the line: the line itself goes on in that record (measured:
    a live lab's records without a time unit, its 60 Hz hum aliased to sigma^2 -1.66, damping
    0.02, beside the line's -33.37, damping 0.30, expected at -33.4; the lowest was taken and
    the sweep ended on it)."""
    res = list(out)
    for k, j in line.items():
        det = res[k]
        j0 = det.fundamental.index
        if j0 == j:
            continue
        if any(t.get(k) == j0 and len(t) > 1 for t in tracks):
            continue  # the own fundamental continues a line: the crossing and branch rules' case
        m, m0 = det.modes[j], det.fundamental.mode
        if abs(m.sigma2) < STRAY_JUMP * abs(m0.sigma2):
            continue  # near the line: a line that softened faster than followed, maybe
        flag = Flag("fundamental_reconciled", (
            f"the fundamental is modes[{j}] (sqrt|sigma^2| = {_r(m):.6g}), where the line the "
            f"sweep's records follow goes on at control {c[k]:.6g}; the record's own choice "
            f"(sqrt|sigma^2| = {_r(m0):.6g}) continues no line of the sweep"))  # fmt: skip
        res[k] = replace(det, fundamental=Fundamental(m, j), flags=(*det.flags, flag))
    return res


def sweep_doubt(flags: Sequence[Flag]) -> Flag | None:
    """The sweep-level ``fundamental_ambiguous`` flag among ``flags`` (None: none)."""
    return next((f for f in flags if f.code == "fundamental_ambiguous"
                 and f.message.startswith(SWEEP_DOUBT)), None)  # fmt: skip


def withhold_type(pred, measurements: Sequence, flags: list[Flag]):
    """``pred`` (a Prediction or None) with its type withheld (``"undetermined"``) when a
    measurement carries the sweep-level ``fundamental_ambiguous`` flag (:func:`_critical_line`);
    that flag is then appended to ``flags``. The sweep policy calls it after the prediction."""
    doubt = next((d for m in measurements if (d := sweep_doubt(m.flags)) is not None), None)
    if doubt is None:
        return pred
    flags.append(doubt)
    if pred is None or pred.transition == "undetermined":
        return pred
    cls = pred.classification
    if cls is not None:
        cls = replace(cls, transition="undetermined")
    return replace(pred, transition="undetermined", classification=cls)
