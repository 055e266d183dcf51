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

Regular corrections. The laws above hold with analytic corrections in the natural small
parameter of each normal form. Near a fold the branch is analytic in its amplitude
``s ~ x^(1/2)``, so the corrections of ``sigma^2`` and ``w`` come in powers of ``x^(1/2)``:
``|sigma^2| = x^(1/2) (c0 + c1 x^(1/2) + c2 x + ...)``. Near a symmetric pitchfork every quantity is
even in the amplitude (``A^2 ~ x``), so ``|sigma^2| = x (c0 + c1 x + ...)``; on the smooth branch of
the subcritical case ``w`` is analytic in ``x`` (``b = 1``); on a side branch of the
supercritical one ``w - w*`` is a series in ``x^(1/2)``.

Method. For a fixed ``mu*`` every model is linear in its coefficients, so the likelihood is
profiled over ``mu*`` (variable projection; a 1-D search on a logarithmic grid, refined by
Brent's method). The number of correction terms and the window of "informative" points (the
``n`` points nearest to ``mu*`` where the law plus corrections holds) are chosen by a chi-square
goodness-of-fit test against the measurement noise; the candidates are then compared on a common
window by BIC, which gives the model probabilities. Free-exponent fits (profiled over ``a`` or
``b``) give ``a``, ``b`` and their standard errors.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy import optimize, stats

from service.analysis._laws_kernels import REL_FLOOR as _REL_FLOOR
from service.analysis._laws_kernels import nll_rows
from service.analysis.common import Flag

__all__ = [
    "CANDIDATES",
    "Classification",
    "Sweep",
    "classify",
    "prepare_sweep",
]

# name -> (a, b, h): a, b exponents; h the step of the regular corrections in powers of x.
CANDIDATES: dict[str, tuple[float, float, float]] = {
    "saddle-node": (0.25, 0.5, 0.5),
    "subcritical-pitchfork": (0.5, 1.0, 1.0),
    "supercritical-pitchfork": (0.5, 0.5, 1.0),
}
TRANSITIONS = (
    "saddle-node",
    "subcritical-pitchfork",
    "supercritical-pitchfork",
    "pitchfork",
    "undetermined",
)
REGIMES = ("underdamped", "overdamped")

_KMAX = 3  # most correction terms in the sigma^2 law
_KW_MAX = 3  # most terms beyond the constant in the static law
_ALPHA = 0.05  # goodness-of-fit level for accepting a window
_GRID = 111


# --------------------------------------------------------------------------------------------
# input
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Sweep:
    """Validated measurements along an upward sweep (internal, shared with the predictor).

    Attributes
    ----------
    mu : ndarray, shape (n,)
        Control parameter, strictly increasing, any unit.
    y : ndarray, shape (n,)
        ``|sigma^2|`` (1/time^2), positive; for ``kind == "omega"`` this is ``omega^2``.
    sd : ndarray, shape (n,)
        Standard deviation of ``y`` (given, or estimated when ``noise_estimated``).
    kind : {"sigma2", "omega"}
        What the caller gave.
    omega, omega_sd : ndarray or None
        The observed rates (``kind == "omega"`` only).
    w, w_sd : ndarray or None
        Static deflection at the probe and its standard deviation (``None``: unknown).
    noise_given : bool
        Whether the caller gave the noise of ``sigma2`` / ``omega``.
    damping : float or None
        Damping ``xi`` (1/time) in ``s^2 + xi s - sigma^2 = 0`` when known.
    w_noise_given : bool
        False when ``w_sd`` was estimated (the static fits then profile their variance).
    """

    mu: np.ndarray
    y: np.ndarray
    sd: np.ndarray
    kind: str
    omega: np.ndarray | None
    omega_sd: np.ndarray | None
    w: np.ndarray | None
    w_sd: np.ndarray | None
    noise_given: bool
    damping: float | None
    w_noise_given: bool = True


def _as_1d(name: str, value: Any, n: int | None = None) -> np.ndarray:
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name} must be an array of numbers, got {value!r}") from exc
    if arr.ndim != 1:
        raise ValueError(f"{name} must be one-dimensional, got shape {arr.shape}")
    if n is not None and arr.size != n:
        raise ValueError(f"{name} must have the length of mu ({n}), got {arr.size}")
    bad = np.flatnonzero(~np.isfinite(arr))
    if bad.size:
        i = int(bad[0])
        raise ValueError(f"{name} must be finite, got {name}[{i}]={arr[i]!r}")
    return arr


