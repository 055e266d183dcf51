"""Components of a lab window's fit that are not the structure's modes, and a fundamental in
doubt.

After the fit of a lab window (:mod:`._lab` locates it, :mod:`._core` fits it), its components
are told apart: stationary lines (mains hum, a line present before the kick), the baseline's
drift (an offset that settles, a ramp, a slow wobble), transients (the hammer's contact the
free-decay model absorbed) and growth too small to mean anything; each is set aside with its
flag and is never the fundamental. :func:`ambiguity` says when the fundamental left may not be
the structure's.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from service.analysis.common import Flag
from service.analysis.detect._results import FEW_PERIODS, LOW_SNR_DB, Mode

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
#: ... or (a quiet line, :func:`quiet_lines`) one whose decay is not significant (within 3
#: standard errors of none) and measured below LINE_QUIET of the decay rate of a kicked mode
#: whose rms envelope over the window is LINE_QUIET_LOUD times larger (an aliased mains line, a
#: rig's or sensor's line: the window too short for LINE_DECAY to tell).
LINE_QUIET, LINE_QUIET_LOUD = 0.2, 10.0
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


def _huge_growth(m: Mode, T: float, peak: float) -> bool:
    """An overdamped mode with a growing term that reaches more than :data:`TRANSIENT_HUGE`
    times the window's largest deviation ``peak`` by the window's end: a record that large is
    not there, so the fit cancels it with another term (a ramp, a response that comes to rest
    off its equilibrium, read as two growing pairs), not a growth of the structure (which the
    record itself would show)."""
    if m.real_poles is None or m.real_amplitudes is None or not math.isfinite(peak):
        return False
    big = max(abs(b) * math.exp(min(s * T, 700.0))
              for s, b in zip(m.real_poles, m.real_amplitudes, strict=True) if s > 0) \
        if any(s > 0 for s in m.real_poles) else 0.0
    return big > TRANSIENT_HUGE * peak


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
                if _huge_growth(m, T, peak) or not _from_rest(m, T) or (
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


#: A component slower than a kicked ringing mode is not the fundamental when the fit's own
#: errors do not tell it from nothing: its amplitude below UNDETERMINED_Z of its standard
#: error (the Gauss-Newton one: the poles' uncertainty included), while the ringing mode's
#: amplitude lies beyond RING_Z of its own.
UNDETERMINED_Z, RING_Z = 2.0, 10.0


def undetermined(modes: list[Mode], T: float, exclude: frozenset[int] | set[int]
                 ) -> frozenset[int]:  # fmt: skip
    """Indices of the components, slower than a kicked ringing mode (:func:`_rings`) whose
    amplitude is determined (beyond :data:`RING_Z` standard errors), whose own amplitude lies
    within :data:`UNDETERMINED_Z` standard errors of 0: the record holds no evidence of them
    (a pair of slow, heavily damped terms the fit made of the noise, their poles undetermined),
    so they cannot be the fundamental beside a mode the record does show. They stay modes
    (a sweep may still follow one); the record is flagged ``fundamental_ambiguous``."""
    rings = [m for j, m in enumerate(modes)
             if j not in exclude and _rings(m, T)
             and m.amplitude > RING_Z * m.amplitude_std]  # fmt: skip
    if not rings:
        return frozenset()
    fastest = max(abs(m.sigma2) for m in rings)
    return frozenset(
        k for k, m in enumerate(modes)
        if k not in exclude and abs(m.sigma2) < fastest
        and not m.amplitude > UNDETERMINED_Z * m.amplitude_std
        and not any(m is r for r in rings)
    )  # fmt: skip


#: Sidebands of an amplitude-modulated line (a ring-down whose envelope is not exponential:
#: joint friction decays it linearly until it sticks; a beat with a slow wobble). The fit
#: spreads such a line into a comb: weaker lines at mirrored frequencies around its carrier. The
#: carrier: the dominant line (the largest amplitude; a kicked ringing one), or midway between
#: it and the strongest other line within SIDEBAND_SPAN of it when that one has SIDEBAND_SPLIT
#: of its amplitude or more (a main lobe split in two). A comb: two lines weaker than
#: SIDEBAND_AMP of the dominant (or that strongest other line), within SIDEBAND_SPAN of it, one
#: on each side of the carrier (the most nearly mirrored pair chooses it) at mirrored
#: frequencies (``omega_a + omega_b = 2 omega_c`` within SIDEBAND_TOL of their offset or
#: SIDEBAND_Z combined standard errors). Then every line weaker than SIDEBAND_AMP of the
#: dominant within SIDEBAND_ORDER + 1/2 of the comb's spacing (its closest pair's offset) from
#: the carrier belongs to it. The comb's lines are never the fundamental (the dominant line is,
#: flagged ``fundamental_ambiguous`` when a slower line was set aside), and the dominant's
#: sigma^2 is known no better than half its difference from the strongest comb line (when that
#: one has SIDEBAND_SPLIT of its amplitude): the carrier lies between them.
SIDEBAND_AMP, SIDEBAND_SPAN, SIDEBAND_TOL, SIDEBAND_Z = 0.5, 0.5, 0.1, 4.0
SIDEBAND_SPLIT, SIDEBAND_ORDER = 0.3, 4


def sidebands(modes: list[Mode], T: float, exclude: frozenset[int] | set[int]
              ) -> tuple[dict[int, tuple[int, int]], int | None]:  # fmt: skip
    """The comb of the dominant line (see :data:`SIDEBAND_AMP`; it rings, :func:`_rings`, in the
    window of length ``T``): its lines (index -> (the
    dominant's index, the number of the comb's spacings from the carrier, signed)) and the
    comb line that bounds the dominant's error (None: none as strong as SIDEBAND_SPLIT)."""
    cand = [k for k, m in enumerate(modes)
            if k not in exclude and m.regime == "underdamped" and m.omega > 0]  # fmt: skip
    if len(cand) < 3:
        return {}, None
    d = max(cand, key=lambda k: modes[k].amplitude)
    D = modes[d]
    if not _rings(D, T):
        return {}, None  # a heavily damped term (the hammer's contact) carries no comb
    near_d = [k for k in cand
              if k != d and abs(modes[k].omega - D.omega) <= SIDEBAND_SPAN * D.omega]
    if not near_d:
        return {}, None
    s = max(near_d, key=lambda k: modes[k].amplitude)
    strong = s if modes[s].amplitude >= SIDEBAND_SPLIT * D.amplitude else None
    centres = [(D.omega, None)]
    if strong is not None:
        centres.append((0.5 * (D.omega + modes[s].omega), s))
    best, offs = None, {}
    for c, split in centres:
        weaker = [k for k in cand if k not in (d, split)
                  and modes[k].amplitude < SIDEBAND_AMP * D.amplitude]  # fmt: skip
        if strong is not None and split is None:
            weaker.append(strong)  # a strong sideband of the dominant line
        weak = [k for k in weaker if k in near_d]
        for a in weak:
            for b in weak:
                ma, mb = modes[a], modes[b]
                if not ma.omega < c < mb.omega:
                    continue
                off = c - ma.omega
                miss = abs(ma.omega + mb.omega - 2.0 * c)
                sd = math.sqrt(ma.omega_std**2 + mb.omega_std**2 + 4.0 * D.omega_std**2)
                if miss <= max(SIDEBAND_TOL * off, SIDEBAND_Z * sd):
                    offs.setdefault(c, []).append(off)
                    # the centre whose pair is the most nearly mirrored
                    if best is None or miss / off < best[0]:
                        best = (miss / off, c, split, weaker)
    if best is None:
        return {}, None
    _, c, split, weaker = best
    step = min(offs[c])  # the comb's spacing: its closest pair's offset
    out = {}
    for k in weaker:
        off = modes[k].omega - c
        if abs(off) <= (SIDEBAND_ORDER + 0.5) * step:
            n = int(round(off / step))
            out[k] = (d, n if n else (1 if off > 0 else -1))
    if split is not None:
        out[split] = (d, 0)
    # the carrier lies between the dominant line and a line as strong as SIDEBAND_SPLIT of it
    comb = [k for k in out if modes[k].amplitude >= SIDEBAND_SPLIT * D.amplitude]
    if strong is not None:
        comb.append(strong)
    bound = max(comb, key=lambda k: modes[k].amplitude) if comb else None
    return out, bound


