"""Informative windows and noise: where a candidate law holds, and how noisy the data are.

The window of "informative" points of a law (the nearest points where it holds with at most
``_KMAX`` corrections) is chosen by a chi-square goodness-of-fit test against the measurement
noise (:func:`select_window`); the static law gets its own, usually wider window
(:func:`_static_window`). Without a given noise the relative noise of ``|sigma^2|`` is estimated
from the scatter about the best candidate (:func:`_estimate_noise`); observed rates of a damped
strip are mapped to ``|sigma^2|`` (:func:`_with_damping`). Used by :mod:`.compare`.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, replace

import numpy as np
from scipy import special

from service.analysis.common import Flag
from service.analysis.predictor._dist import chi2_ppf
from service.analysis.predictor._kernels.laws import REL_FLOOR as _REL_FLOOR
from service.analysis.predictor.laws import CANDIDATES
from service.analysis.predictor.likelihood import (
    _Comp,
    _nll,
    _polynomial_bound,
    _profile,
    _profile_screen,
    _sigma_comp,
    _sigma_exps,
    _variants,
    _w_comp,
)
from service.analysis.predictor.sweep import Sweep

__all__ = ["Window", "select_window"]

_KMAX = 3  # most correction terms in the sigma^2 law
_KW_MAX = 3  # most terms beyond the constant in the static law
_ALPHA = 0.05  # goodness-of-fit level for accepting a window
_NESTED_K = 0  # corrections up to which a smaller window's misfit bounds a larger one's


def _window_sizes(n: int) -> list[int]:
    if n <= 40:
        return list(range(3, n + 1))
    sizes = sorted(set(np.unique(np.round(np.geomspace(3, n, 36)).astype(int)).tolist()))
    return sizes


@dataclass(frozen=True)
class Window:
    """The informative window of a sigma^2 law, a value (:func:`select_window` chooses it).

    Attributes
    ----------
    n : int
        Nearest points in it.
    K : int
        Number of correction terms of the law on it.
    accepted : bool
        Whether the law holds on it (chi-square at ``_ALPHA``); else the best window tried.
    pvalue : float
        The goodness-of-fit p-value read.
    conformal : bool
        Whether the law is the conformal (secondary-fold) form.
    t, log_u : float
        The optimum the verdict was read at: ``log(mu* - mu_last)`` and a conformal law's log
        fold parameter (a later fit of the same law on the window searches from there too).
    """

    n: int
    K: int
    accepted: bool
    pvalue: float
    conformal: bool = False
    t: float = math.nan
    log_u: float = math.nan


def _chi2_sf(x: float, dof: int) -> float:
    """``scipy.stats.chi2.sf(x, dof)`` (the same value) without the distribution machinery's
    per-call overhead (some 50 us, paid hundreds of times per prediction)."""
    return 1.0 if x < 0 else float(special.chdtrc(dof, x))


@functools.lru_cache(maxsize=1024)
def _chi2_isf(alpha: float, dof: int) -> float:
    """Critical chi^2 value exceeded with probability ``alpha`` (``scipy.stats.chi2.isf``;
    memoised: the same few are asked for hundreds of times per prediction)."""
    return float(special.chdtri(dof, alpha))


class _Screens:
    """The tests of one law's windows (:func:`select_window`) and what they carry from one
    window to the next: the last optimum (continuation of the searches), the (K, variant)
    that passed on the last window tried, the lower bounds of nested windows and the best
    failing window so far."""

    def __init__(self, sw: Sweep, p: float, h: float, scale: float) -> None:
        self.sw, self.p, self.h, self.scale = sw, p, h, scale
        self.last = float(sw.mu[-1])
        self.t_prev: float | None = None  # log(mu* - mu_last) of the last fit
        self.lu_prev = math.nan  # and a conformal law's log fold parameter there
        self.held: set[tuple[int, bool]] = set()
        self.floor: dict[tuple[int, bool], float] = {}  # (K, variant) -> bound of -2 log L
        self.fallback: Window | None = None

    def ruled_out(self, n: int, K: int, cf: bool) -> bool:
        """Whether a lower bound of -2 log L fails the test on ``n`` points, with no better
        fallback: a failure known without a search.

        A window holds every smaller one's points (and the same nearest point, so the same
        fold parameter u means the same delta): at every mu* and u its least-squares misfit
        is at least theirs, and with K = 0 (no correction to constrain) -2 log L is that
        misfit, so a smaller window's minimum bounds it (on a long sweep, most of the K = 0
        searches). A plain pitchfork law is a polynomial of degree K + 1 in mu: the best
        polynomial's chi^2 bounds it at every mu* (exact, one small fit)."""
        sw, fb = self.sw, self.fallback
        if fb is None:
            return False
        dof = n - K - 2 - int(cf)
        lb = self.floor.get((K, cf), -math.inf)
        pv_lb = _chi2_sf(lb, dof) if lb > 0 else 1.0
        if not cf and self.p == 1.0 and self.h == 1.0 and not (
            pv_lb < _ALPHA and pv_lb <= fb.pvalue
        ):
            N = sw.mu.size
            idx = slice(N - n, N)
            poly = _polynomial_bound(sw.mu[idx], sw.y[idx], 1.0 / sw.sd[idx], K + 1)
            if poly > lb:
                pv_lb = _chi2_sf(poly, dof) if poly > 0 else 1.0
        return pv_lb < _ALPHA and pv_lb <= fb.pvalue

    def _comp(self, n: int, K: int, cf: bool) -> tuple[np.ndarray, _Comp]:
        N = self.sw.mu.size
        idx = slice(N - n, N)
        return self.sw.mu[idx], _sigma_comp(self.sw, idx, self.p, self.h, K, cf)

    def screen(self, n: int, K: int, cf: bool) -> float:
        """-2 log L of a cheap search (an upper bound of the minimum; a local one first where
        this (K, variant) held on the last window, see :func:`_profile_screen`)."""
        crit = _chi2_isf(_ALPHA, n - K - 2 - int(cf))
        local = crit if (K, cf) in self.held else None
        mu, comp = self._comp(n, K, cf)
        self.t_prev, nll, lu = _profile_screen(
            mu, [comp], self.scale, self.t_prev, self.lu_prev, local
        )
        self.lu_prev = lu if cf else self.lu_prev
        return nll

    def full(self, n: int, K: int, cf: bool) -> float:
        """-2 log L of the full search (a screen can miss the narrow valley of precise data:
        a rejection comes from this one only); its minimum bounds larger windows' (K = 0)."""
        mu, comp = self._comp(n, K, cf)
        prof = _profile(mu, [comp], self.scale, with_interval=False)
        self.t_prev = math.log(max(prof.mu_star - self.last, 1e-300))
        self.lu_prev = prof.log_u if cf else self.lu_prev
        if K <= _NESTED_K:
            self.floor[(K, cf)] = prof.nll
        return prof.nll

    def record(self, n: int, K: int, cf: bool, nll: float) -> Window:
        """The test's verdict on ``nll`` (the fallback kept: the best p-value seen)."""
        pv = _chi2_sf(nll, n - K - 2 - int(cf))
        ok = pv >= _ALPHA
        if ok:
            self.held.add((K, cf))
        else:
            self.held.discard((K, cf))
        t = self.t_prev if self.t_prev is not None else math.nan
        lu = self.lu_prev if cf else math.nan
        if self.fallback is None or pv > self.fallback.pvalue:
            self.fallback = Window(n, K, False, pv, cf, t, lu)
        return Window(n, K, ok, pv, cf, t, lu)

    def window(self, n: int) -> tuple[Window | None, list[tuple[int, bool]]]:
        """Whether some (K, variant) passes on the nearest ``n`` points: the passing one (or
        None) and the fewer ones not proven to fail (searched fully only for the window
        :func:`select_window` returns).

        The (K, variant) that held on the last window are screened first, by local searches
        (the law usually holds on, its optimum close by); then the others, fewest
        corrections first; a window is accepted on the first screen passed. Where none
        passes, the full searches decide, fewest corrections first."""
        combos = [
            (K, cf) for K in range(_KMAX + 1) for cf in _variants(self.p, self.h, K)
            if n - K - 2 - int(cf) >= 1
        ]  # fmt: skip
        failed: list[tuple[int, bool]] = []  # screens failed, full searches put off
        order = [c for c in combos if c in self.held] + [c for c in combos if c not in self.held]
        for c in order:
            if self.ruled_out(n, *c):
                continue
            nll = self.screen(n, *c)
            if nll > _chi2_isf(_ALPHA, n - c[0] - 2 - int(c[1])) and c[0] <= _NESTED_K:
                nll = self.full(n, *c)  # now: its minimum bounds the larger windows
            sel = self.record(n, *c, nll)
            if sel.accepted:
                return sel, [f for f in combos if f < c]
            if c[0] > _NESTED_K:
                failed.append(c)
        for c in sorted(failed):
            sel = self.record(n, *c, self.full(n, *c))
            if sel.accepted:
                return sel, [f for f in combos if f < c]
        return None, []


