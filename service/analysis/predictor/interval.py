"""mu* and its interval: the fits a prediction rests on and the uncertainty read from them.

* :func:`fit_sweep` -- the law given, or the classification's candidates each refitted on its
  own informative window and weighted with their probabilities (:class:`Fits`);
* :func:`interval` -- the profile-likelihood interval of one law, or the mixture of the
  candidates' intervals, each with its fewer-terms rival weighed in (the number of
  corrections is chosen on the data), widened by the truncation spread: the bias of mu* that
  the less-truncated neighbouring fits reveal (:func:`_truncation_spread`), and for a fold's
  law at its correction limit the term it drops carried in (:func:`_next_term`).

Used by :func:`service.analysis.predict.predict`.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy import optimize

from service.analysis.common import Flag
from service.analysis.errors import ParameterError
from service.analysis.predictor._dist import chi2_ppf, norm_cdf, norm_ppf
from service.analysis.predictor.classification import Classification, classify_sweep
from service.analysis.predictor.compare import (
    CANDIDATES,
    ModelFit,
    analyse,
    fewer_terms_rival,
    refit_profile,
)
from service.analysis.predictor.sweep import Sweep

__all__ = ["Fits", "fit_sweep", "interval"]

_FLOOR = 0.05  # least weight of a candidate while the type is not named for lack of slowdown


@dataclass(frozen=True)
class Fits:
    """The fits that enter the prediction (one law, or the candidates with their weights)."""

    fits: tuple[ModelFit, ...]
    probs: tuple[float, ...]
    sweeps: tuple[Sweep, ...]
    name: str
    window: int
    method: str
    flags: tuple[Flag, ...]
    classification: Classification | None
    point_probs: tuple[float, ...] = ()  # weights of the point estimate (no floor)


def _law_for(transition: str | None, a: float | None) -> tuple[str, float, float | None, float]:
    """(name, a, b, h) of the law to fit when the caller fixed it."""
    if transition is not None:
        if transition in CANDIDATES:
            aa, bb, h = CANDIDATES[transition]
            if a is not None and abs(a - aa) > 1e-12 and abs(a - 2 * aa) > 1e-12:
                raise ParameterError(
                    "a", a,
                    f"a={a!r} contradicts transition={transition!r} (a={aa:g}, or {2 * aa:g} "
                    "over-damped)",
                )  # fmt: skip
            return transition, (aa if a is None else a), bb, h
        if transition == "pitchfork":
            return "pitchfork", (0.5 if a is None else a), None, 1.0
        raise ParameterError(
            "transition", transition,
            f"transition must be one of {sorted([*CANDIDATES, 'pitchfork'])}, got "
            f"transition={transition!r}",
        )  # fmt: skip
    assert a is not None
    name = "saddle-node" if abs(a - 0.25) < 1e-12 else ("pitchfork" if a == 0.5 else "custom")
    h = 0.5 if name == "saddle-node" else 1.0
    return name, a, None, h


def fit_sweep(sw0: Sweep, transition: str | None, a: float | None, level: float) -> Fits:
    """Fit the law given, or classify and refit each probable candidate on its own window."""
    if a is None and transition is None:
        cls = classify_sweep(sw0, level=level)
        # each candidate that matters is refitted on its own informative window (the
        # classification compares them on a common one) and averaged with its probability.
        # mu* comes from the eigenvalue law alone: the static law, fitted over its wider window,
        # tells b but biases mu* (measured on the beam: rmse 5.4e-8 with it, 2.3e-8 without,
        # and 90 % instead of 95 % coverage)
        # before the slowdown has shown (no type named), every candidate keeps at least
        # _FLOOR of the weight: the interval then covers each type's mu*
        # (or while a fold explains the records as well as the pitchfork named: the fold's mu*,
        # before the pitchfork's, must stay inside)
        slow = any(f.code in ("slowdown_not_reached", "fold_indistinct", "exponent_undecided")
                   for f in cls.flags)  # fmt: skip
        fits, probs, sweeps, point = [], [], [], []
        for f in cls.fits:
            pr = max(cls.probabilities[f.name], _FLOOR if slow else 0.0)
            if pr <= 1e-3:
                continue
            point.append(cls.probabilities[f.name])
            sw_fit, own, _, _ = analyse(sw0, (f.name, f.a, None, f.h), level)
            fits.append(own[0])
            sweeps.append(sw_fit)
            probs.append(pr)
        flags = [f for f in cls.flags if f.code != "no_static_data"]
        method = "model-average" if len(fits) > 1 else "profile-likelihood"
        return Fits(tuple(fits), tuple(probs), tuple(sweeps), cls.transition, cls.window,
                    method, tuple(flags), cls, tuple(point))  # fmt: skip
    name, aa, _, hh = _law_for(transition, a)
    sw_fit, fits, window, fl = analyse(sw0, (name, aa, None, hh), level)
    flags = [*fl, *fits[0].profile.flags]
    if window < 5:
        flags.append(
            Flag("few_points_near", f"only {window} informative points near mu* (want >= 5)")
        )
    return Fits((fits[0],), (1.0,), (sw_fit,), name, window, "profile-likelihood",
                tuple(flags), None)  # fmt: skip


def _mixture(
    fits: Sequence[ModelFit], probs: Sequence[float], level: float
) -> tuple[float, float, float, float]:
    """Mean, std and ``level`` quantile interval of a mixture of two-piece normals (one per
    candidate: centre mu*, left/right widths from its profile interval)."""
    z = float(norm_ppf(0.5 + level / 2))
    cs = np.array([f.profile.mu_star for f in fits])
    # widths floored at a few ulps of mu* (noise-free data give zero widths, and a mixture of
    # zero-width pieces has no bracket for the quantiles)
    floor = 8 * np.finfo(float).eps * np.maximum(np.abs(cs), 1.0)
    sl = np.maximum([(f.profile.mu_star - f.profile.lo) / z for f in fits], floor)
    sr = np.maximum([(f.profile.hi - f.profile.mu_star) / z for f in fits], floor)
    p = np.asarray(probs, dtype=float)
    p = p / p.sum()

    def cdf(v: float) -> float:
        left = 2 * sl / (sl + sr) * norm_cdf((v - cs) / sl)
        right = 2 * sl / (sl + sr) * 0.5 + 2 * sr / (sl + sr) * (
            norm_cdf((v - cs) / sr) - 0.5
        )
        return float(np.sum(p * np.where(v < cs, left, right)))

    lo_b = float(np.min(cs - 10 * sl))
    hi_b = float(np.max(cs + 10 * sr))
    q_lo = optimize.brentq(lambda v: cdf(v) - (0.5 - level / 2), lo_b, hi_b, xtol=1e-14)
    q_hi = optimize.brentq(lambda v: cdf(v) - (0.5 + level / 2), lo_b, hi_b, xtol=1e-14)
    s68 = np.array([0.5 * (f.profile.hi68 - f.profile.lo68) for f in fits])
    mean = float(np.sum(p * cs))
    std = float(math.sqrt(np.sum(p * (s68**2 + (cs - mean) ** 2))))
    return mean, std, q_lo, q_hi


_RICHARDSON = 2.0  # bias of the main fit over the bias its neighbours reveal


def _truncation_spread(sw: Sweep, fit: ModelFit) -> tuple[float, float]:
    """Downward and upward truncation bias of ``fit``'s mu*, read from neighbouring fits.

    The neighbours truncate less than ``fit``: one more correction term (same window or one
    point less), the window without its one, two or three farthest points or cut to half its
    size (same terms, and one more on the half window), a fold's series with two more terms on
    the same window; and, truncating more, the window one or two points larger (same terms).
    A neighbour's difference ``D = mu*_j - mu*`` carries noise as well as bias: only
    ``sqrt(D^2 - t^2)``, ``t^2 = |s_j^2 - s^2|`` (their 68 % half-widths; Hausman), counts as
    bias, and it is taken as ``_RICHARDSON`` times the largest one (a neighbour keeping half the
    bias: Richardson's extrapolation with ratio 1/2), on the side it points to. A fold's law at
    its truncation limit (``corrections_exhausted``) widens both sides by the larger windows'
    differences. The factor and the neighbours are measured in docs/predictor.md (ledger:
    "Truncation spread").
    """
    m0 = fit.profile.mu_star
    s0 = 0.5 * (fit.profile.hi68 - fit.profile.lo68)
    down = up = 0.0
    half = max(int(math.ceil(fit.n / 2)), 3)
    alternatives = {(fit.n, fit.K + 1), (fit.n - 1, fit.K + 1), (half, fit.K), (half, fit.K + 1)}
    if fit.h < 1:  # a fold's series: two more half-integer terms (see below)
        alternatives.add((fit.n, fit.K + 2))
    alternatives |= {(fit.n + d, fit.K) for d in (-3, -2, -1, 1, 2)}
    # a fold's half-integer series with every correction the law allows: see above
    at_limit = fit.corrections_exhausted and fit.h < 1
    for n2, K2 in sorted(alternatives):
        alt, s_alt = refit_profile(sw, fit, n2, K2)
        if not (math.isfinite(alt) and math.isfinite(s_alt) and math.isfinite(s0)):
            continue
        d = alt - m0
        bias = math.sqrt(max(d * d - abs(s_alt * s_alt - s0 * s0), 0.0))
        own = _RICHARDSON * bias
        other = own if (n2 > fit.n and at_limit) else 0.0
        if d < 0:
            down, up = max(down, own), max(up, other)
        else:
            down, up = max(down, other), max(up, own)
    return down, up


#: flags that say a law does not hold its window within the records' own noise (no
#: :func:`_next_term` there)
_NOT_HELD = ("noise_estimated", "noise_underestimated", "law_misfit", "poor_fit")


def _next_term(sw: Sweep, fit: ModelFit, level: float) -> tuple[float, float]:
    """The ``level`` interval of ``fit``'s mu* with the first term its series drops carried in:
    a fold's law at its correction limit (``corrections_exhausted``) refitted on its window with
    one more correction, every correction with the prior ``N(0, tau^2)``, ``tau`` the largest
    fitted correction relative to the leading term (the series in ``x / x_far``, the window's
    farthest point at 1): the dropped term as large as the ones kept, and none of them larger
    (a truncation-error prior; a prior on the new term alone let the others run away with mu*,
    intervals 20-60 times wider on imperfect columns). The interval is where that fit's profile
    ``-2 log L`` (the prior included) rises by the chi-square quantile of ``level``. ``(nan,
    nan)`` where it does not apply (not a fold at its limit, or no finite fit).

    Measured (docs/predictor.md, ledger: "The dropped term"): an imperfect arch's records in
    the cusp's crossover (``tests/blind``, arch_imperfect lab 0) hold the fold's series with 3
    corrections on 7 points within the noise at a mu* 16 standard deviations early; every
    neighbour of the truncation spread either shares that bias or is discounted as noise."""
    if not (fit.h < 1 and fit.corrections_exhausted):
        return math.nan, math.nan
    m0, K, n = fit.profile.mu_star, fit.K, fit.n
    N = sw.mu.size
    mu, y, wt = sw.mu[N - n:], sw.y[N - n:], 1.0 / sw.sd[N - n:]
    far = m0 - float(mu[0])
    near = m0 - float(mu[-1])
    if not (math.isfinite(m0) and near > 0 and n >= K + 3):
        return math.nan, math.nan
    e = 2 * fit.a + fit.h * np.arange(K + 2)
    X = ((m0 - mu) / far)[:, None] ** e[None, : K + 1]
    c = np.linalg.lstsq(X * wt[:, None], y * wt, rcond=None)[0]
    tau = float(np.max(np.abs(c[1:] / c[0]))) * abs(c[0])
    if not (math.isfinite(tau) and tau > 0):
        return math.nan, math.nan
    prior = np.zeros((K + 1, K + 2))
    prior[np.arange(K + 1), np.arange(1, K + 2)] = 1.0 / tau
    rhs = np.append(y * wt, np.zeros(K + 1))

    def nll(m: float) -> float:
        x = (m - mu) / far
        if not x[-1] > 0:
            return math.inf
        A = np.vstack([x[:, None] ** e[None, :] * wt[:, None], prior])
        r = A @ np.linalg.lstsq(A, rhs, rcond=None)[0] - rhs
        return float(r @ r)

    res = optimize.minimize_scalar(nll, bounds=(float(mu[-1]) + 1e-9 * near, m0 + 4 * near),
                                   method="bounded", options={"xatol": 1e-10 * near})  # fmt: skip
    mr, f0 = float(res.x), float(res.fun)
    if not math.isfinite(f0):
        return math.nan, math.nan
    thr = f0 + float(chi2_ppf(level, 1))

    def end(side: int) -> float:
        inner, d = 0.0, 1e-6 * near
        while d < 64 * near:
            v = mr + side * d
            if side < 0 and v <= mu[-1]:
                return float(mu[-1])
            if nll(v) > thr:
                u = optimize.brentq(lambda s: nll(mr + side * s) - thr, inner, d,
                                    xtol=1e-12 * near)  # fmt: skip
                return mr + side * u
            inner, d = d, 2 * d
        return mr + side * d

    return end(-1), end(+1)


@functools.lru_cache(maxsize=8)
def _z(level: float) -> float:
    """The two-sided normal quantile of ``level`` (1.96 at 0.95)."""
    return float(norm_ppf(0.5 + level / 2))


def interval(
    sw0: Sweep, fit: Fits, level: float, flags: list[Flag]
) -> tuple[float, float, float, float]:
    """(mu*, std, lo, hi): the profile or mixture interval, with the fits' fewer-terms rivals,
    widened by the truncation spread."""
    if len(fit.fits) == 1:
        f0 = fit.fits[0].profile
        m, lo, hi = f0.mu_star, f0.lo, f0.hi
        std = 0.5 * (f0.hi68 - f0.lo68)
    else:
        m, std, lo, hi = _mixture(fit.fits, fit.probs, level)
        pp = np.asarray(fit.point_probs, dtype=float)
        if pp.size == len(fit.fits) and np.any(pp != np.asarray(fit.probs)):
            # the floor widens the interval only; mu* and its std keep the model probabilities
            top = int(np.argmax(pp))
            if pp[top] >= 0.999 * pp.sum():
                f0 = fit.fits[top].profile
                m, std = f0.mu_star, 0.5 * (f0.hi68 - f0.lo68)
            else:
                m, std, _, _ = _mixture(fit.fits, tuple(pp), level)
            lo, hi = min(lo, m), max(hi, m)
    # the number of corrections was chosen on the data: each fit's law with one correction
    # fewer keeps its smoothed-AICc weight in the interval (fewer_terms_rival); mu* stays the
    # chosen fits', the interval and std are the mixture's with the rivals
    fits, probs = list(fit.fits), list(fit.probs)
    for i, (sw, f, pr) in enumerate(zip(fit.sweeps, fit.fits, fit.probs)):
        alt, w = fewer_terms_rival(sw, f, level)
        if w > 0:
            fits.append(alt)
            probs.append(pr * w)
            probs[i] = pr * (1 - w)
    if len(fits) > len(fit.fits):
        _, std_r, lo_r, hi_r = _mixture(fits, probs, level)
        lo, hi, std = min(lo_r, m), max(hi_r, m), max(std, std_r)
    # truncation uncertainty: the statistical interval assumes the law with K corrections is
    # exact over its window; the less-truncated neighbouring fits tell how far the truncation
    # moved mu*, beyond their noise (see _truncation_spread). The interval widens on the side
    # each bias points to (measured on 600 lab plans: the statistical interval alone covered
    # 32-50 % of the beam plans, 90-97 % of the normal-form ones whose laws are exact).
    # The spread is a 95 % allowance (its factor was calibrated at that level), a normal
    # quantile times a systematic standard deviation: at another level it scales with the
    # quantile, and the std it adds does not depend on the level.
    spreads = [_truncation_spread(sw, f) for sw, f, pr in zip(fit.sweeps, fit.fits, fit.probs)
               if pr >= 0.05]  # fmt: skip
    z95 = _z(0.95)
    k = _z(level) / z95
    down = k * max((d for d, _ in spreads), default=0.0)
    up = k * max((u for _, u in spreads), default=0.0)
    sys_spread = max(down, up)
    if sys_spread > 0:
        lo, hi = lo - down, hi + up
        std = math.hypot(std, sys_spread / _z(level))
    # a fold's law at its correction limit: the term it drops, as large as those it keeps,
    # carried into the interval (see _next_term)
    # (only where the law holds its window within the records' own noise: a misfit is already
    # read as noise, the interval widened by it, and the next term is not identified there)
    held = not any(f.code in _NOT_HELD for f in flags)
    for sw, f, pr in zip(fit.sweeps, fit.fits, fit.probs):
        if held and pr >= 0.05 and not any(g.code in _NOT_HELD for g in f.profile.flags):
            n_lo, n_hi = _next_term(sw, f, level)
            if math.isfinite(n_lo) and math.isfinite(n_hi) and (n_lo < lo or n_hi > hi):
                lo, hi = min(lo, n_lo), max(hi, n_hi)
                std = max(std, 0.5 * (hi - lo) / _z(level))
    last = float(sw0.mu[-1])
    lo = max(lo, last)
    half = 0.5 * (hi - lo)
    if not (math.isfinite(half) and half > 0):
        half = math.nan
    if half > 0.5 * max(m - last, 0) or any(f.code == "interval_unbounded" for f in flags):
        flags.append(
            Flag(
                "interval_huge",
                f"the {100 * level:.0f}% interval [{lo:.6g}, {hi:.6g}] is wider than the "
                f"distance to mu* ({m - last:.3g})",
            )
        )
    return m, std, lo, hi