def quiet_lines(modes: list[Mode], T: float, exclude: frozenset[int] | set[int]
                ) -> frozenset[int]:  # fmt: skip
    """Indices of the quiet lines (see :data:`LINE_QUIET`): underdamped components of one cycle
    or more in the window ``T`` whose decay is not significant and whose decay rate, plus two
    standard errors, lies below LINE_QUIET of a kicked ringing mode's (:func:`_rings`, decaying
    beyond 5 standard errors) whose rms envelope (:func:`_size`) is LINE_QUIET_LOUD times
    larger. Never the fundamental; a record whose fundamental would have been one is flagged
    ``fundamental_ambiguous``."""
    out = set()
    for k, m in enumerate(modes):
        if k in exclude or m.regime != "underdamped" or m.omega <= 0 or _cycles(m, T) < 1.0:
            continue
        if not abs(m.damping) <= 3.0 * m.damping_std:
            continue
        top = abs(m.damping) + 2.0 * m.damping_std
        if any(j != k and j not in exclude and _rings(mj, T)
               and _size(mj, T) >= LINE_QUIET_LOUD * _size(m, T)
               and top < LINE_QUIET * mj.damping and mj.damping > 5.0 * mj.damping_std
               for j, mj in enumerate(modes)):  # fmt: skip
            out.add(k)
    return frozenset(out)


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