def prepare_sweep(
    mu: Sequence[float] | np.ndarray,
    sigma2: Sequence[float] | np.ndarray | None = None,
    *,
    sigma2_std: Sequence[float] | np.ndarray | None = None,
    omega: Sequence[float] | np.ndarray | None = None,
    omega_std: Sequence[float] | np.ndarray | None = None,
    w_static: Sequence[float] | np.ndarray | None = None,
    w_static_std: Sequence[float] | np.ndarray | float | None = None,
    damping: float | None = None,
) -> Sweep:
    """Validate a sweep at the door; raise ``ValueError`` naming the parameter and the value.

    Parameters
    ----------
    mu : array_like, shape (n,)
        Control parameter, strictly increasing, n >= 3.
    sigma2 : array_like, shape (n,), optional
        Undamped eigenvalue of the fundamental (1/time^2), < 0 on the stable branch.
    sigma2_std : array_like, shape (n,), optional
        Its standard deviation, > 0.
    omega, omega_std : array_like, shape (n,), optional
        Instead of ``sigma2``: the observed angular rate (rad/time), > 0; ``sigma2 = -omega^2``.
    w_static, w_static_std : array_like, optional
        Static deflection at the probe (any length unit) and its standard deviation.
    damping : float, optional
        Damping ``xi`` (1/time), >= 0.

    Returns
    -------
    Sweep
    """
    m = _as_1d("mu", mu)
    n = m.size
    if n < 3:
        raise ValueError(f"mu needs at least 3 points, got {n}")
    step = np.diff(m)
    if np.any(step <= 0):
        i = int(np.flatnonzero(step <= 0)[0])
        raise ValueError(
            f"mu must be strictly increasing (an upward sweep), got mu[{i}]={m[i]!r} "
            f"then mu[{i + 1}]={m[i + 1]!r}"
        )
    if (sigma2 is None) == (omega is None):
        given = "neither" if sigma2 is None else "both"
        raise ValueError(f"give exactly one of sigma2 and omega, got {given}")
    if sigma2_std is not None and omega is not None:
        raise ValueError("sigma2_std=... goes with sigma2, not with omega (use omega_std)")
    if omega_std is not None and sigma2 is not None:
        raise ValueError("omega_std=... goes with omega, not with sigma2 (use sigma2_std)")
    om = om_sd = None
    if sigma2 is not None:
        s2 = _as_1d("sigma2", sigma2, n)
        pos = np.flatnonzero(s2 >= 0)
        if pos.size:
            i = int(pos[0])
            raise ValueError(
                f"sigma2 must be < 0 (a stable mode on the measured branch), got sigma2[{i}]="
                f"{s2[i]!r}"
            )
        y = -s2
        kind = "sigma2"
        sd = None
        if sigma2_std is not None:
            sd = _as_1d("sigma2_std", sigma2_std, n)
            if np.any(sd <= 0):
                i = int(np.flatnonzero(sd <= 0)[0])
                raise ValueError(f"sigma2_std must be > 0, got sigma2_std[{i}]={sd[i]!r}")
    else:
        om = _as_1d("omega", omega, n)
        if np.any(om <= 0):
            i = int(np.flatnonzero(om <= 0)[0])
            raise ValueError(f"omega must be > 0, got omega[{i}]={om[i]!r}")
        y = om**2
        kind = "omega"
        sd = None
        if omega_std is not None:
            om_sd = _as_1d("omega_std", omega_std, n)
            if np.any(om_sd <= 0):
                i = int(np.flatnonzero(om_sd <= 0)[0])
                raise ValueError(f"omega_std must be > 0, got omega_std[{i}]={om_sd[i]!r}")
            sd = np.sqrt((2 * om * om_sd) ** 2 + 2 * om_sd**4)
    w = w_sd = None
    if w_static is not None:
        w = _as_1d("w_static", w_static, n)
        if w_static_std is not None:
            w_sd = np.broadcast_to(np.asarray(w_static_std, dtype=float), (n,)).copy()
            w_sd = _as_1d("w_static_std", w_sd, n)
            if np.any(w_sd <= 0):
                i = int(np.flatnonzero(w_sd <= 0)[0])
                raise ValueError(f"w_static_std must be > 0, got w_static_std[{i}]={w_sd[i]!r}")
    elif w_static_std is not None:
        raise ValueError("w_static_std=... was given without w_static")
    if damping is not None:
        xi = float(damping)
        if not math.isfinite(xi) or xi < 0:
            raise ValueError(f"damping must be finite and >= 0, got damping={damping!r}")
        damping = xi
    noise_given = sd is not None
    if sd is None:
        sd = np.full(n, np.nan)  # filled by _estimate_noise
    return Sweep(m, y, sd, kind, om, om_sd, w, w_sd, noise_given, damping)


# --------------------------------------------------------------------------------------------
# engine: profile likelihood over mu* of models linear in their coefficients
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class _Comp:
    """One data component: y ~ sum_j beta_j x^e_j, weights 1/sd (``known``) or unknown scale."""

    y: np.ndarray
    wt: np.ndarray
    exps: np.ndarray
    known: bool
    lead: bool = False  # constrain the corrections to stay below _RHO of the leading term
    lead_col: int = 0  # column of the leading term (the columns after it are corrections)
    signed: bool = True  # the leading term must have the sign of y (|sigma^2| > 0)
    mu: np.ndarray | None = None  # own control values (a suffix of the sweep); None: the window
    conformal: bool = False  # series in z (a secondary fold at mu* + delta, delta profiled)


_LOGU = np.linspace(math.log(1e-4), math.log(10.0), 11)  # u = (mu* - mu_last) / delta


