"""Dynamics of the planar Cosserat rod: implicit time stepping, the paper's kick protocol,
and the released-indenter snap-through.

Equation of motion (non-dimensional, paper eqs. beam_equation_damping and Gazzola 2018)::

    M z'' + xi M z' + grad E(z) = 0

with the lumped mass M (ds on node coordinates, (h^2/12) ds on element angles). It is
integrated with the generalised-alpha method (Chung & Hulbert 1993; ``rho_inf = 1`` is the
trapezoidal rule), implicit in every dof: the stiff stretch and shear modes (frequencies
~ n sqrt(12) / h) do not limit the step, which is set by the accuracy wanted on the slow
bending modes only (relative frequency error ~ (omega dt)^2 / 12). Each step is a Newton
solve with the banded tangent ``(1-am)/(beta dt^2) M + ... + (1-af) K``, factorised by a
banded LU (half-bandwidth 4) inside one numba kernel.
"""

from __future__ import annotations

import math
import time
import warnings
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from sim.errors import ParameterError, SimulationError
from sim.resolution import (
    DEFAULT_PERIODS,
    SAMPLES_PER_PERIOD,
    rod_steps_per_period,
    rod_time_grid,
)
from sim.scene import Scene, Signal, add_noise

from . import _kernels as K
from . import statics as S
from .rod import CosseratWarning, Rod


@dataclass(frozen=True)
class Run:
    """Raw result of :func:`integrate`.

    Attributes
    ----------
    t : ndarray (m,)
        Sample times.
    rec : ndarray (m, P)
        Recorded values (see ``probes``).
    z, v : ndarray (N,)
        Final state.
    steps, newton_iterations : int
    stop : {"done", "diverged"}
    cpu_s : float
        Process time spent in the kernel (all attempts).
    dt : float
        The step finally used (smaller than asked after a retry).
    """

    t: np.ndarray
    rec: np.ndarray
    z: np.ndarray
    v: np.ndarray
    steps: int
    newton_iterations: int
    stop: str
    cpu_s: float
    dt: float = 0.0


Probe = tuple[tuple[int, int], tuple[float, float]]


def integrate(
    rod: Rod,
    z0: np.ndarray,
    v0: np.ndarray,
    mu: float,
    *,
    xi: float,
    dt: float,
    nsteps: int,
    every: int = 1,
    probes: list[Probe] | None = None,
    rho_inf: float = 0.8,
    tol: float = 1e-13,
    maxit: int = 12,
    full_its: int = 99,
    fixed_extra: list[int] | None = None,
    retries: int = 3,
) -> Run:
    """Integrate the rod from (z0, v0) at fixed mu.

    Parameters
    ----------
    rod : Rod
    z0, v0 : ndarray (N,)
        Initial positions (consistent with the clamps at ``mu``) and velocities.
    mu : float
        Control parameter (end angles).
    xi : float
        Damping (>= 0).
    dt : float
        Time step (> 0), time units.
    nsteps, every : int
        Number of steps; a sample is kept every ``every`` steps (plus t = 0).
    probes : list of ((i, j), (wi, wj))
        Recorded linear combinations ``wi z[i] + wj z[j]``; default: y at s = 1/4.
    rho_inf : float in [0, 1]
        High-frequency spectral radius of the generalised-alpha method (1: trapezoidal).
    tol, maxit : float, int
        Newton tolerance on max |dz| and iteration cap per step.
    full_its : int
        Newton iterations with a fresh tangent; later ones reuse it (modified Newton).
    fixed_extra : list of int
        Additional dofs held fixed (e.g. an indenter on y(1/2)).
    retries : int
        When a Newton solve fails (violent motion), the run is restarted with the step
        halved (and ``every`` doubled, so the samples are the same), at most ``retries``
        times; ``Run.stop`` is "diverged" if it still fails, with the record up to there.
    """
    _check_stepping(dt, nsteps, every, xi, rho_inf)
    z = rod.apply_bc(np.array(z0, dtype=float), mu)
    v = np.array(v0, dtype=float)
    if z.shape != (rod.N,) or v.shape != (rod.N,):
        raise ParameterError("z0", np.shape(z0), f"z0 and v0 must have shape ({rod.N},)")
    fixed = rod.fixed_mask()
    for i in fixed_extra or []:
        fixed[i] = True
    v[fixed] = 0.0
    mass = rod.mass()
    aL, aR = rod.end_angles(mu)
    g = rod.gradient(z, mu)
    a = np.where(fixed, 0.0, -g / mass - xi * v)
    if probes is None:
        probes = [rod.interp_weights(0.25)]
    z_init, v_init, a_init = z.copy(), v.copy(), a.copy()
    pidx = np.array([p[0] for p in probes], dtype=np.int64)
    pw = np.array([p[1] for p in probes], dtype=np.float64)
    nrec = nsteps // every + 1
    rec = np.zeros((nrec, len(probes)))
    stats = np.zeros(3)
    fixed_u8 = fixed.astype(np.uint8)
    c0 = time.process_time()
    for attempt in range(retries + 1):
        K.integrate(
            z, v, a, mass, fixed_u8, rod.n, rod.ds, rod.EA, rod.GA, 1.0, rod.k_clamp,
            rod.k_clamp, aL, aR, float(xi), float(dt), int(nsteps), int(every), pidx, pw,
            float(rho_inf), float(tol), int(maxit), int(full_its), rec, stats,
        )  # fmt: skip
        if not stats[2] or attempt == retries:
            break
        dt, nsteps, every = 0.5 * dt, 2 * nsteps, 2 * every
        z, v, a = z_init.copy(), v_init.copy(), a_init.copy()
        rec[:] = 0.0
    cpu = time.process_time() - c0
    steps = int(stats[0])
    stop = "diverged" if stats[2] else "done"
    m = steps // every + 1
    return Run(
        t=np.arange(m) * every * dt,
        rec=rec[:m],
        z=z,
        v=v,
        steps=steps,
        newton_iterations=int(stats[1]),
        stop=stop,
        cpu_s=cpu,
        dt=dt,
    )


