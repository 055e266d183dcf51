"""Flags of a detection: the half-record linearity check and the flag block of :func:`detect`."""

from __future__ import annotations

import math

import numpy as np

from service.analysis.common import Flag
from service.analysis.detect._kernels import _ch_sh
from service.analysis.detect._linalg import _pinv_psd, _solve_gram
from service.analysis.detect._modes import _grows
from service.analysis.detect._results import (
    ALIAS_FRACTION,
    FEW_PERIODS,
    GROWTH_Z,
    LOW_SNR_DB,
    MIN_SAMPLES,
    NONLINEAR_Z,
    S2_FLOOR,
    Mode,
)
from service.analysis.detect._spectral import _Spectrum
from service.analysis.detect._varpro import _Fit, _heavy_pass, _levenberg_marquardt, _mode_energy


def _shifted_coefficients(p: np.ndarray, q: np.ndarray, c: np.ndarray, h: int) -> np.ndarray:
    """Linear coefficients of the same modes with the time origin moved to sample ``h``."""
    out = c.copy()
    with np.errstate(all="ignore"):
        _shift_into(p, q, c, h, out)
    return out


def _shift_into(p: np.ndarray, q: np.ndarray, c: np.ndarray, h: int, out: np.ndarray) -> None:
    for k in range(p.size):
        pk, qk = float(p[k]), float(q[k])
        D = 0.25 * pk * pk - qk
        vals = []
        for n in (h, h + 1):
            ch, sh, _ = _ch_sh(D * n * n)
            e = math.exp(min(-0.5 * pk * n, 700.0))
            vals.append(c[1 + 2 * k] * e * ch + c[2 + 2 * k] * e * n * sh)
        ch1, sh1, _ = _ch_sh(D)
        e1 = math.exp(-0.5 * pk)
        c1 = vals[0]
        c2 = (vals[1] - c1 * e1 * ch1) / (e1 * sh1)
        out[1 + 2 * k], out[2 + 2 * k] = c1, c2


def _one_step(y: np.ndarray, fit: _Fit, c: np.ndarray) -> tuple[float, float] | None:
    """One Gauss-Newton step from the full-record poles on a part ``y`` of the record (one
    pass); returns the fundamental's ``q`` and its variance (one-step estimator)."""
    nth = fit.ntheta
    B = _heavy_pass(y, fit.ev.p, fit.ev.q, c, fit.common)
    if B is None:
        return None
    c_part, rss = _solve_gram(B[nth:, nth:])
    A = B[:-1, :-1]
    g = B[:-1, -1] - B[:-1, nth:-1] @ c_part
    Ainv = _pinv_psd(A)
    step = Ainv @ g
    s2 = max(max(rss - float(g @ step), 0.0) / max(y.size - A.shape[0], 1), S2_FLOOR)
    jq = 1
    return float(fit.ev.q[0] + step[jq]), float(Ainv[jq, jq] * s2)


def _linearity_flag(y: np.ndarray, fit: _Fit, dt: float, max_iter: int) -> Flag | None:
    """Compare the fundamental's sigma^2 fitted on the two halves of the record.

    A chirp (frequency drifting with the decaying amplitude) is often absorbed by the full
    record's fit into a cluster of modes at nearly the fundamental's frequency; the halves are
    then fitted with the cluster reduced to its strongest member (Levenberg-Marquardt), else by
    one Gauss-Newton step from the full fit.
    """
    N = y.shape[0]
    h = N // 2
    if h < MIN_SAMPLES:
        return None
    p, q = fit.ev.p, fit.ev.q
    per = math.sqrt(abs(float(q[0]))) * h / (2 * math.pi)
    if per < 1.0:
        return None  # a half record too short to tell
    om = np.sqrt(np.maximum(q - 0.25 * p * p, 0.0))
    cluster = np.flatnonzero(np.abs(om - om[0]) < 2.0 * (2 * math.pi / N))
    if cluster.size > 1 and om[0] > 0:
        e = _mode_energy(fit.ev)
        keep_k = int(cluster[np.argmax(e[cluster])])
        drop = set(cluster.tolist()) - {keep_k}
        idx = [k for k in range(p.size) if k not in drop]
        # the kept member first, so that index 0 is the fundamental
        idx.remove(keep_k)
        idx = [keep_k] + idx
        res = []
        for part in (y[:h], y[h:]):
            f = _levenberg_marquardt(part, p[idx], q[idx], common=fit.common, max_iter=max_iter)
            if f is None:
                return None
            res.append((float(f.ev.q[0]), float(f.cov[1, 1])))
        a, b = res
    else:
        a = _one_step(y[:h], fit, fit.ev.c)
        c_h = _shifted_coefficients(fit.ev.p, fit.ev.q, fit.ev.c, h)
        b = _one_step(y[h:], fit, c_h) if np.all(np.isfinite(c_h)) else None
        if a is None or b is None:
            return None
    (q1, v1), (q2, v2) = a, b
    zval = abs(q1 - q2) / math.sqrt(max(v1 + v2, 1e-300))
    if zval > NONLINEAR_Z:
        s1, s2 = -q1 / dt**2, -q2 / dt**2
        extra = (
            f"; the full record needs {cluster.size} modes within 2 frequency bins of it"
            if cluster.size > 1
            else ""
        )
        return Flag(
            "nonlinear",
            f"the fundamental's sigma^2 drifts from {s1:.6g} (first half) to {s2:.6g} "
            f"(second half), {zval:.1f} standard errors: the response is not linear "
            f"(frequency depends on amplitude){extra}",
        )
    return None


