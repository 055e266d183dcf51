"""One resolution policy: the Cosserat rod's number of elements from a requested accuracy.

The rod's mu* converges as C / n^2 with the node clamp (order 1 with the element clamp; shown in
tests/cosserat and bench/cosserat.py). C is measured per strip, not guessed: mu* at n = 16 and
n = 32 (two cheap bifurcation solves, cached) give C by Richardson. Then

* from a requested relative accuracy ``rtol``: the smallest even n with
  |C| / n^2 <= (rtol / 2) mu* (the other half of rtol is left to the time stepping and the
  model error);
* for a given n: the estimated discretisation error |C| / n^2 of mu* at that n.

Every command (simulate, equilibria, spectrum, bifurcation, warn) of one scene goes through
``rod_resolution`` and therefore uses the same n; every result carries the ``Resolution``.
"""

from __future__ import annotations

import math
from functools import lru_cache

from sim.errors import ParameterError, SimulationError
from sim.results import Resolution
from sim.scene import DEFAULT_RTOL

COARSE = (16, 32)
MIN_ELEMENTS = 16
MAX_ELEMENTS = 2000


@lru_cache(maxsize=256)
def rod_error_constant(actuation: str, end_shortening: float, slenderness: float,
                       poisson: float = 0.5, clamp: str = "node"
                       ) -> tuple[float, float, float, str]:
    """(C, mu*_extrapolated, order, quantity) of the rod's mu*(n) = mu*_inf + C / n^order.

    Richardson from n = 16 and 32 on mu* itself; where the coarse rods find no transition, on
    the fundamental's frequency at mu = 0 (relative), scaled by the beam's mu*.
    """
    from sim.cosserat import statics as S
    from sim.cosserat.bifurcation import find_bifurcation
    from sim.cosserat.rod import Rod

    order = 2 if clamp == "node" else 1  # the element clamp is first order
    n1, n2 = COARSE
    levels = COARSE if clamp != "centre" else (*COARSE, 2 * COARSE[1])
    rods = [Rod(elements=n, end_shortening=end_shortening, slenderness=slenderness,
                actuation=actuation, clamp=clamp, poisson=poisson) for n in levels]
    try:
        mus = [find_bifurcation(rod, xtol=1e-10).mu_star for rod in rods]
        if clamp == "centre":  # its mu* converges at an order between 1 and 2: measured
            order = max(1.0, min(2.0, math.log2(abs((mus[0] - mus[1]) / (mus[1] - mus[2])))))
            n1, n2, mus = COARSE[1], levels[2], mus[1:]
        c = (mus[0] - mus[1]) / (n1**-order - n2**-order)
        return c, mus[1] - c * n2**-order, order, "mu*"
    except (SimulationError, ValueError, ArithmeticError):
        pass  # no transition found on the coarse rods: use the fundamental at mu = 0
    from sim.euler_beam import bifurcation

    mu_beam = bifurcation(actuation).mu_star
    try:
        om = [math.sqrt(abs(S.sigma2(rod, S.branch_state(rod, 0.0), 1)[0][0])) for rod in rods]
    except (SimulationError, ValueError, ArithmeticError) as exc:
        raise SimulationError("slenderness", slenderness,
                              f"no resolution estimate for this strip: {exc}") from None
    c_rel = (om[0] / om[1] - 1.0) / (n1**-order - n2**-order)
    return c_rel * mu_beam, mu_beam, order, "fundamental at mu = 0"


def rod_resolution(actuation: str, *, end_shortening: float, slenderness: float,
                   poisson: float = 0.5, clamp: str = "node", rtol: float | None = None,
                   elements: int | None = None) -> Resolution:
    """The rod's number of elements and its estimated mu* error.

    Parameters
    ----------
    actuation : str
    end_shortening, slenderness, poisson, clamp : the strip and the clamp convention.
    rtol : float, optional
        Requested relative accuracy of mu* (default ``sim.scene.DEFAULT_RTOL``); ignored when
        ``elements`` is given.
    elements : int, optional
        Explicit number of elements (even, >= 4).

    Returns
    -------
    Resolution
        ``size`` = elements, ``mu_star_error`` = |C| / n^order (absolute), ``method``.
    """
    c, mu_inf, order, quantity = rod_error_constant(actuation, float(end_shortening),
                                                    float(slenderness), float(poisson), clamp)
    method = (f"Richardson on {quantity} from n = {COARSE[0]}, {COARSE[1]}: mu*(n) = "
              f"{mu_inf:.8f} {'+' if c >= 0 else '-'} {abs(c):.4g} / n^{order:.3g}")
    if elements is not None:
        n = int(elements)
        used_rtol = None
    else:
        used_rtol = DEFAULT_RTOL if rtol is None else float(rtol)
        if not 0.0 < used_rtol < 0.1:
            raise ParameterError("rtol", rtol, f"rtol must lie in (0, 0.1), got {rtol!r}")
        n = math.ceil((abs(c) / (0.5 * used_rtol * abs(mu_inf))) ** (1.0 / order))
        n = int(n)
        n = max(MIN_ELEMENTS, n + (n % 2))
        if n > MAX_ELEMENTS:
            raise ParameterError(
                "rtol", rtol, f"rtol={rtol!r} needs {n} elements, more than {MAX_ELEMENTS}: "
                f"ask for rtol >= {2 * abs(c) / MAX_ELEMENTS**order / abs(mu_inf):.1e}")
    err = abs(c) / n**order
    if not math.isfinite(err):
        raise SimulationError("mu", None, "no error estimate for this strip")
    return Resolution("cosserat", n, used_rtol, max(err, 1e-15), method)
