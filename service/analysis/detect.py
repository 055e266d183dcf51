"""Eigenfrequency detector: the poles of a damped multi-mode record, with uncertainties and flags.

A record ``w`` (absolute position, uniformly sampled with step ``dt``) is modelled as::

    w[n] = c + sum_k x_k(n dt) + noise,     x_k'' + p_k x_k' + q_k x_k = 0

i.e. a static level ``c`` (the equilibrium deflection) plus the free responses of damped
second-order modes. A mode's two poles are the roots of ``s^2 + p s + q = 0``; in the paper's
notation ``p = xi`` and ``q = -sigma^2``, so ``sigma^2 = -s1 s2`` in both regimes:

* underdamped (``p^2 < 4 q``): ``s = -gamma +- i omega``, ``gamma = p/2``,
  ``sigma^2 = -(gamma^2 + omega^2)``;
* overdamped (``p^2 > 4 q``): two real poles ``-r1, -r2``, ``sigma^2 = -r1 r2``, no FFT peak.

Methods (``method=``)
---------------------
``"fft"``
    The paper's baseline: the highest peak of the FFT magnitude of the mean-removed record,
    at the resolution ``2 pi / (N dt)``; damping from the half-power width of the peak.
``"fft-parabolic"``
    The same with a parabola through the peak bin and its two neighbours (sub-bin frequency).
``"esprit"``
    Initialisation only: strided (decimated) Hankel covariance + ESPRIT poles, model order by
    MDL on the linear amplitudes; no nonlinear refinement.
``"varpro"`` (= ``"auto"``)
    ESPRIT initialisation (whole record, plus its first eighth when the response decays
    within the record, plus unexplained Hann-periodogram peaks), then variable-projection
    (separable) Levenberg-Marquardt least squares on the poles ``(p_k, q_k)`` with the static
    level and the amplitudes projected out; residual rounds (ESPRIT on the residual, whose
    stride adapts to slow content) add missed modes, and refit checks undo two known local
    minima (two modes on one spectral line, an overdamped pair split over two modes). The
    parametrisation is smooth across critical damping, so an overdamped fundamental is
    fitted as two real poles and ``sigma^2 = -q`` keeps its meaning. The model order is
    chosen by MDL (backward elimination of modes whose removal costs less than
    ``4 ln N`` in chi-square units, i.e. ``(1/2) ln N`` per real parameter). The fundamental
    is the significant mode with the smallest ``|sigma^2|``. This is the maximum-likelihood
    estimator for white Gaussian noise, efficient (at the Cramer-Rao bound) above threshold;
    standard errors come from the Gauss-Newton covariance ``s^2 (J^T J)^-1`` of the fit.

``common_damping=True`` imposes the same ``p`` (``= xi = 2 gamma``) on every mode, the beam
model's damping; it lowers the variance when the model holds.

``kind="ambient"`` analyses the biased autocorrelation of the mean-removed record (lags 1 to
at most ``N/2``, cut where it sinks into its estimation noise): for a noise-driven linear
structure it is a sum of damped modes with the same poles. Standard errors then come from the
scatter of the fit over segments of the record (the autocorrelation's errors are correlated).

Flags (``Detection.flags``, codes in :data:`FLAG_CODES`)
--------------------------------------------------------
``no_mode``            nothing above the noise (or a constant record): ``fundamental`` is None.
``few_periods``        the record spans fewer than 2 periods ``2 pi / sqrt|sigma^2|``.
``low_snr``            the fundamental's record-integrated SNR is below 20 dB.
``overdamped``         a mode has two real poles (no FFT peak); ``sigma^2 = -s1 s2``.
``unstable``           a mode has ``sigma^2 > 0`` (a growing real pole).
``nonlinear``          the fundamental's ``sigma^2`` differs between the two halves of the
                       record by more than 5 standard errors (amplitude-dependent frequency).
``aliasing``           significant energy or a mode above 0.8 x Nyquist.
``damping_unresolved`` (FFT methods) a peak no wider than the resolution.
``ambient``            the result comes from an autocorrelation fit (units of variance).
``numerical``          the static level could not be estimated.

Performance: the hot loops are numba kernels in :mod:`service.analysis._detect_kernels`
(fused basis recurrences + Gram matrices, strided Hankel covariance, small symmetric
eigensolvers); no BLAS thread pool is involved in the fit itself.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from functools import lru_cache
from typing import Any

import numpy as np
from scipy.signal import find_peaks

from service.analysis._detect_kernels import (
    _ch_sh,
    hankel_gram,
    model_gram,
    model_values,
    psd_pinv,
    top_eigenpairs,
)
from service.analysis.common import Flag

__all__ = ["METHODS", "KINDS", "FLAG_CODES", "Mode", "Fundamental", "Detection", "detect"]

METHODS = ("auto", "varpro", "esprit", "fft", "fft-parabolic")
KINDS = ("impulse", "ambient")
FLAG_CODES = (
    "no_mode",
    "few_periods",
    "low_snr",
    "overdamped",
    "unstable",
    "nonlinear",
    "aliasing",
    "damping_unresolved",
    "ambient",
    "numerical",
)
MIN_SAMPLES = 16

#: Thresholds of the flags (documented in the messages).
FEW_PERIODS = 2.0  # fundamental periods in the record below which "few_periods" is raised
LOW_SNR_DB = 20.0  # fundamental's record-integrated SNR (energy / noise variance) in dB
NONLINEAR_Z = 5.0  # half-record frequency drift, in combined standard errors
ALIAS_FRACTION = 0.8  # fraction of the Nyquist frequency above which energy is an alias risk


# --------------------------------------------------------------------------------------------
# Results
# --------------------------------------------------------------------------------------------


def _num(x: float | None) -> float | None:
    """A plain float for JSON, ``None`` for missing / non-finite values."""
    if x is None:
        return None
    x = float(x)
    return x if math.isfinite(x) else None


@dataclass(frozen=True)
class Mode:
    """One mode (a pair of poles) of the record.

    Attributes
    ----------
    omega : float
        Damped angular frequency, rad per time unit of the record (0 for an overdamped mode).
    frequency : float
        ``omega / (2 pi)``, cycles per time unit.
    damping : float
        Decay rate ``gamma = p/2`` (1 per time unit); poles ``s = -gamma +- i omega``. For an
        overdamped mode, the mean of the two real decay rates.
    sigma2 : float
        Undamped eigenvalue ``-s1 s2`` (time^-2); negative for a stable mode.
    amplitude : float
        Initial amplitude (record units): ``A`` in ``A exp(-gamma t) cos(omega t + phase)``
        with ``t = 0`` at the first sample; for an overdamped mode ``max(|b1|, |b2|)``.
    phase : float
        Phase at the first sample, rad (0 for an overdamped mode).
    omega_std, damping_std, sigma2_std, amplitude_std : float
        Standard errors (same units).
    regime : str
        ``"underdamped"`` or ``"overdamped"``.
    real_poles : tuple of float or None
        Overdamped mode: its two real poles ``(-r1, -r2)`` (slow first), 1 per time unit.
    real_amplitudes : tuple of float or None
        Overdamped mode: ``(b1, b2)`` in ``b1 exp(-r1 t) + b2 exp(-r2 t)``.
    snr_db : float
        Record-integrated SNR of this mode: ``10 log10(energy / noise variance)``, where the
        energy is the rise of the residual sum of squares when the mode is removed.
    """

    omega: float
    frequency: float
    damping: float
    sigma2: float
    amplitude: float
    phase: float
    omega_std: float
    damping_std: float
    sigma2_std: float
    amplitude_std: float = math.nan
    regime: str = "underdamped"
    real_poles: tuple[float, float] | None = None
    real_amplitudes: tuple[float, float] | None = None
    snr_db: float = math.nan

    def to_dict(self) -> dict[str, Any]:
        return {
            "omega": _num(self.omega),
            "frequency": _num(self.frequency),
            "damping": _num(self.damping),
            "sigma2": _num(self.sigma2),
            "amplitude": _num(self.amplitude),
            "phase": _num(self.phase),
            "omega_std": _num(self.omega_std),
            "damping_std": _num(self.damping_std),
            "sigma2_std": _num(self.sigma2_std),
            "amplitude_std": _num(self.amplitude_std),
            "regime": self.regime,
            "real_poles": None if self.real_poles is None else [_num(v) for v in self.real_poles],
            "real_amplitudes": None
            if self.real_amplitudes is None
            else [_num(v) for v in self.real_amplitudes],
            "snr_db": _num(self.snr_db),
        }


@dataclass(frozen=True)
class Fundamental:
    """The fundamental: the significant mode with the smallest ``|sigma^2|``.

    Attributes
    ----------
    omega, omega_std : float
        Damped angular frequency (0 when overdamped) and its standard error, rad/time.
    sigma2, sigma2_std : float
        Undamped eigenvalue ``-s1 s2`` and its standard error, 1/time^2.
    damping, damping_std : float
        ``gamma = p/2`` and its standard error, 1/time.
    regime : str
        ``"underdamped"`` or ``"overdamped"``.
    poles : tuple of float or None
        For an overdamped fundamental, its two real poles ``(-r1, -r2)`` (1/time).
    index : int
        Its position in ``Detection.modes``.
    """

    omega: float
    sigma2: float
    sigma2_std: float
    damping: float
    regime: str
    omega_std: float = math.nan
    damping_std: float = math.nan
    poles: tuple[float, float] | None = None
    index: int = 0

    def to_dict(self) -> dict[str, Any]:
        return {
            "omega": _num(self.omega),
            "omega_std": _num(self.omega_std),
            "sigma2": _num(self.sigma2),
            "sigma2_std": _num(self.sigma2_std),
            "damping": _num(self.damping),
            "damping_std": _num(self.damping_std),
            "regime": self.regime,
            "poles": None if self.poles is None else [_num(v) for v in self.poles],
            "index": self.index,
        }


@dataclass(frozen=True)
class Detection:
    """Result of :func:`detect`.

    Attributes
    ----------
    modes : tuple of Mode
        Significant modes, sorted by increasing ``|sigma^2|`` (the fundamental first).
    fundamental : Fundamental or None
        ``None`` when no mode was found (flag ``"no_mode"``).
    static_level, static_level_std : float
        Equilibrium offset of the record and its standard error (record units).
    flags : tuple of Flag
    method : str
        The method actually used (``"auto"`` resolves to ``"varpro"``).
    noise_std : float
        Estimated standard deviation of the additive noise (record units).
    snr_db : float
        Per-sample SNR of the fundamental at the first sample, ``10 log10(A^2 / (2 s^2))``
        (``A`` its amplitude, ``s`` the noise std); NaN (flag ``"no_mode"``) without modes.
    n_samples : int
    dt : float
    kind : str
    iterations : int
        Levenberg-Marquardt iterations of the final fit (0 for the non-iterative methods).
    """

    modes: tuple[Mode, ...]
    fundamental: Fundamental | None
    static_level: float
    static_level_std: float
    flags: tuple[Flag, ...]
    method: str
    noise_std: float
    snr_db: float
    n_samples: int = 0
    dt: float = 1.0
    kind: str = "impulse"
    iterations: int = 0

    @property
    def flag_codes(self) -> tuple[str, ...]:
        return tuple(f.code for f in self.flags)

    def to_dict(self) -> dict[str, Any]:
        """The CLI document: plain floats, ``None`` for missing values."""
        return {
            "modes": [m.to_dict() for m in self.modes],
            "fundamental": None if self.fundamental is None else self.fundamental.to_dict(),
            "flags": [f.to_dict() for f in self.flags],
            "static_level": _num(self.static_level),
            "static_level_std": _num(self.static_level_std),
            "method": self.method,
            "noise_std": _num(self.noise_std),
            "snr_db": _num(self.snr_db),
            "n_samples": int(self.n_samples),
            "dt": _num(self.dt),
            "kind": self.kind,
        }


# --------------------------------------------------------------------------------------------
# Small linear algebra
# --------------------------------------------------------------------------------------------


def _pinv_psd(A: np.ndarray, rcond: float = 1e-13) -> np.ndarray:
    """Pseudo-inverse of a symmetric positive semi-definite matrix (Jacobi-scaled, numba)."""
    A = np.ascontiguousarray(A, dtype=float)
    out = np.empty_like(A)
    if A.shape[0]:
        psd_pinv(A, rcond, out)
    return out


# --------------------------------------------------------------------------------------------
# The model in sample units: columns [1, (u1, u2, du1/dp, du1/dq, du2/dp, du2/dq) per mode, y]
# --------------------------------------------------------------------------------------------


@dataclass
class _Eval:
    p: np.ndarray
    q: np.ndarray
    G: np.ndarray  # Gram of [1, u1_0, u2_0, ..., y]
    c: np.ndarray  # linear coefficients [c0, c1_0, c2_0, c1_1, ...]
    rss: float


def _growth_ok(p: np.ndarray, q: np.ndarray, n: int) -> bool:
    if not (np.all(np.isfinite(p)) and np.all(np.isfinite(q))):
        return False
    D = 0.25 * p * p - q
    growth = -0.5 * p + np.sqrt(np.maximum(D, 0.0))
    return bool(np.all(growth * n < 40.0)) and bool(np.all(np.abs(p) < 20.0))


_NO_C = np.zeros(1)


def _evaluate(y: np.ndarray, p: np.ndarray, q: np.ndarray) -> _Eval | None:
    """Gram matrix and projected (variable-projection) linear solve at ``(p, q)``."""
    N = y.shape[0]
    K = p.shape[0]
    if not _growth_ok(p, q, N):
        return None
    m = 2 * K + 2
    G = np.empty((m, m))
    model_gram(y, p, q, _NO_C, False, False, G)
    if not np.all(np.isfinite(G)):
        return None
    Gpp = G[:-1, :-1]
    gy = G[:-1, -1]
    c = _pinv_psd(Gpp) @ gy
    rss = float(G[-1, -1] - 2.0 * c @ gy + c @ Gpp @ c)
    return _Eval(p, q, G, c, max(rss, 0.0))


def _jacobian_system(y: np.ndarray, ev: _Eval, common: bool) -> tuple[np.ndarray, np.ndarray, int]:
    """Normal matrix ``J^T J`` of the full Jacobian ``[dmodel/dtheta | Phi]`` and ``J^T r``.

    ``theta = (p_0, q_0, p_1, q_1, ...)`` or, with ``common``, ``(p, q_0, q_1, ...)``.
    """
    K = ev.p.shape[0]
    ntheta = K + 1 if common else 2 * K
    nphi = 1 + 2 * K
    m = ntheta + nphi + 1
    B = np.empty((m, m))
    model_gram(y, ev.p, ev.q, ev.c, common, True, B)
    A = B[:-1, :-1]
    g = B[:-1, -1] - B[:-1, ntheta : ntheta + nphi] @ ev.c
    return A, g, ntheta


def _theta(p: np.ndarray, q: np.ndarray, common: bool) -> np.ndarray:
    if common:
        return np.concatenate(([np.mean(p)], q))
    return np.column_stack((p, q)).ravel()


def _unpack(theta: np.ndarray, K: int, common: bool) -> tuple[np.ndarray, np.ndarray]:
    if common:
        return np.full(K, theta[0]), theta[1:].copy()
    return theta[0::2].copy(), theta[1::2].copy()


@dataclass
class _Fit:
    ev: _Eval
    cov: np.ndarray  # covariance of [theta, c] (sample units, normalised amplitude)
    ntheta: int
    s2: float  # noise variance estimate
    iterations: int
    common: bool


def _solve_gram(G: np.ndarray) -> tuple[np.ndarray, float]:
    """Linear least squares from the Gram matrix of ``[Phi, y]``: coefficients and RSS."""
    Gpp = G[:-1, :-1]
    gy = G[:-1, -1]
    c = _pinv_psd(Gpp) @ gy
    rss = float(G[-1, -1] - 2.0 * c @ gy + c @ Gpp @ c)
    return c, max(rss, 0.0)


def _heavy_pass(
    y: np.ndarray, p: np.ndarray, q: np.ndarray, c: np.ndarray, common: bool
) -> np.ndarray | None:
    """Gram of ``[J_theta(c), Phi, y]`` at ``(p, q)`` (one fused pass over the record)."""
    if not _growth_ok(p, q, y.shape[0]):
        return None
    K = p.shape[0]
    nth = K + 1 if common else 2 * K
    B = np.empty((nth + 2 * K + 2, nth + 2 * K + 2))
    model_gram(y, p, q, c, common, True, B)
    if not np.all(np.isfinite(B)):
        return None
    return B


def _levenberg_marquardt(
    y: np.ndarray,
    p0: np.ndarray,
    q0: np.ndarray,
    *,
    common: bool,
    max_iter: int,
    c0: np.ndarray | None = None,
) -> _Fit | None:
    """Variable-projection Levenberg-Marquardt on ``theta``, one record pass per trial step.

    Each pass returns the Gram of ``[J_theta, Phi, y]``: its ``[Phi, y]`` block gives the
    projected coefficients ``c(theta)`` and the RSS exactly; ``J_theta`` is built with the
    previous iterate's ``c`` (a lagged Kaufman Jacobian, consistent at convergence). A last
    pass with the final ``c`` gives the Gauss-Newton covariance.
    """
    N = y.shape[0]
    K = p0.shape[0]
    p = np.full(K, float(np.mean(p0))) if common else p0.astype(float).copy()
    q = q0.astype(float).copy()
    nth = K + 1 if common else 2 * K
    if c0 is None:
        ev0 = _evaluate(y, p, q)
        if ev0 is None:
            return None
        c0 = ev0.c
    c = c0
    B = _heavy_pass(y, p, q, c, common)
    if B is None:
        return None
    c, rss = _solve_gram(B[nth:, nth:])
    theta = _theta(p, q, common)
    lam = 1e-4
    it = 0
    small = False
    lagged = False  # B's Jacobian built with an earlier iterate's c
    for it in range(1, max_iter + 1):  # noqa: B007
        A = B[:-1, :-1]
        # gradient J^T r with r = y - Phi c (c exact at theta)
        g = B[:-1, -1] - B[:-1, nth:-1] @ c
        dA = np.diag(A).copy()
        dA[dA == 0] = 1.0
        accepted = False
        while lam < 1e12:
            Ainv = _pinv_psd(A + lam * np.diag(dA))
            dth = (Ainv @ g)[:nth]
            p_new, q_new = _unpack(theta + dth, K, common)
            B_new = _heavy_pass(y, p_new, q_new, c, common)
            if B_new is not None:
                c_new, rss_new = _solve_gram(B_new[nth:, nth:])
                if rss_new <= rss * (1.0 + 1e-13):
                    accepted = True
                    lam_used = lam
                    break
            if lagged:
                # retry with the exact Jacobian before damping the step
                B_ex = _heavy_pass(y, p, q, c, common)
                if B_ex is None:
                    break
                B, lagged = B_ex, False
                A = B[:-1, :-1]
                g = B[:-1, -1] - B[:-1, nth:-1] @ c
                dA = np.diag(A).copy()
                dA[dA == 0] = 1.0
                continue
            lam *= 8.0
        if not accepted:
            break
        gain = rss - rss_new
        theta = theta + dth
        p, q, B, c, rss = p_new, q_new, B_new, c_new, rss_new
        lagged = True
        lam = max(lam / 10.0, 1e-9)
        # converged: an undamped step far below the statistical resolution, or no gain left
        # (a step shrunk by a large lambda says nothing about convergence)
        s2 = max(rss, 1e-300) / max(N - nth - 1 - 2 * K, 1)
        if lam_used <= 1e-2:
            cov_th = np.diag(_pinv_psd(A))[:nth] * s2
            small = bool(np.all(np.abs(dth) <= 2e-2 * np.sqrt(np.maximum(cov_th, 1e-300))))
            if small or gain <= 1e-12 * rss:
                break
        else:
            small = False
    else:
        small = False
    # a last pass with the final c, unless the last step was negligible (then the lagged
    # Jacobian differs from the exact one by O(step) and the covariance is already accurate)
    if max_iter == 0 or not small:
        B_fin = _heavy_pass(y, p, q, c, common)
        if B_fin is not None:
            B = B_fin
    A = B[:-1, :-1]
    npar = nth + 1 + 2 * K
    s2 = rss / max(N - npar, 1)
    cov = _pinv_psd(A) * s2
    ev = _Eval(p, q, np.ascontiguousarray(B[nth:, nth:]), c, rss)
    return _Fit(ev, cov, nth, s2, it, common)


def _mode_energy(ev: _Eval) -> np.ndarray:
    """Rise of the RSS when each mode is removed (others' amplitudes re-fitted), in y units^2."""
    K = ev.p.shape[0]
    Ginv = _pinv_psd(ev.G[:-1, :-1])
    out = np.empty(K)
    for k in range(K):
        j = [1 + 2 * k, 2 + 2 * k]
        ck = ev.c[j]
        Mk = Ginv[np.ix_(j, j)]
        out[k] = float(ck @ _pinv_psd(Mk) @ ck)
    return out


# --------------------------------------------------------------------------------------------
# Initialisation: periodogram band, strided Hankel covariance, ESPRIT
# --------------------------------------------------------------------------------------------


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


def _spectrum(y: np.ndarray) -> _Spectrum:
    win, norm = _hann(y.shape[0])
    H = np.abs(np.fft.rfft(win * y)) ** 2 / norm
    body = H[2:] if H.size > 3 else H[1:]
    noise = float(np.median(body) / math.log(2.0)) if body.size else 0.0
    thr = math.log(max(body.size, 2) / 1e-3)  # 0.1 % false alarm per record (chi2_2 / 2)
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


def _candidates(s: np.ndarray, N: int) -> tuple[np.ndarray, np.ndarray]:
    """Group poles into modes ``(p, q)``: conjugate pairs, and real poles paired by rate."""
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
    reals = sorted(r for r in reals if r * N > -5.0)
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
    keep = np.isfinite(p) & np.isfinite(q) & (p < 1.0) & (p > -20.0 / N)
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


def _prune(
    y: np.ndarray,
    p: np.ndarray,
    q: np.ndarray,
    noise_var: float,
    max_modes: int,
    G: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray | None]:
    """MDL backward elimination of modes at fixed poles (one record pass: the Gram matrix of
    all candidates is computed once, a removal deletes its columns).

    Returns the kept ``p, q``, their energies over the noise variance, and the coefficients.
    """
    N = y.shape[0]
    thr = 4.0 * math.log(N)
    ev = None
    while p.size and G is None:
        ev = _evaluate(y, p, q)
        if ev is not None:
            break
        # drop the fastest-growing candidate and retry
        D = 0.25 * p * p - q
        k = int(np.argmax(-0.5 * p + np.sqrt(np.maximum(D, 0.0))))
        p, q = np.delete(p, k), np.delete(q, k)
    if G is None:
        if ev is None:
            return p, q, np.zeros(0), None
        G = ev.G
    active = list(range(p.size))
    while active:
        idx = [0] + [j for k in active for j in (1 + 2 * k, 2 + 2 * k)] + [G.shape[0] - 1]
        Gs = G[np.ix_(idx, idx)]
        c, rss = _solve_gram(Gs)
        Ginv = _pinv_psd(Gs[:-1, :-1])
        e = np.empty(len(active))
        for i in range(len(active)):
            j = [1 + 2 * i, 2 + 2 * i]
            e[i] = float(c[j] @ _pinv_psd(Ginv[np.ix_(j, j)]) @ c[j])
        npar = 1 + 4 * len(active)
        s2 = rss / max(N - npar, 1)
        s2 = max(s2, min(noise_var, s2), 1e-300)
        i = int(np.argmin(e))
        if e[i] / s2 < thr or len(active) > max_modes:
            del active[i]
            continue
        return p[active], q[active], e / s2, c
    return p[:0], q[:0], np.zeros(0), None


# --------------------------------------------------------------------------------------------
# Validation
# --------------------------------------------------------------------------------------------


def _validate(
    w: Any, dt: Any, method: Any, kind: Any, max_modes: Any, common_damping: Any
) -> tuple[np.ndarray, float, str, str, int]:
    if isinstance(method, str) and method.lower() in METHODS:
        method = method.lower()
    else:
        raise ValueError(f"method={method!r}: unknown, expected one of {', '.join(METHODS)}")
    if kind not in KINDS:
        raise ValueError(f"kind={kind!r}: unknown, expected one of {', '.join(KINDS)}")
    try:
        arr = np.asarray(w)
    except Exception as exc:  # pragma: no cover - numpy raises on ragged input
        raise ValueError(f"w: cannot be read as an array ({exc})") from None
    if arr.dtype.kind not in "biuf":
        raise ValueError(f"w: expected real numbers, got dtype {arr.dtype}")
    arr = arr.astype(float, copy=False)
    if arr.ndim != 1:
        raise ValueError(f"w: expected a 1-D array, got shape {arr.shape}")
    if arr.size < MIN_SAMPLES:
        raise ValueError(f"w: too short ({arr.size} samples), need at least {MIN_SAMPLES}")
    bad = ~np.isfinite(arr)
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise ValueError(
            f"w: {int(bad.sum())} non-finite sample(s), first at index {i} (value {arr[i]!r})"
        )
    if isinstance(dt, bool) or not isinstance(dt, (int, float, np.integer, np.floating)):
        raise ValueError(f"dt={dt!r}: expected a positive number")
    dt = float(dt)
    if not (math.isfinite(dt) and dt > 0):
        raise ValueError(f"dt={dt!r}: must be finite and > 0")
    if max_modes is None:
        max_modes = 6
    if isinstance(max_modes, bool) or not isinstance(max_modes, (int, np.integer)):
        raise ValueError(f"max_modes={max_modes!r}: expected an integer from 1 to 20 or None")
    if not 1 <= int(max_modes) <= 20:
        raise ValueError(f"max_modes={max_modes!r}: expected an integer from 1 to 20 or None")
    if not isinstance(common_damping, (bool, np.bool_)):
        raise ValueError(f"common_damping={common_damping!r}: expected True or False")
    return arr, dt, method, kind, int(max_modes)


# --------------------------------------------------------------------------------------------
# Conversion of a fit to physical modes
# --------------------------------------------------------------------------------------------


def _modes_from_fit(
    fit: _Fit, energies: np.ndarray, dt: float, scale: float
) -> tuple[list[Mode], float, float]:
    ev = fit.ev
    K = ev.p.shape[0]
    cov = fit.cov
    nth = fit.ntheta
    modes: list[Mode] = []
    for k in range(K):
        jp = 0 if fit.common else 2 * k
        jq = 1 + k if fit.common else 2 * k + 1
        p, q = float(ev.p[k]), float(ev.q[k])
        vpp, vqq, vpq = cov[jp, jp], cov[jq, jq], cov[jp, jq]
        c1 = float(ev.c[1 + 2 * k])
        c2 = float(ev.c[2 + 2 * k])
        ic1, ic2 = nth + 1 + 2 * k, nth + 2 + 2 * k
        D = 0.25 * p * p - q
        gamma = 0.5 * p / dt
        gamma_std = 0.5 * math.sqrt(max(vpp, 0.0)) / dt
        sigma2 = -q / dt**2
        sigma2_std = math.sqrt(max(vqq, 0.0)) / dt**2
        snr = 10.0 * math.log10(max(energies[k], 1e-300)) if energies.size else math.nan
        if D < 0:
            om = math.sqrt(-D)
            # d om / d p = p / (4 om) ; d om / d q = -1 / (2 om)   (om^2 = q - p^2/4)
            gp, gq = -p / (4.0 * om), 1.0 / (2.0 * om)
            var_om = gp * gp * vpp + gq * gq * vqq + 2 * gp * gq * vpq
            a_cos, a_sin = c1, -c2 / om  # A cos(phi), A sin(phi)
            amp = math.hypot(a_cos, a_sin)
            phase = math.atan2(a_sin, a_cos)
            # amplitude std: gradient of |(c1, c2/om)| in (c1, c2) (om treated as exact)
            if amp > 0:
                g1, g2 = c1 / amp, (c2 / om**2) / amp
                var_a = g1 * g1 * cov[ic1, ic1] + g2 * g2 * cov[ic2, ic2]
                var_a += 2 * g1 * g2 * cov[ic1, ic2]
            else:
                var_a = 0.0
            modes.append(
                Mode(
                    omega=om / dt,
                    frequency=om / dt / (2 * math.pi),
                    damping=gamma,
                    sigma2=sigma2,
                    amplitude=amp * scale,
                    phase=phase,
                    omega_std=math.sqrt(max(var_om, 0.0)) / dt,
                    damping_std=gamma_std,
                    sigma2_std=sigma2_std,
                    amplitude_std=math.sqrt(max(var_a, 0.0)) * scale,
                    regime="underdamped",
                    snr_db=snr,
                )
            )
        else:
            lam = math.sqrt(D)
            r1, r2 = 0.5 * p - lam, 0.5 * p + lam
            if lam > 0:
                b1 = 0.5 * (c1 + c2 / lam)
                b2 = 0.5 * (c1 - c2 / lam)
            else:  # critically damped: c1 + c2 t ; report as equal split
                b1 = b2 = 0.5 * c1
            amp = max(abs(b1), abs(b2))
            modes.append(
                Mode(
                    omega=0.0,
                    frequency=0.0,
                    damping=gamma,
                    sigma2=sigma2,
                    amplitude=amp * scale,
                    phase=0.0,
                    omega_std=0.0,
                    damping_std=gamma_std,
                    sigma2_std=sigma2_std,
                    amplitude_std=math.sqrt(max(cov[ic1, ic1], 0.0)) * scale,
                    regime="overdamped",
                    real_poles=(-r1 / dt, -r2 / dt),
                    real_amplitudes=(b1 * scale, b2 * scale),
                    snr_db=snr,
                )
            )
    static_std = math.sqrt(max(cov[nth, nth], 0.0)) * scale
    return modes, float(ev.c[0]), static_std


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


def _fundamental(modes: list[Mode]) -> Fundamental | None:
    if not modes:
        return None
    m = modes[0]
    return Fundamental(
        omega=m.omega,
        sigma2=m.sigma2,
        sigma2_std=m.sigma2_std,
        damping=m.damping,
        regime=m.regime,
        omega_std=m.omega_std,
        damping_std=m.damping_std,
        poles=m.real_poles,
        index=0,
    )


# --------------------------------------------------------------------------------------------
# Methods
# --------------------------------------------------------------------------------------------


def _cross(P: np.ndarray, i0: int, i1: int, level: float) -> float:
    """Fractional bin where the line through ``(i0, P[i0])``, ``(i1, P[i1])`` hits ``level``."""
    a0, a1 = P[i0], P[i1]
    return i0 + (level - a0) / (a1 - a0) * (i1 - i0) if a1 != a0 else float(i0)


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
        # half-power width
        half = 0.5 * P[j]
        lo = j
        while lo > 0 and P[lo] > half:
            lo -= 1
        hi = j
        while hi < nb - 1 and P[hi] > half:
            hi += 1
        x_lo = _cross(P, lo, lo + 1, half) if lo < j else float(j)
        x_hi = _cross(P, hi, hi - 1, half) if hi > j else float(j)
        width = max(x_hi - x_lo, 0.0) * d_om
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
    peaks, _ = find_peaks(np.convolve(logp, np.ones(3) / 3, mode="same"), prominence=1.0)
    return int(peaks.size)


def _initial_candidates(
    y: np.ndarray, spec: _Spectrum, max_modes: int, peaks: bool = True
) -> tuple[np.ndarray, np.ndarray]:
    """Candidate modes ``(p, q)``: ESPRIT on the whole record, ESPRIT on its first eighth
    (fast-decaying modes live there and vanish in a whole-record covariance), and the
    significant periodogram peaks that neither explains."""
    N = y.shape[0]
    p, q = _candidates(_esprit(y, spec, 2 * max_modes + 1), N)
    head = y[: N // 8]
    # only when the response decays within the record (the head holds most of the power)
    if head.size >= 128 and float(np.mean(head * head)) > 3.0 * float(np.mean(y * y)):
        hs = _spectrum(head)
        ph, qh = _candidates(_esprit(head, hs, 2 * max_modes + 1), head.size)
        p, q = np.concatenate((p, ph)), np.concatenate((q, qh))
    if peaks:
        p, q = _peak_candidates(spec, N, p, q, max_modes)
    return p, q


def _fit_parametric(
    y: np.ndarray,
    spec: _Spectrum,
    *,
    max_modes: int,
    common: bool,
    refine: bool,
    max_iter: int,
) -> tuple[_Fit | None, np.ndarray]:
    """ESPRIT initialisation, MDL pruning, varpro fit; then up to two rounds of residual
    ESPRIT (multi-scale: a slow residual gets a long strided window) to add missed modes."""
    N = y.shape[0]
    p, q = _initial_candidates(y, spec, max_modes)
    fit: _Fit | None = None
    energy = np.zeros(0)
    for round_ in range(3):
        p, q, energy, c_init = _prune(y, p, q, spec.noise_var, max_modes)
        if p.size == 0 and fit is None:
            if round_ > 0:
                return None, energy
        if p.size:
            new = None
            for _ in range(3):
                new = _levenberg_marquardt(
                    y,
                    p,
                    q,
                    common=common and refine,
                    max_iter=max_iter if refine else 0,
                    c0=None if common else c_init,
                )
                if new is None:
                    break
                p2, q2, energy, c_init = _prune(
                    y, new.ev.p, new.ev.q, new.s2, max_modes, G=new.ev.G
                )
                if p2.size == new.ev.p.size or p2.size == 0:
                    break
                p, q = p2, q2
            if new is not None and p2.size:
                if fit is not None and new.ev.rss >= fit.ev.rss * (1 - 1e-9):
                    break
                fit = new
            elif fit is None:
                return None, energy
        if not refine or round_ == 2:
            break
        # residual: is anything left that the current model misses?
        r = y.copy()
        if fit is not None:
            mv = np.empty(N)
            model_values(fit.ev.p, fit.ev.q, fit.ev.c, mv)
            r -= mv
        rspec = _spectrum(r)
        head = r[: N // 8]
        if not rspec.significant.any() and not (
            head.size >= 128
            and float(np.mean(head * head)) > 3.0 * float(np.mean(r * r))
            and _spectrum(head).significant.any()
        ):
            break
        p_new, q_new = _initial_candidates(r, rspec, max_modes, peaks=False)
        if p_new.size == 0:
            break
        base_p = fit.ev.p if fit is not None else np.zeros(0)
        base_q = fit.ev.q if fit is not None else np.zeros(0)
        p = np.concatenate((base_p, p_new))
        q = np.concatenate((base_q, q_new))
    if fit is not None and refine:
        fit = _merge_close_modes(y, fit, max_iter)
        fit = _repair_real_poles(y, fit, max_iter)
        p2, q2, _, c2 = _prune(y, fit.ev.p, fit.ev.q, fit.s2, max_modes, G=fit.ev.G)
        if 0 < p2.size < fit.ev.p.size:
            new = _levenberg_marquardt(y, p2, q2, common=fit.common, max_iter=max_iter)
            if new is not None:
                fit = new
    if fit is not None:
        energy = _mode_energy(fit.ev) / max(fit.s2, 1e-300)
    return fit, energy


def _repair_real_poles(y: np.ndarray, fit: _Fit, max_iter: int) -> _Fit:
    """Undo a split of one overdamped pair over two modes (a local minimum where each mode
    holds one true real pole and one spurious partner): for every two modes with real (or
    heavily damped, omega < gamma) poles, try one pair made of a pole of each; keep the best
    refit if it costs less than the MDL penalty of the mode it saves (``4 ln N`` noise
    variances)."""
    N = y.shape[0]
    thr = 4.0 * math.log(N)
    for _ in range(3):
        p, q = fit.ev.p, fit.ev.q
        D = 0.25 * p * p - q
        pool = []
        for k in range(p.size):
            lam = math.sqrt(abs(D[k]))
            if D[k] >= 0 or lam < 0.5 * p[k]:
                pool.append((k, (-0.5 * p[k] - lam, -0.5 * p[k] + lam)))
        if len(pool) < 2:
            return fit
        best = None
        for i in range(len(pool)):
            for j in range(i + 1, len(pool)):
                ki, si = pool[i]
                kj, sj = pool[j]
                keep = [k for k in range(p.size) if k not in (ki, kj)]
                for a in si:
                    for b in sj:
                        pn = np.append(p[keep], -(a + b))
                        qn = np.append(q[keep], a * b)
                        f = _levenberg_marquardt(y, pn, qn, common=fit.common, max_iter=max_iter)
                        if f is None or (f.ev.rss - fit.ev.rss) >= thr * fit.s2:
                            continue
                        if best is None or f.ev.rss < best.ev.rss:
                            best = f
        if best is None:
            return fit
        fit = best
    return fit


def _merge_close_modes(y: np.ndarray, fit: _Fit, max_iter: int) -> _Fit:
    """Refit-based order check for suspicious modes: pairs closer than two FFT bins, growing
    oscillations (``p < 0``) and weak modes (energy below 10x the MDL threshold). The weaker
    mode of each is removed and the model refitted; the smaller model wins unless the bigger
    one lowers the RSS by more than the MDL penalty (``4 ln N`` noise variances per mode).
    Guards against local minima where two modes share one spectral line or a spurious mode
    holds part of another."""
    N = y.shape[0]
    thr = 4.0 * math.log(N)
    for _ in range(4):
        p, q = fit.ev.p, fit.ev.q
        K = p.size
        if K < 2:
            return fit
        om = np.sqrt(np.maximum(q - 0.25 * p * p, 0.0))
        e = _mode_energy(fit.ev)
        suspects = set()
        for i in range(K):
            if p[i] < 0:  # s1 + s2 = -p > 0: energy gain, impossible for a passive structure
                suspects.add(i)
            if e[i] < 10.0 * thr * fit.s2:  # weak: may be a partner of a split mode
                suspects.add(i)
            for j in range(i + 1, K):
                if abs(om[i] - om[j]) < 2.0 * (2 * math.pi / N):
                    suspects.add(i if e[i] < e[j] else j)
        if not suspects:
            return fit
        best = None
        for k in sorted(suspects, key=lambda k: e[k]):
            keep = [i for i in range(K) if i != k]
            f = _levenberg_marquardt(y, p[keep], q[keep], common=fit.common, max_iter=max_iter)
            if f is not None and (f.ev.rss - fit.ev.rss) < thr * fit.s2:
                if best is None or f.ev.rss < best.ev.rss:
                    best = f
        if best is None:
            return fit
        fit = best
    return fit


def _order(fit: _Fit, energy: np.ndarray) -> tuple[_Fit, np.ndarray]:
    """Reorder the modes of a fit by increasing |q| (slowest first)."""
    K = fit.ev.p.size
    order = np.argsort(np.abs(fit.ev.q), kind="stable")
    if np.all(order == np.arange(K)):
        return fit, energy
    ev = fit.ev
    cidx = [0] + [j for k in order for j in (1 + 2 * k, 2 + 2 * k)]
    if fit.common:
        tidx = [0] + [1 + k for k in order]
    else:
        tidx = [j for k in order for j in (2 * k, 2 * k + 1)]
    full = tidx + [fit.ntheta + j for j in cidx]
    gidx = cidx + [ev.G.shape[0] - 1]
    ev2 = _Eval(ev.p[order], ev.q[order], ev.G[np.ix_(gidx, gidx)], ev.c[cidx], ev.rss)
    cov = fit.cov[np.ix_(full, full)]
    return _Fit(ev2, cov, fit.ntheta, fit.s2, fit.iterations, fit.common), energy[order]


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
    s2 = max(rss - float(g @ step), 0.0) / max(y.size - A.shape[0], 1)
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


def detect(
    w: Any,
    *,
    dt: float,
    method: str = "auto",
    kind: str = "impulse",
    max_modes: int | None = None,
    common_damping: bool = False,
    check_linearity: bool = True,
    max_iter: int = 50,
) -> Detection:
    """Detect the modes (poles) of a uniformly sampled record.

    Parameters
    ----------
    w : array_like, shape (N,)
        The record: absolute position, including the static offset. ``N >= 16``.
    dt : float
        Sample step (> 0), in the record's own time unit; every output rate is per that unit.
    method : {"auto", "varpro", "esprit", "fft", "fft-parabolic"}
        See the module documentation; ``"auto"`` is ``"varpro"``.
    kind : {"impulse", "ambient"}
        Free decay after a kick, or a noise-driven record (its autocorrelation is analysed).
    max_modes : int or None
        Largest number of modes (pole pairs) kept, 1 to 20 (default 6).
    common_damping : bool
        Impose one decay rate ``gamma = xi/2`` on every mode (the beam model); parametric
        methods only.
    check_linearity : bool
        Refit the two halves of the record and flag a drift of the fundamental (varpro only).
    max_iter : int
        Levenberg-Marquardt iteration cap.

    Returns
    -------
    Detection
        Frozen result; ``to_dict()`` gives the CLI document.

    Raises
    ------
    ValueError
        On a bad argument; the message names the parameter and echoes the value.
    """
    arr, dt, method, kind, max_modes = _validate(w, dt, method, kind, max_modes, common_damping)
    resolved = "varpro" if method == "auto" else method
    N0 = arr.size
    mean = float(np.mean(arr))
    x = arr - mean
    flags: list[Flag] = []
    static_std_override: float | None = None
    ambient_var = 0.0
    if kind == "ambient":
        n_l = N0 // 2
        nfft = 1 << int(math.ceil(math.log2(2 * N0)))
        F = np.fft.rfft(x, nfft)
        acf = np.fft.irfft(F * np.conj(F), nfft)[: n_l + 1] / N0
        # keep the informative lags: up to 1.5x the last one above 5x the tail's rms
        tail = acf[n_l // 2 :]
        tail_rms = float(np.sqrt(np.mean(tail * tail))) if tail.size else 0.0
        loud = np.flatnonzero(np.abs(acf[1:]) > 5.0 * tail_rms)
        n_cut = int(1.5 * (loud[-1] + 1)) if loud.size else MIN_SAMPLES
        n_cut = int(min(max(n_cut, 4 * MIN_SAMPLES), n_l))
        y_raw = acf[1 : n_cut + 1]
        # the estimation errors of an autocorrelation are correlated: cap the model order at
        # the number of resolved peaks of the record's averaged (Welch) spectrum
        max_modes = min(max_modes, max(_welch_peaks(x), 1))
        nb = 16
        bm = x[: (N0 // nb) * nb].reshape(nb, -1).mean(axis=1)
        static_std_override = float(np.std(bm, ddof=1) / math.sqrt(nb))
        n_seg = int(min(8, N0 // (4 * n_cut)))
        flags.append(
            Flag(
                "ambient",
                f"modes fitted to the autocorrelation (lags 1 to {n_cut}); amplitudes are in "
                f"variance units; standard errors from the scatter over {max(n_seg, 0)} "
                "segments of the record" + (" (too few: rough)" if n_seg < 4 else ""),
            )
        )
    else:
        y_raw = x
    scale = float(np.sqrt(np.mean(y_raw * y_raw)))
    tiny = np.finfo(float).tiny * 1e6
    if not math.isfinite(scale) or scale <= tiny or scale <= 1e-14 * max(abs(mean), tiny):
        flags.append(
            Flag("no_mode", f"the record is constant (value {mean:.6g}): no mode to detect")
        )
        return Detection(
            modes=(),
            fundamental=None,
            static_level=mean,
            static_level_std=0.0,
            flags=tuple(flags),
            method=resolved,
            noise_std=0.0,
            snr_db=math.nan,
            n_samples=N0,
            dt=dt,
            kind=kind,
        )
    y = y_raw / scale
    spec = _spectrum(y)
    iterations = 0
    modes: list[Mode]
    if resolved in ("fft", "fft-parabolic"):
        modes, f2 = _fft_modes(y, dt, scale, resolved == "fft-parabolic", spec)
        flags += f2
        noise_std = math.sqrt(spec.noise_var) * scale
        static = mean
        static_std = noise_std / math.sqrt(N0)
    else:
        fit, energy = _fit_parametric(
            y,
            spec,
            max_modes=max_modes,
            common=bool(common_damping),
            refine=resolved == "varpro",
            max_iter=max_iter,
        )
        if fit is None:
            modes = []
            noise_std = math.sqrt(float(np.mean(y * y))) * scale
            static = mean
            static_std = noise_std / math.sqrt(N0)
        else:
            fit, energy = _order(fit, energy)
            iterations = fit.iterations
            modes, c0, static_std = _modes_from_fit(fit, energy, dt, scale)
            static = mean + c0 * scale
            noise_std = math.sqrt(fit.s2) * scale
            if kind == "ambient":
                modes = _ambient_errors(x, fit, y_raw.size, scale, dt, modes, max_iter)
                # white measurement noise is the spike of the autocorrelation at lag 0
                m0 = _model_at_lag0(fit) * scale
                noise_std = math.sqrt(max(float(acf[0]) - m0, 0.0))
                ambient_var = max(m0, 0.0)
            if check_linearity and resolved == "varpro" and kind == "impulse" and fit.ev.p.size > 0:
                fl = _linearity_flag(y, fit, dt, max_iter)
                if fl is not None:
                    flags.append(fl)
    if static_std_override is not None:
        static, static_std = mean, static_std_override
    fund = _fundamental(modes)
    T = N0 * dt
    if fund is None:
        flags.append(
            Flag(
                "no_mode",
                f"no mode rises above the noise (noise std {noise_std:.3g}, "
                f"{N0} samples): the record looks like noise",
            )
        )
        snr_db = math.nan
    else:
        m0 = modes[0]
        periods = T * math.sqrt(abs(fund.sigma2)) / (2 * math.pi)
        if periods < FEW_PERIODS:
            flags.append(
                Flag(
                    "few_periods",
                    f"the record spans {periods:.3g} fundamental period(s) "
                    f"(T = {T:.4g}, sqrt|sigma^2| = {math.sqrt(abs(fund.sigma2)):.4g}); "
                    f"at least {FEW_PERIODS:g} are advised",
                )
            )
        amp = m0.amplitude
        if kind == "ambient":
            # ratio of the structure's response variance to the measurement-noise variance
            power, npow = ambient_var, noise_std * noise_std
        else:
            power, npow = 0.5 * amp * amp, noise_std * noise_std
        snr_db = (
            10 * math.log10(power / npow)
            if npow > 0 and power > 0
            else (300.0 if power > 0 else -300.0)
        )
        snr_db = float(np.clip(snr_db, -300.0, 300.0))
        if math.isfinite(m0.snr_db) and m0.snr_db < LOW_SNR_DB:
            flags.append(
                Flag(
                    "low_snr",
                    f"the fundamental's record SNR is {m0.snr_db:.1f} dB (< {LOW_SNR_DB:g} dB; "
                    f"per-sample {snr_db:.1f} dB): estimates may be off the Cramer-Rao regime",
                )
            )
        grow = [m for m in modes if m.sigma2 > 3.0 * m.sigma2_std]
        if grow:
            txt = ", ".join(f"{m.sigma2:.4g} +- {m.sigma2_std:.2g}" for m in grow)
            flags.append(
                Flag(
                    "unstable",
                    f"{len(grow)} mode(s) with sigma^2 > 0 ({txt}): a real pole grows, the "
                    "equilibrium is unstable",
                )
            )
        od = [m for m in modes if m.regime == "overdamped"]
        if od:
            txt = ", ".join(
                f"sigma^2 = {m.sigma2:.4g} (poles {m.real_poles[0]:.4g}, {m.real_poles[1]:.4g})"
                for m in od
                if m.real_poles is not None
            )
            flags.append(
                Flag(
                    "overdamped",
                    f"{len(od)} overdamped mode(s): {txt}; no FFT peak, sigma^2 = -s1 s2",
                )
            )
    # aliasing: energy in the top of the band, or a mode close to Nyquist
    nyq = math.pi / dt
    kb = int(ALIAS_FRACTION * (spec.hann.size - 1))
    hot = int(np.sum(spec.significant[kb:])) if kb > 0 else 0
    near = [m.omega for m in modes if m.omega > ALIAS_FRACTION * nyq]
    if hot >= 2 or near:
        flags.append(
            Flag(
                "aliasing",
                f"energy above {ALIAS_FRACTION:g} x Nyquist ({nyq:.4g} rad/time): "
                f"{hot} significant bin(s), {len(near)} mode(s) there; sample faster or "
                f"low-pass filter before sampling",
            )
        )
    if not (math.isfinite(static) and math.isfinite(static_std)):
        flags.append(Flag("numerical", "the static level could not be estimated"))
    return Detection(
        modes=tuple(modes),
        fundamental=fund,
        static_level=static,
        static_level_std=static_std,
        flags=tuple(flags),
        method=resolved,
        noise_std=noise_std,
        snr_db=snr_db,
        n_samples=N0,
        dt=dt,
        kind=kind,
        iterations=iterations,
    )
