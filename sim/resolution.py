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

The time grid of a rod simulation is decided here too (``rod_time_grid``, which
``sim.cosserat.dynamics.simulate`` uses), so that its cost is known before it runs
(``rod_cost``). The generalised-alpha step is implicit in every dof: it is set by the accuracy
wanted on the fundamental, ``rod_steps_per_period(rtol)`` ~ rtol^-1/2 steps per period, not by
the element length (no CFL bound: dt does not shrink with h). One step is a Newton solve of a
banded system (about 2 iterations of O(n) each), so a run costs about elements x steps: measured
CPU = 0.10 s + 0.37 us x elements x steps (n = 60-400, 6e4-5e6 element-steps, correlation 0.99);
the 0.1 s is the setup (the static solves, 0.05-0.4 s), not counted in ``RodCost.work``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

from sim.errors import ParameterError, SimulationError
from sim.results import Resolution
from sim.scene import DEFAULT_RTOL, Scene

COARSE = (16, 32)
MIN_ELEMENTS = 16
MAX_ELEMENTS = 2000
#: A rod simulation's default record: 40 fundamental periods, 50 samples per period.
DEFAULT_PERIODS = 40.0
SAMPLES_PER_PERIOD = 50


@lru_cache(maxsize=256)
def rod_error_constant(
    actuation: str,
    end_shortening: float,
    slenderness: float,
    poisson: float = 0.5,
    clamp: str = "node",
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
    rods = [
        Rod(
            elements=n,
            end_shortening=end_shortening,
            slenderness=slenderness,
            actuation=actuation,
            clamp=clamp,
            poisson=poisson,
        )
        for n in levels
    ]
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
        raise SimulationError(
            "slenderness", slenderness, f"no resolution estimate for this strip: {exc}"
        ) from None
    c_rel = (om[0] / om[1] - 1.0) / (n1**-order - n2**-order)
    return c_rel * mu_beam, mu_beam, order, "fundamental at mu = 0"


def _elements_for(c: float, mu: float, order: float, rtol: float) -> int:
    """The smallest even n >= MIN_ELEMENTS with c / n^order <= (rtol / 2) mu, worked out in
    logarithms (an rtol of 1e-320 or a mu* of 0 neither underflows nor divides by zero);
    MAX_ELEMENTS + 1 stands for "more than the cap"."""
    if c == 0.0:
        return MIN_ELEMENTS
    if mu == 0.0:
        return MAX_ELEMENTS + 1
    log_n = (math.log(c) - math.log(0.5) - math.log(rtol) - math.log(mu)) / order
    if log_n > math.log(MAX_ELEMENTS):
        return MAX_ELEMENTS + 1
    n = math.ceil(math.exp(log_n))
    return max(MIN_ELEMENTS, n + (n % 2))


def rod_resolution(
    actuation: str,
    *,
    end_shortening: float,
    slenderness: float,
    poisson: float = 0.5,
    clamp: str = "node",
    rtol: float | None = None,
    elements: int | None = None,
) -> Resolution:
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
    c, mu_inf, order, quantity = rod_error_constant(
        actuation, float(end_shortening), float(slenderness), float(poisson), clamp
    )
    method = (
        f"Richardson on {quantity} from n = {COARSE[0]}, {COARSE[1]}: mu*(n) = "
        f"{mu_inf:.8f} {'+' if c >= 0 else '-'} {abs(c):.4g} / n^{order:.3g}"
    )
    if elements is not None:
        n = int(elements)
        used_rtol = None
    else:
        used_rtol = DEFAULT_RTOL if rtol is None else float(rtol)
        if not 0.0 < used_rtol < 0.1:
            raise ParameterError("rtol", rtol, f"rtol must lie in (0, 0.1), got {rtol!r}")
        n = _elements_for(abs(c), abs(mu_inf), order, used_rtol)
        if n > MAX_ELEMENTS:
            raise ParameterError(
                "rtol",
                rtol,
                f"rtol={rtol!r} needs more than {MAX_ELEMENTS} elements"
                + (f": ask for rtol >= {2 * abs(c) / MAX_ELEMENTS**order / abs(mu_inf):.1e}"
                   if mu_inf else ""),  # fmt: skip
            )
    err = abs(c) / n**order
    if not math.isfinite(err):
        raise SimulationError("mu", None, "no error estimate for this strip")
    return Resolution("cosserat", n, used_rtol, max(err, 1e-15), method)


def rod_steps_per_period(rtol: float) -> int:
    """Time steps per fundamental period for a relative frequency error (omega dt)^2 / 12
    below rtol / 4 (at least 50): 257 at the default rtol, ~ 3.6 / sqrt(rtol)."""
    return max(50, math.ceil(2.0 * math.pi / math.sqrt(3.0 * rtol)))


@dataclass(frozen=True)
class TimeGrid:
    """The time grid of a rod simulation.

    Attributes
    ----------
    duration, sample_dt : float
        Record length and sampling step (time units; given, or the defaults in periods).
    every : int
        Internal steps per sample (the step divides the sampling step).
    samples : int
        Samples after t = 0.
    steps_per_period : int
    """

    duration: float
    sample_dt: float
    every: int
    samples: int
    steps_per_period: int

    @property
    def dt(self) -> float:
        """The internal time step."""
        return self.sample_dt / self.every

    @property
    def steps(self) -> int:
        """Time steps of the run (before any retry with a halved step)."""
        return self.samples * self.every


def rod_time_grid(
    period: float,
    rtol: float,
    duration: float | None = None,
    dt: float | None = None,
    *,
    steps_per_period: int | None = None,
    periods: float = DEFAULT_PERIODS,
    samples_per_period: int = SAMPLES_PER_PERIOD,
) -> TimeGrid:
    """The time grid of a rod simulation whose fundamental period is ``period``.

    ``duration`` (default ``periods`` periods) sampled every ``dt`` (default the period /
    ``samples_per_period``); the internal step is the largest that divides the sampling step
    and makes at least ``steps_per_period`` (default ``rod_steps_per_period(rtol)``) per
    period. Pure: ``sim.cosserat.dynamics.simulate`` runs this grid.
    """
    spp = rod_steps_per_period(rtol) if steps_per_period is None else int(steps_per_period)
    sample_dt = dt if dt is not None else period / samples_per_period
    duration = duration if duration is not None else periods * period
    every = max(1, int(math.ceil(sample_dt / (period / spp))))
    samples = int(math.floor(duration / sample_dt + 1e-9))
    return TimeGrid(float(duration), float(sample_dt), every, samples, spp)


@lru_cache(maxsize=256)
def rod_period(
    actuation: str,
    end_shortening: float,
    slenderness: float,
    poisson: float,
    elements: int,
    mu: float,
    branch: str,
    clamp: str = "node",
) -> float:
    """Fundamental period 2 pi / omega_1 of the rod (``elements``) about its ``branch``
    equilibrium at ``mu``, computed as ``sim.cosserat.dynamics.simulate`` does (the same
    continuation and spectrum; cached). Raises ``SimulationError`` where the rod has no such
    equilibrium (then a simulation stops before its first time step)."""
    from sim.cosserat import statics as S
    from sim.cosserat.rod import Rod

    rod = Rod(
        elements=elements,
        end_shortening=end_shortening,
        slenderness=slenderness,
        actuation=actuation,
        clamp=clamp,
        poisson=poisson,
    )
    s2, _ = S.sigma2(rod, S.branch_state(rod, mu, branch), modes=4)
    return 2.0 * math.pi / math.sqrt(abs(s2[0]))


@dataclass(frozen=True)
class RodCost:
    """What a rod simulation of a scene will do: ``elements`` x ``grid.steps`` (``work``)."""

    elements: int
    period: float
    grid: TimeGrid

    @property
    def steps(self) -> int:
        return self.grid.steps

    @property
    def work(self) -> int:
        """Element-steps: the run's cost is about 0.4 us of one core per element-step."""
        return self.elements * self.grid.steps


def rod_cost(scene: Scene, elements: int | None = None, clamp: str = "node") -> RodCost | None:
    """The elements and time steps ``sim.simulate(scene, model="cosserat")`` will run:
    ``elements`` (default ``rod_resolution``'s) and the grid of ``scene.duration`` and
    ``scene.dt`` (each defaulting as the simulation does) about the scene's equilibrium.
    None where the rod has no equilibrium at ``scene.mu`` on ``scene.branch`` (the simulation
    then fails before its first step). Blocking: static solves of the rod (cached)."""
    if elements is None:
        elements = rod_resolution(
            scene.actuation,
            end_shortening=scene.end_shortening,
            slenderness=scene.slenderness,
            poisson=scene.poisson,
            clamp=clamp,
            rtol=scene.rtol,
            elements=scene.elements,
        ).size
    from scipy.sparse.linalg import ArpackError

    try:
        period = rod_period(
            scene.actuation,
            float(scene.end_shortening),
            float(scene.slenderness),
            float(scene.poisson),
            int(elements),
            float(scene.mu),
            scene.branch,
            clamp,
        )
    except (ValueError, ArithmeticError, ArpackError):  # SimulationError, ParameterError too
        return None
    grid = rod_time_grid(period, scene.rtol, scene.duration, scene.dt)
    return RodCost(int(elements), period, grid)