def select_window(sw: Sweep, p: float, h: float, scale: float, patience: int = 4) -> Window:
    """Largest window of nearest points where the law + <= _KMAX corrections passes chi^2,
    with the fewest corrections that pass there.

    Windows grow from the 3 nearest points; the scan stops after ``patience`` consecutive
    window sizes that no number of corrections can fit (the law has stopped holding). A
    window passes on its first screen passed (:meth:`_Screens.window`); the full searches
    that tell the fewest corrections are run for the window returned alone (measured on
    the symmetric bench sweep: some 8 full searches of the conformal law fewer)."""
    N = sw.mu.size
    scr = _Screens(sw, p, h, scale)
    best: Window | None = None
    below: list[tuple[int, bool]] = []
    misses = 0
    for n in _window_sizes(N):
        sel, lower = scr.window(n)
        if sel is not None:
            best, below = sel, lower
        misses = 0 if sel is not None else misses + 1
        if misses >= patience and (best is not None or n >= 8):
            break
    if best is None:
        assert scr.fallback is not None
        return scr.fallback
    for K, cf in below:
        if scr.ruled_out(best.n, K, cf):
            continue
        nll = scr.screen(best.n, K, cf)
        if nll > _chi2_isf(_ALPHA, best.n - K - 2 - int(cf)):
            nll = scr.full(best.n, K, cf)
        sel = scr.record(best.n, K, cf, nll)
        if sel.accepted:
            return sel
    return best