def _check_stepping(dt: float, nsteps: int, every: int, xi: float, rho_inf: float) -> None:
    """Refuse a time-stepping request that cannot run, naming the parameter and its value."""
    if not (dt > 0 and math.isfinite(dt)):
        raise ParameterError("dt", dt, f"dt must be a positive number, got {dt!r}")
    if int(nsteps) != nsteps or nsteps < 1:
        raise ParameterError("nsteps", nsteps, f"nsteps must be an integer >= 1, got {nsteps!r}")
    if int(every) != every or every < 1:
        raise ParameterError("every", every, f"every must be an integer >= 1, got {every!r}")
    if not (xi >= 0 and math.isfinite(xi)):
        raise ParameterError("xi", xi, f"xi must be >= 0, got {xi!r}")
    if not 0.0 <= rho_inf <= 1.0:
        raise ParameterError("rho_inf", rho_inf, f"rho_inf must lie in [0, 1], got {rho_inf!r}")


def kick_velocity(rod: Rod, X: float, kick: float) -> np.ndarray:
    """Velocity field (N,) after the impulse ``kick * delta(X - X_k)`` (W units), lumped on the
    two nodes around X_k (linear weights; momentum kick sqrt(L dL) in total)."""
    (i, j), (wi, wj) = rod.interp_weights(X)
    v = np.zeros(rod.N)
    p = kick * math.sqrt(rod.end_shortening)
    v[i] += wi * p / rod.ds
    v[j] += wj * p / rod.ds
    return v


def rod_for(scene: Scene, clamp: str = "node"):
    """(Rod, Resolution) of a scene: ``scene.elements`` or the resolution policy's n for
    ``scene.rtol``."""
    from .api import make_rod

    return make_rod(
        scene.actuation,
        end_shortening=scene.end_shortening,
        slenderness=scene.slenderness,
        elements=scene.elements,
        rtol=scene.rtol,
        poisson=scene.poisson,
        clamp=clamp,
    )


def steps_for(rtol: float) -> int:
    """Time steps per fundamental period for a relative frequency error (omega dt)^2 / 12
    below rtol / 4 (at least 50): ``sim.resolution.rod_steps_per_period``."""
    return rod_steps_per_period(rtol)