def _pack(mu_w: np.ndarray, comps: list[_Comp]) -> tuple:
    mus = [np.asarray(mu_w if c.mu is None else c.mu, dtype=float) for c in comps]
    start = np.zeros(len(comps) + 1, dtype=np.int64)
    start[1:] = np.cumsum([m.size for m in mus])
    kmax = max(c.exps.size for c in comps)
    exps = np.zeros((len(comps), kmax))
    for i, c in enumerate(comps):
        exps[i, : c.exps.size] = c.exps
    nexp = np.array([c.exps.size for c in comps], dtype=np.int64)
    opts = np.array(
        [[c.known, c.lead, c.lead_col, c.signed, c.conformal] for c in comps], dtype=np.int64
    )
    return (
        np.concatenate(mus),
        np.concatenate([np.asarray(c.y, dtype=float) for c in comps]),
        np.concatenate([np.asarray(c.wt, dtype=float) for c in comps]),
        start,
        exps,
        nexp,
        opts,
    )


def _nll_u(
    mu_w: np.ndarray, comps: list[_Comp], mu_star: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """-2 log L (up to constants) at each mu* and the secondary-fold parameter
    ``u = (mu* - mu_w[-1]) / delta`` profiled there (0: none, or no conformal component)."""
    ms = np.ascontiguousarray(np.atleast_1d(np.asarray(mu_star, dtype=float)))
    return nll_rows(ms, *_pack(mu_w, comps), float(mu_w[-1]), _LOGU)


def _nll(mu_w: np.ndarray, comps: list[_Comp], mu_star: np.ndarray) -> np.ndarray:
    return _nll_u(mu_w, comps, mu_star)[0]


@dataclass(frozen=True)
class _Profile:
    mu_star: float
    nll: float
    lo: float  # 95 % (profile) interval
    hi: float
    lo68: float
    hi68: float
    flags: tuple[Flag, ...] = ()


def _profile(
    mu_w: np.ndarray,
    comps: list[_Comp],
    scale: float,
    *,
    level: float = 0.95,
    inflate: float = 1.0,
    with_interval: bool = True,
    xatol: float | None = None,
) -> _Profile:
    """Minimise the profile -2 log L over mu* > mu_w[-1] and read off profile intervals."""
    last = float(mu_w[-1])
    # a conformal law profiles the secondary fold at every mu* (some 25 fits each): a coarser
    # grid around the same seeds keeps its cost near the plain laws'
    cf = any(c.conformal for c in comps)
    t = np.linspace(math.log(scale * 1e-9), math.log(scale * 30.0), 61 if cf else _GRID)
    seeds = _seeds(mu_w, comps[0]) if comps[0].lead else []
    if seeds:
        k1, k2 = (15, 9) if cf else (41, 41)
        extra = [
            np.log(d0) + np.concatenate([np.linspace(-1, 1, k1), np.linspace(-0.01, 0.01, k2)])
            for d0 in seeds
        ]
        t = np.unique(np.concatenate([t, *extra]))
        t = t[(t >= math.log(scale * 1e-12)) & (t <= math.log(scale * 30.0))]
    f = _nll(mu_w, comps, last + np.exp(t))
    f = np.where(np.isfinite(f), f, np.inf)
    i = int(np.argmin(f))
    G = t.size
    flags: list[Flag] = []

    def g(tt: float) -> float:
        v = float(_nll(mu_w, comps, np.array([last + math.exp(tt)]))[0])
        return v if math.isfinite(v) else 1e300

    a_, b_ = t[max(i - 1, 0)], t[min(i + 1, G - 1)]
    # tolerance on log(mu* - mu[-1]): 1e-10 relative for final fits, 1e-6 for model selection
    tol = xatol if xatol is not None else (1e-10 if with_interval else 1e-6)
    res = optimize.minimize_scalar(g, bounds=(a_, b_), method="bounded", options={"xatol": tol})
    th, fh = (float(res.x), float(res.fun)) if res.fun <= f[i] else (float(t[i]), float(f[i]))
    if i == 0:
        flags.append(
            Flag("mu_star_at_last_point", f"the fit puts mu* at the last measured mu={last:.6g}")
        )
    if i == G - 1:
        flags.append(Flag("mu_star_far", "the fit puts mu* far beyond the measured range"))
    if not with_interval:
        mh = last + math.exp(th)
        return _Profile(mh, fh, mh, mh, mh, mh, tuple(flags))

    def bounds(delta: float) -> tuple[float, float, bool, bool]:
        # lower side
        j = int(np.searchsorted(t, th)) - 1
        while j >= 0 and f[j] - fh < delta:
            j -= 1
        if j < 0:
            lo, lo_open = last, True
        else:
            tl = optimize.brentq(lambda s: g(s) - fh - delta, t[j], th, xtol=1e-9)
            lo, lo_open = last + math.exp(tl), False
        j = int(np.searchsorted(t, th))
        while j < G and f[j] - fh < delta:
            j += 1
        if j >= G:
            hi, hi_open = last + math.exp(t[-1]), True
        else:
            tu = optimize.brentq(lambda s: g(s) - fh - delta, th, t[j], xtol=1e-9)
            hi, hi_open = last + math.exp(tu), False
        return lo, hi, lo_open, hi_open

    d95 = float(stats.chi2.ppf(level, 1)) * inflate
    lo, hi, lo_open, hi_open = bounds(d95)
    lo68, hi68, _, _ = bounds(1.0 * inflate)
    if hi_open:
        flags.append(
            Flag("interval_unbounded", "the profile likelihood does not bound mu* from above")
        )
    if lo_open:
        flags.append(
            Flag(
                "interval_reaches_last_point",
                f"the {100 * level:.0f}% interval reaches the last measured mu={last:.6g}",
            )
        )
    return _Profile(last + math.exp(th), fh, lo, hi, lo68, hi68, tuple(flags))


def _seeds(mu_w: np.ndarray, c: _Comp) -> list[float]:
    """Distances mu* - mu[-1] from the paper's two-point extrapolation of |sigma^2|^(1/p) through
    the last pairs of points: starting points that bracket the (possibly very narrow) valley of
    the profile likelihood of precise data."""
    p = float(c.exps[0])
    z = c.y ** (1.0 / p)
    out = []
    for k in range(1, min(4, mu_w.size)):
        dz = z[-k - 1] - z[-k]
        if dz > 0:
            d = z[-k] * (mu_w[-k] - mu_w[-k - 1]) / dz + (mu_w[-k] - mu_w[-1])
            if d > 0 and math.isfinite(d):
                out.append(float(d))
    return out


def _sigma_exps(p: float, h: float, K: int) -> np.ndarray:
    return p + h * np.arange(K + 1, dtype=float)


def _w_exps(b: float, Kw: int) -> np.ndarray:
    if b == 0.5:
        e = [0.0, 0.5, 1.0, 1.5, 2.0]
    elif b == 1.0:
        e = [0.0, 1.0, 2.0, 3.0, 4.0]
    else:  # free exponent: w - w* a series in x^b
        e = [0.0, b, 2 * b, 3 * b, 4 * b]
    return np.asarray(e[: Kw + 1], dtype=float)


_KCF = 2  # most corrections of a conformal law (one parameter more than the plain law: with
# three corrections it out-fits a true fold's series over a fixed grid's far points)


def _variants(p: float, h: float, K: int = 0) -> tuple[bool, ...]:
    """Plain law, and for a pitchfork (|sigma^2| ~ x) also the law that knows a secondary fold
    of the measured branch beyond mu* (series in the conformal variable z; see
    :mod:`service.analysis._laws_kernels`). A subcritical pitchfork's trivial branch, unstable
    past mu*, may fold soon after it (the symmetric beam: mu2* = mu* + 0.012); the series in
    x = mu* - mu then converges only within that distance, the series in z much farther."""
    return (False, True) if (p == 1.0 and h == 1.0 and K <= _KCF) else (False,)


def _sigma_comp(
    sw: Sweep, idx: slice, p: float, h: float, K: int, conformal: bool = False
) -> _Comp:
    return _Comp(
        sw.y[idx], 1.0 / sw.sd[idx], _sigma_exps(p, h, K), True, True, conformal=conformal
    )


def _w_comp(
    sw: Sweep, idx: slice, b: float, Kw: int, conformal: bool = False
) -> _Comp | None:
    """Static-deflection component on the window ``idx`` (its own: the static law holds farther
    from mu* than the eigenvalue law, and near mu* w hardly moves)."""
    if sw.w is None:
        return None
    # w - w* = g x^b (1 + corrections): the x^b term must lead inside the window, otherwise the
    # b = 1/2 series (which contains x, x^2 ...) would fit a smooth deflection as well as b = 1
    if sw.w_sd is not None:
        return _Comp(
            sw.w[idx],
            1.0 / sw.w_sd[idx],
            _w_exps(b, Kw),
            sw.w_noise_given,  # an estimated noise is profiled in the final fits
            True,
            1,
            False,
            sw.mu[idx],
            conformal and b == 1.0,
        )
    return _Comp(
        sw.w[idx], np.ones(sw.w[idx].size), _w_exps(b, Kw), False, True, 1, False, sw.mu[idx],
        conformal and b == 1.0,
    )  # fmt: skip


def _window_sizes(n: int) -> list[int]:
    if n <= 40:
        return list(range(3, n + 1))
    sizes = sorted(set(np.unique(np.round(np.geomspace(3, n, 36)).astype(int)).tolist()))
    return sizes


@dataclass(frozen=True)
class _Sel:
    """The informative window and number of correction terms for a sigma^2 law."""

    n: int
    K: int
    accepted: bool
    pvalue: float
    conformal: bool = False


def _select_window(sw: Sweep, p: float, h: float, scale: float, patience: int = 4) -> _Sel:
    """Largest window of nearest points where the law + <= _KMAX corrections passes chi^2.

    Windows grow from the 3 nearest points; the scan stops after ``patience`` consecutive
    window sizes that no number of corrections can fit (the law has stopped holding)."""
    N = sw.mu.size
    best: _Sel | None = None
    fallback: _Sel | None = None
    misses = 0
    for n in _window_sizes(N):
        idx = slice(N - n, N)
        ok = False
        for K in range(_KMAX + 1):
            for cf in _variants(p, h, K):
                dof = n - K - 2 - int(cf)
                if dof < 1:
                    break
                comp = _sigma_comp(sw, idx, p, h, K, cf)
                prof = _profile(sw.mu[idx], [comp], scale, with_interval=False)
                pv = float(stats.chi2.sf(prof.nll, dof))
                if fallback is None or pv > fallback.pvalue:
                    fallback = _Sel(n, K, False, pv, cf)
                if pv >= _ALPHA:
                    best = _Sel(n, K, True, pv, cf)
                    ok = True
                    break
            if ok:
                break
        misses = 0 if ok else misses + 1
        if misses >= patience and (best is not None or n >= 8):
            break
    if best is not None:
        return best
    assert fallback is not None
    return fallback


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
    """Relative noise of |sigma^2| when not given: residual scatter of the nearest points about
    the best candidate law with two corrections (at least 3 degrees of freedom); with fewer than
    6 points it cannot be estimated and ``_ASSUMED_REL`` is assumed (see ``_noise_flag``)."""
    if sw.noise_given:
        return sw
    N = sw.mu.size
    n = min(N, max(8, N // 2))
    idx = slice(N - n, N)
    scale = float(sw.mu[-1] - sw.mu[0])
    best = math.inf
    K = min(2, n - 2 - _MIN_NOISE_DOF)
    if K >= 0:
        for _, (a, _, h) in CANDIDATES.items():
            for cf in _variants(2 * a, h):
                if n - K - 2 - int(cf) < 1:
                    continue
                c = _Comp(sw.y[idx], 1.0 / sw.y[idx], _sigma_exps(2 * a, h, K), True, True,
                          conformal=cf)  # fmt: skip
                prof = _profile(sw.mu[idx], [c], scale, with_interval=False)
                best = min(best, prof.nll / (n - K - 2 - int(cf)))
    s = math.sqrt(best) if math.isfinite(best) else _ASSUMED_REL
    s = max(s, _REL_FLOOR)
    return Sweep(
        sw.mu, sw.y, s * sw.y, sw.kind, sw.omega, sw.omega_sd, sw.w, sw.w_sd, False, sw.damping
    )


def _noise_flag(sw: Sweep) -> Flag:
    """The flag telling how the noise of an estimated-noise sweep was obtained."""
    which = "sigma2_std" if sw.kind == "sigma2" else "omega_std"
    rel = float(np.median(sw.sd / sw.y))
    if sw.mu.size < 4 + _MIN_NOISE_DOF:
        return Flag(
            "noise_assumed",
            f"no {which} given and only {sw.mu.size} points: relative noise of |sigma2| "
            f"assumed to be {rel:.2g}",
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
    return Sweep(sw.mu, y, sd, sw.kind, sw.omega, sw.omega_sd, sw.w, sw.w_sd, sw.noise_given, xi)


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


_K_CRITERION = "aicc"


def _crit(nll: float, bic: float, k: int, m: int) -> float:
    """Criterion choosing the number of correction terms of one candidate: AICc (less biased
    extrapolation to mu* than BIC, whose heavier penalty truncates corrections too early)."""
    if _K_CRITERION == "bic":
        return bic
    return nll + 2 * k + (2 * k * (k + 1) / (m - k - 1) if m - k - 1 > 0 else math.inf)


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
) -> ModelFit:
    """Fit one candidate: sigma^2 law on the nearest ``n`` points, static law (if any) on the
    nearest ``n_w``; corrections chosen by BIC; mu* profiled jointly."""
    N = sw.mu.size
    idx = slice(N - n, N)
    n_w = n if n_w is None else n_w
    idx_w = slice(N - n_w, N)
    best: ModelFit | None = None
    best_crit = math.inf
    kw_range = [0]
    if sw.w is not None and b is not None:
        kw_range = [kw for kw in range(1, _KW_MAX + 1) if n_w - kw - 1 >= 2] or [0]
    for K in range(_KMAX + 1):
        for cf in _variants(2 * a, h, K):
            if n - K - 2 - int(cf) < 1:
                break
            for Kw in kw_range:
                comps = [_sigma_comp(sw, idx, 2 * a, h, K, cf)]
                bic_pen = (K + 2 + int(cf)) * math.log(n)
                if Kw:
                    wc = _w_comp(sw, idx_w, float(b), Kw, cf)
                    assert wc is not None
                    comps.append(wc)
                    bic_pen += (Kw + 1 + (0 if wc.known else 1)) * math.log(n_w)
                prof = _profile(sw.mu[idx], comps, scale, with_interval=False)
                bic = prof.nll + bic_pen
                k_all = K + 2 + int(cf) + (Kw + 1 if Kw else 0)
                m_all = n + (n_w if Kw else 0)
                crit = _crit(prof.nll, bic, k_all, m_all)
                if best is None or crit < best_crit:
                    best_crit = crit
                    best = ModelFit(
                        name, a, b if b is not None else math.nan, h, n, K, Kw, bic, prof, n_w,
                        cf,
                    )  # fmt: skip
    assert best is not None
    comps = [_sigma_comp(sw, idx, 2 * a, h, best.K, best.conformal)]
    if best.Kw:
        wc = _w_comp(sw, idx_w, float(b), best.Kw, best.conformal)  # type: ignore[arg-type]
        assert wc is not None
        comps.append(wc)
    prof = _profile(sw.mu[idx], comps, scale, level=level)
    return ModelFit(name, a, best.b, h, n, best.K, best.Kw, best.bic, prof, n_w, best.conformal)


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
        sw = Sweep(sw.mu, sw.y, sw.sd, sw.kind, sw.omega, sw.omega_sd, sw.w,
                   np.full(N, sig), sw.noise_given, sw.damping, False)  # fmt: skip
        flags.append(
            Flag(
                "w_noise_estimated", f"no w_static_std given: estimated from the scatter, {sig:.2g}"
            )
        )
    else:
        # over-dispersion of the static data (e.g. the mean of a kicked, nonlinear record is
        # shifted by ~ amplitude^2 / |sigma^2|, far above a detector's stated offset error):
        # scale the given noise by the reduced chi-square of the widest static series
        m = min(N, max(8, n))
        if m - 5 >= _MIN_NOISE_DOF:
            idx = slice(N - m, N)
            c = _Comp(sw.w[idx], 1.0 / sw.w_sd[idx], np.array([0.0, 0.5, 1.0, 1.5, 2.0]), True)
            phi = float(_nll(sw.mu[idx], [c], np.array([mu_star]))[0]) / (m - 5)
            if phi > float(stats.chi2.ppf(0.99, m - 5)) / (m - 5):
                sw = Sweep(sw.mu, sw.y, sw.sd, sw.kind, sw.omega, sw.omega_sd, sw.w,
                           sw.w_sd * math.sqrt(phi), sw.noise_given, sw.damping,
                           sw.w_noise_given)  # fmt: skip
                flags.append(
                    Flag(
                        "w_noise_underestimated",
                        f"the static deflections scatter {math.sqrt(phi):.3g} times more than "
                        "w_static_std: that noise was scaled up by this factor",
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
                if stats.chi2.sf(chi, dof) >= _ALPHA:
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


def _exp_grid(lo: float, hi: float, cands: list[float]) -> np.ndarray:
    """Grid for a free exponent: uniform, plus the candidate values and their close neighbours
    (precise data give valleys far narrower than the uniform step)."""
    extra = [c + d for c in cands for d in (-0.02, -0.005, 0.0, 0.005, 0.02)]
    return np.unique(np.concatenate([np.linspace(lo, hi, 16), extra]))


def _free_exponent(
    mu_w: np.ndarray, make: Any, grid: np.ndarray, scale: float, fixed_mu: float | None = None
) -> tuple[float, float]:
    """Profile -2 log L over an exponent; return (estimate, standard error from Delta = 1)."""

    def prof(e: float) -> float:
        comps = make(e)
        if fixed_mu is not None:
            return float(_nll(mu_w, comps, np.array([fixed_mu]))[0])
        return _profile(mu_w, comps, scale, with_interval=False, xatol=1e-7).nll

    f = np.array([prof(e) for e in grid])
    f = np.where(np.isfinite(f), f, np.inf)
    i = int(np.argmin(f))
    a_, b_ = grid[max(i - 1, 0)], grid[min(i + 1, grid.size - 1)]
    res = optimize.minimize_scalar(prof, bounds=(a_, b_), method="bounded", options={"xatol": 1e-4})
    eh, fh = (float(res.x), float(res.fun)) if res.fun <= f[i] else (float(grid[i]), float(f[i]))

    def cross(sign: int) -> float:
        j = int(np.searchsorted(grid, eh)) + (0 if sign > 0 else -1)
        while 0 <= j < grid.size and f[j] - fh < 1.0:
            j += sign
        if not 0 <= j < grid.size:
            return math.inf
        return abs(
            optimize.brentq(
                lambda e: prof(e) - fh - 1.0, min(eh, grid[j]), max(eh, grid[j]), xtol=1e-5
            )
            - eh
        )

    up, dn = cross(+1), cross(-1)
    se = 0.5 * (up + dn) if math.isfinite(up) and math.isfinite(dn) else min(up, dn)
    return eh, se


# --------------------------------------------------------------------------------------------
# result
# --------------------------------------------------------------------------------------------


def _clean(v: Any) -> Any:
    if isinstance(v, float | np.floating):
        return float(v) if math.isfinite(v) else None
    if isinstance(v, dict):
        return {k: _clean(x) for k, x in v.items()}
    if isinstance(v, tuple | list):
        return [_clean(x) for x in v]
    return v


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

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dict (non-finite numbers become ``None``; flags become dicts)."""
        return {
            "transition": self.transition,
            "a": _clean(self.a),
            "a_std": _clean(self.a_std),
            "b": _clean(self.b),
            "b_std": _clean(self.b_std),
            "mu_star": _clean(self.mu_star),
            "mu_star_std": _clean(self.mu_star_std),
            "probabilities": _clean(dict(self.probabilities)),
            "regime": self.regime,
            "window": self.window,
            "damping": _clean(self.damping),
            "flags": [f.to_dict() for f in self.flags],
        }


# --------------------------------------------------------------------------------------------
# main entry
# --------------------------------------------------------------------------------------------


def _candidates(sw: Sweep) -> list[tuple[str, float, float | None, float]]:
    if sw.w is None:
        return [("saddle-node", 0.25, None, 0.5), ("pitchfork", 0.5, None, 1.0)]
    return [(k, a, b, h) for k, (a, b, h) in CANDIDATES.items()]


_Law = tuple[str, float, "float | None", float]  # name, a, b (None: no static law), h


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

    def select(s: Sweep) -> dict[str, _Sel]:
        return {nm: _select_window(s, p, h, scale) for nm, (p, h) in sel_laws.items()}

    sels = select(sw)
    if not any(s.accepted for s in sels.values()):
        # over-dispersion: the data scatter more than their stated noise (or the simulator's
        # round-off dominates near mu*): scale the noise by the best reduced chi-square
        N = sw.mu.size
        m = min(N, max(8, N // 2))
        phi = math.inf
        for p, h in sel_laws.values():
            K = min(2, m - 2 - _MIN_NOISE_DOF)
            if K < 0:
                break
            phi = min(phi, _sigma_chi2(sw, p, h, m, K, scale) / (m - K - 2))
        if math.isfinite(phi) and phi > 1:
            sw = Sweep(sw.mu, sw.y, sw.sd * math.sqrt(phi), sw.kind, sw.omega, sw.omega_sd,
                       sw.w, sw.w_sd, sw.noise_given, sw.damping)  # fmt: skip
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
    fits = [
        _fit_candidate(sw, name, a, (b if sw.w is not None else None), h, n_c, scale, level, n_w)
        for name, a, b, h in cands
    ]
    fits.sort(key=lambda f: f.bic)
    return sw, fits, n_c, flags


def _probabilities(fits: list[ModelFit]) -> dict[str, float]:
    bics = np.array([f.bic for f in fits])
    wts = np.exp(-0.5 * (bics - bics.min()))
    wts /= wts.sum()
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
            sw, fits, n_c, fl = _compare(sw, scale, law, level)
            return sw, fits, n_c, flags + fl

        # damping unknown: profile it. xi = 0 is the plain law; a point with omega < xi/2 is in
        # the over-damped layer where the observed rate is the slow pole.
        def score(s: Sweep) -> tuple[tuple[bool, int, float], tuple[float, float, _Sel]]:
            out = None
            for p, h in ((0.5, 0.5), (1.0, 1.0)):
                sel = _select_window(s, p, h, scale)
                key = (not sel.accepted, -sel.n, -sel.pvalue)
                if out is None or key < out[0]:
                    out = (key, (p, h, sel))
            assert out is not None
            return out

        r = np.sort(sw.omega)
        xis = 2 * np.geomspace(r[0] / 2, r[-1], 20)
        key0, law0 = score(sw)
        best = (key0, law0, 0.0)
        for xi in xis:
            k, law_x = score(_with_damping(sw, float(xi)))
            if k < best[0]:
                best = (k, law_x, float(xi))
        _, (p, h, sel), xi = best
        if xi > 0:
            # refine xi on the chosen law and window
            j = int(np.argmin(np.abs(xis - xi)))
            lo_x, hi_x = xis[max(j - 1, 0)], xis[min(j + 1, xis.size - 1)]
            res = optimize.minimize_scalar(
                lambda t: _sigma_chi2(_with_damping(sw, math.exp(t)), p, h, sel.n, sel.K, scale),
                bounds=(math.log(lo_x), math.log(hi_x)),
                method="bounded",
                options={"xatol": 1e-4},
            )
            xi = math.exp(float(res.x))
            s = _with_damping(sw, xi)
            chi_xi = _sigma_chi2(s, p, h, sel.n, sel.K, scale)
            # the damping is identified only if some point is over-damped, and it must pay for
            # its parameter against the plain law on the same window
            p0, h0, sel0 = law0
            chi_0 = _sigma_chi2(sw, p0, h0, sel.n, sel.K, scale) if sel.n == sel0.n else math.inf
            if np.any(sw.omega < xi / 2) and chi_xi + math.log(sel.n) < chi_0:
                s, fits, n_c, fl = _compare(s, scale, law, level)
                return s, fits, n_c, flags + fl
        sw, fits, n_c, fl = _compare(sw, scale, law, level)
        return sw, fits, n_c, flags + fl
    sw, fits, n_c, fl = _compare(sw, scale, law, level)
    return sw, fits, n_c, flags + fl


def classify(
    mu: Sequence[float] | np.ndarray,
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
    mu : array_like, shape (n,)
        Control parameter along the upward sweep, strictly increasing, n >= 3, any unit.
    sigma2 : array_like, shape (n,), optional
        Undamped eigenvalue of the fundamental mode (1/time^2), negative on the stable branch
        (e.g. ``-s1 s2`` from a pole detector). Give this or ``omega``.
    sigma2_std : array_like, shape (n,), optional
        Standard deviation of ``sigma2``. Without it the relative noise is estimated from the
        scatter (flag ``noise_estimated``).
    omega : array_like, shape (n,), optional
        Observed angular rate (rad/time): the pole modulus ``sqrt(-sigma^2)`` when under-damped
        (the FFT peak when ``xi << omega``), the slow decay rate when over-damped. Inside the
        boundary layer these follow the doubled exponent; the damping is then fitted.
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
    ValueError
        Non-finite values, length mismatch, fewer than 3 points, non-increasing ``mu``,
        ``sigma2 >= 0``, non-positive standard deviations.

    Notes
    -----
    Laws fitted (``x = mu* - mu``): ``|sigma^2| = x^(2a) sum_k c_k x^(k h)`` and
    ``w = w* + sum_j g_j x^(e_j)`` (paper, eqs. saddleGrowthRate, pitchforkGrowthRate,
    saddleEquilibriums, pitchforkEquilibriums, with regular corrections).
    """
    if not 0.0 < min_probability <= 1.0:
        raise ValueError(f"min_probability must be in (0, 1], got {min_probability!r}")
    sw0 = prepare_sweep(
        mu,
        sigma2,
        sigma2_std=sigma2_std,
        omega=omega,
        omega_std=omega_std,
        w_static=w_static,
        w_static_std=w_static_std,
        damping=damping,
    )
    return _classify_sweep(sw0, min_probability=min_probability)


def _classify_sweep(
    sw0: Sweep, *, min_probability: float = 0.9, level: float = 0.95
) -> Classification:
    """:func:`classify` on a validated sweep (``level``: of the candidates' profile intervals)."""
    sw, fits, n_c, flags = _analyse(sw0, None, level)
    probs = _probabilities(fits)
    top = fits[0]
    N = sw.mu.size
    idx = slice(N - n_c, N)
    scale = float(sw.mu[-1] - sw.mu[0])

    # regime
    regime = "underdamped"
    if sw.damping is not None and sw.damping > 0:
        if sw.kind == "omega":
            over = sw.omega is not None and bool(sw.omega[-1] < sw.damping / 2)
        else:
            over = bool(sw.y[-1] < sw.damping**2 / 4)
        if over:
            regime = "overdamped"
            flags.append(
                Flag(
                    "overdamped",
                    f"the nearest points lie in the over-damped boundary layer (xi={sw.damping:.3g}"
                    "): the observed time scale there follows the doubled exponent 2a",
                )
            )

    # free exponent a (on the window, corrections of the best model)
    def make_a(p: float) -> list[_Comp]:
        return [_Comp(sw.y[idx], 1.0 / sw.sd[idx], _sigma_exps(p, top.h, top.K), True, True,
                      conformal=top.conformal)]  # fmt: skip

    a2, a2_se = _free_exponent(sw.mu[idx], make_a, _exp_grid(0.2, 2.5, [0.5, 1.0, 2.0]), scale)
    a_hat, a_se = a2 / 2, a2_se / 2
    if regime == "overdamped" and sw.kind == "omega":
        a_hat, a_se = 2 * a_hat, 2 * a_se  # the observed (slow) time scale exponent

    # free exponent b at the best mu*
    b_hat = b_se = math.nan
    if sw.w is not None:
        wsd = sw.w_sd

        n_w = max(top.n_w, n_c)
        iw = slice(N - n_w, N)

        def make_b(b: float) -> list[_Comp]:
            e = _w_exps(b, max(top.Kw, 2))
            wt = 1.0 / wsd[iw] if wsd is not None else np.ones(n_w)
            known = wsd is not None and sw.w_noise_given
            # w - w* = g x^b (1 + corrections): the x^b term must lead inside the window
            return [
                _Comp(sw.w[iw], wt, e, known, True, 1, False,  # type: ignore[index]
                      conformal=top.conformal)
            ]  # fmt: skip

        if n_w >= 5:
            b_hat, b_se = _free_exponent(
                sw.mu[iw],
                make_b,
                _exp_grid(0.25, 1.9, [0.5, 1.0]),
                scale,
                fixed_mu=top.profile.mu_star,
            )
        else:
            flags.append(Flag("b_not_estimated", f"only {n_w} informative points for b"))
    else:
        flags.append(
            Flag("no_static_data", "no w_static: b and the criticality of a pitchfork unknown")
        )

    # decision
    p_top = probs[top.name]
    transition = top.name
    if p_top < min_probability:
        p_pf = probs.get("subcritical-pitchfork", 0.0) + probs.get("supercritical-pitchfork", 0.0)
        transition = "pitchfork" if p_pf >= min_probability else "undetermined"
        flags.append(
            Flag(
                "ambiguous",
                f"the best candidate {top.name} has probability {p_top:.2f} < {min_probability}",
            )
        )
    a_model = top.a * (2 if (regime == "overdamped" and sw.kind == "omega") else 1)
    if math.isfinite(a_se) and a_se > 0:
        cands = [0.25, 0.5] if regime == "underdamped" else [0.5, 1.0]
        z = min(abs(a_hat - c) for c in cands) / a_se
        if z > 4 and min(abs(a_hat - c) for c in cands) > 0.05:
            flags.append(
                Flag(
                    "exponent_off",
                    f"free exponent a={a_hat:.3f}+-{a_se:.3f} is far from every candidate "
                    f"({', '.join(f'{c:g}' for c in cands)}); a doubled exponent is the mark of "
                    "over-damped data given as sigma2 = -omega^2 (give omega= instead)",
                )
            )
            transition = "undetermined"
    elif not math.isfinite(a_se):
        flags.append(Flag("a_unbounded", "the exponent a is not bounded by the data"))
    if n_c < 5:
        flags.append(Flag("few_points_near", f"only {n_c} informative points near mu* (want >= 5)"))
    prof = top.profile
    flags.extend(prof.flags)
    mu_std = 0.5 * (prof.hi68 - prof.lo68)
    del a_model
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