def _doubt_with(doubt: Flag | None, f: Mode, txt: str) -> Flag:
    """The ``fundamental_ambiguous`` flag ``doubt`` with the reason ``txt`` added before its
    advice (None: a new flag for the fundamental ``f`` with that reason)."""
    if doubt is None:
        return Flag("fundamental_ambiguous",
                    f"the fundamental ({f.frequency:.6g} cycles/time) may not be the "
                    f"structure's: {txt}. Check the record (a clean single kick), or give the "
                    "band")  # fmt: skip
    head, sep, tail = doubt.message.partition(". Check the record")
    return Flag(doubt.code, f"{head}; {txt}{sep}{tail}")


def with_undetermined(doubt: Flag | None, modes: list[Mode], idx: list[int]) -> Flag:
    """The ``fundamental_ambiguous`` flag ``doubt`` (None: a new one) saying that the slower
    components ``modes[idx]`` (:func:`undetermined`) were not taken as the fundamental."""
    f = modes[0]
    txt = ("the slower " + ", ".join(
        f"modes[{j}] ({modes[j].frequency:.6g} cycles/time, amplitude {modes[j].amplitude:.3g} "
        f"+- {modes[j].amplitude_std:.3g})" for j in idx)
        + f" not taken: the fit does not tell {'it' if len(idx) == 1 else 'them'} from nothing "
        f"(amplitude within {UNDETERMINED_Z:g} standard errors of 0) beside a ringing mode "
        "the record shows")  # fmt: skip
    return _doubt_with(doubt, f, txt)


def split_rival(modes: list[Mode], f: int, others: set[int]) -> int | None:
    """The strongest of ``others`` (modes of the structure) within AMBIG_CLOSE of the
    fundamental ``modes[f]``'s frequency and 1/AMBIG_WEAK times stronger (None: none): one line
    split in several, whose frequency lies between them (its sigma^2 error covers half their
    difference, :func:`comb_bounded`)."""
    m = modes[f]
    if m.regime != "underdamped" or not m.omega > 0:
        return None
    close = [k for k in others
             if modes[k].regime == "underdamped" and modes[k].combination is None
             and abs(modes[k].omega / m.omega - 1.0) <= AMBIG_CLOSE
             and m.amplitude < AMBIG_WEAK * modes[k].amplitude]  # fmt: skip
    return max(close, key=lambda k: modes[k].amplitude) if close else None


def comb_bounded(f: Mode, other: Mode | None) -> Mode:
    """The dominant line ``f`` of a comb (:func:`sidebands`) with its sigma^2 error at least half
    its difference from the comb's strongest line ``other`` (None: ``f`` unchanged)."""
    if other is None:
        return f
    sd = 0.5 * abs(f.sigma2 - other.sigma2)
    if not sd > f.sigma2_std:
        return f
    om = 0.5 * abs(f.omega - other.omega)
    return replace(f, sigma2_std=sd, omega_std=max(f.omega_std, om))


def with_sidebands(doubt: Flag | None, modes: list[Mode], idx: list[int], bound: int | None
                   ) -> Flag | None:  # fmt: skip
    """The ``fundamental_ambiguous`` flag ``doubt`` (None: a new one) saying that the
    fundamental ``modes[0]`` was read at the dominant line of a comb whose lines ``modes[idx]``
    are its sidebands, when one of them is slower or bounds its error (else ``doubt``)."""
    f = modes[0]
    slower = [j for j in idx if modes[j].omega < f.omega]
    if not slower and bound is None:
        return doubt
    txt = ("it is the dominant line of a comb of sidebands (" + ", ".join(
        f"modes[{j}] ({modes[j].frequency:.6g})" for j in idx)
        + "): an amplitude-modulated ring-down (an envelope that is not exponential: joint "
        "friction, a line that sticks, a beat), read at the dominant line")  # fmt: skip
    if bound is not None:
        txt += (f"; its sigma^2 error is at least half its difference from modes[{bound}] "
                "(the carrier lies between them)")
    return _doubt_with(doubt, f, txt)


def with_quiet_lines(doubt: Flag | None, modes: list[Mode], idx: list[int]) -> Flag:
    """The ``fundamental_ambiguous`` flag ``doubt`` (None: a new one) saying that the slower
    quiet lines ``modes[idx]`` (:func:`quiet_lines`) were not taken as the fundamental."""
    f = modes[0]
    txt = ("the slower " + ", ".join(f"modes[{j}] ({modes[j].frequency:.6g} cycles/time, "
                                     f"decay {modes[j].damping:.3g} +- {modes[j].damping_std:.3g})"
                                     for j in idx)
           + " set aside as a stationary line: it does not decay measurably while a kicked "
           "mode 10x stronger rings down (an aliased mains line, a rig's or a sensor's line; "
           "a weak, lightly damped fundamental would look the same)")  # fmt: skip
    return _doubt_with(doubt, f, txt)