def simulate(
    scene: Scene,
    *,
    steps_per_period: int | None = None,
    periods: float = DEFAULT_PERIODS,
    samples_per_period: int = SAMPLES_PER_PERIOD,
    rho_inf: float = 0.8,
    clamp: str = "node",
) -> Signal:
    """The paper's impulse-response protocol on the discrete Cosserat rod.

    The rod is brought to end-to-end distance L - dL on ``scene.branch`` (U_A: buckled to
    negative w at mu = 0), its ends rotated quasi-statically to ``scene.mu`` (Newton
    continuation: the exact static equilibrium, no settling transient), kicked at
    ``scene.kick_position`` and its transverse position recorded at ``scene.probe``.

    Parameters
    ----------
    scene : Scene
        Uses actuation, mu, branch (U_A or U_B), damping, kick, kick_position, probe,
        duration, dt, snr_db, seed, end_shortening, slenderness, elements.
    steps_per_period : int or None
        Internal steps per fundamental period; default ``steps_for(scene.rtol)``, relative
        frequency error of the time stepping (2 pi / steps)^2 / 12 <= rtol / 4; the step
        divides the sampling step.
    periods : float
        Default duration in fundamental periods (when ``scene.duration`` is None).
    samples_per_period : int
        Default sampling (when ``scene.dt`` is None).
    rho_inf : float
        Generalised-alpha spectral radius at infinite frequency (default 0.8: damps the
        stiff stretch/shear/rotation modes a point kick excites; its algorithmic damping
        of the fundamental, ~ (omega dt)^3, is ~1e-4 per unit time at 100 steps per period).
    clamp : {"node", "element"}

    Returns
    -------
    Signal
        ``t`` (time units), ``w`` = W(probe, t) (units of sqrt(L dL)), ``w_static``, and
        ``info`` with the equilibrium's Lambda, the rod's linear spectrum (sigma2), the
        resolution (elements, estimated mu* error), the Richardson estimate of the
        fundamental's sigma^2 error (n against n/2), the step, the Newton count, the CPU
        time and the stop reason.

    Raises
    ------
    sim.errors.SimulationError
        (parameter "mu") past the fold, on an unstable equilibrium, or on U_A past the
        antisymmetric pitchfork (where it has merged with S_B).
    """
    rod, res = rod_for(scene, clamp)
    z_eq, lam, s2 = _stable_equilibrium(rod, scene)
    s2_err = _richardson_sigma2_error(rod, scene, s2[0], clamp)
    if steps_per_period is None:
        steps_per_period = steps_for(scene.rtol)
    omega1 = math.sqrt(abs(s2[0]))
    period = 2.0 * math.pi / omega1
    grid = rod_time_grid(
        period,
        scene.rtol,
        scene.duration,
        scene.dt,  # its cost: rod_cost
        steps_per_period=steps_per_period,
        periods=periods,
        samples_per_period=samples_per_period,
    )
    every, dt, n_samples = grid.every, grid.dt, grid.samples
    v0 = kick_velocity(rod, scene.kick_position, scene.kick)
    probe = rod.interp_weights(scene.probe)
    r = math.sqrt(rod.end_shortening)
    run = integrate(
        rod,
        z_eq,
        v0,
        scene.mu,
        xi=scene.damping,
        dt=dt,
        nsteps=n_samples * every,
        every=every,
        probes=[(probe[0], (probe[1][0] / r, probe[1][1] / r))],
        rho_inf=rho_inf,
    )
    w_static = rod.w_at(z_eq, scene.probe)
    w = add_noise(run.rec[:, 0].copy(), w_static, scene.snr_db, scene.seed)
    info: dict[str, Any] = {
        "lambda": math.sqrt(max(0.0, -rod.axial_force(z_eq))),
        "sigma2": [float(x) for x in s2],
        "omega": omega1,
        "min_eigenvalue": float(lam),
        "internal_dt": run.dt,
        "steps": run.steps,
        "newton_iterations": run.newton_iterations,
        "cpu_s": run.cpu_s,
        "stop": run.stop,
        "clamp": clamp,
        "rho_inf": rho_inf,
        "elements": rod.n,
        "resolution": res,
        "sigma2_error": s2_err,
        "time_error": (2.0 * math.pi / steps_per_period) ** 2 / 12.0,
    }
    if run.stop != "done":
        warnings.warn(
            f"time stepping stopped early ({run.stop}) at step {run.steps}",
            CosseratWarning,
            stacklevel=2,
        )
    return Signal(t=run.t, w=w, w_static=float(w_static), model="cosserat", scene=scene, info=info)


