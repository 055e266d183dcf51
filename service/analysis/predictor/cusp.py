"""The imperfect pitchfork (the cusp family) fitted: no real structure is perfect.

A pitchfork's symmetry is always broken a little (a stress-free angle, a load's offset): its
equilibrium is ``eps + (mu* - mu) x -+ c x^3 = 0`` (softening ``-``, stiffening ``+``) and the
fundamental's stiffness along the measured branch ``k = (mu* - mu) -+ 3 c x^2``
(:mod:`._kernels.cusp`). Far from mu* (``lambda = mu* - mu >> G``, ``G = c^(1/3) eps^(2/3)``)
``k ~ lambda``: it looks like a perfect pitchfork (``a = 1/2``). Near mu*:

* softening: the branch ends at a fold ``mu_f = mu* - 3 2^(-2/3) G`` before mu*, where
  ``k ~ (mu_f - mu)^(1/2)`` (``a = 1/4``): the structure snaps there, the load a lab must not
  cross;
* stiffening: the branch never ends and the stiffness is least, ``K_MIN G``, at
  ``mu_m = mu* - R_MIN G``: no loss of stability.

``G = 0`` is the perfect pitchfork, so the perfect law is nested in both. :func:`assess` fits
the three (perfect, softening, stiffening; eigenvalue law ``|sigma^2| = k sum_j alpha_j
(lambda/scale)^j``, the corrections chosen on the perfect law by AICc) on the nearest points
(a :class:`CuspWindow`, chosen by :func:`window`) and returns their ``-2 log L``, BIC weights
and the profile-likelihood interval of the point each imperfect law predicts (the fold, or the
least stiffness): an :class:`Imperfection`. What the answer makes of it is
:mod:`.imperfect`'s.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
from scipy import optimize, special

from service.analysis.predictor._dist import chi2_ppf
from service.analysis.predictor._kernels.cusp import (
    R_FOLD,
    R_MIN,
    amplitude,
    fold_nll,
    polish,
    profile_g,
    profile_point,
    profile_scan,
    scan2,
)
from service.analysis.predictor.interval import _RICHARDSON
from service.analysis.predictor.sweep import Sweep

__all__ = ["ESTABLISHED", "CuspFit", "CuspWindow", "Imperfection", "assess", "window"]

N_MAX = 40  # nearest points the cusp laws are fitted on
K_MAX = 2  # most corrections of the cusp laws
SHIFT_STIFF = 3.0  # a stiffening law's least stiffness may lie this many G before the last point
_TS = np.linspace(math.log(1e-7), math.log(3.0), 40)  # log((mu_p - mu_last) / scale)
_GS = np.linspace(math.log(1e-7), math.log(1.0), 26)  # log(G / scale)
_TS_C = np.linspace(math.log(1e-7), math.log(3.0), 22)  # the window choice's coarser grids
_GS_C = np.linspace(math.log(1e-6), math.log(1.0), 12)
_ALPHA = 0.01  # goodness-of-fit level of a window
_PERFECT = np.array([-math.inf])  # log(G / scale) of the perfect law
REQUIRE_HOLDS = True  # tell a law only where one holds on the window (see the ledger)
#: the point's truncation bias allowed on each side, in units of ``G``: the cusp's neglected
#: terms (measured on link and coupled columns: folds up to 0.033 G earlier than the cusp law's
#: fit where it holds and its statistical interval is narrow; see the ledger)
TRUNCATION = 0.05
#: -2 log L gain of an imperfect law over the perfect one that establishes the imperfection (a
#: likelihood ratio of 1e3); below it the perfect answer stands
ESTABLISHED = 2 * math.log(1e3)


@dataclass(frozen=True)
class CuspFit:
    """One imperfect law fitted.

    Attributes
    ----------
    law : str
        ``"imperfect-softening"`` or ``"imperfect-stiffening"``.
    mu_p, lo, hi : float
        The point it predicts (the fold, softening; the least stiffness, stiffening) and its
        profile-likelihood interval (control units).
    mu_star : float
        The perfect pitchfork's point ``mu*`` of the same fit (the cusp's centre).
    G : float
        The imperfection's load scale ``c^(1/3) eps^(2/3)`` (control units; 0: perfect).
    nll : float
        ``-2 log L`` of the eigenvalues.
    least_sigma2 : float
        ``|sigma^2|`` the law gives at ``mu_p`` (0 at a fold), 1/time^2.
    correction : float
        The largest relative departure of the correction factor ``sum_j alpha_j
        (lambda/scale)^j / alpha_0`` from 1 over the window: near 0 where the law's own
        stiffness follows the records, large where its corrections do.
    lo_fits : float
        The lower end of the two fits' statistical intervals alone (this law and the one with
        one more correction), without the truncation's bias: what an imperfection the records
        do not establish can claim (NaN: ``lo``).
    """

    law: str
    mu_p: float
    lo: float
    hi: float
    mu_star: float
    G: float
    nll: float
    least_sigma2: float
    correction: float = math.nan
    lo_fits: float = math.nan


@dataclass(frozen=True)
class Imperfection:
    """The perfect and imperfect pitchforks compared on the nearest ``window`` points with
    ``K`` corrections: ``-2 log L`` of the perfect law, the two imperfect fits and the BIC
    weights of the three (``"perfect"``, ``"imperfect-softening"``, ``"imperfect-stiffening"``);
    ``first``, ``last``: the window's first and last controls; ``fits``: whether one of the
    laws fits a window within the noise (else no law is told, none being right);
    ``nll_fold``: ``-2 log L`` of the perfect fold law with ``K`` corrections on the same
    points (a softening cusp's rival where the perfect laws name a fold)."""

    window: int
    K: int
    nll_perfect: float
    mu_star_perfect: float
    soft: CuspFit
    stiff: CuspFit
    weights: dict[str, float]
    dispersion: float = 1.0
    last: float = math.nan
    first: float = math.nan
    fits: bool = True
    nll_fold: float = math.inf

    @property
    def misfit_ratio(self) -> float:
        """The best law's reduced chi-square on the window (``-2 log L`` over its degrees of
        freedom): how far the records scatter beyond their noise about the best law."""
        dof = max(self.window - self.K - 3, 1)
        return min(self.nll_perfect, self.soft.nll, self.stiff.nll) / dof

    @property
    def evidence_soft(self) -> float:
        """How much better the softening law explains the records (``-2 log L`` gain, over
        the best law's reduced chi-square when the records scatter more than their noise)."""
        return max(self.nll_perfect - self.soft.nll, 0.0) / self.dispersion

    @property
    def evidence_stiff(self) -> float:
        """How much better the stiffening law explains the records (the same)."""
        return max(self.nll_perfect - self.stiff.nll, 0.0) / self.dispersion


def _perfect(mu: np.ndarray, y: np.ndarray, wt: np.ndarray, scale: float, K: int
             ) -> tuple[float, float]:
    """``(-2 log L, t)`` of the perfect pitchfork law with ``K`` corrections, mu* profiled."""
    empty = np.empty(0)
    f, _ = profile_scan(mu, y, wt, scale, _TS, empty, True, K, 0.0, False)
    i = int(np.argmin(f))
    if not math.isfinite(f[i]):
        return math.inf, math.nan
    lo, hi = _TS[max(i - 1, 0)], _TS[min(i + 1, _TS.size - 1)]
    r = optimize.minimize_scalar(
        lambda t: profile_g(mu, y, wt, scale, t, empty, True, K, 0.0, True)[0], bounds=(lo, hi),
        method="bounded", options={"xatol": 1e-7},
    )  # fmt: skip
    return (float(r.fun), float(r.x)) if r.fun < f[i] else (float(f[i]), float(_TS[i]))


def _joint(
    mu: np.ndarray, y: np.ndarray, wt: np.ndarray, scale: float, K: int, soft: bool,
    shift: float, ts: np.ndarray, gs: np.ndarray, starts: int = 3, coarse: bool = False,
) -> tuple[float, float, float, np.ndarray]:
    """The law's joint minimum over ``(t, g)``: the grid ``ts x gs`` (and the perfect law at
    each ``t``) brackets it, :func:`._kernels.cusp.polish` finds it from the grid's best
    ``starts`` local minima (a stiffening column's valley is narrower than the grids: profiling
    ``g`` on the grid at each ``t`` stopped at ``-2 log L`` 1.5e4 for the minimum 1.7), until
    one reaches the noise (``-2 log L`` at most the number of points); with ``coarse`` the
    window choice's coarse grid's best local minimum is a start too (a grid's minima can all
    miss a basin the other's finds: a stiffening column's window held on the coarse grid,
    -2 log L 200 from the fine grid's starts). Returns ``(nll, t, g, scan)``: ``scan`` the
    grid's profile over ``ts`` (``g = -inf``: the perfect law)."""
    F = scan2(mu, y, wt, scale, ts, gs, soft, K, shift)
    P = scan2(mu, y, wt, scale, ts, _PERFECT, soft, K, shift)[:, 0]  # g = -inf
    ok = np.isfinite(F)
    Fi = np.where(ok, F, np.inf)
    jb = np.argmin(Fi, axis=1)
    rows = Fi[np.arange(ts.size), jb]
    f = np.minimum(rows, P)
    g = np.where(rows <= P, gs[jb], -np.inf)
    i0 = int(np.argmin(f))
    best = (float(f[i0]), float(ts[i0]), float(g[i0]))
    if not ok.any():
        return best[0], best[1], best[2], f
    pad = np.pad(Fi, 1, constant_values=np.inf)
    loc = ok.copy()
    for di in (-1, 0, 1):
        for dj in (-1, 0, 1):
            if di or dj:
                loc &= Fi <= pad[1 + di:pad.shape[0] - 1 + di, 1 + dj:pad.shape[1] - 1 + dj]
    cand = sorted((float(F[i, j]), float(ts[i]), float(gs[j])) for i, j in zip(*np.nonzero(loc)))
    cand = cand[:starts]
    if coarse:
        Fc = scan2(mu, y, wt, scale, _TS_C, _GS_C, soft, K, shift)
        if np.isfinite(Fc).any():
            i, j = np.unravel_index(np.argmin(np.where(np.isfinite(Fc), Fc, np.inf)), Fc.shape)
            cand.append((float(Fc[i, j]), float(_TS_C[i]), float(_GS_C[j])))
    box = np.array([ts[0], ts[-1], gs[0], gs[-1]])
    for _, t0, g0 in cand:
        r = polish(mu, y, wt, scale, t0, g0, soft, K, shift, 0.3, 1e-7, 2000, box)
        if r[0] < best[0]:
            best = (float(r[0]), float(r[1]), float(r[2]))
        if best[0] <= mu.size:
            break
    return best[0], best[1], best[2], f


def _fold_law(mu: np.ndarray, y: np.ndarray, wt: np.ndarray, scale: float, K: int) -> float:
    """``-2 log L`` of the perfect fold law (``a = 1/4``) with ``K`` corrections, its fold
    profiled (the scan over ``_TS``, refined by Brent's method between its neighbours)."""
    last = float(mu[-1])

    def nll(t: float) -> float:
        return fold_nll(mu, y, wt, scale, last + scale * math.exp(t), K)

    f = np.array([nll(float(t)) for t in _TS])
    i = int(np.argmin(f))
    if not math.isfinite(f[i]):
        return math.inf
    r = optimize.minimize_scalar(nll, bounds=(_TS[max(i - 1, 0)], _TS[min(i + 1, _TS.size - 1)]),
                                 method="bounded", options={"xatol": 1e-9})  # fmt: skip
    return float(min(r.fun, f[i]))


def _fit(
    mu: np.ndarray, y: np.ndarray, wt: np.ndarray, scale: float, K: int, soft: bool,
    level: float, with_interval: bool = True,
) -> CuspFit:
    """One imperfect law: its joint minimum over ``t`` (the point it predicts) and ``g``
    (:func:`_joint`) and (with ``with_interval``) the interval where the profile over ``t``
    rises by the chi-square quantile of ``level`` (else the point alone)."""
    shift = 0.0 if soft else SHIFT_STIFF
    name = "imperfect-softening" if soft else "imperfect-stiffening"
    f0, t0, g0, f = _joint(mu, y, wt, scale, K, soft, shift, _TS, _GS, coarse=True)
    if not math.isfinite(f0):
        nan = math.nan
        return CuspFit(name, nan, nan, nan, nan, nan, math.inf, nan)
    last = float(mu[-1])
    G = scale * math.exp(g0) if g0 > -700 else 0.0
    mu_p = last + scale * math.exp(t0) - shift * G
    mu_star = mu_p + (R_FOLD if soft else R_MIN) * G
    least, corr = _law_value(mu, y, wt, scale, K, mu_star, G, soft, mu_p)
    if not with_interval:
        return CuspFit(name, mu_p, mu_p, mu_p, mu_star, G, f0, math.nan, corr)
    # the interval: where the profile over the point (G profiled) rises by the chi-square
    # quantile of level on each side
    thr = f0 + float(chi2_ppf(level, 1))
    gc = g0 if g0 > -700 else float(_GS[0])
    lo = _end(mu, y, wt, scale, K, soft, shift, mu_p, gc, thr, -1)
    hi = _end(mu, y, wt, scale, K, soft, shift, mu_p, gc, thr, +1)
    # the normal form's truncation (see the ledger): the statistical ends alone are lo_fits
    bias = TRUNCATION * G
    return CuspFit(name, mu_p, min(lo, mu_p - bias), max(hi, mu_p + bias), mu_star, G, f0,
                   0.0 if soft else least, corr, min(lo, mu_p))  # fmt: skip


def _end(
    mu: np.ndarray, y: np.ndarray, wt: np.ndarray, scale: float, K: int, soft: bool,
    shift: float, m0: float, g0: float, thr: float, side: int,
) -> float:
    """The interval's end on ``side`` (-1 below the point ``m0``, +1 above): the profile over
    ``g`` (:func:`._kernels.cusp.profile_point`, continued from ``g0``) at distances from
    ``m0`` doubling from ``1e-7 scale`` until it exceeds ``thr``, then the crossing by Brent's
    method; the search's end (``3 scale`` from the last point, or the domain's) when it never
    does."""
    last = float(mu[-1])
    g_max = float(_GS[-1])  # G at most the window's span (beyond, the normal equations lose
    inner, gc = 0.0, g0  # every digit)
    d = 1e-7 * scale
    while d <= 4.0 * scale:
        m = m0 + side * d
        f, g = profile_point(mu, y, wt, scale, m, soft, K, shift, gc, 0.7, g_max)
        if f <= thr:
            inner, gc = d, (g if g > -700 else gc)
            d *= 2.0
            continue
        def excess(u: float, g_in: float = gc) -> float:
            v = profile_point(mu, y, wt, scale, m0 + side * u, soft, K, shift, g_in, 0.7, g_max)
            return min(v[0] - thr, 1e6)

        if not excess(inner) < 0:  # (the profile's search lost the valley: the wider end)
            return float(m)
        u = optimize.brentq(excess, inner, d, xtol=1e-13 * scale, rtol=1e-10)
        return float(m0 + side * u)
    return float(min(m0 + side * d, last + 3.0 * scale) if side > 0 else m0 - inner)


def _law_value(
    mu: np.ndarray, y: np.ndarray, wt: np.ndarray, scale: float, K: int, mu_star: float,
    G: float, soft: bool, at: float,
) -> tuple[float, float]:
    """``|sigma^2|`` of the fitted law at the control ``at`` (its coefficients by weighted
    least squares at ``mu*`` and ``G``), and its corrections' largest relative departure from
    1 over the window (:attr:`CuspFit.correction`)."""
    lam = mu_star - mu
    k = lam + (-3.0 if soft else 3.0) * G * np.array(
        [amplitude(li / G, soft) ** 2 if G > 0 else 0.0 for li in lam]
    )  # fmt: skip
    X = k[:, None] * (lam[:, None] / scale) ** np.arange(K + 1)[None, :]
    coef, *_ = np.linalg.lstsq(X * wt[:, None], y * wt, rcond=None)
    la = mu_star - at
    ka = la + (-3.0 if soft else 3.0) * G * (amplitude(la / G, soft) ** 2 if G > 0 else 0.0)
    factor = ((lam[:, None] / scale) ** np.arange(K + 1)[None, :]) @ coef
    corr = float(np.max(np.abs(factor / coef[0] - 1.0))) if coef[0] != 0 else math.inf
    return float(ka * np.sum(coef * (la / scale) ** np.arange(K + 1))), corr


@dataclass(frozen=True, eq=False)
class CuspWindow:
    """The nearest points of a sweep the cusp laws are fitted on (a value: :func:`window`
    chooses it, :func:`assess` fits on it).

    Attributes
    ----------
    mu, y : numpy.ndarray
        Controls and ``|sigma^2|`` of the nearest points, ascending in control.
    wt : numpy.ndarray
        Their weights ``1 / sd``.
    found : bool
        Whether one of the three laws fitted a window within the noise (else the smallest, 6
        points).
    """

    mu: np.ndarray
    y: np.ndarray
    wt: np.ndarray
    found: bool

    @classmethod
    def nearest(cls, sw: Sweep, n: int, found: bool = True) -> CuspWindow:
        """The nearest ``n`` points of ``sw`` (contiguous float arrays, for the kernels)."""
        return cls(np.ascontiguousarray(sw.mu[-n:], dtype=float),
                   np.ascontiguousarray(sw.y[-n:], dtype=float),
                   np.ascontiguousarray(1.0 / sw.sd[-n:], dtype=float), found)  # fmt: skip

    @property
    def n(self) -> int:
        """Number of points."""
        return int(self.mu.size)

    @property
    def scale(self) -> float:
        """The window's span in control (the laws' unit of ``mu* - mu``)."""
        return float(self.mu[-1] - self.mu[0])


def window(sw: Sweep, n_max: int = N_MAX) -> CuspWindow:
    """The largest window of nearest points (from 6, growing geometrically until one fails) on
    which one of the three laws, with ``K_MAX`` corrections, fits within the noise
    (chi-square at ``_ALPHA``; coarse grids); the 6 nearest when none does."""
    N = min(sw.mu.size, n_max)
    sizes = sorted({int(round(v)) for v in np.geomspace(6, N, 4)})
    ok = 6
    found = False
    for n in sizes:
        w = CuspWindow.nearest(sw, n)
        mu, y, wt, scale = w.mu, w.y, w.wt, w.scale
        K = min(K_MAX, n - 5)
        best = math.inf
        for soft, shift in ((True, 0.0), (False, SHIFT_STIFF)):
            best = min(best, _joint(mu, y, wt, scale, K, soft, shift, _TS_C, _GS_C, 1)[0])
        dof = n - K - 3
        if dof >= 1 and special.chdtrc(dof, best) >= _ALPHA:
            ok, found = n, True
        else:  # a larger window fits no better
            break
    return CuspWindow.nearest(sw, ok, found)


def _joined(
    f: CuspFit, mu: np.ndarray, y: np.ndarray, wt: np.ndarray, scale: float, K: int,
    level: float,
) -> CuspFit:
    """``f`` with its interval joined with that of the same law with one more correction,
    where the window allows it (the truncation's share: a link column's fold 1.4 half-widths
    before a one-correction law's interval lay inside the two-correction law's)."""
    if K >= K_MAX or mu.size - K - 4 < 1 or not math.isfinite(f.lo):
        return f
    more = _fit(mu, y, wt, scale, K + 1, f.law == "imperfect-softening", level)
    if not math.isfinite(more.lo):
        return f
    # the truncation's bias beyond the two statistical intervals: twice the change of the
    # point (as the perfect laws' neighbours, interval._RICHARDSON)
    bias = _RICHARDSON * abs(more.mu_p - f.mu_p) if math.isfinite(more.mu_p) else 0.0
    return replace(f, lo=min(f.lo, more.lo, f.mu_p - bias), hi=max(f.hi, more.hi, f.mu_p + bias),
                   lo_fits=min(f.lo_fits, more.lo_fits))


def assess(sw: Sweep, level: float = 0.95) -> Imperfection | None:
    """Compare the perfect pitchfork with the softening and stiffening imperfect ones on the
    nearest points of ``sw`` (its ``y = |sigma^2|`` and noise ``sd``) where one of them holds;
    None with fewer than 6 points."""
    if sw.mu.size < 6:
        return None
    w = window(sw, N_MAX)
    n, mu, y, wt, scale = w.n, w.mu, w.y, w.wt, w.scale
    # corrections: AICc of the perfect law (the nested imperfect laws keep them)
    best = (math.inf, 0, math.inf, math.nan)
    for K in range(0, K_MAX + 1):
        k = K + 2
        if n - k - 2 < 1:
            break
        nll, t = _perfect(mu, y, wt, scale, K)
        aicc = nll + 2 * k + 2 * k * (k + 1) / (n - k - 1)
        if aicc < best[0]:
            best = (aicc, K, nll, t)
    _, K, nll_p, t_p = best
    if not math.isfinite(nll_p):
        return None
    soft = _joined(_fit(mu, y, wt, scale, K, True, level), mu, y, wt, scale, K, level)
    # the structure was recorded stable at the last control: its fold lies beyond it (a
    # barely identified fit with one more correction reached 0.8 for records stable to 1.17)
    soft = replace(soft, lo=max(soft.lo, float(mu[-1])),
                   lo_fits=max(soft.lo_fits, float(mu[-1])))
    # the stiffening law's interval matters only where it may be told
    stiff = _fit(mu, y, wt, scale, K, False, level, with_interval=False)
    if nll_p - stiff.nll >= ESTABLISHED:  # (before the dispersion: a superset)
        stiff = _joined(_fit(mu, y, wt, scale, K, False, level), mu, y, wt, scale, K, level)
    phi = 1.0  # the gains are read against the records' noise (see docs/predictor.md)
    pen = math.log(n)
    crit = {
        "perfect": nll_p / phi + (K + 2) * pen,
        "imperfect-softening": min(soft.nll, nll_p) / phi + (K + 3) * pen,
        "imperfect-stiffening": min(stiff.nll, nll_p) / phi + (K + 3) * pen,
    }
    c0 = min(crit.values())
    raw = {k: math.exp(-0.5 * (v - c0)) for k, v in crit.items()}
    tot = sum(raw.values())
    weights = {k: v / tot for k, v in raw.items()}
    mu_star_p = float(mu[-1] + scale * math.exp(t_p))
    # whether the best law holds on the window: the refined fits with the corrections chosen
    # (not the window's choice, which allows K_MAX: on the beam's antisymmetric warn a window
    # of 17 points held with 2 corrections while every law with the 1 chosen misfit by 1e5 and
    # the softening law's "gain" of 5e3 named an imperfection, its interval reaching 3.98)
    best_nll = min(nll_p, soft.nll, stiff.nll)
    holds = bool(special.chdtrc(max(n - K - 3, 1), best_nll) >= _ALPHA / 10)
    holds = holds or REQUIRE_HOLDS is False
    return Imperfection(n, K, nll_p, mu_star_p, soft, stiff, weights, phi, float(mu[-1]),
                        float(mu[0]), holds, _fold_law(mu, y, wt, scale, K))  # fmt: skip

