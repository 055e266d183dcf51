"""The shared profile-likelihood engine: candidate laws, their fits and comparison.

Laws fitted along the measured stable branch, ``x = mu* - mu > 0`` (paper, Sec. "Asymptotic
analysis"; eqs. saddleGrowthRate, pitchforkGrowthRate, saddleEquilibriums,
pitchforkEquilibriums, with regular corrections):

    |sigma^2| = x^(2a) sum_k c_k x^(k h),        w = w* + sum_j g_j x^(e_j)

(``h = 1/2`` near a fold, ``1`` near a pitchfork; see :data:`CANDIDATES`). A pitchfork law also
comes in a variant that knows a secondary fold of the measured branch at ``mu* + delta``: the
series run in the conformal variable ``z = 2x / (1 + sqrt(1 + x/delta))`` (``delta`` profiled;
see :mod:`._kernels.laws`). Physics: the trivial branch of a subcritical
pitchfork, unstable beyond mu*, may fold soon after it (the symmetric beam: U_A folds at
mu2* = mu* + 0.0119); the equilibrium is then analytic in the fold's amplitude
``s = sqrt(mu* + delta - mu)``, so every series in ``x`` converges only within ``delta`` of mu*
and ``sigma^2(mu)`` carries a square-root branch point at ``mu* + delta``, while a series in
``z ~ s - sqrt(delta)`` converges far beyond. As ``delta -> inf`` the law is the plain one.

The number of correction terms and the window of "informative" points (the nearest points where
the law holds) are chosen by a chi-square goodness-of-fit test against the measurement noise
(:mod:`.windows`, with the noise estimate); the candidates are compared on a
common window by BIC, which gives the model probabilities.

Public entry points (used by :mod:`service.analysis.classify` and
:mod:`.interval`): :func:`analyse`, :func:`probabilities`, :func:`refit_profile`,
:func:`free_exponent_a`, :func:`free_exponent_b`, :func:`secondary_fold`,
:func:`fewer_terms_rival`, :func:`fold_rival_gap`, :class:`ModelFit`,
:data:`CANDIDATES`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from service.analysis.common import Flag
from service.analysis.predictor.damping import identify_damping
from service.analysis.predictor.exponents import exponent_grid, free_exponent
from service.analysis.predictor.laws import CANDIDATES
from service.analysis.predictor.likelihood import (
    _Comp,
    _nll_u,
    _polynomial_bound,
    _Profile,
    _profile,
    _sigma_comp,
    _sigma_exps,
    _variants,
    _w_comp,
    _w_exps,
)
from service.analysis.predictor.sweep import Sweep
from service.analysis.predictor.windows import (
    _KMAX,
    _KW_MAX,
    _MIN_NOISE_DOF,
    Window,
    _chi2_sf,
    _estimate_noise,
    _noise_flag,
    _sigma_chi2,
    _static_window,
    _with_damping,
    select_window,
)

__all__ = [
    "CANDIDATES",
    "Law",
    "ModelFit",
    "analyse",
    "free_exponent_a",
    "free_exponent_b",
    "probabilities",
    "refit_profile",
    "fewer_terms_rival",
    "secondary_fold",
    "fold_rival_gap",
]


# --------------------------------------------------------------------------------------------
# model comparison
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class ModelFit:
    """Fit of one candidate transition on the common window (internal, used by ``predict``).

    Attributes
    ----------
    name : str
        Candidate name (``"saddle-node"``, ``"pitchfork"``, ...).
    a, b : float
        Exponents of the law (b is NaN without static data).
    h : float
        Step of the regular corrections in powers of ``x``.
    n, K, Kw : int
        Window size (nearest points), sigma^2 correction terms, static-law terms.
    bic : float
        Bayesian information criterion.
    profile : _Profile
        mu* and its profile-likelihood intervals.
    n_w : int
        Window of the static law.
    conformal : bool
        Whether the law knows a secondary fold beyond mu* (series in the conformal variable).
    weight : float
        Model probability from the comparison (NaN: from the BIC alone).
    """

    name: str
    a: float
    b: float
    h: float
    n: int
    K: int
    Kw: int
    bic: float
    profile: _Profile
    n_w: int = 0
    conformal: bool = False
    weight: float = math.nan  # model probability from the comparison (NaN: from the BIC alone)

    @property
    def corrections_exhausted(self) -> bool:
        """Whether the eigenvalue law used every correction term the engine allows."""
        return self.K >= _KMAX


_K_CRITERION = "aicc"
_NO_PROFILE = _Profile(math.nan, math.nan, math.nan, math.nan, math.nan, math.nan)
_RIVAL_MIN = 1e-3  # least weight of a fewer-terms rival that enters an interval


def _crit(nll: float, bic: float, k: int, m: int) -> float:
    """Criterion choosing the number of correction terms of one candidate: AICc (less biased
    extrapolation to mu* than BIC, whose heavier penalty truncates corrections too early)."""
    if _K_CRITERION == "bic":
        return bic
    return nll + 2 * k + (2 * k * (k + 1) / (m - k - 1) if m - k - 1 > 0 else math.inf)


def _sigma_bound(sw: Sweep, idx: slice, a: float, h: float, K: int, cf: bool) -> float:
    """Lower bound of -2 log L of the eigenvalue law over every mu* (-inf where none is
    known): a plain pitchfork law is a polynomial in mu (:func:`_polynomial_bound`)."""
    if 2 * a == 1.0 and h == 1.0 and not cf:
        return _polynomial_bound(sw.mu[idx], sw.y[idx], 1.0 / sw.sd[idx], K + 1)
    return -math.inf


def _sigma_floor(
    sw: Sweep, idx: slice, a: float, h: float, K: int, cf: bool, scale: float, joint: bool,
    hint: tuple[float, float] | None = None,
) -> float:
    """Lower bound of the eigenvalue law's -2 log L inside a joint fit with the static law:
    the eigenvalue law's own minimum over mu* (the joint -2 log L is the sum of the two at
    one mu*), searched only where a joint fit follows (usually a hit of the window
    selection's memo); never below :func:`_sigma_bound`."""
    lb = _sigma_bound(sw, idx, a, h, K, cf)
    if joint:
        comp = _sigma_comp(sw, idx, 2 * a, h, K, cf)
        prof = _profile(sw.mu[idx], [comp], float(scale), with_interval=False, hint=hint)
        lb = max(lb, prof.nll)
    return lb


def _w_bound(b: float, Kw: int, wc: _Comp) -> float:
    """Lower bound of -2 log L of the static law over every mu*: with its noise known, 0 (a
    chi^2), or for the plain b = 1 law (a polynomial of degree Kw in mu) the best polynomial's
    chi^2; -inf with the noise estimated (a log-likelihood of any sign)."""
    if not wc.known:
        return -math.inf
    if b == 1.0 and not wc.conformal:
        assert wc.mu is not None  # the static law's own window
        return _polynomial_bound(wc.mu, wc.y, wc.wt, Kw)
    return 0.0


def _fit_candidate(
    sw: Sweep,
    name: str,
    a: float,
    b: float | None,
    h: float,
    n: int,
    scale: float,
    level: float = 0.95,
    n_w: int | None = None,
    hints: dict[tuple, tuple[float, float]] | None = None,
) -> ModelFit:
    """Fit one candidate: sigma^2 law on the nearest ``n`` points, static law (if any) on the
    nearest ``n_w``; corrections chosen by BIC; mu* profiled jointly. ``hints``: optima found
    by the window choice, ``(p, h, n, K, conformal) -> (t, log u)`` (see :func:`_profile`)."""
    hints = hints or {}
    N = sw.mu.size
    idx = slice(N - n, N)
    n_w = n if n_w is None else n_w
    idx_w = slice(N - n_w, N)
    kw_range = [0]
    if sw.w is not None and b is not None:
        kw_range = [kw for kw in range(1, _KW_MAX + 1) if n_w - kw - 1 >= 2] or [0]
    # (K, variant, Kw) with a lower bound of -2 log L, tried from the lowest bound up: a
    # term count whose bound cannot beat the best criterion found is never searched (exact)
    combos = []
    for K in range(_KMAX + 1):
        # a secondary fold beyond mu* belongs to a branch that continues past mu*: the trivial
        # branch of a subcritical pitchfork, never the side branch of a supercritical one
        # (it ends at mu*)
        cfs = (False,) if name == "supercritical-pitchfork" else _variants(2 * a, h, K)
        for cf in cfs:
            if n - K - 2 - int(cf) < 1:
                break
            lb_s = _sigma_floor(sw, idx, a, h, K, cf, scale, joint=kw_range != [0],
                                hint=hints.get((2 * a, h, n, K, cf)))  # fmt: skip
            for Kw in kw_range:
                lb = lb_s
                if Kw:
                    lb += _w_bound(float(b), Kw, _w_comp(sw, idx_w, float(b), Kw, cf))
                combos.append((lb, K, cf, Kw))
    best: ModelFit | None = None
    best_crit = best_pen = math.inf
    key: tuple[int, bool, int] = (0, False, 0)
    for lb, K, cf, Kw in sorted(combos, key=lambda c: c[0]):
        comps = [_sigma_comp(sw, idx, 2 * a, h, K, cf)]
        bic_pen = (K + 2 + int(cf)) * math.log(n)
        if Kw:
            wc = _w_comp(sw, idx_w, float(b), Kw, cf)
            assert wc is not None
            comps.append(wc)
            bic_pen += (Kw + 1 + (0 if wc.known else 1)) * math.log(n_w)
        k_all = K + 2 + int(cf) + (Kw + 1 if Kw else 0)
        m_all = n + (n_w if Kw else 0)
        if best is not None and _crit(lb, lb + bic_pen, k_all, m_all) >= best_crit:
            continue  # no mu* makes this law beat the best (an exact lower bound)
        # the full search: the terms are chosen on these values, and a screening
        # search misses the narrow valley of precise data with enough corrections
        # (measured: a beam plan at 1.5e-5 noise chose 2 corrections and mu* 5.7 away)
        hint = hints.get((2 * a, h, n, K, cf))
        nll = _profile(sw.mu[idx], comps, scale, with_interval=False, hint=hint).nll
        bic = nll + bic_pen
        crit = _crit(nll, bic, k_all, m_all)
        if best is None or crit < best_crit or (crit == best_crit and (K, cf, Kw) < key):
            best_crit, best_pen, key = crit, bic_pen, (K, cf, Kw)
            best = ModelFit(
                name, a, b if b is not None else math.nan, h, n, K, Kw, bic, _NO_PROFILE,
                n_w, cf,
            )  # fmt: skip
    assert best is not None
    comps = [_sigma_comp(sw, idx, 2 * a, h, best.K, best.conformal)]
    if best.Kw:
        wc = _w_comp(sw, idx_w, float(b), best.Kw, best.conformal)  # type: ignore[arg-type]
        assert wc is not None
        comps.append(wc)
    # a law that misses its window beyond the noise (far, precise points where no truncated
    # series holds) widens its interval by the reduced chi-square (Birge ratio)
    inflate = 1.0
    fl: list[Flag] = []
    hint = hints.get((2 * a, h, n, best.K, best.conformal))
    chi = _profile(sw.mu[idx], comps, scale, with_interval=False, hint=hint).nll
    if all(c.known for c in comps):
        dof = n - best.K - 2 - int(best.conformal) + (n_w - best.Kw - 1 if best.Kw else 0)
        if dof >= 1 and chi > dof and _chi2_sf(chi, dof) < 0.01:
            inflate = chi / dof
            fl.append(
                Flag(
                    "law_misfit",
                    f"the {name} law misses its {n} nearest points beyond the noise (chi^2 = "
                    f"{chi:.3g} for {dof} degrees of freedom): interval widened by that ratio",
                )
            )
    prof = _profile(sw.mu[idx], comps, scale, level=level, inflate=inflate, hint=hint)
    if fl:
        prof = replace(prof, flags=(*prof.flags, *fl))
    return ModelFit(
        name, a, best.b, h, n, best.K, best.Kw, chi + best_pen, prof, n_w, best.conformal
    )


def _candidates(sw: Sweep) -> list[tuple[str, float, float | None, float]]:
    if sw.w is None:
        return [("saddle-node", 0.25, None, 0.5), ("pitchfork", 0.5, None, 1.0)]
    return [(k, a, b, h) for k, (a, b, h) in CANDIDATES.items()]


Law = tuple[str, float, "float | None", float]  # name, a, b (None: no static law), h
_Law = Law


def _compare(
    sw: Sweep, scale: float, law: _Law | None = None, level: float = 0.95
) -> tuple[Sweep, list[ModelFit], int, list[Flag]]:
    """Select the informative window, fit every candidate (or only ``law``) on it, return the
    fits sorted by BIC (and the sweep as used: noise rescaled, static noise estimated)."""
    flags: list[Flag] = []
    sel_laws = (
        {"saddle-node": (0.5, 0.5), "pitchfork": (1.0, 1.0)}
        if law is None
        else {law[0]: (2 * law[1], law[3])}
    )

    def select(s: Sweep) -> dict[str, Window]:
        return {nm: select_window(s, p, h, scale) for nm, (p, h) in sel_laws.items()}

    sels = select(sw)
    if not any(s.accepted for s in sels.values()):
        # over-dispersion: the data scatter more than their stated noise (or the simulator's
        # round-off dominates near mu*): scale the noise by the best reduced chi-square on the
        # nearest 8 points, where the laws hold (as the noise estimate reads it). Read over half
        # the sweep, a coarse grid's far points measured the series' truncation instead: a
        # noise-free fold was scaled to undetermined or a pitchfork, 1e-3 off (test_predict_lab)
        N = sw.mu.size
        m = min(N, 8)
        phi = math.inf
        for p, h in sel_laws.values():
            K = min(2, m - 2 - _MIN_NOISE_DOF)
            if K < 0:
                break
            phi = min(phi, _sigma_chi2(sw, p, h, m, K, scale) / (m - K - 2))
        if math.isfinite(phi) and phi > 1:
            sw = replace(sw, sd=sw.sd * math.sqrt(phi))
            flags.append(
                Flag(
                    "noise_underestimated",
                    f"the nearest points scatter {math.sqrt(phi):.3g} times more than the given "
                    "noise: the noise was scaled up by that factor",
                )
            )
            sels = select(sw)
    acc = [s.n for s in sels.values() if s.accepted]
    if acc:
        n_c = min(acc) if len(acc) > 1 else acc[0]
        n_c = max(n_c, min(sw.mu.size, 5))
    else:
        n_c = min(sw.mu.size, max(s.n for s in sels.values()))
        flags.append(
            Flag(
                "poor_fit",
                "no candidate law (with up to "
                f"{_KMAX} corrections) fits the nearest points within their noise",
            )
        )
    n_w = n_c
    if sw.w is not None and (law is None or law[2] is not None):
        # mu* from the eigenvalues alone fixes the static window
        N = sw.mu.size
        idx = slice(N - n_c, N)
        pre = min(
            (
                _profile(
                    sw.mu[idx],
                    [_sigma_comp(sw, idx, p, h, min(sels[nm].K, n_c - 3), sels[nm].conformal)],
                    scale,
                    with_interval=False,
                )  # fmt: skip
                for nm, (p, h) in sel_laws.items()
            ),
            key=lambda pr: pr.nll,
        )
        sw, n_w, fl = _static_window(sw, n_c, pre.mu_star)
        flags.extend(fl)
    cands = _candidates(sw) if law is None else [(law[0], law[1], law[2], law[3])]
    hints = {
        (p, h, s.n, s.K, s.conformal): (s.t, s.log_u)
        for nm, (p, h) in sel_laws.items()
        for s in (sels[nm],)
        if s.accepted and math.isfinite(s.t)
    }
    fits = [
        _fit_candidate(sw, name, a, (b if sw.w is not None else None), h, n_c, scale, level, n_w,
                       hints)
        for name, a, b, h in cands
    ]  # fmt: skip
    probs = _bic_weights(fits)
    if law is None and acc and max(acc) > n_c:
        # the candidates hold over different windows: compare them on the larger one as well.
        # On the smaller window a flexible wrong law can follow the data; on the larger one the
        # law that converges farther (e.g. a pitchfork's series in the conformal variable, or a
        # true fold's) wins. The probabilities are the mean of both comparisons, so that two
        # windows that disagree leave the type undetermined instead of confidently wrong.
        n_x = max(acc)
        wide = [
            _fit_candidate(sw, name, a, (b if sw.w is not None else None), h, n_x, scale,
                           level, max(n_w, n_x), hints)
            for name, a, b, h in cands
        ]  # fmt: skip
        pw = _bic_weights(wide)
        probs = [0.5 * (p1 + p2) for p1, p2 in zip(probs, pw, strict=True)]
    fits = [replace(f, weight=float(pr)) for f, pr in zip(fits, probs, strict=True)]
    fits.sort(key=lambda f: -f.weight)
    return sw, fits, n_c, flags


def _bic_weights(fits: list[ModelFit]) -> list[float]:
    bics = np.array([f.bic for f in fits])
    wts = np.exp(-0.5 * (bics - bics.min()))
    return (wts / wts.sum()).tolist()


def _probabilities(fits: list[ModelFit]) -> dict[str, float]:
    if all(math.isfinite(f.weight) for f in fits):
        wts = np.array([f.weight for f in fits])
    else:
        wts = np.array(_bic_weights(fits))
    wts = wts / wts.sum()
    return {f.name: float(wv) for f, wv in zip(fits, wts, strict=True)}


def _analyse(
    sw: Sweep, law: _Law | None = None, level: float = 0.95
) -> tuple[Sweep, list[ModelFit], int, list[Flag]]:
    """Noise estimate, damping (omega data), window and candidate fits (all, or ``law``)."""
    flags: list[Flag] = []
    sw = _estimate_noise(sw)
    if not sw.noise_given:
        flags.append(_noise_flag(sw))
    scale = float(sw.mu[-1] - sw.mu[0])
    if sw.kind == "omega":
        assert sw.omega is not None
        if sw.damping is not None:
            sw = _with_damping(sw, sw.damping)
        else:
            xi = identify_damping(sw, scale)
            if xi > 0:
                sw = _with_damping(sw, xi)
    sw, fits, n_c, fl = _compare(sw, scale, law, level)
    return sw, fits, n_c, flags + fl


# --------------------------------------------------------------------------------------------
# public entry points
# --------------------------------------------------------------------------------------------


def analyse(
    sweep: Sweep, law: Law | None = None, level: float = 0.95
) -> tuple[Sweep, list[ModelFit], int, list[Flag]]:
    """Fit every candidate law (or only ``law``) to a prepared sweep.

    Parameters
    ----------
    sweep : Sweep
        From :func:`.sweep.prepare_sweep`.
    law : (name, a, b, h), optional
        One law to fit: its name, time exponent ``a``, static exponent ``b`` (None: the
        eigenvalues alone) and correction step ``h``.
    level : float
        Level of the profile intervals of the final fits.

    Returns
    -------
    sweep : Sweep
        The sweep as used (noise estimated or rescaled, damping applied to ``omega`` data).
    fits : list of ModelFit
        Sorted by BIC (best first), each on the common informative window.
    window : int
        Size of that window (nearest points).
    flags : list of Flag
    """
    return _analyse(sweep, law, level)


def probabilities(fits: list[ModelFit]) -> dict[str, float]:
    """Model probabilities (BIC weights) of fitted candidates."""
    return _probabilities(fits)


def refit_profile(sweep: Sweep, fit: ModelFit, n: int, K: int) -> tuple[float, float]:
    """mu* of ``fit``'s eigenvalue law refitted on the nearest ``n`` points with ``K``
    corrections (same variant) and its standard deviation, half the width of the 68 % profile
    interval (control units); NaNs when that fit has no degrees of freedom left."""
    if n - K - 2 - int(fit.conformal) < 1 or n < 3 or K < 0 or n > sweep.mu.size:
        return math.nan, math.nan
    N = sweep.mu.size
    idx = slice(N - n, N)
    comp = _sigma_comp(sweep, idx, 2 * fit.a, fit.h, K, fit.conformal)
    scale = float(sweep.mu[-1] - sweep.mu[0])
    # the 68 % interval alone: the same mu* and half-width as the full profile's
    prof = _profile(sweep.mu[idx], [comp], scale, with_interval=True, only68=True)
    return prof.mu_star, 0.5 * (prof.hi68 - prof.lo68)


def fewer_terms_rival(sweep: Sweep, fit: ModelFit, level: float) -> tuple[ModelFit, float]:
    """``fit``'s eigenvalue law with one correction fewer on the same window (same variant,
    its profile interval at ``level``) and the weight it keeps against ``fit``: smoothed AICc
    between the two term counts, ``1 / (1 + exp(dAICc / 2))`` (Buckland et al. 1997), on the
    eigenvalue data alone. ``(fit, 0.0)`` when ``fit`` has no correction or the rival's weight
    is below ``_RIVAL_MIN``.

    The number of corrections is chosen on the data (AICc on the window, the same test the
    rival is weighed by): an interval read from the chosen fit alone ignores that choice
    (ledger: docs/predictor.md, "Fewer-terms rival").
    """
    cf = int(fit.conformal)
    n, K = fit.n, fit.K
    if K < 1 or n - K - 1 - cf < 1 or n > sweep.mu.size:
        return fit, 0.0
    N = sweep.mu.size
    idx = slice(N - n, N)
    scale = float(sweep.mu[-1] - sweep.mu[0])
    x = sweep.mu[idx]

    def nll(k: int) -> float:
        comp = _sigma_comp(sweep, idx, 2 * fit.a, fit.h, k, fit.conformal)
        return _profile(x, [comp], scale, with_interval=False).nll

    d_aicc = _crit(nll(K - 1), math.nan, K + 1 + cf, n) - _crit(nll(K), math.nan, K + 2 + cf, n)
    w = 1.0 / (1.0 + math.exp(min(d_aicc / 2, 700.0)))
    if not w >= _RIVAL_MIN:
        return fit, 0.0
    comp = _sigma_comp(sweep, idx, 2 * fit.a, fit.h, K - 1, fit.conformal)
    prof = _profile(x, [comp], scale, level=level)
    return replace(fit, K=K - 1, Kw=0, profile=prof), w


def secondary_fold(sweep: Sweep, fit: ModelFit) -> float:
    """Distance ``delta`` from ``fit``'s mu* to the secondary fold its conformal law profiled
    (control units; ``inf`` for a plain law or when the plain law is best at that mu*)."""
    if not fit.conformal or not math.isfinite(fit.profile.mu_star):
        return math.inf
    N = sweep.mu.size
    idx = slice(N - fit.n, N)
    comp = _sigma_comp(sweep, idx, 2 * fit.a, fit.h, fit.K, True)
    _, u = _nll_u(sweep.mu[idx], [comp], np.array([fit.profile.mu_star]))
    x_last = fit.profile.mu_star - float(sweep.mu[-1])
    return x_last / float(u[0]) if u[0] > 0 else math.inf


def fold_rival_gap(sweep: Sweep, fit: ModelFit) -> float:
    """How much worse a fold explains ``fit``'s eigenvalues: ``-2 log L`` of the saddle-node
    law with one correction more than ``fit`` has (so as many parameters as a conformal law's,
    whose fold parameter it gives up) minus ``fit``'s own, on ``fit``'s window, the eigenvalues
    alone (dimensionless; ``inf`` when that fold law has no degree of freedom left)."""
    N = sweep.mu.size
    idx = slice(N - fit.n, N)
    K = fit.K + 1
    if fit.n - K - 2 < 1:
        return math.inf
    scale = float(sweep.mu[-1] - sweep.mu[0])
    a, _, h = CANDIDATES["saddle-node"]
    fold = _sigma_comp(sweep, idx, 2 * a, h, K)
    own = _sigma_comp(sweep, idx, 2 * fit.a, fit.h, fit.K, fit.conformal)
    mu = sweep.mu[idx]
    gap = (_profile(mu, [fold], scale, with_interval=False).nll
           - _profile(mu, [own], scale, with_interval=False).nll)  # fmt: skip
    return float(gap)


def free_exponent_a(sweep: Sweep, fit: ModelFit, n: int) -> tuple[float, float]:
    """Free time exponent ``a`` (``sqrt|sigma^2| ~ x^a``) and its standard error on the
    nearest ``n`` points, with ``fit``'s corrections and variant, mu* profiled."""
    N = sweep.mu.size
    idx = slice(N - n, N)
    scale = float(sweep.mu[-1] - sweep.mu[0])

    def make(p: float) -> list[_Comp]:
        return [
            _Comp(sweep.y[idx], 1.0 / sweep.sd[idx], _sigma_exps(p, fit.h, fit.K), True, True,
                  conformal=fit.conformal)
        ]  # fmt: skip

    last = float(sweep.mu[-1])
    hint = None
    if fit.profile.mu_star > last:  # the fit's optimum: where the law's own search starts too
        hint = (math.log(fit.profile.mu_star - last), fit.profile.log_u)
    a2, a2_se = free_exponent(
        sweep.mu[idx], make, exponent_grid(0.2, 2.5, [0.5, 1.0, 2.0]), scale, center=2 * fit.a,
        hint=hint,
    )  # fmt: skip
    return a2 / 2, a2_se / 2


def free_exponent_b(sweep: Sweep, fit: ModelFit, n: int) -> tuple[float, float]:
    """Free static exponent ``b`` (``|w - w*| ~ x^b``) and its standard error on the nearest
    ``n`` points at ``fit``'s mu* (NaN without static data)."""
    if sweep.w is None:
        return math.nan, math.nan
    N = sweep.mu.size
    iw = slice(N - n, N)
    scale = float(sweep.mu[-1] - sweep.mu[0])
    wsd = sweep.w_sd
    w = sweep.w

    def make(b: float) -> list[_Comp]:
        e = _w_exps(b, max(fit.Kw, 2))
        wt = 1.0 / wsd[iw] if wsd is not None else np.ones(n)
        known = wsd is not None and sweep.w_noise_given
        # w - w* = g x^b (1 + corrections): the x^b term must lead inside the window
        return [_Comp(w[iw], wt, e, known, True, 1, False, conformal=fit.conformal)]

    return free_exponent(
        sweep.mu[iw], make, exponent_grid(0.25, 1.9, [0.5, 1.0]), scale,
        fixed_mu=fit.profile.mu_star,
    )  # fmt: skip
