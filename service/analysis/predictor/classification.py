"""Classify the shape transition ahead of an upward sweep of the control parameter.

From measurements along the stable branch (control ``mu``, undamped eigenvalue ``sigma2`` of the
fundamental, optionally the static deflection ``w_static`` at the probe) estimate jointly the
transition point ``mu*`` and the exponents of

    sqrt|sigma^2| ~ |mu* - mu|^a,        |w - w*| ~ |mu* - mu|^b          (paper, Sec. "Asymptotic
                                                                           analysis", eq. expansion)

and decide between the candidates (paper, Secs. "Analysis of the amplitude equations" and
Appendix "Over-damped boundary layer"):

=========================  =====  =====  ====================================================
transition                  a      b      leading law on the measured (stable) branch
=========================  =====  =====  ====================================================
saddle-node                 1/4    1/2    sigma^2 ~ -x^(1/2), w - w* ~ x^(1/2)   (fold)
subcritical-pitchfork       1/2    1      sigma^2 ~ -x,       w - w* ~ x         (smooth branch)
supercritical-pitchfork     1/2    1/2    sigma^2 ~ -x,       w - w* ~ x^(1/2)   (side branch)
=========================  =====  =====  ====================================================

with ``x = mu* - mu > 0``. Inside the over-damped boundary layer ``x < xi^(1/a)`` the observed
time scale (FFT period, slow decay rate) follows the doubled exponent ``2a``; the undamped
eigenvalue ``sigma^2 = -s1 s2`` (product of the two poles) does not.

The laws, their regular corrections, the windows and the model comparison are the shared
engine's (:mod:`.compare`; a pitchfork law there may also know a secondary fold
of the measured branch beyond mu*). This module takes the decision: the most probable
candidate is named only when its probability reaches ``min_probability``; otherwise the result
is ``"pitchfork"`` (both pitchforks together reach it) or ``"undetermined"``. Free-exponent fits
give ``a``, ``b`` and their standard errors.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field, replace

import numpy as np

from service.analysis.common import Flag
from service.analysis.errors import ParameterError
from service.analysis.predictor.cache import profile_memo
from service.analysis.predictor.compare import (
    CANDIDATES,
    ModelFit,
    analyse,
    free_exponent_a,
    free_exponent_b,
    probabilities,
)
from service.analysis.predictor.rules import MIN_T_RATIO, Evidence, withhold
from service.analysis.predictor.sweep import Sweep, average_repeats, prepare_sweep

__all__ = [
    "CANDIDATES",
    "MIN_T_RATIO",
    "REGIMES",
    "TRANSITIONS",
    "Classification",
    "Sweep",
    "classify",
    "classify_sweep",
    "prepare_sweep",
]

TRANSITIONS = (
    "saddle-node",
    "subcritical-pitchfork",
    "supercritical-pitchfork",
    "pitchfork",
    "undetermined",
)
REGIMES = ("underdamped", "overdamped")
# --------------------------------------------------------------------------------------------
# result
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Classification:
    """Result of :func:`classify`.

    Attributes
    ----------
    transition : str
        ``"saddle-node"``, ``"subcritical-pitchfork"``, ``"supercritical-pitchfork"``,
        ``"pitchfork"`` (criticality not told by the data) or ``"undetermined"``.
    a, a_std : float
        Free estimate of the time exponent, ``sqrt|sigma^2| ~ |mu* - mu|^a``, with its standard
        error (profile likelihood). Inside the over-damped layer (``omega`` data) this is the
        doubled, observed exponent.
    b, b_std : float
        Free estimate of the static exponent ``|w - w*| ~ |mu* - mu|^b``; NaN without
        ``w_static`` (flagged ``no_static_data``).
    mu_star, mu_star_std : float
        mu* (unit of ``mu``) of the most probable candidate; ``mu_star_std`` is the half-width of
        its 68 % profile interval.
    probabilities : dict of str to float
        Model probabilities (BIC weights) of the candidates; keys are transition names.
    regime : str
        ``"underdamped"`` or ``"overdamped"`` (the nearest points inside the boundary layer).
    flags : tuple of Flag
        Reasons to doubt the result.
    window : int
        Number of nearest points used (the informative window).
    damping : float
        Damping ``xi`` fitted (``omega`` data) or given; NaN when unknown.
    """

    transition: str
    a: float
    a_std: float
    b: float
    b_std: float
    mu_star: float
    mu_star_std: float
    probabilities: dict[str, float]
    regime: str
    flags: tuple[Flag, ...]
    window: int = 0
    damping: float = math.nan
    fits: tuple[ModelFit, ...] = field(default=(), repr=False, compare=False)


def classify(
    mu: Sequence[float] | np.ndarray | Sweep,
    sigma2: Sequence[float] | np.ndarray | None = None,
    *,
    sigma2_std: Sequence[float] | np.ndarray | None = None,
    omega: Sequence[float] | np.ndarray | None = None,
    omega_std: Sequence[float] | np.ndarray | None = None,
    w_static: Sequence[float] | np.ndarray | None = None,
    w_static_std: Sequence[float] | np.ndarray | float | None = None,
    damping: float | None = None,
    min_probability: float = 0.9,
) -> Classification:
    """Classify the transition ahead of a sweep and estimate mu*, a and b jointly.

    Parameters
    ----------
    mu : array_like, shape (n,), or Sweep
        Control parameter along the upward sweep, strictly increasing, n >= 3, any unit; or a
        sweep already prepared by :func:`prepare_sweep` (the other data arguments are then
        ignored).
    sigma2 : array_like, shape (n,), optional
        Undamped eigenvalue of the fundamental mode (1/time^2), negative on the stable branch
        (e.g. ``-s1 s2`` from a pole detector). Give this or ``omega``.
    sigma2_std : array_like, shape (n,), optional
        Standard deviation of ``sigma2``. Without it the relative noise is estimated from the
        scatter about the best law on the nearest points and about local cubics along the
        sweep (flag ``noise_estimated``).
    omega : array_like, shape (n,), optional
        Observed angular rate (rad/time): the pole modulus ``sqrt(-sigma^2)`` when under-damped
        (the FFT peak when ``xi << omega``), the slow decay rate when over-damped. Inside the
        boundary layer these follow the doubled exponent; without ``damping`` it is fitted, and
        kept only on decisive evidence (an over-damped layer near mu* with under-damped points
        beyond it, fitting far better than one more correction term): a fold's slow rate in
        the layer grows like a pitchfork's frequency, so rates alone rarely prove a damping.
    omega_std : array_like, shape (n,), optional
        Standard deviation of ``omega``.
    w_static : array_like, shape (n,), optional
        Static deflection at the probe of each equilibrium (tells b, hence the criticality of a
        pitchfork).
    w_static_std : array_like or float, optional
        Its standard deviation (unknown: profiled out).
    damping : float, optional
        Damping ``xi`` (1/time) when known; sets the regime (over-damped when the nearest
        ``|sigma^2| < xi^2 / 4``).
    min_probability : float
        Probability the best candidate needs to be named; below it the result is
        ``"pitchfork"`` (when both pitchforks together reach it) or ``"undetermined"``.

    Returns
    -------
    Classification

    Raises
    ------
    ParameterError
        (a ValueError) Non-finite values, length mismatch, fewer than 3 points,
        non-increasing ``mu``, ``sigma2 >= 0``, non-positive standard deviations.

    Notes
    -----
    Laws fitted (``x = mu* - mu``): ``|sigma^2| = x^(2a) sum_k c_k x^(k h)`` and
    ``w = w* + sum_j g_j x^(e_j)`` (paper, eqs. saddleGrowthRate, pitchforkGrowthRate,
    saddleEquilibriums, pitchforkEquilibriums, with regular corrections).
    """
    _check_probability(min_probability)
    if isinstance(mu, Sweep):
        return classify_sweep(mu, min_probability=min_probability)
    mu, v, sd, repeats = average_repeats(
        mu, {"sigma2": sigma2, "omega": omega, "w_static": w_static},
        {"sigma2": sigma2_std, "omega": omega_std, "w_static": w_static_std},
    )  # fmt: skip
    sw0 = prepare_sweep(
        mu,
        v["sigma2"],
        sigma2_std=sd["sigma2"],
        omega=v["omega"],
        omega_std=sd["omega"],
        w_static=v["w_static"],
        w_static_std=sd["w_static"],
        damping=damping,
    )
    out = classify_sweep(sw0, min_probability=min_probability)
    return out if repeats is None else replace(out, flags=(*out.flags, repeats))


def _check_probability(min_probability: float) -> None:
    if not 0.0 < min_probability <= 1.0:
        raise ParameterError(
            "min_probability", min_probability,
            f"min_probability must be in (0, 1], got {min_probability!r}",
        )  # fmt: skip


def _regime(sw: Sweep, flags: list[Flag]) -> str:
    """``"overdamped"`` when the nearest point lies in the over-damped boundary layer of the
    sweep's damping (flag ``overdamped``), else ``"underdamped"``."""
    if sw.damping is None or not sw.damping > 0:
        return "underdamped"
    if sw.kind == "omega":
        over = sw.omega is not None and bool(sw.omega[-1] < sw.damping / 2)
    else:
        over = bool(sw.y[-1] < sw.damping**2 / 4)
    if not over:
        return "underdamped"
    flags.append(
        Flag(
            "overdamped",
            f"the nearest points lie in the over-damped boundary layer (xi={sw.damping:.3g}"
            "): the observed time scale there follows the doubled exponent 2a",
        )
    )
    return "overdamped"


