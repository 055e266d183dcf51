"""A damping nobody gave, identified from rates (``omega`` data without ``damping``).

A rate below ``xi / 2`` is the slow pole of an over-damped mode, ``omega (xi - omega) =
|sigma^2|`` (:func:`.windows._with_damping`); near a fold that slow rate grows
like a pitchfork's frequency (both ``~ x^(1/2)``), so a damping is kept only on decisive
evidence: an over-damped layer near mu* with under-damped points beyond it, fitting far better
than the undamped laws given one more correction term instead. Used by
:mod:`.compare` before the candidates are fitted.
"""

from __future__ import annotations

import math

import numpy as np
from scipy import optimize

from service.analysis.predictor.cache import fit_cache
from service.analysis.predictor.sweep import Sweep
from service.analysis.predictor.windows import (
    _KMAX,
    Window,
    _sigma_chi2,
    _with_damping,
    select_window,
)

__all__ = ["identify_damping"]

_XI_EVIDENCE = 25.0  # chi^2 drop that identifies a damping nobody gave (5 standard deviations)
_XI_DOF = 2  # degrees of freedom a damping nobody gave must leave in its window
_XI_UNDER = 0.5  # share of the sweep a damping nobody gave must leave under-damped (>= 3 points)


def identify_damping(sw: Sweep, scale: float) -> float:
    """The damping ``xi`` of rates given without one (0: none identified), the same for every
    law fitted afterwards (memoised in the profile scope: a prediction refits each law).

    xi is profiled: a point with omega < xi/2 is in the over-damped layer where the observed
    rate is the slow pole. It is identified only on decisive evidence (module docstring;
    ``tests/analysis/test_unstated_noise.py``)."""
    memo = fit_cache()
    key = None
    if memo is not None:
        osd = b"" if sw.omega_sd is None else sw.omega_sd.tobytes()
        key = ("damping", sw.mu.tobytes(), sw.omega.tobytes(), sw.sd.tobytes(), osd, scale)  # type: ignore[union-attr]
        if key in memo:
            return memo[key]  # type: ignore[return-value]
    xi = _search_damping(sw, scale)
    if key is not None:
        memo[key] = xi  # type: ignore[index,assignment]
    return xi


def _search_damping(sw: Sweep, scale: float) -> float:
    """xi on a grid of 20 (the law and window of each scored by the window choice), refined
    on the best one's law and window, then kept only if the evidence is decisive."""
    assert sw.omega is not None

    def score(s: Sweep) -> tuple[tuple[bool, int, float], tuple[float, float, Window]]:
        out = None
        for p, h in ((0.5, 0.5), (1.0, 1.0)):
            sel = select_window(s, p, h, scale)
            key = (not sel.accepted, -sel.n, -sel.pvalue)
            if out is None or key < out[0]:
                out = (key, (p, h, sel))
        assert out is not None
        return out

    r = np.sort(sw.omega)
    xis = 2 * np.geomspace(r[0] / 2, r[-1], 20)
    # a damping is searched only where it can be identified: some point over-damped
    # (xi / 2 > the slowest rate; below, it is the plain law) and the crossover seen
    # (enough points under-damped, see the test below)
    n_under = max(3, math.ceil(_XI_UNDER * r.size))
    top = r[r.size - n_under] if n_under <= r.size else -math.inf
    key0, law0 = score(sw)
    best = (key0, law0, 0.0)
    for xi in xis[(xis / 2 > r[0]) & (xis / 2 <= top)]:
        k, law_x = score(_with_damping(sw, float(xi)))
        if k < best[0]:
            best = (k, law_x, float(xi))
    _, (p, h, sel), xi = best
    if xi <= 0:
        return 0.0
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
    # the evidence is read at the refined damping, on the window it selects (a grid point's
    # window can leave no degree of freedom where the refined one fits within the noise)
    s_xi = _with_damping(sw, xi)
    _, (p, h, sel) = score(s_xi)
    # xi is a parameter of the fit: the damped law keeps _XI_DOF degrees of freedom after it
    # (fewer corrections if need be; a window it fits exactly proves nothing)
    K = min(sel.K, sel.n - 3 - int(sel.conformal) - _XI_DOF)
    if K < 0:
        return 0.0
    chi_xi = _sigma_chi2(s_xi, p, h, sel.n, K, scale, sel.conformal)
    # the damping must beat the undamped laws on the same window decisively, even spending its
    # parameter on one more correction instead: xi is searched, and a spurious damping doubles
    # the exponent near mu* (measured: beam plans given as omega had 10 of 33 called
    # over-damped when an undamped law on a smaller window exempted the comparison; coverage
    # 67 %, intervals past mu*)
    k_0 = [k for k in (K, K + 1) if k <= _KMAX and sel.n - k - 2 >= 1]
    chi_0 = min(
        _sigma_chi2(sw, p0, h0, sel.n, k, scale)
        for p0, h0 in ((0.5, 0.5), (1.0, 1.0))
        for k in k_0
    )
    # a boundary layer: over-damped points near mu*, and the crossover seen (under-damped
    # points farther out; with none, a fold's slow rate ~ x^(1/2) is a pitchfork's
    # frequency, and the omega data alone cannot tell them apart)
    n_over = int(np.sum(sw.omega < xi / 2))
    layer = n_over > 0 and sw.omega.size - n_over >= max(3, _XI_UNDER * sw.omega.size)
    # noise read from the sweep's own scatter (none given) is uncertain; where the damped law
    # itself scatters more than that estimate allows (chi^2 per degree of freedom above 1),
    # the estimate is taken as that much too low and the evidence shrinks with it (Birge's
    # ratio). Measured: calibration plan 854 (beam, supercritical, omega without std), noise
    # estimated at half the true one, the damped fold's chi^2 7.7 on 5 degrees of freedom
    # against 34.3 undamped: a spurious damping, the pitchfork named a saddle-node (p = 1.0)
    birge = 1.0
    if not sw.noise_given:
        birge = max(1.0, chi_xi / (sel.n - K - 3 - int(sel.conformal)))
    if layer and (chi_xi + max(math.log(sel.n), _XI_EVIDENCE) * birge) < chi_0:
        return xi
    return 0.0
