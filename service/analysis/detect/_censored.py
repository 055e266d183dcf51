"""Clipped samples as censored data: the fit of a window that holds them (EM).

A saturated sensor holds every value beyond its range at the range's edge: such a sample says
only that the signal was at or beyond that level (a right- or left-censored observation), and
fitting it as a value pulls the model's peaks down to the edge (a flat top is no free decay).
The maximum-likelihood fit of the other samples with these censored is found by the
expectation-maximisation iteration for censored Gaussian data (the Tobit model): each clipped
sample is replaced by its expected value given the current fit and that it lies beyond the
edge, ``mu + s lambda((edge - mu) / s)`` above the upper edge (``lambda`` the inverse Mills
ratio ``phi / (1 - Phi)``, ``mu`` the model, ``s`` the noise std), symmetrically below the
lower one, and the poles are refitted from the last ones (variable projection, MDL pruning),
until the replaced values settle. The whole window of free response is read this way, not only
its longest unclipped stretch: a clipped run costs its own samples, not the cycles around it.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from service.analysis.detect._kernels import model_values
from service.analysis.detect._varpro import _Fit, _levenberg_marquardt, _prune

#: EM iterations at most, and the change of the replaced values (in noise stds, largest) below
#: which they have settled.
EM_ITER, EM_TOL = 10, 0.25


def expected_beyond(mu: np.ndarray, edge: float, s: float, upper: bool) -> np.ndarray:
    """``E[y | y >= edge]`` (``upper``) or ``E[y | y <= edge]`` for ``y ~ N(mu, s^2)``:
    ``mu +- s sqrt(2/pi) / erfcx(+-(edge - mu) / (s sqrt 2))`` (stable for any ``mu``)."""
    from scipy.special import erfcx  # only clipped records: plain detection loads no scipy

    sign = 1.0 if upper else -1.0
    z = sign * (edge - mu) / (s * math.sqrt(2.0))
    return mu + sign * s * math.sqrt(2.0 / math.pi) / erfcx(z)


def _normalised(a: np.ndarray, detrend: Callable[[np.ndarray], np.ndarray]) -> tuple:
    """``(y, scale)``: the record (``detrend`` applied) less its mean over ``scale``, rms 1."""
    d = detrend(a)
    d = d - float(np.mean(d))
    big = float(np.max(np.abs(d)))
    if not big > 0:
        return d, 0.0
    y = d / big
    r = math.sqrt(float(np.mean(y * y)))
    return y / r, big * r


def fit_censored(
    raw: np.ndarray, hi: np.ndarray, lo: np.ndarray, *,
    detrend: Callable[[np.ndarray], np.ndarray],
    first: Callable[[np.ndarray], _Fit | None], max_modes: int, max_iter: int,
) -> tuple[np.ndarray, int]:  # fmt: skip
    """The window ``raw`` with its clipped samples (``hi``: held at its largest value, ``lo``:
    at its smallest; boolean masks) replaced by their expected values at the EM fit's
    convergence, and the number of EM steps. ``detrend`` is the linear map applied to a record
    before a fit (the identity or a slope removal), ``first(y)`` the full fit of a normalised
    record (its poles start the EM). EM creeps where much is censored: its steps are
    extrapolated (SQUAREM, Varadhan and Roland 2008: two steps ``r``, ``v`` give the step
    length ``-|r|/|v|``), the values kept beyond their edges."""
    mask = hi | lo
    up = float(raw[hi][0]) if hi.any() else math.nan
    down = float(raw[lo][0]) if lo.any() else math.nan
    state: dict = {"fit": None}

    def step(a: np.ndarray) -> tuple[np.ndarray, float] | None:
        """One EM step from the values ``a``: the refit, then the expected values."""
        y, scale = _normalised(a, detrend)
        if not scale > 0:
            return None
        old = state["fit"]
        if old is None:
            fit = first(y)
        else:
            p, q, _, c = _prune(y, old.ev.p, old.ev.q, old.s2, max_modes)
            c0 = None if old.common else c
            fit = _levenberg_marquardt(y, p, q, common=old.common, max_iter=max_iter,
                                       c0=c0) if p.size else None  # fmt: skip
        if fit is None:
            return None
        state["fit"] = fit
        mv = np.empty(y.size)
        model_values(fit.ev.p, fit.ev.q, fit.ev.c, mv)
        pred = a - (y - mv) * scale  # the model in record units (the slope included)
        s = math.sqrt(fit.s2) * scale
        if not (s > 0 and math.isfinite(s)):
            return None
        new = a.copy()
        if hi.any():
            new[hi] = expected_beyond(pred[hi], up, s, True)
        if lo.any():
            new[lo] = expected_beyond(pred[lo], down, s, False)
        return (new, s) if np.all(np.isfinite(new)) else None

    def clamp(a: np.ndarray) -> np.ndarray:
        if hi.any():
            a[hi] = np.maximum(a[hi], up)
        if lo.any():
            a[lo] = np.minimum(a[lo], down)
        return a

    a = raw.copy()
    k = 0
    while k < EM_ITER:
        one = step(a)
        k += 1
        if one is None:
            break
        a1, s = one
        r = a1[mask] - a[mask]
        if float(np.max(np.abs(r))) < EM_TOL * s:
            a = a1
            break
        two = step(a1)
        k += 1
        if two is None:
            a = a1
            break
        a2, s = two
        v = a2[mask] - a1[mask] - r
        nv = float(np.linalg.norm(v))
        alpha = min(-float(np.linalg.norm(r)) / nv, -1.0) if nv > 0 else -1.0
        a = a.copy()
        a[mask] = a[mask] - 2.0 * alpha * r + alpha * alpha * v
        a = clamp(a) if np.all(np.isfinite(a)) else a2
    return a, k