def _static_exponent(
    sw: Sweep, top: ModelFit, n_c: int, flags: list[Flag]
) -> tuple[float, float]:
    """The free static exponent b (and its standard error) at the best law's mu*; NaN without
    static data or with fewer than 5 informative points (flagged)."""
    if sw.w is None:
        flags.append(
            Flag(
                "no_static_data",
                "no w_static (or one that never varies, without its std): b and the "
                "criticality of a pitchfork unknown",
            )
        )
        return math.nan, math.nan
    n_w = max(top.n_w, n_c)
    if n_w < 5:
        flags.append(Flag("b_not_estimated", f"only {n_w} informative points for b"))
        return math.nan, math.nan
    return free_exponent_b(sw, top, n_w)


def _named(
    probs: dict[str, float], top: str, min_probability: float, flags: list[Flag]
) -> str:
    """The type the probabilities name: the best candidate at ``min_probability``, else
    ``"pitchfork"`` when the two pitchforks together reach it, else ``"undetermined"``."""
    p_top = probs[top]
    if p_top >= min_probability:
        return top
    p_pf = probs.get("subcritical-pitchfork", 0.0) + probs.get("supercritical-pitchfork", 0.0)
    flags.append(
        Flag(
            "ambiguous",
            f"the best candidate {top} has probability {p_top:.2f} < {min_probability}",
        )
    )
    return "pitchfork" if p_pf >= min_probability else "undetermined"


