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
    is the significant mode with the smallest ``|sigma^2|`` that is neither a combination tone
    nor a trend (a component that the record cannot tell from a quadratic drift).
    This is the maximum-likelihood estimator for white Gaussian noise, efficient (at the
    Cramer-Rao bound) above threshold; standard errors come from the Gauss-Newton covariance
    ``s^2 (J^T J)^-1`` of the fit.

``common_damping=True`` imposes the same ``p`` (``= xi = 2 gamma``) on every mode, the beam
model's damping; it lowers the variance when the model holds.

Lab records (``kind="impulse"``): a record may be a ``quantity`` = displacement, velocity or
acceleration (the same poles; the static level only from a displacement); the window of free
response is located first (a pre-trigger, the hammer's contact, a second kick, clipped samples:
flags below), lines seen before the kick (or given as ``notch``) are fitted as undamped modes,
and lines, drift and transients are set aside (``Mode.kind``) before the fundamental is chosen.
The user may give ``start`` (the free response's first sample, as a time) and ``notch``.
A record with none of these features is analysed exactly as before.

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
``unstable``           a mode grows: a pole with a positive real part beyond 3 standard errors,
                       ``sigma^2 > 0`` (a growing real pole), or an envelope that grows
                       (a growing oscillation, two growing real poles) at least 2x over the
                       record; the equilibrium is unstable (past the transition) or driven.
``trend``              slow components set aside: slower than the record (``sqrt|sigma^2| T
                       < 2 pi``) and, once a quadratic ``a + b t + c t^2`` is removed from
                       their waveform, below the detection threshold of a mode (``4 ln N``
                       noise variances): a drift, never the fundamental (no fundamental and
                       ``no_mode`` when every mode is one).
``nonlinear``          the fundamental's ``sigma^2`` differs between the two halves of the
                       record by more than 5 standard errors (amplitude-dependent frequency).
``aliasing``           significant energy or a mode above 0.8 x Nyquist.
``damping_unresolved`` (FFT methods) a peak no wider than the resolution.
``ambient``            the result comes from an autocorrelation fit (units of variance).
``numerical``          the static level could not be estimated.
``combination_tone``   a mode's frequency is a sum or difference of stronger modes' frequencies
                       (or twice one): a quadratic nonlinearity; it is marked
                       (``Mode.combination``) and never chosen as the fundamental.
``relaxation``         the fundamental is slow and looks like a relaxation of the sensor or of
                       the equilibrium (creep, temperature, a settling offset): overdamped but
                       not rising from rest as a kicked mode does, or less than one oscillation
                       in the record, beside a mode that rings; kept as the fundamental (near
                       the transition that is the physics), the message names the ringing mode.
``pretrigger``         (impulse) the record is quiet before the response (a scope's pre-trigger,
                       the strip at rest before the kick or a release): a lead-in of at least
                       2 % of the record below 5 % of the amplitude after it, 4x longer than
                       the rise; the record is analysed from the rise past 20 % of its
                       largest deviation (``Detection.start``). With hum or drift on the
                       lead-in (a lab's record), the lead-in is the part whose moving rms stays
                       below 35 % of the response's, and the analysis starts where the record
                       leaves the lead-in's band (module ``_lab``).
``stationary_line``    lines that do not decay (mains hum and its harmonics, any line present
                       before the kick or given by the user as ``notch``) are fitted and set
                       aside (``Mode.kind = "line"``); never the fundamental, never ``unstable``.
``drift``              beside a kicked ringing mode, a slower component that was not kicked
                       (already there in the lead-in before the kick, regressed on its
                       waveform extrapolated back; an overdamped one not starting from rest,
                       less than one oscillation in the record, fewer than 2 at below 15 %
                       of the ringing mode's amplitude:
                       an offset that settles, a ramp, a slow wobble) is set aside
                       (``Mode.kind = "drift"``); never the fundamental. A record whose
                       slowest mode grows beside a ringing one is refitted with its slope
                       removed (a ramp of the baseline).
``forced_part``        the hammer's contact: the first samples after the kick misfit while the
                       rest fits (cut, ``Detection.start`` moves past them), or a mode that
                       dies within the record beside a ringing one, or (a lab window) an
                       overdamped pair damped 100x harder than the ringing modes (``Mode.kind
                       = "transient"``); never the fundamental.
``repeated_kick``      later kicks in the record (the envelope jumps again, or a ringing line's
                       complex amplitude leaves a free decay's constant ratio): the first
                       ring-down is analysed, up to the next kick (``Detection.n_samples``).
``clipped``            samples held at the record's extreme in several runs (a saturated
                       sensor): censored data, each only known to lie beyond the range; the
                       fit reads the whole window with them replaced by their expected values
                       given the fit (EM for censored Gaussian data, module ``_censored``).
``negligible_growth``  a growing component that stays below 1 % of the largest amplitude over
                       the record (a by-product of the fit beside a loud ringing): not read as
                       ``unstable``.
``start_given``        the analysis starts at the user's ``start`` (no kick is located).
``no_static_level``    ``quantity`` is a velocity or an acceleration: the poles are the
                       structure's, the static level is NaN (only a displacement has one).
``fundamental_ambiguous`` (a record read through a lab window: a lead-in, a later kick,
                       clipped samples) the fundamental may not be the structure's: another
                       mode lies within 25 % of its frequency with at least 10 % of its
                       amplitude (one line split in several by a model that does not hold
                       over the window: a later kick or clipped samples inside it; or two
                       close modes), or it dies within the window (5 e-folds; 1 beside a
                       ringing mode 3x stronger) 3x faster than a ringing mode (a
                       transient), or does not decay beside a ringing mode
                       3x stronger (a line, a drift), or a stronger component up to 5x slower
                       was set aside as a line or a drift from fewer than 4 cycles, or a
                       slower oscillation of a cycle or more was set aside as a drift.
                       A warning: :data:`WARNING_FLAGS` lists the flags that say the
                       fundamental may be wrong; the others describe the record.
``baseline_drift``     (a displacement read through a lab window) the baseline moves: drift
                       set aside, the residual's block means scatter beyond noise (chi^2 at
                       1e-6 false alarm), or the level at rest before the kick differs from
                       the fitted static level by 5 standard errors. A sensor's offset cannot
                       be told from the static deflection: static_level is NaN (the sweep
                       then predicts from frequencies alone).

Detection limit: the record SNR of a mode is its energy over the noise variance,
``10 log10(A^2 N_eff / (2 s^2))`` = the per-sample SNR ``A^2 / (2 s^2)`` in dB plus
``10 log10(N_eff)``, ``N_eff = sum_n exp(-2 gamma n dt)`` (``Mode.snr_db``). A mode is kept when
its fitted energy exceeds the MDL threshold ``4 ln N`` noise variances (15.2 dB at N = 4000,
16.6 dB at N = 1e5); with the scatter of the fitted energy, a mode is kept in >= 95 % of records
from a record SNR of about 20 dB, at about 0.01 spurious modes per record (measured in the
tests). Weak modes that decay within the record are found in the periodograms of the record's
heads ``N/2, N/4, ...`` matched to their decay.

Normalisation: the record is divided by a power of two (exact) and by its rms inside, and
every computation runs in sample units, so the result is equivariant under ``w -> k w`` and
``t -> c t`` (rates scale as ``1/c``, amplitudes as ``k``, flags unchanged), with no overflow at
any finite magnitude. The noise level used for significance and standard errors is never
below :data:`NOISE_FLOOR` times the record's rms: on a noise-free record, rounding is not a mode.

Layout: ``_core`` (validation, normalisation, :func:`detect`), ``_methods`` (the method table
:data:`METHOD_TABLE`: a new method is a function and a row), ``_spectral`` (periodogram,
ESPRIT, FFT peak), ``_varpro`` (variable-projection Levenberg-Marquardt, MDL pruning),
``_modes`` (physical modes, combination tones, the fundamental), ``_flags``, ``_results``
(dataclasses, flag codes, thresholds). The hot loops are numba kernels in ``_kernels`` (fused
basis recurrences + Gram matrices, strided Hankel covariance, small symmetric eigensolvers); no
BLAS thread pool is involved in the fit itself.
"""

from service.analysis.detect._core import QUANTITIES, detect
from service.analysis.detect._methods import METHOD_TABLE, METHODS
from service.analysis.detect._results import (
    ALIAS_FRACTION,
    COMBINATION_RATE_REL,
    COMBINATION_REL,
    COMBINATION_WIDTH,
    COMBINATION_Z,
    FEW_PERIODS,
    FLAG_CODES,
    KINDS,
    LOW_SNR_DB,
    MIN_SAMPLES,
    MODE_KINDS,
    NOISE_FLOOR,
    NONLINEAR_Z,
    WARNING_FLAGS,
    Detection,
    Fundamental,
    Mode,
)

__all__ = [
    "METHODS",
    "METHOD_TABLE",
    "KINDS",
    "MODE_KINDS",
    "QUANTITIES",
    "FLAG_CODES",
    "WARNING_FLAGS",
    "MIN_SAMPLES",
    "FEW_PERIODS",
    "LOW_SNR_DB",
    "NONLINEAR_Z",
    "ALIAS_FRACTION",
    "COMBINATION_Z",
    "COMBINATION_REL",
    "COMBINATION_WIDTH",
    "COMBINATION_RATE_REL",
    "NOISE_FLOOR",
    "Mode",
    "Fundamental",
    "Detection",
    "detect",
]
