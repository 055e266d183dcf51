"""Spectral side of the detector: periodogram band, strided-Hankel ESPRIT, candidate poles,
and the paper's FFT-peak baseline."""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from service.analysis.common import Flag
from service.analysis.detect._kernels import hankel_gram, top_eigenpairs
from service.analysis.detect._linalg import _pinv_psd
from service.analysis.detect._results import PEAK_FALSE_ALARM, S2_FLOOR, Mode


@dataclass
class _Spectrum:
    y: np.ndarray
    hann: np.ndarray  # Hann-window periodogram, normalised to the white-noise variance
    noise_var: float  # robust (median) white-noise level, from the Hann periodogram
    significant: np.ndarray  # boolean per bin (Hann periodogram: no far leakage)
    k_hi: int  # highest significant bin (0 if none)

    @property
    def power(self) -> np.ndarray:
        """Plain periodogram ``|rfft|^2 / N`` (the paper's FFT), computed on demand."""
        return np.abs(np.fft.rfft(self.y)) ** 2 / self.y.shape[0]


@lru_cache(maxsize=16)
def _hann(n: int) -> tuple[np.ndarray, float]:
    win = np.hanning(n + 2)[1:-1]
    win.setflags(write=False)
    return win, float(np.sum(win * win))


def _spectrum(y: np.ndarray, floor: float = S2_FLOOR) -> _Spectrum:
    """Hann periodogram, its noise level (at least ``floor``) and its significant band."""
    win, norm = _hann(y.shape[0])
    H = np.abs(np.fft.rfft(win * y)) ** 2 / norm
    body = H[2:] if H.size > 3 else H[1:]
    noise = float(np.median(body) / math.log(2.0)) if body.size else 0.0
    noise = max(noise, floor)
    thr = math.log(max(body.size, 2) / PEAK_FALSE_ALARM)  # per record (chi2_2 / 2)
    sig = H > noise * thr
    sig[0] = False
    k_hi = 0
    if sig.any():
        # band edge: where 99.9 % of the power above the noise floor lies (a lone noise bin
        # or a weak high harmonic must not shrink the ESPRIT window; residual rounds get the
        # latter with their own stride)
        excess = np.cumsum(np.where(sig, H - noise, 0.0))
        k_hi = int(np.searchsorted(excess, 0.999 * excess[-1])) + 1
        k_hi = min(k_hi, H.size - 1)
    return _Spectrum(y, H, noise, sig, k_hi)