def _record_flags(
    modes: list[Mode],
    *,
    n: int,
    dt: float,
    spec: _Spectrum,
    static: float,
    static_std: float,
    growth: list[tuple[float, float]] | None = None,
    trend: frozenset[int] = frozenset(),
    aside: frozenset[int] | None = None,
) -> list[Flag]:
    """The flags that read the final modes: few_periods, low_snr, unstable, overdamped,
    combination_tone, trend, aliasing and numerical.

    ``modes[0]`` is the fundamental unless it is set aside (``0 in aside``: every mode is);
    ``growth`` holds each mode's envelope growth rate and its standard error (or None),
    ``trend`` the indices of the modes set aside as a slow trend, ``aside`` those that the
    unstable and overdamped flags do not read (trends, stationary lines, drift, negligible
    growth; default: the trends).
    """
    aside = trend if aside is None else aside
    flags = _fundamental_flags(modes[0], n * dt) if modes and 0 not in aside else []
    relax = _relaxation_flag(modes, n * dt) if modes and 0 not in aside else None
    if relax is not None:
        flags.append(relax)
    flags += _mode_flags(modes, n * dt, growth=growth, trend=aside)
    tr = _trend_flag(modes, trend, n * dt)
    if tr is not None:
        flags.append(tr)
    alias = _aliasing_flag(modes, dt, spec)
    if alias is not None:
        flags.append(alias)
    if not (math.isfinite(static) and math.isfinite(static_std)):
        flags.append(Flag("numerical", "the static level could not be estimated"))
    return flags


#: A slow fundamental suspect of being a relaxation: overdamped but not starting from rest
#: (its value at the first sample, b1 + b2, above RELAX_REST of its largest over the record: a
#: kick from rest gives 0), or less than one oscillation in the record; beside a mode at
#: least RELAX_RING times its amplitude that rings FEW_PERIODS periods.
RELAX_REST, RELAX_RING = 0.5, 0.3


def _relaxation_flag(modes: list[Mode], T: float) -> Flag | None:
    """relaxation: the fundamental is slow and looks like a relaxation, and a mode rings
    beside it. A kick gives an overdamped mode two terms of opposite signs (it starts from
    rest: ``b1 + b2 = 0``); a relaxation of the sensor or of the equilibrium (creep,
    temperature, a settling offset) is one decaying term, or a component that does not
    complete one oscillation in the record, and it is read as the slowest mode.
    The fundamental is kept (near the transition a slow fundamental beside a ringing higher
    mode is the physics): the flag says what else it may be."""
    m0 = modes[0]
    if m0.regime == "overdamped":
        ra, rp = m0.real_amplitudes, m0.real_poles
        if ra is None or rp is None or None in ra or None in rp:
            return None
        b1, b2 = m0.real_amplitudes
        p1, p2 = m0.real_poles
        t = np.linspace(0.0, T, 257)
        size = float(np.max(np.abs(b1 * np.exp(p1 * t) + b2 * np.exp(p2 * t))))
        if not size > 0 or abs(b1 + b2) < RELAX_REST * size:
            return None  # it rises from rest (zero at the kick): a kicked overdamped mode
        what = f"a slow decay that does not start from rest (real amplitudes {b1:.3g}, {b2:.3g})"
    else:
        size = m0.amplitude
        cycles = m0.omega * T / (2 * math.pi)  # oscillations seen, not the undamped rate
        if not (cycles < 1.0 and size > 0):
            return None
        what = f"less than one oscillation in the record ({cycles:.3g})"
    rings = [(k, m) for k, m in enumerate(modes[1:], 1)
             if m.regime == "underdamped" and m.amplitude > RELAX_RING * size
             and math.sqrt(abs(m.sigma2)) * T / (2 * math.pi) >= FEW_PERIODS]  # fmt: skip
    if not rings:
        return None
    k, m = max(rings, key=lambda km: km[1].amplitude)
    return Flag(
        "relaxation",
        f"the fundamental is {what}, beside modes[{k}], which rings at sqrt|sigma^2| = "
        f"{math.sqrt(abs(m.sigma2)):.4g} with {m.amplitude / size:.3g}x its amplitude: a "
        "relaxation of the sensor or of the equilibrium (creep, temperature, a settling "
        "offset) looks like this (a kicked overdamped mode starts from rest); "
        "far from the transition the ringing mode is the fundamental",
    )