def _sigma_chi2(
    sw: Sweep, p: float, h: float, n: int, K: int, scale: float, conformal: bool | None = None
) -> float:
    """Best chi^2 of the law on the nearest n points (over its variants when ``conformal`` is
    None)."""
    N = sw.mu.size
    idx = slice(N - n, N)
    cfs = _variants(p, h) if conformal is None else (conformal,)
    return min(
        _profile(sw.mu[idx], [_sigma_comp(sw, idx, p, h, K, cf)], scale, with_interval=False).nll
        for cf in cfs
    )


_ASSUMED_REL = 1e-2  # relative noise assumed when it can be neither given nor estimated
_MIN_NOISE_DOF = 3


def _estimate_noise(sw: Sweep) -> Sweep:
    """Relative noise of |sigma^2| when not given: the smaller of two estimates that can only
    err upwards (by a law's truncation), each a residual scatter:

    * about the best candidate law with two corrections on the nearest ``m`` points, for
      ``m`` the fewest with ``_MIN_NOISE_DOF`` degrees of freedom and for half the sweep
      (the law holds near mu*; on a coarse grid half the sweep reaches where it does not,
      and its misfit there read as noise was 100x the true noise on beam plans);
    * model-free, :func:`_local_scatter` (local cubics in mu, away from mu* as well).

    With fewer than 6 points neither exists and ``_ASSUMED_REL`` is assumed (``_noise_flag``).
    """
    if sw.noise_given:
        return sw
    N = sw.mu.size
    scale = float(sw.mu[-1] - sw.mu[0])
    local = _local_scatter(sw.mu, sw.y) ** 2
    best = math.inf
    for n in sorted({min(N, 8), min(N, max(8, N // 2))}):
        idx = slice(N - n, N)
        K = min(2, n - 2 - _MIN_NOISE_DOF)
        if K < 0:
            continue
        for _, (a, _, h) in CANDIDATES.items():
            for cf in _variants(2 * a, h):
                if n - K - 2 - int(cf) < 1:
                    continue
                c = _Comp(sw.y[idx], 1.0 / sw.y[idx], _sigma_exps(2 * a, h, K), True, True,
                          conformal=cf)  # fmt: skip
                prof = _profile(sw.mu[idx], [c], scale, with_interval=False)
                best = min(best, prof.nll / (n - K - 2 - int(cf)))
    if not best < local / _LOCAL_TRUNCATED**2:
        best = local
    s = math.sqrt(best) if math.isfinite(best) else _ASSUMED_REL
    s = max(s, _REL_FLOOR)
    return replace(sw, sd=s * sw.y, noise_given=False)


_LOCAL_TRUNCATED = 3.0  # a law's scatter this much below the local one: the cubics truncate
_CHI2_1_MEDIAN = 0.454936423119572  # median of chi^2 with one degree of freedom


def _local_scatter(mu: np.ndarray, y: np.ndarray) -> float:
    """Model-free relative noise of ``y``: each 5 consecutive points leave one residual degree
    of freedom about a weighted cubic in ``mu`` (weights ``1/|y|``), whose squared residual is
    ``(sum d_i y_i)^2 / sum (d_i y_i)^2`` with ``d`` the fourth divided difference's weights;
    the noise is read from their median (robust to the blocks near mu*, where y is not a
    cubic on the grid's scale). ``inf`` with fewer than 3 blocks."""
    N = mu.size
    if N < 7:
        return math.inf
    i = np.arange(N - 4)[:, None] + np.arange(5)[None, :]  # (B, 5) block indices
    m, v = mu[i], y[i]
    diff = m[:, :, None] - m[:, None, :]  # (B, 5, 5)
    diff[:, np.arange(5), np.arange(5)] = 1.0
    with np.errstate(all="ignore"):
        d = 1.0 / np.prod(diff / np.ptp(m, axis=1)[:, None, None], axis=2)  # scaled weights
    with np.errstate(all="ignore"):
        dv = d * v
        r2 = np.sum(dv, axis=1) ** 2 / np.sum(dv * dv, axis=1)
    r2 = r2[np.isfinite(r2)]  # a block of nearly coincident points over- or underflows
    if r2.size < 3:
        return math.inf
    return math.sqrt(float(np.median(r2)) / _CHI2_1_MEDIAN)


def _noise_flag(sw: Sweep) -> Flag:
    """The flag telling how the noise of an estimated-noise sweep was obtained."""
    which = "sigma2_std" if sw.kind == "sigma2" else "omega_std"
    rel = float(np.median(sw.sd / sw.y))
    if sw.mu.size < 4 + _MIN_NOISE_DOF:
        how = (
            f"assumed to be {rel:.2g}"
            if rel == _ASSUMED_REL
            else f"read from the scatter about the best law on so few points as {rel:.2g} (an "
            "uncertain estimate; exact data give the floor 1e-12)"
        )
        return Flag(
            "noise_assumed",
            f"no {which} given and only {sw.mu.size} points: relative noise of |sigma2| {how}",
        )
    return Flag(
        "noise_estimated",
        f"no {which} given: relative noise of |sigma2| estimated from the scatter as {rel:.2g}",
    )


def _with_damping(sw: Sweep, xi: float) -> Sweep:
    """Map observed rates to |sigma^2| for damping ``xi``: omega^2 above xi/2, omega (xi - omega)
    below it (the slow over-damped pole r satisfies r (xi - r) = s1 s2 = |sigma^2|)."""
    assert sw.omega is not None
    r = sw.omega
    over = r < xi / 2
    y = np.where(over, r * (xi - r), r**2)
    if sw.omega_sd is not None:
        d = np.where(over, np.abs(xi - 2 * r), 2 * r)
        sd = np.sqrt((d * sw.omega_sd) ** 2 + 2 * sw.omega_sd**4)
    else:
        rel = sw.sd / sw.y  # estimated relative noise of omega^2
        sd = rel * y * np.where(over, np.abs(xi - 2 * r) / np.maximum(xi - r, 1e-300) / 2, 1.0)
        sd = np.maximum(sd, _REL_FLOOR * y)
    return replace(sw, y=y, sd=sd, damping=xi)


def _static_window(sw: Sweep, n: int, mu_star: float) -> tuple[Sweep, int, list[Flag]]:
    """Window of the static law (>= n points) and, when not given, the noise of w.

    The noise of w is estimated from the scatter about the widest static series (b = 1/2, five
    terms, which contains the smooth b = 1 law) on the nearest max(8, n) points. The window then
    grows while either static law (<= 1 + _KW_MAX terms, mu* fixed at the eigenvalue estimate)
    passes the chi-square test; the candidates are compared on the largest such window, where
    the wrong law cannot follow the data."""
    flags: list[Flag] = []
    N = sw.mu.size
    if sw.w is None:
        return sw, n, flags
    if sw.w_sd is None:
        m = min(N, max(8, n))
        if m - 5 < _MIN_NOISE_DOF:
            return sw, n, flags
        idx = slice(N - m, N)
        c = _Comp(sw.w[idx], np.ones(m), np.array([0.0, 0.5, 1.0, 1.5, 2.0]), True)
        rss = float(_nll(sw.mu[idx], [c], np.array([mu_star]))[0])
        sig = max(math.sqrt(rss / (m - 5)), _REL_FLOOR * float(np.max(np.abs(sw.w))), 1e-300)
        sw = replace(sw, w_sd=np.full(N, sig), w_noise_given=False)
        flags.append(
            Flag(
                "w_noise_estimated", f"no w_static_std given: estimated from the scatter, {sig:.2g}"
            )
        )
    else:
        # over-dispersion of the static data (e.g. the mean of a kicked, nonlinear record is
        # shifted by ~ amplitude^2 / |sigma^2|, far above a detector's stated offset error):
        # scale the given noise by the reduced chi-square of the widest static series. It is
        # read at the eigenvalues' mu*, so it also holds the series' truncation and that mu*'s
        # own error seen through records more precise than it (the simulator's, 1e-13 near
        # mu*): a quasi-likelihood for the fits, not proof that the records scatter (rule
        # static_misfit reads the static law at a shared mu* instead)
        m = min(N, max(8, n))
        if m - 5 >= _MIN_NOISE_DOF:
            idx = slice(N - m, N)
            c = _Comp(sw.w[idx], 1.0 / sw.w_sd[idx], np.array([0.0, 0.5, 1.0, 1.5, 2.0]), True)
            phi = float(_nll(sw.mu[idx], [c], np.array([mu_star]))[0]) / (m - 5)
            if phi > float(chi2_ppf(0.99, m - 5)) / (m - 5):
                sw = replace(sw, w_sd=sw.w_sd * math.sqrt(phi))
                flags.append(
                    Flag(
                        "w_noise_underestimated",
                        f"the static deflections miss the static law at the eigenvalues' mu* "
                        f"by {math.sqrt(phi):.3g} times w_static_std (a scatter beyond it, the "
                        "law's truncation or that mu*'s own error): that noise was scaled up "
                        "by this factor for the fits",
                    )
                )
    best_n = n
    for b in (0.5, 1.0):
        misses = 0
        for m in range(n, N + 1):
            idx = slice(N - m, N)
            ok = False
            for Kw in range(1, _KW_MAX + 1):
                dof = m - Kw - 1
                if dof < 1:
                    break
                wc = _w_comp(sw, idx, b, Kw)
                assert wc is not None
                wc = _Comp(wc.y, wc.wt, wc.exps, True, True, 1, False, wc.mu)  # chi^2 test
                chi = float(_nll(sw.mu[idx], [wc], np.array([mu_star]))[0])
                if _chi2_sf(chi, dof) >= _ALPHA:
                    ok = True
                    break
            if ok:
                best_n = max(best_n, m)
                misses = 0
            else:
                misses += 1
                if misses >= 3:
                    break
    return sw, best_n, flags
