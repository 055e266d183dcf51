"""Results of the detector (frozen dataclasses), flag codes and thresholds."""

from __future__ import annotations

import math
from dataclasses import dataclass

from service.analysis.common import Flag

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
    "combination_tone",
    "trend",
    "pretrigger",
    "relaxation",
    "stationary_line",
    "drift",
    "negligible_growth",
    "forced_part",
    "repeated_kick",
    "clipped",
    "start_given",
    "no_static_level",
    "fundamental_ambiguous",
    "baseline_drift",
)
#: The flags that say the fundamental may be wrong (or that there is none); the others
#: describe the record and what was done with it (a wrong fundamental carrying only those is
#: silently wrong).
WARNING_FLAGS = frozenset({
    "no_mode", "few_periods", "low_snr", "unstable", "nonlinear", "aliasing", "numerical",
    "relaxation", "fundamental_ambiguous",
})  # fmt: skip
#: ``Mode.kind``: a mode of the structure, or a component set aside (never the fundamental).
MODE_KINDS = ("mode", "line", "drift", "trend", "transient")
MIN_SAMPLES = 16

#: Thresholds of the flags (documented in the messages).
FEW_PERIODS = 2.0  # fundamental periods in the record below which "few_periods" is raised
LOW_SNR_DB = 20.0  # fundamental's record-integrated SNR (energy / noise variance) in dB
NONLINEAR_Z = 5.0  # half-record frequency drift, in combined standard errors
ALIAS_FRACTION = 0.8  # fraction of the Nyquist frequency above which energy is an alias risk
#: Combination tones: |omega_k - (omega_i +- omega_j)| within COMBINATION_Z combined standard
#: errors, or within COMBINATION_REL x (omega_i +- omega_j) when the record is so clean that the
#: standard errors are below the model error of a nonlinear response (whose frequencies drift
#: with the decaying amplitude).
COMBINATION_Z = 4.0
COMBINATION_REL = 2e-3
#: ... or within this fraction of the candidate's own decay rate (half linewidth): a broad line's
#: fitted frequency moves by a fraction of its width when the model misses other tones.
COMBINATION_WIDTH = 0.1
#: An overdamped mode whose slow decay rate is gamma_i + gamma_j of two stronger modes within
#: this relative tolerance is their zero-frequency difference tone (a decaying mean shift).
COMBINATION_RATE_REL = 0.25
#: Slow components (see :func:`service.analysis.detect._modes._trends`): a mode whose undamped
#: rate ``sqrt|sigma^2|`` times the record length ``T`` is below this (less than one cycle of
#: its undamped frequency, ``2 pi`` radians) is a candidate trend; it is set aside when what a
#: quadratic trend ``a + b t + c t^2`` cannot absorb of it is below the detection threshold of a
#: mode (``ORDER_PENALTY ln N`` noise variances).
TREND_RADIANS = 2.0 * math.pi
#: A pole grows significantly when its real part is above this many standard errors.
GROWTH_Z = 3.0
#: Relative numerical noise floor: the noise std is never taken below this fraction of the
#: record's rms (float64 arithmetic on Gram matrices resolves residual energies to about
#: ``1e-16 x`` the record's energy; a noise-free record must not make rounding significant).
NOISE_FLOOR = 1e-7
#: Relative resolution of a residual sum of squares computed from a Gram matrix (a few ulps of
#: the record's energy ``sum y^2``): two fits whose RSS differ by less are equally good.
RSS_TOL = 64 * 2.220446049250313e-16
#: The same as a noise-variance floor in the normalised units of the record (rms 1).
S2_FLOOR = NOISE_FLOOR * NOISE_FLOOR
#: Detection thresholds of a mode (the trade between weak modes kept and false modes; see
#: ``bench/detector_weak.py`` and docs/charts.md for the measured trade). Candidate peaks of
#: the periodograms are significant at this false-alarm probability per record (white noise),
PEAK_FALSE_ALARM = 1e-3
#: and a mode is kept when it lowers the residual sum of squares by more than this many
#: ``ln N`` noise variances (MDL: ``(k / 2) ln N`` for its ``k = 4`` parameters, doubled
#: because the RSS is compared in noise variances, ``2 x`` the log-likelihood).
ORDER_PENALTY = 4.0


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
        Standard errors (same units); on a lab window the sandwich's where larger
        (module ``_uncertainty``: misfit, coloured residual, censored samples).
    regime : str
        ``"underdamped"`` or ``"overdamped"``.
    real_poles : tuple of float or None
        Overdamped mode: its two real poles ``(-r1, -r2)`` (slow first), 1 per time unit.
    real_amplitudes : tuple of float or None
        Overdamped mode: ``(b1, b2)`` in ``b1 exp(-r1 t) + b2 exp(-r2 t)``.
    snr_db : float
        Record SNR of this mode: ``10 log10(energy / noise variance)``, where the energy is the
        rise of the residual sum of squares when the mode is removed (others re-fitted). For a
        lone mode this is the per-sample SNR ``A^2 / (2 s^2)`` plus ``10 log10(N_eff)`` with
        ``N_eff = sum_n exp(-2 gamma n dt)`` the effective number of samples.
    combination : str or None
        Set when the mode is a combination tone of stronger modes (its frequency is a sum or
        difference of theirs, or twice one of them, within the tolerance of
        :data:`COMBINATION_Z`), e.g. ``"omega[2] - omega[1]"`` with indices into
        ``Detection.modes``. Such a mode is never the fundamental.
    kind : str
        ``"mode"`` (of the structure), or set aside and never the fundamental: ``"line"``
        (a stationary line: mains hum, a line present before the kick or with zero decay),
        ``"drift"`` (a slow baseline not kicked from rest beside a ringing mode) or
        ``"trend"`` (slower than the record, flag ``trend``) or ``"transient"`` (dies early
        in the record beside a ringing mode: the hammer's contact, flag ``forced_part``).
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
    combination: str | None = None
    kind: str = "mode"


@dataclass(frozen=True)
class Fundamental:
    """The fundamental: a :class:`Mode` of ``Detection.modes`` and its index there.

    The fundamental is the significant mode with the smallest ``|sigma^2|`` that is neither a
    combination tone of stronger modes nor a slow trend (flag ``"trend"``). Its attributes are
    those of the mode (read through).

    Attributes
    ----------
    mode : Mode
        The mode itself.
    index : int
        Its position in ``Detection.modes`` (0: the fundamental is listed first).
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
    """

    mode: Mode
    index: int = 0

    @property
    def omega(self) -> float:
        return self.mode.omega

    @property
    def omega_std(self) -> float:
        return self.mode.omega_std

    @property
    def sigma2(self) -> float:
        return self.mode.sigma2

    @property
    def sigma2_std(self) -> float:
        return self.mode.sigma2_std

    @property
    def damping(self) -> float:
        return self.mode.damping

    @property
    def damping_std(self) -> float:
        return self.mode.damping_std

    @property
    def regime(self) -> str:
        return self.mode.regime

    @property
    def poles(self) -> tuple[float, float] | None:
        return self.mode.real_poles


@dataclass(frozen=True)
class Detection:
    """Result of :func:`detect`.

    Attributes
    ----------
    modes : tuple of Mode
        Significant modes, sorted by increasing ``|sigma^2|``, the fundamental first (a
        slower trend, flag ``"trend"``, comes after it).
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
        Samples analysed (from ``start`` to the end of the record, or to a later kick).
    dt : float
    kind : str
    iterations : int
        Levenberg-Marquardt iterations of the final fit (0 for the non-iterative methods).
    start : int
        Index of the first sample analysed: 0, or the kick after a quiet pre-trigger (flag
        ``"pretrigger"``), after a hammer's contact (``"forced_part"``), a clipped run
        (``"clipped"``) or at the user's start (``"start_given"``); amplitudes and phases are
        at that sample (time ``start * dt``).
    quantity : str
        ``"displacement"`` (default), ``"velocity"`` or ``"acceleration"``: what the record
        measures; only a displacement has a static level (else NaN, flag
        ``no_static_level``).
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
    start: int = 0
    quantity: str = "displacement"

    @property
    def flag_codes(self) -> tuple[str, ...]:
        return tuple(f.code for f in self.flags)