def _trend_flag(modes: list[Mode], trend: frozenset[int], T: float) -> Flag | None:
    """trend: the slow components set aside (never the fundamental)."""
    if not trend:
        return None
    txt = ", ".join(
        f"modes[{k}] (sigma^2 = {modes[k].sigma2:.4g}, sqrt|sigma^2| T = "
        f"{math.sqrt(abs(modes[k].sigma2)) * T:.3g})"
        for k in sorted(trend)
    )
    return Flag(
        "trend",
        f"{len(trend)} slow component(s) set aside as a trend: {txt}; slower than the record "
        f"(T = {T:.4g}), they neither complete a cycle nor decay appreciably and cannot be "
        "told from a quadratic drift (of the sensor or the equilibrium); never the "
        "fundamental; record longer or remove the drift to resolve them",
    )


def _fundamental_flags(m0: Mode, T: float) -> list[Flag]:
    """few_periods (record shorter than FEW_PERIODS periods) and low_snr (record SNR)."""
    flags = []
    root = math.sqrt(abs(m0.sigma2))
    periods = T * root / (2 * math.pi)
    if periods < FEW_PERIODS:
        flags.append(
            Flag(
                "few_periods",
                f"the record spans {periods:.3g} fundamental period(s) "
                f"(T = {T:.4g}, sqrt|sigma^2| = {root:.4g}); "
                f"at least {FEW_PERIODS:g} are advised",
            )
        )
    if math.isfinite(m0.snr_db) and m0.snr_db < LOW_SNR_DB:
        flags.append(
            Flag(
                "low_snr",
                f"the fundamental's record SNR is {m0.snr_db:.1f} dB (< {LOW_SNR_DB:g} dB): "
                "estimates may be off the Cramer-Rao regime",
            )
        )
    return flags


def _mode_flags(
    modes: list[Mode],
    T: float = math.inf,
    *,
    growth: list[tuple[float, float]] | None = None,
    trend: frozenset[int] = frozenset(),
) -> list[Flag]:
    """unstable, overdamped (neither counts trends; overdamped does not count decaying
    offsets of a nonlinear response) and combination_tone.

    unstable: a mode (not a trend) with a pole with a positive real part beyond
    :data:`GROWTH_Z` standard errors: ``sigma^2 > 0`` (one growing real pole), or an envelope
    that grows at least 2x over the record ``T`` (:func:`_grows`: a growing oscillation, or
    growing real poles). Combination tones count through ``sigma^2`` only (their decay
    follows their parents').
    """
    flags = []
    grow = []
    for k, m in enumerate(modes):
        if k in trend:
            continue
        g = None if growth is None else growth[k]
        if m.sigma2 > GROWTH_Z * m.sigma2_std or (m.combination is None and _grows(m, g, T)):
            rate = -m.damping if g is None else max(g[0], -m.damping)
            grow.append(f"modes[{k}] (sigma^2 = {m.sigma2:.4g} +- {m.sigma2_std:.2g}, "
                        f"growth rate {rate:.4g})")  # fmt: skip
    if grow:
        flags.append(
            Flag(
                "unstable",
                f"{len(grow)} mode(s) grow ({', '.join(grow)}): a pole with a positive real "
                "part, the record grows: the equilibrium is unstable (past the transition) "
                "or the structure is driven",
            )
        )
    od = [
        m
        for k, m in enumerate(modes)
        if m.regime == "overdamped" and m.real_poles and not m.combination and k not in trend
    ]
    if od:
        txt = ", ".join(
            f"sigma^2 = {m.sigma2:.4g} (poles {m.real_poles[0]:.4g}, {m.real_poles[1]:.4g})"
            for m in od
        )
        flags.append(
            Flag(
                "overdamped",
                f"{len(od)} overdamped mode(s): {txt}; no FFT peak, sigma^2 = -s1 s2",
            )
        )
    comb = [(k, m) for k, m in enumerate(modes) if m.combination is not None]
    if comb:
        txt = ", ".join(f"omega[{k}] = {m.omega:.6g} = {m.combination}" for k, m in comb)
        flags.append(
            Flag(
                "combination_tone",
                f"{len(comb)} mode(s) are combination tones of stronger modes ({txt}): "
                "a nonlinear (quadratic) response; they are not eigenfrequencies",
            )
        )
    return flags


def _aliasing_flag(modes: list[Mode], dt: float, spec: _Spectrum) -> Flag | None:
    """Energy in the top of the band (2+ significant bins), or a mode above ALIAS_FRACTION x
    Nyquist."""
    nyq = math.pi / dt
    kb = int(ALIAS_FRACTION * (spec.hann.size - 1))
    hot = int(np.sum(spec.significant[kb:])) if kb > 0 else 0
    near = [m.omega for m in modes if m.omega > ALIAS_FRACTION * nyq]
    if hot >= 2 or near:
        return Flag(
            "aliasing",
            f"energy above {ALIAS_FRACTION:g} x Nyquist ({nyq:.4g} rad/time): "
            f"{hot} significant bin(s), {len(near)} mode(s) there; sample faster or "
            f"low-pass filter before sampling",
        )
    return None