def _stable_equilibrium(rod: Rod, scene: Scene) -> tuple[np.ndarray, float, np.ndarray]:
    """The rod's equilibrium on ``scene.branch`` at ``scene.mu``, refused unless it is stable.

    Returns the state, the Hessian's smallest eigenvalue and the four lowest sigma^2.

    Raises
    ------
    sim.errors.SimulationError
        (parameter "mu") on an unstable equilibrium, or on U_A/U_B past the antisymmetric
        pitchfork (where the branch has merged with S_B).
    """
    z_eq = S.branch_state(rod, scene.mu, scene.branch)
    lam = S.min_eigenvalues(rod, z_eq)[0]
    s2, _ = S.sigma2(rod, z_eq, modes=4)
    k_mid = 3 * (rod.n // 2) + 1
    if lam <= 0.0:
        raise SimulationError(
            "mu",
            scene.mu,
            f"the {scene.branch} equilibrium of the rod ({rod.n} elements) at "
            f"mu={scene.mu!r} is unstable (smallest Hessian eigenvalue {lam:.3e}): past its "
            "transition, the strip would snap (see `snapwarn bifurcation --model cosserat`)",
        )
    if (
        scene.actuation == "antisymmetric"
        and scene.branch in ("U_A", "U_B")
        and abs(z_eq[k_mid]) < 1e-9 * math.sqrt(rod.end_shortening)
    ):
        raise SimulationError(
            "mu",
            scene.mu,
            f"{scene.branch} does not exist at mu={scene.mu!r}: past the rod's "
            f"supercritical pitchfork ({rod.n} elements) it has merged with S_B",
        )
    return z_eq, float(lam), s2


def _richardson_sigma2_error(rod: Rod, scene: Scene, s2_1: float, clamp: str) -> float:
    """Relative error of the fundamental's sigma^2 by Richardson: n elements against n/2.

    The spatial convergence order is 2 for node clamps and 1 for element clamps; infinite
    when the coarse rod is already past its own fold.
    """
    half = Rod(
        elements=max(4, 2 * (rod.n // 4)),
        end_shortening=rod.end_shortening,
        slenderness=rod.slenderness,
        actuation=rod.actuation,
        clamp=clamp,
        poisson=rod.poisson,
    )
    try:
        s2_half = S.sigma2(half, S.branch_state(half, scene.mu, scene.branch), 1)[0][0]
    except (SimulationError, np.linalg.LinAlgError):  # n/2 is past its own fold
        return math.inf
    s2_err = abs(s2_1 - s2_half) / (2.0 ** (2 if clamp == "node" else 1) - 1.0)
    return float(s2_err / abs(s2_1))


@dataclass(frozen=True)
class SnapThrough:
    """The released-indenter snap-through (paper Appendix "Snap-through time").

    Attributes
    ----------
    mu_star, mu : float
        The fold and the control parameter the rod is pulled to (mu = mu* + dmu).
    t : ndarray (m,)
        Time after the release.
    w_mid, w_probe : ndarray (m,)
        W(1/2, t) and W(1/4, t) (units of sqrt(L dL)).
    w_mid_final : float
        W(1/2) of the U_B equilibrium at mu (where the strip snaps to).
    t_snap : float or None
        First time W(1/2) reaches ``w_mid_final`` (None if not within the record).
    info : dict
    """

    mu_star: float
    mu: float
    t: np.ndarray
    w_mid: np.ndarray
    w_probe: np.ndarray
    w_mid_final: float
    t_snap: float | None
    info: dict = field(default_factory=dict)


def snap_through(
    dmu: float,
    *,
    end_shortening: float = 1e-2,
    slenderness: float = 1e-3,
    elements: int = 50,
    damping: float = 6e-4,
    duration: float = 5.0,
    dt: float = 1e-3,
    mu_star: float | None = None,
    every: int = 1,
) -> SnapThrough:
    """The paper's released-indenter experiment, asymmetric actuation.

    Start from the rod's equilibrium at its fold mu*; hold the midpoint's transverse position
    (the indenter) while the left end is rotated quasi-statically to mu* + dmu (static Newton
    solves of the pinned rod); release and record the snap to U_B.

    Parameters
    ----------
    dmu : float
        Distance past the fold (> 0).
    end_shortening, slenderness, elements : the rod.
    damping : float
        xi (the paper's Fig. 7 used xi ~ 6e-4).
    duration, dt : float
        Record length and time step (time units).
    mu_star : float or None
        The fold, if already known (else computed by :func:`bifurcation`).
    every : int
        Internal steps per recorded sample (the rod steps ``dt / every``; the record is
        sampled every ``dt`` whatever ``every``).
    """
    from .bifurcation import find_bifurcation

    if not (dmu > 0 and math.isfinite(dmu)):
        raise ParameterError("dmu", dmu, f"dmu must be > 0, got {dmu!r}")
    rod = Rod(
        elements=elements,
        end_shortening=end_shortening,
        slenderness=slenderness,
        actuation="asymmetric",
    )
    ms = find_bifurcation(rod).mu_star if mu_star is None else float(mu_star)
    k = 3 * (rod.n // 2) + 1
    z = S.branch_state(rod, ms - 1e-6)  # U_A at the fold (to 1e-6)
    # pinned equilibria: y(1/2) held by the indenter while mu is raised quasi-statically
    z = _pinned_follow(rod, z, ms - 1e-6, ms + dmu, k)
    zB = S.branch_state(rod, ms + dmu, "U_B")
    nsteps = int(round(duration / dt))
    r = math.sqrt(end_shortening)
    probes = [
        ((k, k), (1.0 / r, 0.0)),
        (rod.interp_weights(0.25)[0], tuple(w / r for w in rod.interp_weights(0.25)[1])),
    ]
    run = integrate(
        rod, z, np.zeros(rod.N), ms + dmu, xi=damping, dt=dt / every, nsteps=nsteps * every,
        every=every, probes=probes,
    )  # fmt: skip
    w_mid = run.rec[:, 0]
    wf = float(zB[k] / r)
    hit = np.flatnonzero(w_mid >= wf)
    t_snap = float(run.t[hit[0]]) if hit.size else None
    return SnapThrough(
        mu_star=ms,
        mu=ms + dmu,
        t=run.t,
        w_mid=w_mid,
        w_probe=run.rec[:, 1],
        w_mid_final=wf,
        t_snap=t_snap,
        info={"stop": run.stop, "cpu_s": run.cpu_s, "steps": run.steps, "dt": run.dt},
    )


def _pinned_follow(
    rod: Rod, z: np.ndarray, mu0: float, mu1: float, k: int, steps: int = 20
) -> np.ndarray:
    """Equilibria with dof k held (the indenter) from mu0 to mu1 (mu given, dof k's reaction
    free): Newton on the free dofs other than k."""
    hold = z[k]
    for m in np.linspace(mu0, mu1, steps + 1)[1:]:
        z = _newton_held(rod, z, float(m), k, hold)
    return z


def _newton_held(rod: Rod, z: np.ndarray, mu: float, k: int, value: float) -> np.ndarray:
    import scipy.sparse.linalg as spla

    z = rod.apply_bc(z.copy(), mu)
    z[k] = value
    fixed = rod.fixed_mask()
    fixed[k] = True
    for _ in range(40):
        g = rod.gradient(z, mu)
        g[fixed] = 0.0
        ab = S._dirichlet_band(rod, rod.hessian_band(z), fixed)
        dz = spla.spsolve(S._sparse(ab), -g)
        z += dz
        if np.max(np.abs(dz)) < 1e-11:
            return z
    raise S.ConvergenceError(f"pinned Newton did not converge at mu={mu!r}", mu)
