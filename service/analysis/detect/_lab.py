"""Records as labs make them: the kick, repeated kicks, clipped samples, stationary lines.

A lab's impulse record is rarely a free decay from its first sample: a scope records a
pre-trigger (the structure at rest, with the mains hum and the sensor's drift on it), the
hammer's contact forces the structure for a few ms, a second hit may follow, the sensor may
saturate. This module finds the part of the record that is a free response (the window the
fit reads) and the lines that are there before the kick; :mod:`._core` fits the window and
:mod:`._modes` tells lines and drift from the modes.

Everything here is a no-op on a record that starts with its free response and holds no quiet
lead-in, no clipped run and no second kick: such records are analysed as before.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from service.analysis.common import Flag
from service.analysis.detect._kernels import running_min
from service.analysis.detect._results import FEW_PERIODS, LOW_SNR_DB, MIN_SAMPLES, Mode

#: A quiet lead-in: its envelope (moving rms, lines and noise included) stays below this
#: fraction of the response's largest envelope ...
LEAD_QUIET = 0.35
#: ... for at least this fraction of the record (and MIN_SAMPLES samples); it ends where the
#: envelope leaves this many times its median level before the rise.
LEAD_MIN, LEAD_RISE = 0.02, 2.5
#: A later kick: the envelope jumps to at least this many times its value just before.
KICK_JUMP = 1.6
#: Clipping: the record's extreme held in at least this many separate runs (the rule of the
#: recordings' ``clipped`` flag).
CLIP_RUNS = 3
#: A window shorter than this fraction of the record is not used (the whole is fitted).
WINDOW_MIN = 0.2


@dataclass
class Window:
    """The part of a record read as free response: ``[start, stop)``; ``lead`` the end of a
    quiet lead-in (0: none); ``kicks`` the indices of later kicks; the flags that say so;
    ``user_start`` whether the start is the user's; ``quiet`` whether the lead-in is quiet
    (below 5 % of the response: no hum, no drift on it)."""

    start: int = 0
    stop: int = 0
    lead: int = 0
    kicks: list[int] = field(default_factory=list)
    n_clipped: int = 0
    flags: list[Flag] = field(default_factory=list)
    user_start: bool = False
    quiet: bool = False  # the lead-in is quiet (below 5 % of the response: no hum, no drift)
    clip: np.ndarray | None = None  # the record's clipped samples (boolean mask), None: none


def _movmean(x: np.ndarray, L: int) -> np.ndarray:
    """Centred moving mean over ``L`` samples (shorter at the ends)."""
    n = x.size
    if L <= 1 or n < 2:
        return x.copy()
    L = min(L, n)
    c = np.empty(n + 1)
    c[0] = 0.0
    np.cumsum(x, out=c[1:])
    h = L // 2
    i = np.arange(n)
    lo = i - h
    lo[: h] = 0
    hi = i - h + L
    hi[n - (L - h) + 1 :] = n
    return (c[hi] - c[lo]) / (hi - lo)


def _trailmean(x: np.ndarray, L: int) -> np.ndarray:
    """Trailing moving mean over ``L`` samples (fewer at the start): sample ``i`` sees only
    ``x[i - L + 1 : i + 1]``, never what follows it."""
    c = np.empty(x.size + 1)
    c[0] = 0.0
    np.cumsum(x, out=c[1:])
    i = np.arange(1, x.size + 1)
    lo = np.maximum(i - L, 0)
    return (c[i] - c[lo]) / (i - lo)


def _causal_envelope(arr: np.ndarray, L: int) -> tuple[np.ndarray, np.ndarray]:
    """The record less its trailing moving mean over a tenth of the record (``hpc``) and
    ``hpc``'s moving rms over ``L`` samples: the baseline before a sample is judged from the
    samples before it only, so the response after a kick (its mean shifted by a one-sided
    clipping, a slow mode) does not leak into the lead-in before it, as a centred mean's
    would over half its length."""
    n = arr.size
    peak = float(np.max(np.abs(arr)))
    x = arr / peak if peak > 0 and math.isfinite(peak) else arr
    x = x - float(np.mean(x))
    hpc = x - _trailmean(x, max(8, n // 10))
    return hpc, np.sqrt(np.maximum(_movmean(hpc * hpc, L), 0.0))


def clipped_mask(arr: np.ndarray) -> np.ndarray | None:
    """Samples held at the record's largest or smallest value (a saturated sensor): that
    value held in at least :data:`CLIP_RUNS` separate runs of two samples on average (a
    decaying response reaches its extreme once); None when there are none."""
    if arr.size < 3 * CLIP_RUNS or float(arr.max()) == float(arr.min()):
        return None
    mask = np.zeros(arr.size, dtype=bool)
    for level in (float(arr.max()), float(arr.min())):
        at = arr == level
        runs = int(np.count_nonzero(at[1:] & ~at[:-1])) + int(at[0])
        if runs >= CLIP_RUNS and int(at.sum()) >= 2 * runs:
            mask |= at
    return mask if mask.any() else None


def _envelope(
    arr: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, int, int, tuple[float, bool]]:
    """The record with its slow baseline removed (``hp``: a moving mean over a tenth of the
    record subtracted), its moving rms over a short window ``e`` (``n / 400``) and over a long
    one ``E`` (two periods of the slowest strong line of ``hp``'s spectrum, which smooths the
    beats of the modes), the long window ``LL``, and ``(period, few)``: that period and whether
    a strong line rings fewer than 4 cycles in the record."""
    n = arr.size
    peak = float(np.max(np.abs(arr)))
    x = arr / peak if peak > 0 and math.isfinite(peak) else arr  # any magnitude (scale-free)
    x = x - float(np.mean(x))
    hp = x - _movmean(x, max(8, n // 10))
    L = max(8, n // 400)
    sq = hp * hp
    e = np.sqrt(np.maximum(_movmean(sq, L), 0.0))
    P = np.abs(np.fft.rfft(hp)) ** 2
    # a strong line of fewer than 4 cycles in the record: its ringing's moving rms rises and
    # falls over the record like a later kick would (no later kick is looked for then)
    few = bool(P.size > 8 and P[1:4].max() >= 0.05 * float(P[4:].max()))
    P[:4] = 0.0
    strong = np.flatnonzero(P >= 0.05 * float(P.max())) if P.max() > 0 else np.zeros(0, int)
    period = n / max(int(strong[0]), 4) if strong.size else n / 4
    LL = int(min(max(2 * period, L), n // 20))
    E = np.sqrt(np.maximum(_movmean(sq, LL), 0.0))
    return hp, e, E, L, LL, (period, few)


def _lead(e: np.ndarray, L: int, period: float) -> tuple[int, int]:
    """``(lead, i_half)``: the end of a quiet lead-in before the first kick (0: none) and the
    first sample where the envelope passes half its largest value. The lead-in lasts at least
    :data:`LEAD_MIN` of the record and half the dominant ``period`` (or 5 % of the record):
    the short envelope also dips near the zero crossings of a ringing record. It ends at the
    first sample where the envelope leaves :data:`LEAD_RISE` times its median before
    ``i_half`` (a long hammer's contact rises over many samples: the lead's
    level is not read on the rise), stays below :data:`LEAD_QUIET` of the largest envelope,
    and is 4x longer than the rise (a kick; a growing or smoothly starting record rises as
    long as it has been quiet)."""
    n = e.size
    emax = float(e.max())
    if not emax > 0:
        return 0, 0
    i_half = int(np.argmax(e > 0.5 * emax))
    m = max(MIN_SAMPLES, int(LEAD_MIN * n), int(min(0.5 * period, 0.05 * n)))
    end = i_half - 2 * L
    if end < m:
        return 0, i_half
    base = float(np.median(e[:end]))
    rise_from = int(np.argmax(e[: i_half + 1] > min(LEAD_RISE * base, 0.5 * emax)))
    if rise_from < m:
        return 0, i_half
    level = float(np.max(e[: max(rise_from - L, 1)]))
    if not level < LEAD_QUIET * emax:
        return 0, i_half
    # the rise is timed from the lead's band (a loud lead-in: from 1.25x its median)
    band = np.flatnonzero(e[:rise_from] <= (1.25 * base if LEAD_RISE * base > 0.5 * emax
                                           else LEAD_RISE * base))  # fmt: skip
    foot = int(band[-1]) if band.size else 0
    if not (i_half - foot) * 4 <= foot:
        return 0, i_half
    return rise_from, i_half


def _onset(hp: np.ndarray, lead: int, i_half: int) -> int:
    """The first sample after the lead-in where the record leaves the lead's band (its largest
    deviation, hum and noise included, times 1.5)."""
    band = 1.5 * float(np.max(np.abs(hp[:lead]))) if lead else 0.0
    seg = np.abs(hp[lead : i_half + 1])
    out = np.flatnonzero(seg > band)
    return lead + int(out[0]) if out.size else lead


def _later_kicks(E: np.ndarray, first: int, LL: int) -> list[int]:
    """Later kicks: the long-window envelope ``E`` (window ``LL``) rises by :data:`KICK_JUMP`
    from a local minimum after the first kick's peak within ``2 LL`` samples (a ring-down only
    decays, a growing record grows slowly; the long window smooths the beats of the modes).
    Returns the local minima (the foot of each rise)."""
    n = E.size
    out: list[int] = []
    if first >= n - 2:
        return out
    j0 = first + int(np.argmax(E[first : min(n, first + n // 10)]))
    top = float(E[j0])
    # the lowest value over the 2 LL samples up to each sample (a trailing running minimum)
    cm = running_min(E, LL)
    trail = np.empty(n)
    trail[LL:] = cm[: n - LL]
    trail[:LL] = cm[0]
    hit = (E > KICK_JUMP * trail) & (E > 0.1 * top)
    hit[: min(n, j0 + 2 * LL + 1)] = False
    hit[n - n // 20 :] = False  # the baseline's moving mean is one-sided there
    j = 0
    while len(out) < 8:
        k = np.flatnonzero(hit[j:])
        if not k.size:
            break
        j1 = j + int(k[0])
        w0 = max(j0, j1 - 2 * LL)
        out.append(w0 + int(np.argmin(E[w0 : j1 + 1])))
        j = j1 + 2 * LL + 1
    return out


#: A later kick seen in a ringing line's complex amplitude: demodulated at its frequency and
#: smoothed twice over KICK_PERIODS periods (at least the inverse of the gap to the nearest
#: other strong line, whose beat it then cancels), the amplitude's ratio over that span
#: departs from its median (a free decay keeps it constant) by more than KICK_DEV_Z times the
#: median departure (its scatter: noise, leakage of the other lines), KICK_DEV at least and
#: KICK_DEV_MAX at most,
#: for at least half the span, where the line is at least KICK_STRONG of its largest
#: amplitude. The
#: KICK_LINES strongest lines of the window's spectrum (above KICK_PEAK of the strongest's
#: power) are each read.
KICK_PERIODS, KICK_DEV, KICK_DEV_MAX, KICK_DEV_Z, KICK_STRONG = 1, 0.1, 0.25, 6.0, 0.1
KICK_LINES, KICK_PEAK = 3, 0.1


def _line_kick(hp: np.ndarray, a: int, b: int, least: int = 0) -> int | None:
    """The sample (before a later kick) where the window ``[a, b)`` should stop, from the
    complex amplitudes of its strongest lines (:func:`_kick_in_line`: the earliest stop that
    leaves at least ``least`` samples); None when they decay freely to the end. A kick moves
    every kicked mode's amplitude or phase at once (up or down: a second hit out of phase
    lowers the envelope), which an envelope rise alone misses; a stationary line (hum) keeps
    its complex amplitude and says nothing."""
    seg = hp[a:b]
    m = seg.size
    if m < 256:
        return None
    P = np.abs(np.fft.rfft(seg * np.hanning(m))) ** 2
    P[:3] = 0.0
    peaks = np.flatnonzero((P[1:-1] >= P[:-2]) & (P[1:-1] > P[2:])) + 1
    peaks = peaks[P[peaks] >= KICK_PEAK * float(P.max())]
    hits = []
    for k in peaks[np.argsort(P[peaks])[::-1]][:KICK_LINES]:
        lo, mid, hi = np.log(P[k - 1 : k + 2] + 1e-300)
        den = lo - 2 * mid + hi
        w = 2 * math.pi * (k + (0.5 * (lo - hi) / den if den < 0 else 0.0)) / m
        gap = np.abs(peaks[peaks != k] - k)
        span = int(round(m / float(gap.min()))) if gap.size else 0
        hit = _kick_in_line(seg, w, span, least)
        if hit is not None:
            hits.append(a + hit)
    return min(hits) if hits else None


def _kick_in_line(seg: np.ndarray, w: float, span: int = 0, least: int = 0) -> int | None:
    """Where the window ``seg`` should stop before a kick seen in its line at ``w`` (rad per
    sample): its complex amplitude ``z`` (demodulated, smoothed twice over ``Lp``: KICK_PERIODS
    periods, or ``span`` samples if longer, a sixth of the window at most) keeps the ratio
    ``z(t + Lp) / z(t)`` of a free decay, except from ``2 Lp`` before a kick on; None when it
    does (or only before ``least`` samples)."""
    m = seg.size
    Lp = int(round(KICK_PERIODS * 2 * math.pi / w))
    if Lp < 8 or 6 * Lp > m:
        return None
    Lp = max(Lp, min(span, m // 6))  # a neighbour too close to cancel: the longest span
    z = seg * np.exp(-1j * w * np.arange(m))
    re = _movmean(_movmean(z.real, Lp), Lp)
    im = _movmean(_movmean(z.imag, Lp), Lp)
    z = re + 1j * im
    mag = np.abs(z)
    r = z[Lp:] / np.where(mag[:-Lp] > 0, z[:-Lp], 1.0)
    ok = (mag[:-Lp] >= KICK_STRONG * float(mag.max())) & (mag[Lp:] > 0)
    ok[: 3 * Lp // 2] = False  # the filter's edge and the contact
    ok[max(0, ok.size - Lp) :] = False
    if np.count_nonzero(ok) < 2 * Lp:
        return None
    ref = complex(float(np.median(r[ok].real)), float(np.median(r[ok].imag)))
    if abs(ref) == 0:
        return None
    dev = np.abs(r / ref - 1.0)
    thr = min(KICK_DEV_MAX, max(KICK_DEV, KICK_DEV_Z * float(np.median(dev[ok]))))
    bad = ok & (dev > thr)
    bad[:least] = False
    # the first run of at least Lp/2 samples: the kick comes up to 2 Lp after its start (the
    # smoothed amplitudes reach Lp and 2 Lp ahead), never before it
    run = np.convolve(bad.astype(float), np.ones(Lp // 2), mode="valid") >= Lp // 2
    hit = np.flatnonzero(run)
    if not hit.size:
        return None
    return int(hit[0])


def locate(arr: np.ndarray, dt: float, *, start: float | None = None) -> Window:
    """The window of free response of an impulse record (see the module docstring).

    ``start`` (record time from the first sample, the user's) overrides the located kick.
    """
    n = arr.size
    win = Window(0, n)
    clip = clipped_mask(arr)
    hp, e, E, L, LL, (period, few) = _envelope(arr)
    # a strong line of fewer than 4 cycles dips near its zero crossings for longer than a
    # lead-in must last: no lead-in is looked for then (give ``start``)
    # the lead-in is looked for on a causal baseline first, then on the centred one: the
    # centred baseline sees the response's mean after the kick (half its length ahead), the
    # causal one lags a slow wobble; either may hide a lead-in, none makes one up
    # (_causal_envelope)
    hpc, ec = _causal_envelope(arr, L)
    lead, i_half = _lead(ec, L, period)
    if not lead:
        hpc = hp
        lead, i_half = _lead(e, L, period)
    if few:
        lead = 0
    if start is not None:
        win.start = int(min(max(round(start / dt), 0), n - MIN_SAMPLES))
        win.user_start = True
        win.lead = win.start
    elif lead:
        win.lead = lead
        win.start = _onset(hpc, lead, i_half)
    kicks = [] if few else _later_kicks(E, max(win.start, i_half), LL)
    if kicks:
        stop = kicks[0]
        if stop - win.start >= max(WINDOW_MIN * n, 4 * MIN_SAMPLES):
            win.stop = stop
            win.kicks = kicks
            win.flags.append(
                Flag(
                    "repeated_kick",
                    f"{len(kicks)} later kick(s) in the record (first at t = "
                    f"{kicks[0] * dt:.6g} from its first sample): the first ring-down is "
                    f"analysed (samples {win.start} to {win.stop}), the later ones are not",
                )
            )
    if (win.lead or clip is not None) and not win.user_start:
        least = int(max(WINDOW_MIN * n, 4 * MIN_SAMPLES))
        stop = _line_kick(hp, win.start, win.stop, least)
        if stop is not None and stop - win.start >= max(WINDOW_MIN * n, 4 * MIN_SAMPLES):
            win.kicks = sorted({*win.kicks, stop})
            win.stop = stop
            if not any(f.code == "repeated_kick" for f in win.flags):
                win.flags.append(Flag(
                    "repeated_kick",
                    f"a later kick in the record (the dominant line's amplitude or phase "
                    f"jumps near t = {stop * dt:.6g} from its first sample): the first "
                    f"ring-down is analysed (samples {win.start} to {win.stop}), the later "
                    "one is not",
                ))  # fmt: skip
    if clip is not None:
        win.n_clipped = int(clip.sum())
        win.clip = clip
        inside = int(np.count_nonzero(clip[win.start : win.stop]))
        win.flags.append(
            Flag(
                "clipped",
                f"{win.n_clipped} sample(s) held at the record's extreme (a saturated sensor); "
                f"the fit reads samples {win.start} to {win.stop} with the {inside} clipped "
                "one(s) among them as censored (only known to lie beyond the range: "
                "replaced by their expected values given the fit, iterated)",
            )
        )
    return win


def clipped_edges(
    arr: np.ndarray, win: Window
) -> tuple[np.ndarray, np.ndarray] | tuple[None, None]:
    """The window's samples clipped at the record's upper and at its lower edge (boolean
    masks over ``[win.start, win.stop)``); ``(None, None)`` when none is inside."""
    if win.clip is None:
        return None, None
    sl = slice(win.start, win.stop)
    hi = win.clip[sl] & (arr[sl] == float(arr.max()))
    lo = win.clip[sl] & (arr[sl] == float(arr.min()))
    return (hi, lo) if (hi.any() or lo.any()) else (None, None)


def lead_lines(arr: np.ndarray, lead: int) -> np.ndarray:
    """Angular frequencies (rad per sample) of the lines present in a quiet lead-in (mains hum
    and its harmonics, any stationary line): the significant peaks of its Hann periodogram
    (false-alarm 1e-3), sub-bin by a parabola on the log magnitude. Empty without a lead-in of
    at least 64 samples."""
    if lead < 64:
        return np.zeros(0)
    x = arr[:lead] - np.polyval(np.polyfit(np.arange(lead), arr[:lead], 1), np.arange(lead))
    nfft = 1 << int(math.ceil(math.log2(4 * lead)))
    P = np.abs(np.fft.rfft(x * np.hanning(lead), nfft)) ** 2
    noise = float(np.median(P)) / math.log(2.0)  # chi^2_2 median -> mean
    thr = noise * math.log(nfft / 2 / 1e-3)
    k = np.flatnonzero((P[1:-1] > thr) & (P[1:-1] >= P[:-2]) & (P[1:-1] >= P[2:])) + 1
    out = []
    for i in k:
        a, b, c = np.log(P[i - 1 : i + 2] + 1e-300)
        den = a - 2 * b + c
        d = 0.5 * (a - c) / den if den < 0 else 0.0
        out.append(2 * math.pi * (i + d) / nfft)
    # one per resolved line (the Hann main lobe is 4 bins of the unpadded lead)
    out.sort()
    res = 4 * math.pi * 2 / lead
    merged: list[float] = []
    for w in out:
        if not merged or w - merged[-1] > res:
            merged.append(w)
    return np.asarray(merged[:8])


#: A stationary line: its decay over the window ``gamma T`` below this (and not significant),
#: while a kicked mode beside it decays by at least LINE_RING_DECAY.
LINE_DECAY, LINE_RING_DECAY = 0.05, 0.3
#: A line seen before the kick (or given by the user) matches a mode within this many
#: frequency bins of the window (``2 pi / T``) or 4 standard errors.
LINE_BINS = 1.5
#: A mode that does not decay over the window is a line only when the lead-in before the kick
#: (where lines are looked for) is shorter than this many of its cycles.
LINE_LEAD_CYCLES = 3.0
#: A slow component not kicked from rest: its value at the window's first sample above this
#: fraction of its largest (a kicked overdamped mode starts from rest).
DRIFT_REST = 0.25
#: A kicked ringing mode decays by at least this many e-folds over the window.
RING_DECAY = 0.1
#: A transient (the hammer's contact absorbed by the fit): a mode whose envelope decays by
#: more than this many e-folds over the window (its slow pole), slower than a ringing mode.
TRANSIENT_DECAY = 8.0
#: ... or an overdamped mode whose terms exceed this many times the window's largest deviation
#: (two terms that cancel: a component that large cannot be in the record otherwise).
TRANSIENT_HUGE = 10.0
#: ... or (a lab window) an overdamped mode whose ``p`` (the sum of its decay rates) exceeds
#: this many times the smallest ``p`` of the (faster) ringing modes: with Rayleigh damping
#: ``p = alpha + beta omega^2`` a slower mode's ``p`` is below every faster mode's.
TRANSIENT_P = 100.0
#: A slow oscillation of fewer than FEW_PERIODS cycles, or a slow real pole, that decays by
#: less than this many e-folds over the window beside a ringing mode is the baseline's drift.
DRIFT_DECAY = 0.5
#: ... at less than this fraction of the ringing modes' decay rate (a structure's modes share
#: their damping's order; a drift does not decay); or an oscillation that grows but stays
#: below this fraction of the ringing mode's amplitude (past a transition the soft mode grows
#: as a real pole, not as an oscillation).
DRIFT_SMALL, DRIFT_RELATIVE = 0.1, 0.2
#: ... or an oscillation of fewer than FEW_PERIODS cycles below this fraction of the ringing
#: mode's amplitude (a wobble of the baseline; flagged ``fundamental_ambiguous`` when it
#: rings a cycle or more: the record is too short to tell it from a slow fundamental).
DRIFT_WEAK = 0.15
#: ... or below DRIFT_WEAK of it with fewer than WOBBLE_CYCLES cycles and no significant decay
#: (not ringing, :func:`_rings`), or a decay as slight as DRIFT_DECAY / DRIFT_RELATIVE allow
#: (:func:`_wobbles`): a kicked mode decays, a wobble of the baseline does not (flagged
#: ``fundamental_ambiguous`` by :func:`ambiguity`: the window is too short to tell).
WOBBLE_CYCLES = 2 * FEW_PERIODS
#: A growing mode whose largest amplitude over the window stays below this fraction of the
#: largest mode's is not evidence of instability (a fit's by-product beside a loud ringing).
GROWTH_NEGLIGIBLE = 1e-2


def _cycles(m: Mode, T: float) -> float:
    return m.omega * T / (2 * math.pi)


def _rings(m: Mode, T: float) -> bool:
    """A kicked ringing mode: underdamped, at least FEW_PERIODS oscillations in the window
    before it dies (decays by TRANSIENT_DECAY e-folds: a transient rings no cycles of its
    own), above the low-SNR level, and decaying (by RING_DECAY e-folds over the window at
    least, beyond 3 standard errors: a kicked mode decays, a line or a drift does not)."""
    alive = min(T, TRANSIENT_DECAY / m.damping) if m.damping > 0 else T
    return (
        m.regime == "underdamped"
        and _cycles(m, alive) >= FEW_PERIODS
        and (not math.isfinite(m.snr_db) or m.snr_db >= LOW_SNR_DB)
        and m.damping * T >= RING_DECAY
        and m.damping > 3.0 * m.damping_std
    )


def _from_rest(m: Mode, T: float) -> bool:
    """An overdamped mode whose two terms cancel at the first sample (kicked from rest)."""
    ra, rp = m.real_amplitudes, m.real_poles
    if ra is None or rp is None:
        return True
    t = np.linspace(0.0, T, 257)
    size = float(np.max(np.abs(ra[0] * np.exp(rp[0] * t) + ra[1] * np.exp(rp[1] * t))))
    return not size > 0 or abs(ra[0] + ra[1]) < DRIFT_REST * size


def _size(m: Mode, T: float) -> float:
    """The mode's rms envelope over the window ``T`` (its amplitude times the rms of
    ``exp(-gamma t)``): a transient's large initial amplitude counts for the short time it
    lasts."""
    x = 2.0 * m.damping * T
    if m.regime != "underdamped" or abs(x) < 1e-12:
        return m.amplitude
    return m.amplitude * math.sqrt(max(-math.expm1(-min(x, 700.0)) / x, 0.0))


def _wobbles(modes: list[Mode], T: float, rings: list[int]) -> set[int]:
    """Among the ringing modes ``rings``, those that are a wobble of the baseline beside a
    faster one: fewer than :data:`WOBBLE_CYCLES` cycles in the window, below
    :data:`DRIFT_WEAK` of the strongest faster ringing mode's rms envelope over the window
    (:func:`_size`), and a decay as slight
    as the :data:`DRIFT_DECAY` / :data:`DRIFT_RELATIVE` rule allows against the faster modes'
    least."""
    out = set()
    for k in rings:
        m = modes[k]
        faster = [modes[j] for j in rings if abs(modes[j].sigma2) > abs(m.sigma2)]
        if not faster or _cycles(m, T) >= WOBBLE_CYCLES:
            continue
        if (_size(m, T) < DRIFT_WEAK * max(_size(f, T) for f in faster)
                and abs(m.damping) * T < DRIFT_DECAY
                and abs(m.damping) < DRIFT_RELATIVE * min(f.damping for f in faster)):
            out.add(k)
    return out


def lines_and_drift(
    modes: list[Mode], T: float, seeds: np.ndarray, exclude: frozenset[int] | set[int],
    lead_T: float = 0.0, peak: float = math.inf, window: bool = False,
) -> tuple[frozenset[int], frozenset[int], frozenset[int]]:  # fmt: skip
    """Indices of the stationary lines, of the slow drift and of the transients among
    ``modes`` (a window of
    length ``T``; ``seeds`` the angular frequencies of lines seen before the kick or given
    by the user, rad per time unit; ``exclude`` the trends already set aside).

    * line: an underdamped mode at a seed's frequency (within :data:`LINE_BINS` bins or 4
      standard errors) that does not decay appreciably (``gamma T < 10 LINE_DECAY``); or one
      whose decay is not significant (``gamma T <`` :data:`LINE_DECAY` and within 3 standard
      errors of 0) beside a kicked mode that decays (``gamma T >=`` :data:`LINE_RING_DECAY`),
      unless a lead-in of ``lead_T`` holding :data:`LINE_LEAD_CYCLES` of its cycles did not
      show it: a stationary line decays neither before nor after the kick;
    * drift: beside a kicked ringing mode (:func:`_rings`) a slower component that was not
      kicked: an overdamped one that does not start from rest (a step, a ramp or a settling
      of the baseline) or whose slow pole decays by less than :data:`DRIFT_DECAY` e-folds
      over the window (a step: a fundamental that slow is not resolved by the record), an
      oscillation of less than one cycle in the window, one of less than FEW_PERIODS that
      decays by less than :data:`DRIFT_DECAY` e-folds at a rate below :data:`DRIFT_RELATIVE`
      of the ringing modes', or one that grows while staying below :data:`DRIFT_SMALL` of
      the ringing (a slow wobble), or one of fewer than FEW_PERIODS cycles (of fewer than
      :data:`WOBBLE_CYCLES` that does not decay significantly, or as slightly as the
      :data:`DRIFT_DECAY` rule allows) below :data:`DRIFT_WEAK` of the ringing mode's amplitude;
    * transient: beside a kicked ringing mode a slower one that dies within the window
      (:data:`TRANSIENT_DECAY` e-folds): the hammer's contact, a forced part the fit absorbed;
      or an overdamped one whose terms exceed :data:`TRANSIENT_HUGE` times the record's
      largest deviation ``peak`` (they cancel: a pair the fit made of the contact); on a
      record read through a lab ``window`` (a kick located), also an overdamped one whose
      ``p`` exceeds :data:`TRANSIENT_P` times the ringing modes' smallest.
    """
    lines: set[int] = set()
    for k, m in enumerate(modes):
        if k in exclude or m.regime != "underdamped" or m.omega <= 0:
            continue
        gT = m.damping * T
        tol = max(LINE_BINS * 2 * math.pi / T, 4.0 * m.omega_std)
        if seeds.size and np.min(np.abs(seeds - m.omega)) <= tol and abs(gT) < 10 * LINE_DECAY:
            lines.add(k)
            continue
        still = abs(gT) < LINE_DECAY and abs(m.damping) <= 3.0 * m.damping_std
        # a line is there before the kick too: a lead-in of LINE_LEAD_CYCLES of it that did
        # not show it says it is a lightly damped mode that the window is too short to see decay
        seen = _cycles(m, lead_T) >= LINE_LEAD_CYCLES
        if still and _cycles(m, T) >= 1.0 and not seen:
            ring = any(
                j != k and j not in exclude and mj.regime == "underdamped"
                and mj.damping * T >= LINE_RING_DECAY and mj.damping > 5.0 * mj.damping_std
                and mj.amplitude > m.amplitude
                for j, mj in enumerate(modes)
            )  # fmt: skip
            if ring:
                lines.add(k)
    drift: set[int] = set()
    rings = [
        j for j, m in enumerate(modes)
        if j not in exclude and j not in lines and _rings(m, T)
    ]  # fmt: skip
    wobble = _wobbles(modes, T, rings)
    drift |= wobble
    rings = [j for j in rings if j not in wobble]
    transient: set[int] = set()
    if rings:
        fastest_ring = min(abs(modes[j].sigma2) for j in rings)
        ring_decay = max(0.0, min(modes[j].damping for j in rings))
        for k, m in enumerate(modes):
            if k in exclude or k in lines or abs(m.sigma2) >= fastest_ring:
                continue
            slow = -max(m.real_poles) if m.regime == "overdamped" and m.real_poles else m.damping
            if slow * T > TRANSIENT_DECAY:
                transient.add(k)
            elif m.regime == "overdamped":
                if not _from_rest(m, T) or (
                    0 <= slow * T < DRIFT_DECAY and slow < DRIFT_RELATIVE * ring_decay
                ):
                    drift.add(k)
            elif (
                _cycles(m, T) < 1.0
                or (_cycles(m, T) < FEW_PERIODS and abs(m.damping) * T < DRIFT_DECAY
                    and abs(m.damping) < DRIFT_RELATIVE * ring_decay)
                or (m.damping < 0 and m.amplitude * math.exp(min(-m.damping * T, 700.0))
                    < DRIFT_SMALL * max(modes[j].amplitude for j in rings))
                or (_cycles(m, T) < FEW_PERIODS
                    and m.amplitude < DRIFT_WEAK * max(modes[j].amplitude for j in rings))
                or (_cycles(m, T) < WOBBLE_CYCLES and not _rings(m, T)
                    and _size(m, T) < DRIFT_WEAK * max(_size(modes[j], T) for j in rings))
            ):  # fmt: skip
                drift.add(k)
        # (also where the first pass read it as a combination tone)
        transient |= {k for k, m in enumerate(modes)
                      if m.regime == "overdamped" and m.amplitude > TRANSIENT_HUGE * peak
                      and k not in lines and k not in drift and k not in rings}  # fmt: skip
        # an overdamped pair whose decay rates sum (its p) far above the ringing modes' p:
        # no mode of the structure (Rayleigh damping p = alpha + beta omega^2 grows with the
        # frequency: a slower mode is not damped harder than any faster one, so the least
        # damped ringing mode bounds it; a fast, heavily damped ringing mode the fit made of
        # the contact says nothing), a forced part the fit absorbed
        p_ring = min(2.0 * modes[j].damping for j in rings)
        transient |= {k for k, m in enumerate(modes)
                      if window and m.regime == "overdamped" and m.real_poles is not None
                      and -(m.real_poles[0] + m.real_poles[1]) > TRANSIENT_P * p_ring
                      and k not in lines and k not in drift
                      and abs(m.sigma2) < fastest_ring}  # fmt: skip
    return frozenset(lines), frozenset(drift), frozenset(transient)


#: A slow component was there before the kick (a drift, not a kicked mode) when the lead-in,
#: regressed on a constant, a ramp and the component's waveform extrapolated back over it, holds
#: that waveform at more than BEFORE_SHARE of its size and BEFORE_Z standard errors from none.
BEFORE_SHARE, BEFORE_Z = 0.5, 5.0
#: A waveform that extrapolates back to more than this many times the lead-in's range is not
#: looked for there (a kicked mode's growth backwards).
BEFORE_RANGE = 1e3


def _grows(m: Mode, T: float) -> bool:
    """Whether the component grows by more than a factor e over the window ``T`` (a growing
    record past the transition: never read as a drift the lead-in holds)."""
    if m.regime == "overdamped" and m.real_poles is not None:
        return max(m.real_poles) * T > 1.0
    return -m.damping * T > 1.0


def before_kick(
    modes: list[Mode], T: float, lead: np.ndarray | None, offset: int, dt: float,
    exclude: frozenset[int] | set[int], lines: frozenset[int] | set[int] = frozenset(),
) -> frozenset[int]:  # fmt: skip
    """Indices of the components slower than a kicked ringing mode (:func:`_rings`) that the
    lead-in before the kick already holds: a kicked mode is not there before its kick, a
    drift of the baseline (a wobble, a settling) is. ``lead``: the record before the kick, in
    the modes' units; ``offset``: the fitted window's first sample less the lead-in's first
    (the lead's samples are at ``-offset .. len(lead) - offset - 1`` of the window);
    ``lines``: the stationary lines (their frequencies are regressed out of the lead too)."""
    if lead is None or lead.size < 64:
        return frozenset()
    rings = [m for j, m in enumerate(modes) if j not in exclude and _rings(m, T)]
    if not rings:
        return frozenset()
    fastest = max(abs(m.sigma2) for m in rings)
    u = (np.arange(lead.size) - offset) * dt
    t = u - u.mean()
    cols = [np.ones(lead.size), t]
    for j in sorted(lines):
        cols += [np.cos(modes[j].omega * u), np.sin(modes[j].omega * u)]
    out = set()
    for k, m in enumerate(modes):
        if k in exclude or not abs(m.sigma2) < fastest or _rings(m, T) or _grows(m, T):
            continue
        with np.errstate(over="ignore", invalid="ignore"):
            if m.regime == "overdamped" and m.real_poles is not None and m.real_amplitudes:
                (s1, s2), (b1, b2) = m.real_poles, m.real_amplitudes
                w = b1 * np.exp(s1 * u) + b2 * np.exp(s2 * u)
            else:
                w = m.amplitude * np.exp(-m.damping * u) * np.cos(m.omega * u + m.phase)
        # extrapolated back to far beyond the lead's own range: not there before the kick
        span = float(np.ptp(lead))
        if not np.all(np.isfinite(w)) or not 0 < float(np.ptp(w)) <= BEFORE_RANGE * span:
            continue
        X = np.column_stack((*cols, w))
        coef, *_ = np.linalg.lstsq(X, lead, rcond=None)
        r = lead - X @ coef
        s2 = float(r @ r) / max(lead.size - X.shape[1], 1)
        cov = np.linalg.pinv(X.T @ X) * s2
        se = math.sqrt(max(float(cov[-1, -1]), 0.0))
        beta = float(coef[-1])
        if beta > BEFORE_SHARE and (se == 0.0 or beta > BEFORE_Z * se):
            out.add(k)
    return frozenset(out)


def negligible_growth(modes: list[Mode], T: float) -> frozenset[int]:
    """Modes that grow but stay below :data:`GROWTH_NEGLIGIBLE` of the largest amplitude over
    the window: a by-product of the fit beside a loud ringing, not an instability."""
    if len(modes) < 2:
        return frozenset()
    big = max(m.amplitude for m in modes)
    out = set()
    for k, m in enumerate(modes):
        rate = -m.damping
        if m.regime == "overdamped" and m.real_poles is not None:
            rate = max(m.real_poles)
        if not rate > 0:
            continue
        peak = m.amplitude * math.exp(min(rate * T, 700.0))
        if peak < GROWTH_NEGLIGIBLE * big:
            out.add(k)
    return frozenset(out)


#: The forced part: residual blocks whose mean square exceeds this many noise variances ...
FORCED_LEVEL = 9.0
#: ... confined to this head fraction of the window, the next FORCED_AFTER of it quiet.
FORCED_HEAD, FORCED_AFTER = 0.1, 0.2


def forced_head(residual: np.ndarray, noise_std: float) -> int:
    """Samples to skip at the head of a window whose fit leaves a misfit confined to its
    first samples (the hammer's contact: a forced response, not a free one); 0 when the
    residual's head is like the rest.

    The residual is cut in blocks of ``B = max(8, N / 200)`` samples; a block misfits when
    its mean square exceeds :data:`FORCED_LEVEL` noise variances (an rms 3x the noise: for
    white residuals a ``chi^2_B / B`` that large has a probability below 1e-9). The skip is the
    end of the last misfitting block within the first :data:`FORCED_HEAD` of the window, when
    the following :data:`FORCED_AFTER` of it fits (mean square below 2.5 variances): a misfit
    spread over the record (an amplitude-dependent frequency) is not a contact."""
    n = residual.size
    if not (noise_std > 0 and math.isfinite(noise_std)) or n < 64:
        return 0
    B = max(8, n // 200)
    nb = n // B
    ms = np.mean((residual[: nb * B] / noise_std).reshape(nb, B) ** 2, axis=1)
    head = max(1, int(FORCED_HEAD * nb))
    bad = np.flatnonzero(ms[:head] > FORCED_LEVEL)
    if not bad.size:
        return 0
    end = int(bad[-1]) + 1
    after = ms[end : end + max(1, int(FORCED_AFTER * nb))]
    if after.size == 0 or float(np.mean(after)) > 2.5:
        return 0
    return end * B


#: The flags of components set aside, in their order: (flag, the mode's description in the
#: list, the message around the list; ``{n}`` the count, ``{txt}`` the list, ``{big}`` the
#: largest amplitude).
_ASIDE_FLAGS = (
    ("forced_part",
     lambda m: f"sigma^2 = {m.sigma2:.4g}, decay rate {m.damping:.4g}",
     "{n} transient(s) that die early in the record set aside: {txt}; slower than a ringing "
     "mode but gone within the record (the hammer's contact, a forced response the free-decay "
     "model absorbed); never the fundamental"),
    ("stationary_line",
     lambda m: f"{m.frequency:.6g} cycles/time, amplitude {m.amplitude:.3g}",
     "{n} stationary line(s) fitted and set aside: {txt}; present before the kick, given as "
     "notch frequencies, or not decaying while the kicked modes do (mains hum and its "
     "harmonics look like this); never the fundamental"),
    ("drift",
     lambda m: f"sigma^2 = {m.sigma2:.4g}",
     "{n} slow component(s) set aside as a drift of the baseline: {txt}; slower than a kicked "
     "ringing mode and not kicked from rest (an offset that settles, a ramp, a slow wobble of "
     "the sensor or of the equilibrium); never the fundamental"),
    ("negligible_growth",
     lambda m: f"amplitude {m.amplitude:.3g}, growth rate {-m.damping:.3g}",
     "{n} growing component(s) stay below " + f"{GROWTH_NEGLIGIBLE:g}" + " of the largest "
     "amplitude ({big:.3g}) over the record: {txt}; a by-product of the fit, not read as an "
     "instability"),
)  # fmt: skip


def aside_flags(
    modes: list[Mode], lines: frozenset[int], drift: frozenset[int], tiny: frozenset[int],
    transient: frozenset[int] = frozenset(),
) -> list[Flag]:  # fmt: skip
    """The flags forced_part (a transient), stationary_line, drift and negligible_growth
    (indices into ``modes``), built from :data:`_ASIDE_FLAGS`."""
    sets = {"forced_part": transient, "stationary_line": lines, "drift": drift,
            "negligible_growth": tiny}  # fmt: skip
    out = []
    for code, describe, text in _ASIDE_FLAGS:
        idx = sets[code]
        if not idx:
            continue
        txt = ", ".join(f"modes[{k}] ({describe(modes[k])})" for k in sorted(idx))
        big = max(m.amplitude for m in modes)
        out.append(Flag(code, text.format(n=len(idx), txt=txt, big=big)))
    return out


#: The fundamental is ambiguous (flag ``fundamental_ambiguous``) when another mode of the
#: structure lies within AMBIG_CLOSE of its frequency with at least AMBIG_AMP of its amplitude
#: (one line split in several by a model that does not hold over the window: a later kick or
#: clipped samples inside it; or two close modes the record does not tell apart) ...
AMBIG_CLOSE, AMBIG_AMP = 0.25, 0.1
#: ... or when it dies within the window (AMBIG_DECAY e-folds; one e-fold beside a ringing mode
#: at least 1/AMBIG_WEAK times stronger) AMBIG_FASTER times faster than a ringing mode (a
#: transient the fit absorbed), or does not decay beside a ringing mode at least 1/AMBIG_WEAK
#: times stronger that does (a line or a drift kept as a mode).
AMBIG_WEAK, AMBIG_DECAY, AMBIG_FASTER = 1.0 / 3.0, 5.0, 3.0
#: ... or when a stronger component within AMBIG_SLOWER times below its frequency was set
#: aside as a line or a drift from fewer than 2 FEW_PERIODS cycles in the window.
AMBIG_SLOWER = 5.0


def ambiguity(modes: list[Mode], T: float) -> Flag | None:
    """The warning ``fundamental_ambiguous`` (None: the fundamental ``modes[0]`` is not in
    doubt): another candidate is comparably plausible, or the fundamental does not behave as
    a kicked mode of the structure beside one that does (window length ``T``)."""
    if not modes or modes[0].kind != "mode" or modes[0].regime != "underdamped":
        return None
    f = modes[0]
    rivals = [(j, m) for j, m in enumerate(modes) if j and m.kind == "mode"
              and m.combination is None]  # fmt: skip
    why = []
    close = [j for j, m in rivals
             if m.regime == "underdamped" and f.omega > 0
             and abs(m.omega / f.omega - 1.0) <= AMBIG_CLOSE
             and m.amplitude >= AMBIG_AMP * f.amplitude]  # fmt: skip
    if close:
        why.append(
            ", ".join(f"modes[{j}] ({modes[j].frequency:.6g})" for j in close)
            + f" within {100 * AMBIG_CLOSE:g} % of its frequency with at least "
            f"{100 * AMBIG_AMP:g} % of its amplitude (one line split in several: a later kick "
            "or clipped samples in the window, or two close modes)"
        )
    ringing = [(j, m) for j, m in rivals if _rings(m, T)]
    strong = [(j, m) for j, m in ringing if f.amplitude < AMBIG_WEAK * m.amplitude]
    for group, decay in ((ringing, AMBIG_DECAY), (strong, 1.0)):
        if not group:
            continue
        j, slow = min(group, key=lambda jm: jm[1].damping)
        if f.damping * T > decay and f.damping > AMBIG_FASTER * slow.damping:
            why.append(f"it dies within the window ({f.damping * T:.3g} e-folds), "
                       f"{f.damping / slow.damping:.3g}x faster than modes[{j}] that rings on"
                       + (" and is 3x stronger" if decay == 1.0 else "")
                       + " (a transient?)")  # fmt: skip
            break
    if strong and (f.damping * T < RING_DECAY or not f.damping > 3.0 * f.damping_std):
        j = max(strong, key=lambda jm: jm[1].amplitude)[0]
        why.append(f"it does not decay ({f.damping * T:.3g} e-folds over the window) while "
                   f"the stronger modes[{j}] rings down (a line or a drift?)")
    slower = [j for j, m in enumerate(modes)
              if j and m.kind in ("line", "drift") and m.regime == "underdamped"
              and f.omega / AMBIG_SLOWER <= m.omega < f.omega and m.amplitude >= f.amplitude
              and _cycles(m, T) < 2 * FEW_PERIODS]  # fmt: skip
    if slower:
        j = slower[0]
        why.append(f"the stronger, slower modes[{j}] ({modes[j].frequency:.6g}, set aside as "
                   f"a {modes[j].kind}) rings only {_cycles(modes[j], T):.2g} cycles in the "
                   "window: too few to tell a fundamental from a line or a drift")  # fmt: skip
    wobble = [j for j, m in enumerate(modes)
              if j and m.kind == "drift" and m.regime == "underdamped" and m.omega < f.omega
              and _cycles(m, T) >= 1.0]  # fmt: skip
    if wobble:
        j = wobble[0]
        why.append(f"the slower modes[{j}] ({modes[j].frequency:.6g}, {_cycles(modes[j], T):.2g} "
                   "cycles in the window) was set aside as a drift: were it the structure's "
                   "fundamental, the window is too short to tell")  # fmt: skip
    if not why:
        return None
    return Flag(
        "fundamental_ambiguous",
        f"the fundamental ({f.frequency:.6g} cycles/time) may not be the structure's: "
        + "; ".join(why) + ". Check the record (a clean single kick), or give the band",
    )


#: The baseline drifts (flag ``baseline_drift``, static level NaN) when the block means of the
#: residual over the window (DRIFT_BLOCKS blocks) scatter with a chi^2 above DRIFT_CHI2 (the
#: 1e-6 false-alarm point of chi^2 with 15 degrees of freedom), or the quiet lead-in's level
#: differs from the fitted static level by more than DRIFT_Z standard errors; either only where
#: the movement also exceeds DRIFT_FLOOR of the larger of the window's largest deviation and the
#: static level (below it, on near-noiseless records, a model's own misfit is "significant",
#: and no sensor's drift of that size moves the static level appreciably).
DRIFT_BLOCKS, DRIFT_CHI2, DRIFT_Z, DRIFT_FLOOR = 16, 56.5, 5.0, 1e-3


def baseline_drift(
    residual: np.ndarray, noise_std: float, static: float, static_std: float,
    lead: np.ndarray | None, drift_modes: int, peak: float = 0.0,
) -> str | None:  # fmt: skip
    """Why the static level of a lab record cannot be trusted (None: nothing says so).

    ``residual``: the window minus its fitted model (modes and static level), with any slope
    the fit removed left in; ``lead``: the lead-in before the kick (the structure at rest);
    ``drift_modes``: the number of components set aside as drift. A sensor's offset, ramp or
    wobble is not the structure's equilibrium, and a constant offset cannot be told from it at
    all: where the baseline is seen to move, the level it has is not reported as static.
    ``peak``: the larger of the window's largest deviation from the static level and that
    level's magnitude (the floor's scale)."""
    floor = DRIFT_FLOOR * peak if math.isfinite(peak) else 0.0
    why = []
    if drift_modes:
        why.append(f"{drift_modes} slow component(s) set aside as drift")
    n = residual.size
    B = n // DRIFT_BLOCKS
    if B >= 8 and noise_std > 0 and math.isfinite(noise_std):
        bm = residual[: DRIFT_BLOCKS * B].reshape(DRIFT_BLOCKS, B).mean(axis=1)
        chi2 = float(np.sum((bm - bm.mean()) ** 2)) / (noise_std**2 / B)
        if chi2 > DRIFT_CHI2 and float(np.ptp(bm)) > floor:
            why.append(f"the residual's baseline moves by {float(np.ptp(bm)):.3g} over the "
                       f"window (chi^2 {chi2:.3g}, {DRIFT_BLOCKS - 1} degrees of freedom)")
    if lead is not None and lead.size >= 64:
        sd = math.hypot(float(np.std(lead)) / math.sqrt(lead.size),
                        static_std if math.isfinite(static_std) else 0.0)  # fmt: skip
        diff = float(np.mean(lead)) - static
        if sd > 0 and abs(diff) > DRIFT_Z * sd and abs(diff) > floor:
            why.append(f"the level at rest before the kick differs from it by {diff:.3g} "
                       f"({abs(diff) / sd:.3g} standard errors)")  # fmt: skip
    return "; ".join(why) or None