def _esprit(y: np.ndarray, spec: _Spectrum, max_poles: int) -> np.ndarray:
    """Continuous-time poles (per sample) of ``y`` by strided-Hankel ESPRIT."""
    N = y.shape[0]
    if spec.k_hi == 0:
        return np.zeros(0, dtype=complex)
    nu = spec.k_hi / N  # highest significant frequency, cycles per sample
    L = int(min(max(3 * max_poles, 16), max(N // 3, 4)))
    stride = max(1, int(0.12 / max(nu, 1e-12)))
    stride = max(1, min(stride, (N // 2) // max(L - 1, 1)))
    R = np.empty((L, L))
    M = hankel_gram(y, L, stride, R)
    R /= M
    r = min(L - 2, max_poles + 4)
    w = np.empty(r)
    V = np.empty((L, r))
    top_eigenpairs(R, r, 4, w, V)
    edge = spec.noise_var * (1.0 + math.sqrt(L / M)) ** 2
    nsig = int(np.sum(w > 2.0 * edge))
    nsig = min(max(nsig, 0), max_poles, L - 2)
    if nsig == 0:
        return np.zeros(0, dtype=complex)
    U = V[:, :nsig]
    U1, U2 = U[:-1], U[1:]
    Phi = _pinv_psd(U1.T @ U1, 1e-14) @ (U1.T @ U2)
    z = np.linalg.eigvals(Phi)
    z = z[np.abs(z) > 1e-12]
    s = np.log(z.astype(complex)) / stride
    # a pole that hardly changes across the Hankel window (|s| x span < 0.1) is not resolved
    # by it: leave slow content to the residual rounds, whose stride is set by that content
    span = (L - 1) * stride
    return s[np.abs(s) * span >= 0.1]


#: Largest growth over the record (natural log) of a candidate pole when the record itself
#: grows (its tail holds most of its power); otherwise e^5 (real) and e^10 (complex) poles.
_GROWTH_LOG = 30.0


def _candidates(s: np.ndarray, N: int, grows: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """Group poles into modes ``(p, q)``: conjugate pairs, and real poles paired by rate.

    Growing poles are artefacts of the Hankel window in a decaying record: a real pole growing
    by more than ``e^5`` over the record, or a pair by more than ``e^10``, is dropped, unless
    the record ``grows`` (then up to ``e^30``, :data:`_GROWTH_LOG`).
    """
    ps: list[float] = []
    qs: list[float] = []
    reals: list[float] = []
    tol = 1e-9
    for si in s:
        if not np.isfinite(si):
            continue
        if abs(si.imag) > max(tol, 0.5 / N) and si.imag > 0:
            ps.append(-2.0 * si.real)
            qs.append(si.real**2 + si.imag**2)
        elif abs(si.imag) <= max(tol, 0.5 / N):
            reals.append(-si.real)
    # the slowest real pole near 0 is the static level (always in the model): drop one
    reals.sort(key=abs)
    if reals and abs(reals[0]) * N < 1.0:
        reals = reals[1:]
    # a real pole growing by more than e^5 over the record is an artefact of the window
    real_max, pair_max = (_GROWTH_LOG, _GROWTH_LOG) if grows else (5.0, 10.0)
    reals = sorted(r for r in reals if r * N > -real_max)
    while len(reals) >= 2:
        r1, r2 = reals.pop(0), reals.pop(0)
        ps.append(r1 + r2)
        qs.append(r1 * r2)
    if reals:
        r = reals[0]
        ps.append(2.0 * r)
        qs.append(r * r)
    p = np.asarray(ps, dtype=float)
    q = np.asarray(qs, dtype=float)
    keep = np.isfinite(p) & np.isfinite(q) & (p < 1.0) & (p > -2.0 * pair_max / N)
    return p[keep], q[keep]


def _peak_candidates(
    spec: _Spectrum, N: int, p: np.ndarray, q: np.ndarray, max_modes: int
) -> tuple[np.ndarray, np.ndarray]:
    """Add the significant periodogram peaks that no candidate explains (low per-sample SNR:
    the Hankel covariance of a short window may bury a mode the whole-record FFT sees)."""
    P = spec.hann
    nb = P.size
    if nb < 3:
        return p, q
    k = np.arange(1, nb - 1)
    is_max = (P[k] >= P[k - 1]) & (P[k] > P[k + 1]) & spec.significant[k]
    peaks = k[is_max]
    peaks = peaks[peaks >= 2]  # bins 0-1: a slow drift, left to the residual rounds
    if peaks.size == 0:
        return p, q
    peaks = peaks[np.argsort(-P[peaks])][:max_modes]
    bin_w = 2 * math.pi / N
    om_have = np.sqrt(np.maximum(q - 0.25 * p * p, 0.0))
    add_p, add_q = [], []
    for j in peaks:
        # parabola through the log of the Hann main lobe
        a, b, c = (math.log(max(P[i], 1e-300)) for i in (j - 1, j, j + 1))
        den = a - 2 * b + c
        delta = float(np.clip(0.5 * (a - c) / den, -0.5, 0.5)) if den < 0 else 0.0
        om = (j + delta) * bin_w
        if om_have.size and np.min(np.abs(om_have - om)) < 2 * bin_w:
            continue
        pj = 0.5 * bin_w
        add_p.append(pj)
        add_q.append(om * om + 0.25 * pj * pj)
    if not add_p:
        return p, q
    return np.concatenate((p, add_p)), np.concatenate((q, add_q))


def _welch_peaks(x: np.ndarray) -> int:
    """Number of peaks of the averaged (Welch) log-spectrum with a prominence above 10x."""
    n = x.size
    seg = max(min(n // 8, 4096), 16)
    nseg = n // seg
    if nseg < 2:
        return 1
    win = np.hanning(seg)
    P = np.zeros(seg // 2 + 1)
    for i in range(nseg):
        P += np.abs(np.fft.rfft(win * x[i * seg : (i + 1) * seg])) ** 2
    logp = np.log10(np.maximum(P, 1e-300 + P.max() * 1e-30))
    from scipy.signal import find_peaks  # only ambient records: scipy.signal costs ~0.4 s CPU

    peaks, _ = find_peaks(np.convolve(logp, np.ones(3) / 3, mode="same"), prominence=1.0)
    return int(peaks.size)


def _initial_candidates(
    y: np.ndarray, spec: _Spectrum, max_modes: int, peaks: bool = True
) -> tuple[np.ndarray, np.ndarray]:
    """Candidate modes ``(p, q)``: ESPRIT on the whole record, ESPRIT on its first eighth
    (fast-decaying modes live there and vanish in a whole-record covariance), and the
    significant periodogram peaks that neither explains. A record whose last eighth holds most
    of its power grows: growing poles are then kept (see :func:`_candidates`)."""
    N = y.shape[0]
    tail = y[N - N // 8 :]
    grows = tail.size >= 2 and float(np.mean(tail * tail)) > 3.0 * float(np.mean(y * y))
    p, q = _candidates(_esprit(y, spec, 2 * max_modes + 1), N, grows)
    head = y[: N // 8]
    # only when the response decays within the record (the head holds most of the power)
    if head.size >= 128 and float(np.mean(head * head)) > 3.0 * float(np.mean(y * y)):
        hs = _spectrum(head)
        ph, qh = _candidates(_esprit(head, hs, 2 * max_modes + 1), head.size)
        p, q = np.concatenate((p, ph)), np.concatenate((q, qh))
    if peaks:
        p, q = _peak_candidates(spec, N, p, q, max_modes)
    return p, q


def _cross(P: np.ndarray, i0: int, i1: int, level: float) -> float:
    """Fractional bin where the line through ``(i0, P[i0])``, ``(i1, P[i1])`` hits ``level``."""
    a0, a1 = P[i0], P[i1]
    return i0 + (level - a0) / (a1 - a0) * (i1 - i0) if a1 != a0 else float(i0)


def _half_power_width(P: np.ndarray, j: int) -> float:
    """Width (in bins) of the peak ``j`` of ``P`` at half its power (linear interpolation)."""
    half = 0.5 * P[j]
    lo = j
    while lo > 0 and P[lo] > half:
        lo -= 1
    hi = j
    while hi < P.size - 1 and P[hi] > half:
        hi += 1
    x_lo = _cross(P, lo, lo + 1, half) if lo < j else float(j)
    x_hi = _cross(P, hi, hi - 1, half) if hi > j else float(j)
    return max(x_hi - x_lo, 0.0)


def _fft_modes(
    y: np.ndarray, dt: float, scale: float, parabolic: bool, spec: _Spectrum
) -> tuple[list[Mode], list[Flag]]:
    """The paper's FFT peak (plus the significant secondary peaks)."""
    N = y.shape[0]
    P = spec.power
    mag = np.sqrt(P * N)
    flags: list[Flag] = []
    nb = P.size
    if nb < 3 or not spec.significant.any():
        return [], flags
    # local maxima (bins >= 1) that are significant
    k = np.arange(1, nb - 1)
    is_max = (P[k] >= P[k - 1]) & (P[k] > P[k + 1]) & spec.significant[k]
    peaks = list(k[is_max])
    if spec.significant[nb - 1] and P[nb - 1] > P[nb - 2]:
        peaks.append(nb - 1)
    if not peaks:
        return [], flags
    top = max(P[j] for j in peaks)
    # keep peaks within 30 dB of the highest one that are not leakage of a stronger neighbour
    kept = []
    for j in sorted(peaks, key=lambda j: -P[j]):
        if P[j] < 1e-3 * top:
            continue
        if any(abs(j - i) <= 8 and P[i] > 20.0 * P[j] for i in kept):
            continue
        kept.append(j)
    d_om = 2 * math.pi / (N * dt)
    modes: list[Mode] = []
    unresolved = []
    for j in sorted(kept):
        delta = 0.0
        if parabolic and 1 <= j < nb - 1:
            a, b, c = mag[j - 1], mag[j], mag[j + 1]
            den = a - 2 * b + c
            if den < 0:
                delta = float(np.clip(0.5 * (a - c) / den, -0.5, 0.5))
        om = (j + delta) * d_om
        width = _half_power_width(P, j) * d_om
        gamma = 0.5 * width
        if width < 1.5 * d_om:
            unresolved.append(om)
        # resolution-limited errors: uniform over a bin (plain peak), amplitude from the bin
        q_std = d_om / math.sqrt(12.0)
        amp = 2.0 * float(mag[j]) / N * scale
        modes.append(
            Mode(
                omega=float(om),
                frequency=float(om / (2 * math.pi)),
                damping=float(gamma),
                sigma2=float(-(om * om + gamma * gamma)),
                amplitude=amp,
                phase=0.0,
                omega_std=q_std,
                damping_std=0.5 * q_std,
                sigma2_std=float(2.0 * om * q_std),
                amplitude_std=math.sqrt(2.0 * spec.noise_var / N) * scale,
                regime="underdamped",
                snr_db=10 * math.log10(max(P[j] / max(spec.noise_var, 1e-300), 1e-300)),
            )
        )
    if unresolved:
        flags.append(
            Flag(
                "damping_unresolved",
                f"{len(unresolved)} FFT peak(s) no wider than the resolution "
                f"{d_om:.4g} rad/time: their damping is the window's, not the mode's",
            )
        )
    # fundamental: lowest-frequency peak within 20 dB of the highest one
    a_top = 2.0 * math.sqrt(top * N) / N * scale
    strong = [m for m in modes if m.amplitude >= 0.1 * a_top]
    first = min(strong, key=lambda m: m.omega) if strong else modes[0]
    others = [m for m in modes if m is not first]
    return [first] + sorted(others, key=lambda m: -m.sigma2), flags


def prev_fast_len(n: int) -> int:
    """The largest ``2^a 3^b 5^c <= n`` (``n >= 1``): ``scipy.fft.prev_fast_len(n, real=True)``,
    here because importing ``scipy.fft`` costs a command ~0.2 s CPU for this one integer."""
    best = 1
    p5 = 1
    while p5 <= n:
        p35 = p5
        while p35 <= n:
            best = max(best, p35 << ((n // p35).bit_length() - 1))
            p35 *= 3
        p5 *= 5
    return best


@lru_cache(maxsize=64)
def _head_lengths(N: int) -> tuple[int, ...]:
    """``N`` and FFT-friendly lengths of about ``N/2, N/4, ...`` down to 64 samples."""
    heads = [N]
    L = N // 2
    while L >= 64:
        heads.append(prev_fast_len(L))
        L //= 2
    return tuple(heads)


def _head_peaks(
    r: np.ndarray, spec: _Spectrum, p: np.ndarray, q: np.ndarray, max_modes: int
) -> tuple[np.ndarray, np.ndarray]:
    """Candidate modes from the Hann periodograms of the record's heads ``r[:L]``,
    ``L = N`` (``spec``, the record's own) and about ``N/2, N/4, ...`` (FFT-friendly lengths,
    down to 64 samples): a mode that decays within the record keeps
    its energy in a head, where a window matched to its decay sees it above the noise although
    the whole-record periodogram spreads it over many bins. A peak is significant at a
    :data:`PEAK_FALSE_ALARM` rate per record over all heads and bins (white noise of the variance
    ``spec.noise_var``); peaks within two bins of an existing candidate are left out. The initial
    damping is the head's resolution (``p = 2 / L``)."""
    N = r.shape[0]
    noise_var = spec.noise_var
    heads = _head_lengths(N)
    if noise_var <= 0:
        return np.zeros(0), np.zeros(0)
    om_have = list(np.sqrt(np.maximum(q - 0.25 * p * p, 0.0)))
    add_p: list[float] = []
    add_q: list[float] = []
    for L in heads:
        if L == N:
            P = spec.hann
        else:
            win, norm = _hann(L)
            X = np.fft.rfft(win * r[:L])
            P = (X.real * X.real + X.imag * X.imag) / norm
        nb = P.size
        if nb < 4:
            continue
        thr = noise_var * math.log(nb * len(heads) / PEAK_FALSE_ALARM)
        mid = P[2:-1]
        peaks = np.flatnonzero((mid > thr) & (mid >= P[1:-2]) & (mid > P[3:])) + 2
        if peaks.size == 0:
            continue
        bin_w = 2 * math.pi / L
        for j in peaks[np.argsort(-P[peaks])][:max_modes]:
            a, b, c = (math.log(max(P[i], 1e-300)) for i in (j - 1, j, j + 1))
            den = a - 2 * b + c
            delta = float(np.clip(0.5 * (a - c) / den, -0.5, 0.5)) if den < 0 else 0.0
            om = (j + delta) * bin_w
            if om_have and min(abs(o - om) for o in om_have) < 2 * bin_w:
                continue
            pj = 2.0 / L
            om_have.append(om)
            add_p.append(pj)
            add_q.append(om * om + 0.25 * pj * pj)
    return np.asarray(add_p), np.asarray(add_q)
