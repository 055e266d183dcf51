"""Conversion of a fit (sample units, normalised record) to physical modes; the ambient
(segment-scatter) standard errors; combination tones and the choice of the fundamental."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from service.analysis.detect._kernels import _ch_sh
from service.analysis.detect._results import (
    COMBINATION_RATE_REL,
    COMBINATION_REL,
    COMBINATION_WIDTH,
    COMBINATION_Z,
    GROWTH_Z,
    ORDER_PENALTY,
    TREND_RADIANS,
    Fundamental,
    Mode,
)
from service.analysis.detect._varpro import _evaluate, _Fit, _levenberg_marquardt


def _modes_from_fit(
    fit: _Fit, energies: np.ndarray, dt: float, scale: float
) -> tuple[list[Mode], float, float]:
    """Physical modes of a fit (rates per time unit of ``dt``, amplitudes times ``scale``),
    the static level (normalised units) and its standard error (times ``scale``)."""
    ev, cov, nth = fit.ev, fit.cov, fit.ntheta
    modes: list[Mode] = []
    for k in range(ev.p.shape[0]):
        jp = 0 if fit.common else 2 * k
        jq = 1 + k if fit.common else 2 * k + 1
        p, q = float(ev.p[k]), float(ev.q[k])
        ic = nth + 1 + 2 * k  # first amplitude coefficient of the mode in cov
        common = {
            "damping": 0.5 * p / dt,
            "damping_std": 0.5 * math.sqrt(max(cov[jp, jp], 0.0)) / dt,
            "sigma2": -q / dt**2,
            "sigma2_std": math.sqrt(max(cov[jq, jq], 0.0)) / dt**2,
            "snr_db": 10.0 * math.log10(max(energies[k], 1e-300)) if energies.size else math.nan,
        }
        c1, c2 = float(ev.c[1 + 2 * k]), float(ev.c[2 + 2 * k])
        if 0.25 * p * p - q < 0:
            v = (cov[jp, jp], cov[jq, jq], cov[jp, jq], cov[ic, ic], cov[ic + 1, ic + 1],
                 cov[ic, ic + 1])  # fmt: skip
            modes.append(_underdamped(p, q, c1, c2, v, dt, scale, common))
        else:
            modes.append(_overdamped(p, q, c1, c2, cov[ic, ic], dt, scale, common))
    static_std = math.sqrt(max(cov[nth, nth], 0.0)) * scale
    return modes, float(ev.c[0]), static_std


def _underdamped(
    p: float, q: float, c1: float, c2: float, v: tuple, dt: float, scale: float, common: dict
) -> Mode:
    """An underdamped mode from ``(p, q)``, its basis coefficients ``c1, c2`` and the
    variances ``v = (pp, qq, pq, c1c1, c2c2, c1c2)`` (sample units, normalised record)."""
    vpp, vqq, vpq, v11, v22, v12 = v
    om = math.sqrt(q - 0.25 * p * p)
    # d om / d p = -p / (4 om) ; d om / d q = 1 / (2 om)   (om^2 = q - p^2/4)
    gp, gq = -p / (4.0 * om), 1.0 / (2.0 * om)
    var_om = gp * gp * vpp + gq * gq * vqq + 2 * gp * gq * vpq
    a_cos, a_sin = c1, -c2 / om  # A cos(phi), A sin(phi)
    amp = math.hypot(a_cos, a_sin)
    var_a = 0.0
    if amp > 0:  # gradient of |(c1, c2/om)| in (c1, c2) (om treated as exact)
        g1, g2 = c1 / amp, (c2 / om**2) / amp
        var_a = g1 * g1 * v11 + g2 * g2 * v22 + 2 * g1 * g2 * v12
    return Mode(
        omega=om / dt,
        frequency=om / dt / (2 * math.pi),
        amplitude=amp * scale,
        phase=math.atan2(a_sin, a_cos),
        omega_std=math.sqrt(max(var_om, 0.0)) / dt,
        amplitude_std=math.sqrt(max(var_a, 0.0)) * scale,
        regime="underdamped",
        **common,
    )


def _overdamped(
    p: float, q: float, c1: float, c2: float, v11: float, dt: float, scale: float, common: dict
) -> Mode:
    """An overdamped mode (two real poles) from ``(p, q)`` and its basis coefficients."""
    lam = math.sqrt(0.25 * p * p - q)
    r1, r2 = 0.5 * p - lam, 0.5 * p + lam
    if lam > 0:
        b1, b2 = 0.5 * (c1 + c2 / lam), 0.5 * (c1 - c2 / lam)
    else:  # critically damped: c1 + c2 t ; report as equal split
        b1 = b2 = 0.5 * c1
    return Mode(
        omega=0.0,
        frequency=0.0,
        amplitude=max(abs(b1), abs(b2)) * scale,
        phase=0.0,
        omega_std=0.0,
        amplitude_std=math.sqrt(max(v11, 0.0)) * scale,
        regime="overdamped",
        real_poles=(-r1 / dt, -r2 / dt),
        real_amplitudes=(b1 * scale, b2 * scale),
        **common,
    )


def _pole_growth(fit: _Fit, dt: float, y: np.ndarray) -> list[tuple[float, float]]:
    """Growth rate of each mode's envelope and its standard error, per time unit of ``dt``.

    The rate is the largest real part of the mode's poles (``-gamma`` when underdamped, the
    slow real pole ``-p/2 + sqrt(p^2/4 - q)`` when overdamped); its standard error is the delta
    method on the Gauss-Newton covariance of ``(p, q)``. Two close real poles that share one
    growing exponential are not resolved one by one (their delta-method errors are large
    while their weighted rate is sharp; the same near the real axis): when a positive slow pole,
    or the real part of a pair with ``omega < |gamma|``, is not significant by the delta
    method, the likelihood-ratio test of :func:`_stable_rss` decides, reported as the
    standard error ``rate / z`` with ``z = sqrt(RSS rise / s^2)`` (so ``rate > 3 std`` iff
    ``z > 3``, the same level).
    """
    ev, cov = fit.ev, fit.cov
    out = []
    for k in range(ev.p.shape[0]):
        jp = 0 if fit.common else 2 * k
        jq = 1 + k if fit.common else 2 * k + 1
        p, q = float(ev.p[k]), float(ev.q[k])
        D = 0.25 * p * p - q
        if D > 0:
            lam = math.sqrt(D)
            rate, gp, gq = -0.5 * p + lam, -0.5 + 0.25 * p / lam, -0.5 / lam
        else:
            rate, gp, gq = -0.5 * p, -0.5, 0.0
        var = gp * gp * cov[jp, jp] + gq * gq * cov[jq, jq] + 2.0 * gp * gq * cov[jp, jq]
        std = math.sqrt(max(float(var), 0.0))
        # near the real axis (overdamped, or omega < gamma) the delta method fails
        if (D > 0 or -D < 0.25 * p * p) and rate > 0 and not rate > GROWTH_Z * std:
            rise = _stable_rss(y, fit, k) - ev.rss
            z = math.sqrt(max(rise, 0.0) / fit.s2)
            std = rate / z if z > 0 else math.inf
        out.append((rate / dt, std / dt))
    return out


def _stable_rss(y: np.ndarray, fit: _Fit, k: int) -> float:
    """Least RSS with mode ``k`` held at the edge of stability (its slow pole at 0, ``q = 0``:
    a constant, already in the model, plus ``exp(-p t)`` with ``p >= 0``; ``p = 0`` gives a
    line), the other poles fixed: a log grid of ``p N`` from 1e-3 to 1e4 and ``p = 0``; and
    the undamped pair at its fitted ``q`` (``p = 0``). The others are not refitted, so the rise
    is an upper bound (a test at most slightly liberal towards the flag)."""
    N = y.shape[0]
    p, q = fit.ev.p.copy(), fit.ev.q.copy()
    best = math.inf
    if q[k] > 0:
        p[k] = 0.0
        ev = _evaluate(y, p, q)
        if ev is not None:
            best = ev.rss
    q[k] = 0.0
    for pn in np.concatenate(([0.0], np.logspace(-3.0, 4.0, 29))):
        p[k] = pn / N
        ev = _evaluate(y, p, q)
        if ev is not None:
            best = min(best, ev.rss)
    return best


def _grows(m: Mode, growth: tuple[float, float] | None, T: float) -> bool:
    """Whether the mode's envelope grows: a pole with a positive real part beyond
    :data:`GROWTH_Z` standard errors that at least doubles the envelope over the record
    (``rate T > ln 2``). The rate is the mean real part ``-gamma`` (the envelope of an
    oscillation, or both real poles growing) or the slow real pole ``growth = (rate, std)``
    of :func:`_pole_growth`. The size condition keeps out the slow envelope drifts of weak
    modes of a nonlinear response (energy exchanged between modes, a few standard errors on a
    noise-free record); a growing real pole with a decaying partner is ``sigma^2 > 0``,
    tested on its own."""
    rates = [(-m.damping, m.damping_std)]
    if growth is not None:
        rates.append(growth)
    return any(r > GROWTH_Z * sd and r * T > math.log(2.0) for r, sd in rates)


def _model_at_lag0(fit: _Fit) -> float:
    """Fitted autocorrelation extrapolated one step back (to lag 0), normalised units."""
    ev = fit.ev
    v = float(ev.c[0])
    for k in range(ev.p.size):
        D = 0.25 * ev.p[k] ** 2 - ev.q[k]
        ch, sh, _ = _ch_sh(float(D))
        e = math.exp(0.5 * ev.p[k])
        v += ev.c[1 + 2 * k] * e * ch - ev.c[2 + 2 * k] * e * sh
    return v


def _ambient_errors(
    x: np.ndarray,
    fit: _Fit,
    n_lags: int,
    scale: float,
    dt: float,
    modes: list[Mode],
    max_iter: int,
) -> list[Mode]:
    """Standard errors of an autocorrelation fit from the scatter over record segments.

    The autocorrelation's estimation errors are strongly correlated across lags, so the
    Gauss-Newton covariance (white residuals) is far too optimistic. The record is cut into
    ``B`` segments (each at least 4 fitted lag ranges long), the fit is repeated on each
    segment's autocorrelation from the full-record poles, and the standard error of the full
    estimate is ``std(segment estimates) / sqrt(B)``.
    """
    N0 = x.size
    B = int(min(8, N0 // (4 * n_lags)))
    if B < 2:
        return [
            replace(m, omega_std=math.inf, damping_std=math.inf, sigma2_std=math.inf) for m in modes
        ]
    seg = N0 // B
    ests = []
    for b in range(B):
        xs = x[b * seg : (b + 1) * seg]
        xs = xs - xs.mean()
        nfft = 1 << int(math.ceil(math.log2(2 * seg)))
        F = np.fft.rfft(xs, nfft)
        acf = np.fft.irfft(F * np.conj(F), nfft)[1 : n_lags + 1] / seg
        f = _levenberg_marquardt(
            acf / scale, fit.ev.p, fit.ev.q, common=fit.common, max_iter=max_iter
        )
        if f is None:
            continue
        ests.append((f.ev.p.copy(), f.ev.q.copy()))
    if len(ests) < 2:
        return [
            replace(m, omega_std=math.inf, damping_std=math.inf, sigma2_std=math.inf) for m in modes
        ]
    P = np.array([e[0] for e in ests])
    Q = np.array([e[1] for e in ests])
    root = math.sqrt(len(ests))
    out = []
    for k, m in enumerate(modes):
        om = np.sqrt(np.maximum(Q[:, k] - 0.25 * P[:, k] ** 2, 0.0)) / dt
        out.append(
            replace(
                m,
                omega_std=float(np.std(om, ddof=1) / root),
                damping_std=float(np.std(0.5 * P[:, k] / dt, ddof=1) / root),
                sigma2_std=float(np.std(-Q[:, k] / dt**2, ddof=1) / root),
            )
        )
    return out


def _combinations(
    modes: list[Mode], aside: frozenset[int] = frozenset()
) -> dict[int, tuple[int, int, str]]:
    """Combination tones among ``modes``: ``{k: (i, j, sign)}``.

    An underdamped mode whose frequency is ``omega_i + omega_j``, ``|omega_i - omega_j|`` or
    ``2 omega_i`` of two stronger modes (record SNR), within :data:`COMBINATION_Z` combined
    standard errors, a relative :data:`COMBINATION_REL`, or :data:`COMBINATION_WIDTH` times its
    own decay rate (its half linewidth; sign ``"+"`` / ``"-"``), the parents ringing (less
    than one e-fold per cycle); and an
    overdamped mode whose slow decay rate is ``gamma_i + gamma_j`` of two stronger underdamped
    modes within a relative :data:`COMBINATION_RATE_REL` (sign ``"0"``): the difference tone
    ``omega_i - omega_j = 0`` of a quadratic response, a mean shift that decays at the sum of
    the rates (a true overdamped fundamental of a structure with one damping ``xi`` has its slow
    rate below ``xi / 2``, the sums are ``>= xi``). Components in ``aside`` (stationary lines:
    mains hum is added by the sensor's wiring, not the structure's response) are no parents.
    """
    out: dict[int, tuple[int, int, str]] = {}
    strength = [m.snr_db if math.isfinite(m.snr_db) else -math.inf for m in modes]
    under = [k for k, m in enumerate(modes) if m.regime == "underdamped" and m.omega > 0]
    # a parent rings: it loses less than one e-fold per cycle (a component that dies within a
    # cycle, such as a hammer's contact absorbed by the fit, makes no combination tone)
    rings = [k for k in under
             if 2 * math.pi * modes[k].damping < modes[k].omega and k not in aside]  # fmt: skip
    for k, mk in enumerate(modes):
        if mk.regime != "overdamped" or mk.real_poles is None:
            continue
        slow = -max(mk.real_poles)  # the slow decay rate (> 0 when decaying)
        parents = [i for i in rings if strength[i] > strength[k]]
        best = math.inf
        for a, i in enumerate(parents):
            for j in parents[a:]:
                target = modes[i].damping + modes[j].damping
                d = abs(slow - target)
                if slow > 0 and target > 0 and d <= COMBINATION_RATE_REL * target and d < best:
                    best = d
                    out[k] = (i, j, "0")
    for k in under:
        mk = modes[k]
        parents = [i for i in rings if i != k and strength[i] > strength[k]]
        best = math.inf
        for a, i in enumerate(parents):
            for j in parents[a:]:
                mi, mj = modes[i], modes[j]
                var = mk.omega_std**2 + mi.omega_std**2 + mj.omega_std**2
                for sign, target in (("+", mi.omega + mj.omega), ("-", abs(mi.omega - mj.omega))):
                    if sign == "-" and i == j:
                        continue
                    tol = max(
                        COMBINATION_Z * math.sqrt(var),
                        COMBINATION_REL * target,
                        COMBINATION_WIDTH * mk.damping,
                    )
                    d = abs(mk.omega - target)
                    if d <= tol and d < best:
                        best = d
                        hi, lo = (i, j) if mi.omega >= mj.omega else (j, i)
                        out[k] = (hi, lo, sign)
    return out


def _fundamental(
    modes: list[Mode], *, n: int, dt: float, trend: frozenset[int] = frozenset(),
    aside: frozenset[int] = frozenset(), sidebands: dict[int, tuple[int, int]] | None = None,
) -> tuple[list[Mode], list[int]]:  # fmt: skip
    """Mark combination tones and put the fundamental first.

    Parameters
    ----------
    modes : list of Mode
        The method's modes, in its order (by increasing ``|sigma^2|`` for the parametric
        methods).
    n, dt : int, float
        Record length and sample step.
    trend : frozenset of int
        Indices of slow components set aside as a trend (see :func:`_trends`) or as lines,
        drift or transients.
    aside : frozenset of int
        Indices of the stationary lines (no parents of combination tones).
    sidebands : dict or None
        Sidebands of an amplitude-modulated line (index -> (the line's index, how many of the
        comb's spacings from its carrier, signed; 0: the other half of a split line)): marked
        as combination tones of that line.

    Returns
    -------
    modes : list of Mode
        The fundamental first (the first mode of the method's order that is neither a
        combination tone nor a trend; when every mode is one of those, the first mode is not a
        fundamental), then the others in the method's order.
    order : list of int
        ``modes[i]`` is the input's ``modes[order[i]]``.
    """
    if not modes:
        return [], []
    comb = _combinations(modes, aside)
    side = {k: v for k, v in (sidebands or {}).items() if k not in comb}
    free = [k for k in range(len(modes)) if k not in comb and k not in side and k not in trend]
    first = free[0] if free else next((k for k in range(len(modes))
                                       if k not in comb and k not in side), 0)  # fmt: skip
    order = [first] + [k for k in range(len(modes)) if k != first]
    pos = {k: i for i, k in enumerate(order)}
    out = []
    for k in order:
        m = modes[k]
        if k in comb:
            i, j, sign = comb[k]
            if sign == "0":
                a, b = sorted((pos[i], pos[j]))
                rate = f"2 gamma[{a}]" if a == b else f"gamma[{a}] + gamma[{b}]"
                txt = f"0 (a decaying offset at the rate {rate})"
            elif i == j:
                txt = f"2 omega[{pos[i]}]"
            else:
                txt = f"omega[{pos[i]}] {sign} omega[{pos[j]}]"
            m = replace(m, combination=txt)
        elif k in side:
            d, n = side[k]
            txt = (f"omega[{pos[d]}], the other half of its split line" if n == 0 else
                   f"omega[{pos[d]}]'s carrier {'+' if n > 0 else '-'} {abs(n)} x its "
                   "sideband spacing")  # fmt: skip
            m = replace(m, combination=txt + " (amplitude modulation)")
        out.append(m)
    return out, order


def _waveform(m: Mode, n: int, dt: float) -> np.ndarray:
    """The mode's contribution at the samples ``0 .. n-1`` (record units)."""
    u = np.arange(n, dtype=float)
    with np.errstate(over="ignore", invalid="ignore"):
        if m.regime == "overdamped" and m.real_poles is not None and m.real_amplitudes:
            (s1, s2), (b1, b2) = m.real_poles, m.real_amplitudes
            return b1 * np.exp(np.minimum(s1 * dt * u, 700.0)) + b2 * np.exp(
                np.minimum(s2 * dt * u, 700.0)
            )
        env = np.exp(np.minimum(-m.damping * dt * u, 700.0))
        return m.amplitude * env * np.cos(m.omega * dt * u + m.phase)


def _trends(modes: list[Mode], *, n: int, dt: float, noise_std: float) -> frozenset[int]:
    """Indices of the modes that the record cannot tell from a polynomial trend.

    A component much slower than the record (undamped rate ``sqrt|sigma^2|`` times the record
    length ``T = n dt`` small) neither completes a cycle nor decays (or grows) appreciably
    over the record: over ``[0, T]`` it is its Taylor polynomial ``a + b t + c t^2 + ...``, and
    a drift of the sensor or of the equilibrium is fitted by such a mode. Its poles then say
    nothing about the structure, and it must not be taken for the fundamental (it would be the
    slowest mode). The rule, from what the record resolves:

    * candidate: ``sqrt|sigma^2| T <`` :data:`TREND_RADIANS` (``2 pi``: less than one cycle of
      its undamped frequency; an overdamped pair counts its geometric mean rate);
    * set aside when the part of its waveform (over the record's samples) that a quadratic
      ``a + b t + c t^2`` cannot absorb has an energy below the detector's own threshold for a
      mode, :data:`ORDER_PENALTY` ``ln n`` noise variances (MDL): a mode made of that part
      alone would not be kept. A slow mode that decays (or grows) within the record, e.g. an
      overdamped fundamental near the transition, or a growth ``exp(s t)`` with ``s T`` near 1
      at a high SNR, leaves far more than that and stays a mode.

    Quadratic, not linear: the curvature of a slowly decaying offset (``c t^2``) is still a
    trend; the threshold is relative to the noise, so the test is equivariant under
    ``w -> k w`` and ``t -> c t``.
    """
    if not (noise_std > 0 and math.isfinite(noise_std)) or n < 4:
        return frozenset()
    T = n * dt
    slow = [k for k, m in enumerate(modes) if math.sqrt(abs(m.sigma2)) * T < TREND_RADIANS]
    if not slow:
        return frozenset()
    thr = ORDER_PENALTY * math.log(n)
    x = np.linspace(-1.0, 1.0, n)
    Q, _ = np.linalg.qr(np.column_stack((np.ones(n), x, 1.5 * x * x - 0.5)))
    out = set()
    for k in slow:
        v = _waveform(modes[k], n, dt) / noise_std
        if not np.all(np.isfinite(v)):
            continue
        r = v - Q @ (Q.T @ v)
        if float(r @ r) < thr:
            out.add(k)
    return frozenset(out)


def _scaled(m: Mode, f: float) -> Mode:
    """The mode with its amplitudes multiplied by ``f`` (the record's power-of-two unit)."""
    if f == 1.0:
        return m
    ra = m.real_amplitudes
    return replace(
        m,
        amplitude=m.amplitude * f,
        amplitude_std=m.amplitude_std * f,
        real_amplitudes=None if ra is None else (ra[0] * f, ra[1] * f),
    )


def _as_fundamental(modes: list[Mode]) -> Fundamental | None:
    return Fundamental(modes[0], 0) if modes else None