@profile_memo()
def classify_sweep(
    sw0: Sweep, *, min_probability: float = 0.9, level: float = 0.95
) -> Classification:
    """:func:`classify` on a prepared sweep (``level``: of the candidates' profile intervals).

    The candidates are fitted and compared (:func:`.compare.analyse`); the most
    probable is named when its probability reaches ``min_probability`` (or the two pitchforks'
    together, as ``"pitchfork"``), unless one of the withholding rules finds that
    the records cannot decide the type yet (the rules of stage ``"classification"`` of
    :data:`.rules.RULES`). Flags come in the order the steps raise them."""
    _check_probability(min_probability)
    sw, fits, n_c, flags = analyse(sw0, None, level)
    probs = probabilities(fits)
    top = fits[0]
    regime = _regime(sw, flags)
    # free exponent a (on the window, corrections of the best model)
    a_hat, a_se = free_exponent_a(sw, top, n_c)
    if regime == "overdamped" and sw.kind == "omega":
        a_hat, a_se = 2 * a_hat, 2 * a_se  # the observed (slow) time scale exponent
    b_hat, b_se = _static_exponent(sw, top, n_c, flags)
    transition = _named(probs, top.name, min_probability, flags)
    ev = Evidence(sw0, sw, fits, a_hat, a_se, regime)
    transition = withhold(transition, ev, "classification", flags)
    if not math.isfinite(a_se):
        flags.append(Flag("a_unbounded", "the exponent a is not bounded by the data"))
    if n_c < 5:
        flags.append(Flag("few_points_near", f"only {n_c} informative points near mu* (want >= 5)"))
    prof = top.profile
    flags.extend(prof.flags)
    mu_std = 0.5 * (prof.hi68 - prof.lo68)
    return Classification(
        transition=transition,
        a=float(a_hat),
        a_std=float(a_se),
        b=float(b_hat),
        b_std=float(b_se),
        mu_star=float(prof.mu_star),
        mu_star_std=float(mu_std),
        probabilities=probs,
        regime=regime,
        flags=tuple(flags),
        window=n_c,
        damping=float(sw.damping) if sw.damping is not None else math.nan,
        fits=tuple(fits),
    )
