"""Snap-through past the transition, for every backend (paper, "Snap-through dynamics").

Protocol (as in the paper): asymmetric and symmetric actuation, the strip starts on U_A at mu*
and the control is set to mu* + dmu (right of the transition, where U_A has vanished or lost
stability); antisymmetric actuation, it starts on S_B at mu* and the control is set to
mu* - dmu (left of the supercritical pitchfork, where S_B is unstable) and escapes to U_A or
U_B. A symmetry-breaking velocity ``perturbation * dmu`` (an impulse at X = 1/4) lets a
pitchfork leave its unstable state: scaling it with dmu (the amplitude equation's natural
velocity scale) makes the escape time of the pitchfork scale exactly as dmu^(-1/2) in the
normal-form limit; the saddle-node starts at rest from the fold shape (dmu^(-1/4)).

The amplitude is A(t) = W(X_p, t) - W*(X_p) at the probe X_p (1/2 for the saddle-node, 1/4 for
the pitchforks, where the critical mode is largest); the snap time is the first time |A|
reaches half the distance to the state it snaps to.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from sim.errors import ParameterError
from sim.results import Resolution
from sim.scene import Scene

PERTURBATION = 1e-3  # symmetry-breaking impulse per unit dmu (pitchforks)
MAX_DURATION = 500.0


@dataclass(frozen=True)
class SnapResult:
    """One snap-through record.

    Attributes
    ----------
    actuation, model : str
    dmu : float
        Distance from mu* (> 0; to the left of mu* for the antisymmetric actuation).
    mu, mu_star : float
        The control set and the backend's own mu*.
    from_branch, to_branch : str
    snap_time : float or None
        First time |A| reaches half the distance to ``to_branch`` (None: not within record).
    t, amplitude : ndarray, shape (m,)
        Time (time units) and A(t) = W(probe, t) - W*(probe) (units of sqrt(L dL)).
    probe : float
    resolution : Resolution or None
    info : dict
    """

    actuation: str
    model: str
    dmu: float
    mu: float
    mu_star: float
    from_branch: str
    to_branch: str
    snap_time: float | None
    t: np.ndarray
    amplitude: np.ndarray
    probe: float
    resolution: Resolution | None = None
    info: dict = field(default_factory=dict)


def _protocol(actuation: str) -> tuple[float, str, str, float]:
    """(side, from, to, probe): side +1 right of mu*, -1 left."""
    if actuation == "antisymmetric":
        return -1.0, "S_B", "U_A", 0.25
    if actuation == "symmetric":
        return 1.0, "U_A", "U_B", 0.25
    return 1.0, "U_A", "U_B", 0.5


def normal_form_time(actuation: str, dmu: float) -> float:
    """Snap time of the normal form alone (its blow-up time) in the protocol above."""
    from sim.normal_form import normal_form

    nf = normal_form(actuation)
    side, _, _, _ = _protocol(actuation)
    c = nf.coefficients
    if nf.saddle_node:  # A'' = a1 dmu + a2 A^2 from rest: T = dmu^(-1/4) * const
        s = (c["a1"] * c["a2"] * dmu) ** 0.25
        return 2.0 ** 0.5 * _beta_quarter() / s
    v0 = _pitchfork_v0(nf, dmu)
    r = math.sqrt(abs(c["b1"]) * dmu)
    return math.asinh(r / max(abs(v0), 1e-300)) / r  # order of magnitude (escape to A = 1)


def _beta_quarter() -> float:
    # integral_0^inf dx / sqrt(x^3 / 3 + x) ... used only for the default duration
    return 2.62


def _pitchfork_v0(nf, dmu: float) -> float:
    return PERTURBATION * dmu * float(nf.phi(np.array([0.25]))[0]) / nf.I1


def _target_distance(actuation: str, mu: float, start: float, to_branch: str,
                     probe: float) -> float:
    from sim.euler_beam import equilibrium

    return abs(float(equilibrium(actuation, mu, to_branch).shape(np.array([probe]))[0]) - start)


def _first_crossing(t: np.ndarray, a: np.ndarray, level: float) -> float | None:
    hit = np.flatnonzero(np.abs(np.nan_to_num(a, nan=np.inf)) >= level)
    if not hit.size:
        return None
    k = int(hit[0])
    if k == 0:
        return float(t[0])
    a0, a1 = abs(a[k - 1]), abs(a[k]) if math.isfinite(a[k]) else abs(a[k - 1])
    f = (level - a0) / (a1 - a0) if a1 != a0 else 1.0
    return float(t[k - 1] + f * (t[k] - t[k - 1]))


def snap(scene: Scene, model: str, dmu: float, *, duration: float | None = None,
         dt: float | None = None) -> SnapResult:
    """Snap-through of ``scene``'s strip with one backend (see the module docstring).

    Parameters
    ----------
    scene : Scene
        Uses actuation, damping (and the strip and resolution for the rod).
    model : {"euler-beam", "cosserat", "normal-form"}
    dmu : float
        Distance from mu* (> 0, < 0.5).
    duration, dt : float, optional
        Record length and step (time units); default 4 normal-form snap times, 2000 samples.
    """
    if model not in ("euler-beam", "cosserat", "normal-form"):
        raise ParameterError("model", model,
                             f"model must be euler-beam, cosserat or normal-form, got {model!r}")
    if not (isinstance(dmu, (int, float)) and math.isfinite(dmu) and 0.0 < dmu < 0.5):
        raise ParameterError("dmu", dmu, f"dmu must lie in (0, 0.5), got {dmu!r}")
    act = scene.actuation
    side, frm, to, probe = _protocol(act)
    if duration is None:
        duration = default_duration(act, dmu)
    if not (math.isfinite(duration) and 1e-3 <= duration <= MAX_DURATION):
        raise ParameterError("duration", duration,
                             f"duration must lie in [0.001, {MAX_DURATION}], got {duration!r}")
    if dt is None:
        dt = duration / 4000.0
    if not (math.isfinite(dt) and 0.0 < dt <= duration / 8):
        raise ParameterError("dt", dt, f"dt must lie in (0, duration / 8], got {dt!r}")
    if model == "cosserat":
        return _rod_snap(scene, dmu, duration, dt)
    from sim.euler_beam import bifurcation, equilibrium

    bif = bifurcation(act)
    mu = bif.mu_star + side * dmu
    w_star = float(equilibrium(act, bif.mu_star * (1 - 1e-12), "U_A").shape(np.array([probe]))[0])
    level = 0.5 * _target_distance(act, mu, w_star, to, probe)
    pert = 0.0 if bif.transition == "saddle-node" else PERTURBATION * dmu
    t = np.arange(int(round(duration / dt)) + 1) * dt
    if model == "normal-form":
        from sim.normal_form import normal_form

        nf = normal_form(act)
        v0 = pert * float(nf.phi(np.array([0.25]))[0]) / nf.I1
        A = nf.integrate(side * dmu, 0.0, v0, t, damping=scene.damping)
        amp = float(nf.phi(np.array([probe]))[0]) * A
        res = None
    else:
        from sim.euler_beam.dynamics import snap_through

        st = snap_through(act, side * dmu, duration=float(t[-1]), dt=dt, damping=scene.damping,
                          probe=probe, perturbation=pert)
        t, amp = st.t, st.w - w_star
        res = bif.resolution
    return SnapResult(act, model, float(dmu), mu, bif.mu_star, frm, to,
                      _first_crossing(t, amp, level), t, amp, probe, res,
                      {"level": level, "perturbation": pert})  # fmt: skip


def default_duration(actuation: str, dmu: float) -> float:
    """A snap's default record length: 4 normal-form snap times and 2 time units, at most
    ``MAX_DURATION``."""
    return min(MAX_DURATION, 4.0 * normal_form_time(actuation, dmu) + 2.0)


@dataclass(frozen=True)
class RodSnapGrid:
    """The time grid of a rod's snap: ``samples`` records ``dt`` apart, each ``every``
    internal steps of ``dt / every``, no coarser than the rod's own step (``step``: its
    fundamental period at rest / ``sim.resolution.rod_steps_per_period(rtol)``, the step a
    simulation of the same scene runs). ``steps`` = samples x every; the cost of the run is
    about elements x steps (``work``)."""

    samples: int
    every: int
    step: float
    elements: int

    @property
    def steps(self) -> int:
        return self.samples * self.every

    @property
    def work(self) -> int:
        return self.elements * self.steps


def rod_snap_grid(scene: Scene, elements: int, duration: float, dt: float) -> RodSnapGrid:
    """The grid :func:`snap` runs the rod on (see :class:`RodSnapGrid`). Blocking: the rod's
    equilibrium at rest (cached); ParameterError when it has none."""
    from sim.resolution import rod_cost

    cost = rod_cost(scene, elements)
    if cost is None:
        raise ParameterError("scene", scene.actuation,
                             "the rod has no equilibrium at rest to take its time step from")
    step = cost.period / cost.grid.steps_per_period
    every = max(1, math.ceil(dt / step * (1 - 1e-12)))
    return RodSnapGrid(int(round(duration / dt)), every, step, int(elements))


def _rod_snap(scene: Scene, dmu: float, duration: float, dt: float) -> SnapResult:
    """The rod: asymmetric, the paper's released indenter (``cosserat.snap_through``);
    pitchforks, the state at the rod's own mu* with the control stepped to mu* +- dmu and the
    symmetry-breaking impulse (``PERTURBATION * dmu`` at X = 1/4)."""
    from sim.backends import BACKENDS
    from sim.cosserat import statics as S
    from sim.cosserat.dynamics import integrate, kick_velocity, snap_through
    from sim.cosserat.rod import Rod

    bif = BACKENDS["cosserat"].bifurcation(scene)
    n = bif.resolution.size
    grid = rod_snap_grid(scene, n, duration, dt)
    if scene.actuation == "asymmetric":
        st = snap_through(dmu, end_shortening=scene.end_shortening,
                          slenderness=scene.slenderness, elements=n, damping=scene.damping,
                          duration=duration, dt=dt, mu_star=bif.mu_star,
                          every=grid.every)  # fmt: skip
        _check_resolved(st.info["stop"], st.t, duration, st.info["dt"])
        k = bif.w_star.size // 2
        amp = st.w_mid - float(bif.w_star[k])
        level = 0.5 * abs(st.w_mid_final - float(bif.w_star[k]))
        return SnapResult("asymmetric", "cosserat", float(dmu), st.mu, st.mu_star, "U_A", "U_B",
                          _first_crossing(st.t, amp, level), st.t, amp, 0.5, bif.resolution,
                          {"level": level, **st.info})  # fmt: skip
    side, frm, to, probe = _protocol(scene.actuation)
    rod = Rod(elements=n, end_shortening=scene.end_shortening, slenderness=scene.slenderness,
              actuation=scene.actuation, poisson=scene.poisson)
    mu = bif.mu_star + side * dmu
    z0 = bif.info["z_star"]
    w0 = rod.w_at(z0, probe)
    target = S.branch_state(rod, mu, "U_B" if to == "U_B" else "U_A")
    level = 0.5 * abs(rod.w_at(target, probe) - w0)
    pert = PERTURBATION * dmu
    (i, j), (wi, wj) = rod.interp_weights(probe)
    r = math.sqrt(rod.end_shortening)
    run = integrate(rod, z0, kick_velocity(rod, 0.25, pert), mu, xi=scene.damping,
                    dt=dt / grid.every, nsteps=grid.steps, every=grid.every,
                    probes=[((i, j), (wi / r, wj / r))])  # fmt: skip
    _check_resolved(run.stop, run.t, duration, run.dt)
    amp = run.rec[:, 0] - w0
    return SnapResult(scene.actuation, "cosserat", float(dmu), mu, bif.mu_star, frm, to,
                      _first_crossing(run.t, amp, level), run.t, amp, probe, bif.resolution,
                      {"level": level, "perturbation": pert, "stop": run.stop,
                       "cpu_s": run.cpu_s})  # fmt: skip


def _check_resolved(stop: str, t: np.ndarray, duration: float, step: float) -> None:
    """A rod whose integration diverged (Newton failed after its step was halved) gives no
    snap: ParameterError naming the duration, never a truncated record passed as one."""
    if stop == "done":
        return
    reached = float(t[-1]) if len(t) else 0.0
    raise ParameterError(
        "duration", duration,
        f"the rod's integration diverged at t={reached:.4g} of duration={duration:.4g} "
        f"(Newton failed at the step {step:.3g}, halved 3 times): the snap is not resolved; "
        "ask for a shorter duration, a larger dmu or more elements",
    )  # fmt: skip
