"""Predict the transition point mu* ahead of an upward sweep, with a 95 % interval and an alarm.

Two estimators:

* :func:`paper_rule` -- the paper's baseline (Discussion, Table 2), kept as published
  (:mod:`.paper_rule`, re-exported here).
* :func:`predict` -- a weighted least-squares fit of ``|sigma^2| = x^(2a) sum_k c_k x^(k h)``,
  ``x = mu* - mu`` (``h = 1/2`` near a fold, ``1`` near a pitchfork; see
  :mod:`service.analysis.classify`), over the informative window of nearest points, the number of
  correction terms chosen by a chi-square test, ``mu*`` profiled (variable projection) and the
  interval read from the profile likelihood and widened by the truncation spread
  (:mod:`.interval`). When neither ``a`` nor ``transition`` is given the
  candidates are averaged with their model probabilities.

The predictor is unit-agnostic: ``mu`` may be an angle, a load, a voltage; ``sigma2`` is in
1/time^2 of the recording.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from service.analysis.alarm import Alarm, alarm_for, next_measurement
from service.analysis.common import Flag, unique_flags
from service.analysis.errors import ParameterError
from service.analysis.predictor.cache import profile_memo
from service.analysis.predictor.classification import Classification
from service.analysis.predictor.cusp import assess
from service.analysis.predictor.imperfect import Verdict, decide
from service.analysis.predictor.interval import Fits, fit_sweep, interval
from service.analysis.predictor.paper_rule import PaperRule, check_exponent, paper_rule
from service.analysis.predictor.rules import Evidence, withhold
from service.analysis.predictor.sweep import (
    Sweep,
    average_repeats,
    drop_past,
    positive_1d,
    prepare_sweep,
)
from service.analysis.predictor.windows import _estimate_noise, _with_damping

__all__ = ["PaperRule", "Prediction", "bounded_by", "paper_rule", "predict"]

#: A table with both ``sigma2`` and ``omega``: the |sigma^2| they tell may differ by this many
#: standard deviations of their difference (the noises given, ``sigma2_std`` and ``omega_std``)
_AGREE_Z = 5.0
#: ... and always by this relative amount: the digits a table keeps (six significant digits
#: round omega^2 and sigma2 by up to 1.5e-5 together), the whole tolerance when no std is given
_AGREE_RTOL = 1e-4


# --------------------------------------------------------------------------------------------
# our estimator
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Prediction:
    """Result of :func:`predict`.

    Attributes
    ----------
    mu_star : float
        Predicted transition point (unit of ``mu``).
    mu_star_interval : tuple of float
        ``(lo, hi)`` interval at ``level`` (95 % by default); ``lo >= mu[-1]`` since every
        measured point was stable.
    mu_star_std : float
        Standard error (half-width of the 68 % profile interval; mixture spread when averaged).
    a : float
        Time exponent used (probability-weighted when averaged).
    method : str
        ``"profile-likelihood"`` (one law) or ``"model-average"`` (candidates weighted by their
        probabilities).
    alarm : Alarm
        The alarm at the last point (:class:`service.analysis.alarm.Alarm`): ``t_ratio``
        (``T / T0``, ``T = 1/sqrt|sigma^2|``), ``distance`` (``(mu* - mu[-1])`` in interval
        half-widths), ``level`` (``"none"``, ``"watch"`` (T > 3 T0), ``"warning"`` (T > 10 T0)
        or ``"critical"``: the interval's lower end within one half-width of the last point).
    next_safe_mu : float
        Suggested next measurement: ``mu[-1] + min(step_fraction * (bound - margin - mu[-1]),
        max_step_growth * (mu[-1] - mu[-2]))`` with ``bound`` the smaller of the interval's lower
        end and the model-free two-point ``sigma^4`` extrapolation; NaN with flag
        ``no_safe_step`` when that bound is not beyond the last point.
    flags : tuple of Flag
    transition : str
        Transition assumed or classified; ``"none"`` when the records are those of an imperfect
        stiffening structure that never loses stability (never a snap).
    probabilities : dict of str to float
        Candidate probabilities of the classification (one entry when the law was given);
        candidates above 1e-3 enter the average.
    window : int
        Number of informative (nearest) points used.
    n_terms : int
        Terms of the fitted law (leading + corrections) of the most probable candidate.
    baseline : PaperRule or None
        The paper's rule on the same measurements (``sigma2``, or the ``omega`` read as
        ``|sigma^2|``); None only when it cannot be computed (flag ``no_baseline`` says why).
    classification : Classification or None
        The classification used when the law was not given.
    least_sigma2, least_sigma2_mu : float
        Transition ``"none"`` (an imperfect stiffening pitchfork: no loss of stability): the
        least ``|sigma^2|`` the fitted law gives (1/time^2) and the control where it occurs
        (then also ``mu_star``, with its interval); NaN otherwise.

    Notes
    -----
    ``mu_star`` always lies inside ``mu_star_interval``, and every flag refers to them: a
    softening imperfect pitchfork's answer is its fold (transition ``"saddle-node"``), a
    stiffening one's the control of least stiffness (``"none"``).
    """

    mu_star: float
    mu_star_interval: tuple[float, float]
    mu_star_std: float
    a: float
    method: str
    alarm: Alarm
    next_safe_mu: float
    flags: tuple[Flag, ...]
    transition: str = "undetermined"
    probabilities: dict[str, float] = field(default_factory=dict)
    window: int = 0
    n_terms: int = 0
    baseline: PaperRule | None = None
    classification: Classification | None = field(default=None, repr=False, compare=False)
    least_sigma2: float = math.nan
    least_sigma2_mu: float = math.nan


@profile_memo()
def predict(
    mu: Sequence[float] | np.ndarray | Sweep,
    sigma2: Sequence[float] | np.ndarray | None = None,
    *,
    sigma2_std: Sequence[float] | np.ndarray | None = None,
    omega: Sequence[float] | np.ndarray | None = None,
    omega_std: Sequence[float] | np.ndarray | None = None,
    w_static: Sequence[float] | np.ndarray | None = None,
    w_static_std: Sequence[float] | np.ndarray | float | None = None,
    transition: str | None = None,
    a: float | None = None,
    damping: float | None = None,
    level: float = 0.95,
    step_fraction: float = 0.5,
    margin: float = 0.0,
    max_step_growth: float = 2.0,
) -> Prediction:
    """Predict mu* from measurements along an upward sweep.

    Parameters
    ----------
    mu : array_like, shape (n,), or Sweep
        Control parameter, strictly increasing, n >= 3, any unit; or a sweep prepared by
        :func:`service.analysis.classify.prepare_sweep` (the data arguments are then ignored).
    sigma2 : array_like, shape (n,), optional
        Undamped eigenvalue of the fundamental (1/time^2), negative. Give this or ``omega``
        (or both when they agree: see ``omega``).
    sigma2_std : array_like, shape (n,), optional
        Its standard deviation (weights of the fit); estimated from the scatter when absent.
    omega, omega_std : array_like, shape (n,), optional
        Observed rate (rad/time) instead of ``sigma2`` (see :func:`classify`): the modulus
        ``|s| = sqrt(omega_d^2 + (xi/2)^2)`` of the fundamental's poles ``s`` while it
        oscillates (``omega_d`` its damped frequency; detect's ``sigma2`` is ``-|s|^2``), its
        slow decay rate once over-damped. Given with ``sigma2``, the two must tell the same
        ``|sigma^2|`` on every row (``omega^2``, or ``omega (xi - omega)`` below ``xi/2`` with
        ``damping`` given; within :data:`_AGREE_Z` standard deviations of the noises given,
        and the relative :data:`_AGREE_RTOL`): ``sigma2`` is then used; else
        :class:`ParameterError` naming ``omega`` and the worst row.
    w_static, w_static_std : array_like, optional
        Static deflection at the probe (used by the classification).
    transition : str, optional
        ``"saddle-node"``, ``"subcritical-pitchfork"``, ``"supercritical-pitchfork"`` or
        ``"pitchfork"``: fit that law only.
    a : float, optional
        Time exponent of the law to fit (``|sigma^2| ~ x^(2a)``), > 0; with neither ``a`` nor
        ``transition`` the candidates are classified and averaged. Alone it fits that exponent
        (``transition`` of the result ``"saddle-node"`` for 1/4, ``"pitchfork"`` for 1/2,
        else ``"custom"``); with a named ``transition`` it must be that law's ``a`` or its
        over-damped double (any ``a`` with ``"pitchfork"``).
    damping : float, optional
        Damping ``xi`` (1/time) when known: the records' envelope decays as
        ``exp(-xi t / 2)`` (twice the decay rate that detect reports as ``damping``).
    level : float
        Confidence level of ``mu_star_interval`` (0.95).
    step_fraction, margin, max_step_growth : float
        The next-measurement policy (:func:`service.analysis.alarm.next_measurement`): a
        fraction of the way to the safe bound, a distance kept below it, the trust region.

    Returns
    -------
    Prediction

    Raises
    ------
    ParameterError
        (a ValueError) Invalid measurements (see :func:`classify`), ``sigma2`` and ``omega``
        that disagree (``.parameter == "omega"``), ``a <= 0``, unknown ``transition``,
        ``level`` or ``step_fraction`` outside (0, 1), ``margin < 0``.
    """
    _check_policy(level, step_fraction, margin, max_step_growth)
    if a is not None:
        a = check_exponent(a)
    past = None  # the control of the first row past the transition (sigma2 >= 0 from there)
    repeats = None
    if isinstance(mu, Sweep):
        sw0 = mu
    else:
        mu, v, sd, repeats = average_repeats(
            mu, {"sigma2": sigma2, "omega": omega, "w_static": w_static},
            {"sigma2": sigma2_std, "omega": omega_std, "w_static": w_static_std},
        )  # fmt: skip
        sigma2, omega, w_static = v["sigma2"], v["omega"], v["w_static"]
        sigma2_std, omega_std, w_static_std = sd["sigma2"], sd["omega"], sd["w_static"]
        past, mu, sigma2, (sigma2_std, w_static, w_static_std, omega, omega_std) = drop_past(
            mu, sigma2, sigma2_std, w_static, w_static_std, omega, omega_std
        )
        both = sigma2 is not None and omega is not None  # sigma2 is used once omega agrees
        sw0 = prepare_sweep(
            mu, sigma2, sigma2_std=sigma2_std, omega=None if both else omega,
            omega_std=None if both else omega_std, w_static=w_static,
            w_static_std=w_static_std, damping=damping,
        )  # fmt: skip
        if both:
            _check_rates_agree(sw0, omega, omega_std)
    fit = fit_sweep(sw0, transition, a, level)
    flags = list(fit.flags) + ([repeats] if repeats is not None else [])
    m, std, lo, hi = interval(sw0, fit, level, flags)
    verdict = _imperfect(sw0, fit, (m, std, lo, hi), level) if past is None else None
    if verdict is not None:
        m, std, lo, hi = verdict.mu_star, verdict.std, verdict.lo, verdict.hi
        flags.extend(verdict.flags)
    last = float(sw0.mu[-1])
    m = min(max(m, lo), hi)  # the headline inside its interval (see _imperfect, interval)
    # T/T0 as sqrt(y0) / sqrt(y): the same float as the pipeline's omega0 / omega
    t_ratio = float(math.sqrt(sw0.y[0]) / math.sqrt(sw0.y[-1]))
    # type none (no loss of stability) is never a snap alarm
    none = verdict is not None and verdict.transition == "none"
    alarm = alarm_for(last, t_ratio, m, (lo, hi), transition="none" if none else None)
    if past is not None:  # stepped past the transition: it lies below that row
        m, lo, hi = min(m, past), min(lo, past), min(hi, past)
        alarm = _past_alarm(past, t_ratio, m, lo, hi, flags)
    if t_ratio < 2.0:
        flags.append(
            Flag(
                "slowdown_not_reached",
                f"T/T0 = {t_ratio:.3g} < 2: the critical slowing down has barely begun, the "
                "asymptotic laws may not hold yet and the interval can be over-confident",
            )
        )
    # the next measurement: a fraction of the way to the interval's lower end, never beyond the
    # model-free sigma^4 bound of the last pair and never more than max_step_growth times the
    # last step (an interval whose lower end is at the last point leaves the model-free bound
    # alone in charge)
    nxt = next_measurement(
        sw0.mu, sw0.y, trusted_bound=lo if lo > last else None, margin=margin,
        step_fraction=step_fraction, max_step_growth=max_step_growth,
    )  # fmt: skip
    if not math.isfinite(nxt.mu):
        flags.append(
            Flag(
                "no_safe_step",
                f"the safe bound {nxt.bound:.6g} (interval's lower end or the model-free sigma^4 "
                f"bound, minus margin {margin:g}) is not beyond the last measured mu={last:.6g}",
            )
        )
    a_used = float(np.sum(np.array(fit.probs) * np.array([f.a for f in fit.fits])) /
                   np.sum(fit.probs))  # fmt: skip
    if verdict is not None and verdict.a is not None:
        a_used = verdict.a
    baseline = _baseline(sw0, a_used, flags)
    if not math.isfinite(m):
        flags.append(Flag("no_estimate", "no finite mu* could be estimated"))
    cls = fit.classification
    transition = fit.name
    probs = dict(cls.probabilities) if cls is not None else {}
    if cls is not None and not (verdict is not None and verdict.decided):
        # a transition the caller gave is never withheld
        ev = Evidence(sw0, sw0, cls.fits, probabilities=probs)
        transition = withhold(transition, ev, "prediction", flags)
    if verdict is not None and verdict.transition is not None:
        transition = verdict.transition
    shown = verdict.probabilities if verdict is not None else None
    flags = _consistent(flags, m, lo, hi, last)
    return Prediction(
        mu_star=float(m),
        mu_star_interval=(float(lo), float(hi)),
        mu_star_std=float(std),
        a=a_used,
        method=fit.method,
        alarm=alarm,
        next_safe_mu=float(nxt.mu),
        flags=tuple(unique_flags(flags)),
        transition=transition,
        probabilities=(
            dict(shown)
            if shown is not None
            else dict(cls.probabilities)
            if cls is not None
            else {f.name: float(p) for f, p in zip(fit.fits, fit.probs, strict=True)}
        ),
        window=int(fit.window),
        n_terms=int(fit.fits[int(np.argmax(fit.probs))].K + 1),
        baseline=baseline,
        classification=cls,
        least_sigma2=verdict.least_sigma2 if verdict is not None else math.nan,
        least_sigma2_mu=verdict.least_mu if verdict is not None else math.nan,
    )


#: the perfect laws' flags that say they misfit their records: only then can an imperfect law
#: be told or a type be withheld for it
_MISFIT = ("law_misfit", "noise_underestimated", "poor_fit", "exponent_off")


def _imperfect(sw0: Sweep, fit: Fits, answer: tuple[float, ...], level: float) -> Verdict | None:
    """The imperfect pitchforks weighed against the perfect answer
    (:func:`service.analysis.predictor.imperfect.decide`) whenever the law was classified (a
    perfect fold law named on an imperfect column's records can be late: its far records are
    a pitchfork's); None otherwise."""
    cls = fit.classification
    if cls is None:
        return None
    probs = cls.probabilities
    # the records' own noise when given (a rescaled noise hides the misfit that tells an
    # imperfection), else estimated; rates read with the damping given, never one inferred
    # (an imperfect fold's slow rates can pass for an over-damped layer)
    sw = sw0
    if sw.kind == "omega" and sw.damping is not None:
        sw = _with_damping(sw, sw.damping)
    if not sw.noise_given:
        sw = _estimate_noise(sw)
    imp = assess(sw, level)
    if imp is None:
        return None
    misfit = any(f.code in _MISFIT for f in fit.flags)
    return decide(imp, fit.name, dict(probs), answer, level, misfit=misfit)


def _baseline(sw0: Sweep, a: float, flags: list[Flag]) -> PaperRule | None:
    """The paper's rule on the sweep (its ``|sigma^2|``, from ``omega`` too); None with the
    flag ``no_baseline`` naming why when it cannot be computed."""
    try:
        return paper_rule(sw0.mu, -sw0.y, a)
    except ParameterError as exc:
        flags.append(Flag("no_baseline", f"the paper's rule cannot be computed: {exc}"))
        return None


def _consistent(flags: list[Flag], m: float, lo: float, hi: float, last: float) -> list[Flag]:
    """The flags that still hold of the final ``mu*`` and interval: a candidate's
    ``mu_star_at_last_point`` or ``interval_reaches_last_point`` is dropped when the answer's
    mu* (or interval) lies clear of the last measured control; ``interval_huge`` quotes the
    final interval (or goes when it no longer holds)."""
    tol = 1e-9 * max(abs(last), 1.0)
    out = []
    for f in flags:
        if f.code == "mu_star_at_last_point" and m - last > tol:
            continue
        if f.code == "interval_reaches_last_point" and lo - last > tol:
            continue
        if f.code == "interval_huge":
            half = 0.5 * (hi - lo)
            if not (half > 0.5 * max(m - last, 0) or any(
                    g.code == "interval_unbounded" for g in flags)):  # fmt: skip
                continue
            f = Flag(f.code, f"the {f.message.split('%')[0].split()[-1]}% interval [{lo:.6g}, "
                     f"{hi:.6g}] is wider than the distance to mu* ({m - last:.3g})")  # fmt: skip
        out.append(f)
    return out


def bounded_by(pred: Prediction, past: float) -> Prediction:
    """``pred`` with mu* and its interval ended at ``past``, the control of a record that grew
    (the strip was unstable there: mu* lies below it)."""
    lo, hi = pred.mu_star_interval
    if not (pred.mu_star > past or hi > past):
        return pred
    return replace(pred, mu_star=min(pred.mu_star, past),
                   mu_star_interval=(min(lo, past), min(hi, past)))  # fmt: skip


def _past_alarm(
    past: float, t_ratio: float, m: float, lo: float, hi: float, flags: list[Flag]
) -> Alarm:
    """The critical alarm (and flag) of a table whose last rows are past the transition."""
    flags.append(
        Flag(
            "past_transition",
            f"sigma2 >= 0 from mu={past:.6g} on: the strip is unstable there, past its "
            "transition; those rows are left out of the fit, and mu* and its interval end "
            "there",
        )
    )
    reason = f"sigma2 >= 0 at mu={past:.6g}: past the transition there"
    return Alarm("critical", reason, past, t_ratio, m, (lo, hi), math.nan)


def _check_rates_agree(sw: Sweep, omega: Any, omega_std: Any) -> None:
    """Refuse rates ``omega`` given beside ``sigma2`` (the sweep ``sw``) that tell another
    ``|sigma^2|`` on some row.

    The relation is the one the predictor reads rates by (:func:`prepare_sweep`; with a damping
    ``xi``, ``windows._with_damping``): while the fundamental oscillates its
    poles ``s1, s2`` are complex conjugates and ``omega = |s|`` gives ``|sigma^2| = s1 s2 =
    omega^2`` whatever the damping; with ``damping`` given, a rate below ``xi/2`` is the slow
    over-damped pole, ``|sigma^2| = omega (xi - omega)``. Without ``damping`` every rate is read
    as ``omega^2`` (a damping is not inferred from ``sigma2`` data). The two may differ by
    ``_AGREE_Z`` standard deviations of their difference (``sigma2_std`` and ``omega_std`` as
    given, a missing one counting as none) and, always, by the relative ``_AGREE_RTOL``.

    Parameters
    ----------
    sw : Sweep
        The validated ``sigma2`` sweep (rows past the transition already cut).
    omega, omega_std : array_like, shape (n,) or None
        The rates (rad/time, > 0) and their standard deviations (> 0).

    Raises
    ------
    ParameterError
        ``omega`` or ``omega_std`` invalid (not finite, <= 0, another length), or ``omega`` at
        odds with ``sigma2``: ``.parameter == "omega"``, ``.value`` the rate of the worst row.
    """
    n = sw.mu.size
    om = positive_1d("omega", omega, n)
    om_sd = positive_1d("omega_std", omega_std, n) if omega_std is not None else None
    xi = sw.damping
    over = om < xi / 2 if xi is not None else np.zeros(n, dtype=bool)
    with np.errstate(over="ignore", invalid="ignore"):
        y_om = np.where(over, om * ((xi or 0.0) - om), om**2)
        var = sw.sd**2 if sw.noise_given else np.zeros(n)
        if om_sd is not None:
            slope = np.where(over, np.abs((xi or 0.0) - 2 * om), 2 * om)
            var = var + (slope * om_sd) ** 2 + 2 * om_sd**4
        allowed = np.maximum(_AGREE_Z * np.sqrt(var), _AGREE_RTOL * np.maximum(sw.y, y_om))
        allowed = np.maximum(allowed, np.finfo(float).tiny)  # below it floats cannot differ
        excess = np.abs(sw.y - y_om) / allowed
    excess = np.where(np.isnan(excess), np.inf, excess)  # omega^2 overflowed: no agreement
    if not np.any(excess > 1):
        return
    i = int(np.argmax(excess))
    tol = (
        f"{_AGREE_Z:g} standard deviations of sigma2_std and omega_std (and {_AGREE_RTOL:g} "
        "relative)"
        if sw.noise_given or om_sd is not None
        else f"the relative tolerance {_AGREE_RTOL:g} (no sigma2_std or omega_std given)"
    )
    law = (
        f"-omega (xi - omega) = {-float(y_om[i])!r} (over-damped: omega < xi/2 = {xi / 2:g})"
        if over[i] and xi is not None
        else f"-omega^2 = {-float(y_om[i])!r}"
    )
    raise ParameterError(
        "omega", float(om[i]),
        f"sigma2 and omega disagree: at row {i} (mu={float(sw.mu[i])!r}) sigma2[{i}]="
        f"{-float(sw.y[i])!r} but omega[{i}]={float(om[i])!r} gives sigma2 = {law}, beyond "
        f"{tol}; {int(np.sum(excess > 1))} of {n} rows disagree. Give one of the two columns, "
        "or columns that agree: omega is the modulus sqrt(omega_d^2 + gamma^2) of the "
        "fundamental's poles (not the damped frequency omega_d alone), and its slow decay rate "
        "once over-damped" + (" (then give the damping xi)" if xi is None else ""),
    )  # fmt: skip


def _check_policy(level: float, step_fraction: float, margin: float, growth: float) -> None:
    if not 0 < level < 1:
        raise ParameterError("level", level, f"level must be in (0, 1), got level={level!r}")
    if not 0 < step_fraction < 1:
        raise ParameterError(
            "step_fraction", step_fraction,
            f"step_fraction must be in (0, 1), got step_fraction={step_fraction!r}",
        )  # fmt: skip
    if not (math.isfinite(margin) and margin >= 0):
        raise ParameterError(
            "margin", margin, f"margin must be finite and >= 0, got margin={margin!r}"
        )
    if not (math.isfinite(growth) and growth > 0):
        raise ParameterError(
            "max_step_growth", growth,
            f"max_step_growth must be > 0, got max_step_growth={growth!r}",
        )  # fmt: skip
