"""Records as labs make them: the kick, repeated kicks, clipped samples, stationary lines.

A lab's impulse record is rarely a free decay from its first sample: a scope records a
pre-trigger (the structure at rest, with the mains hum and the sensor's drift on it), the
hammer's contact forces the structure for a few ms, a second hit may follow, the sensor may
saturate. This module finds the part of the record that is a free response (the window the
fit reads) and the lines that are there before the kick; :mod:`._core` fits the window and
:mod:`._aside` tells lines, drift and transients from the modes.

Everything here is a no-op on a record that starts with its free response and holds no quiet
lead-in, no clipped run and no second kick: such records are analysed as before.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from service.analysis.common import Flag
from service.analysis.detect._kernels import running_min
from service.analysis.detect._results import MIN_SAMPLES

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
