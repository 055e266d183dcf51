"""Impulse responses of the Euler beam: modal superposition and nonlinear time integration.

The damped beam (paper eq. beam_equation_damping) with its inextensibility constraint,

    W_TT + xi W_T + W_XXXX + Lambda(T)^2 W_XX = 0,   int_0^1 W_X^2 dX = 2,

is kicked at rest on an equilibrium by a transverse impulse: W_T(X, 0+) = kick delta(X - X_k).
The record is what a sensor at the probe sees: W(X_p, T) = W_eq(X_p) + response.

* ``method="modal"`` superposes the constrained linear modes (exact for the linearised problem;
  each mode eta'' + xi eta' - sigma^2 eta = 0 in closed form, any damping regime). Modes above
  0.8 x Nyquist of the sampling are left out, as a sensor's anti-aliasing filter would.
* ``method="nonlinear"`` integrates the Galerkin system with Lambda^2 as the Lagrange
  multiplier of the constraint (discrete-gradient midpoint rule, numba kernel): the full
  geometric nonlinearity of the model, including snap-through past mu*.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from sim.errors import SimulationError
from sim.euler_beam import _kernels, galerkin
from sim.euler_beam.stability import DEFAULT_N, Spectrum, spectrum_of
from sim.euler_beam.statics import ACTUATION_SLOPE, BeamError, Equilibrium, equilibrium
from sim.scene import Scene, Signal, add_noise

PERIODS = 40  # default record length in fundamental periods
SAMPLES_PER_PERIOD = 50  # default sampling of the fundamental
MAX_SAMPLES = 400_000
MAX_GROWTH = 12.0  # largest e-folding of an unstable mode over a record (e^12 ~ 1.6e5)


@dataclass(frozen=True)
class Discrete:
    """The Galerkin system of one actuation and mu, with a discrete equilibrium.

    Attributes
    ----------
    basis : galerkin.Basis
    mu, s : float
        End rotation and slope ratio (0, -1, +1).
    k4, k2 : ndarray, shape (n,)
        int lift'' phi'' and int lift' phi' (lift = mu * ell).
    c0 : float
        int lift'^2.
    a_eq : ndarray, shape (n,)
        Discrete equilibrium (Newton-converged on the Galerkin equations).
    lam_eq : float
        Its Lambda^2.
    """

    basis: galerkin.Basis
    mu: float
    s: float
    k4: np.ndarray
    k2: np.ndarray
    c0: float
    a_eq: np.ndarray
    lam_eq: float

    def lift(self, X: np.ndarray) -> np.ndarray:
        return self.mu * galerkin.lift(X, self.s)

    def shape(self, a: np.ndarray, X: np.ndarray) -> np.ndarray:
        return self.lift(X) + self.basis.eval(X) @ a

    def constraint(self, a: np.ndarray) -> float:
        return float(a @ self.basis.K2 @ a + 2 * self.k2 @ a + self.c0)


def _lift_terms(B: galerkin.Basis, mu: float, s: float) -> tuple[np.ndarray, np.ndarray, float]:
    d1 = mu * galerkin.lift(B.X, s, 1)
    d2 = mu * galerkin.lift(B.X, s, 2)
    return B.d2phi.T @ (B.w * d2), B.dphi.T @ (B.w * d1), float(np.sum(B.w * d1 * d1))


def discretize(eq: Equilibrium, n: int = DEFAULT_N) -> Discrete:
    """Galerkin system about ``eq``, with the equilibrium re-converged on the discrete equations."""
    B = galerkin.basis(n)
    s = ACTUATION_SLOPE[eq.actuation]
    k4, k2, c0 = _lift_terms(B, eq.mu, s)
    # L2 projection of W_eq - lift as the starting point, then Newton on (a, lam)
    r = B.phi.T @ (B.w * (eq.shape(B.X) - eq.mu * galerkin.lift(B.X, s)))
    a = np.linalg.solve(B.M, r)
    lam = eq.lambda2
    for _ in range(20):
        g = B.K2 @ a + k2
        res = np.concatenate([B.K4 @ a + k4 - lam * g, [a @ B.K2 @ a + 2 * k2 @ a + c0 - 2.0]])
        Jm = np.zeros((n + 1, n + 1))
        Jm[:n, :n] = B.K4 - lam * B.K2
        Jm[:n, n] = -g
        Jm[n, :n] = 2 * g
        step = np.linalg.solve(Jm, -res)
        a += step[:n]
        lam += step[n]
        if np.max(np.abs(step)) < 1e-14 * (1 + abs(lam)):
            break
    return Discrete(B, eq.mu, s, k4, k2, c0, a, float(lam))


def kick_load(B: galerkin.Basis, position: float, width: float = 0.0) -> np.ndarray:
    """Generalised load <phi_i, f> of a unit impulse: a point (width 0) or a normalised
    Gaussian of that width (units of L), shape (n,)."""
    if width > 0:
        prof = np.exp(-0.5 * ((B.X - position) / width) ** 2)
        prof /= np.sum(B.w * prof)
        return B.phi.T @ (B.w * prof)
    return B.eval(np.array([position]))[0]


def _kick_velocity(
    D: Discrete, a: np.ndarray, kick: float, position: float, width: float
) -> np.ndarray:
    """Generalised velocity after the impulse, projected on the constraint's tangent space.

    The impulse ``kick * delta(X - position)`` (or a normalised Gaussian of ``width``) gives
    M v = kick * <phi, delta>; the constraint's impulsive reaction removes the component along
    M^{-1} g (M-orthogonal projection), g = grad c / 2.
    """
    B = D.basis
    v = np.linalg.solve(B.M, kick * kick_load(B, position, width))
    g = B.K2 @ a + D.k2
    Mig = np.linalg.solve(B.M, g)
    return v - Mig * (g @ v) / (g @ Mig)


def default_sampling(sp: Spectrum, damping: float) -> tuple[float, float]:
    """(duration, dt): 40 periods at 50 samples per period of the fundamental; for an
    overdamped fundamental, 5 slow decay times in 2000 samples."""
    s2 = float(sp.sigma2[0])
    disc = s2 + 0.25 * damping**2
    if disc < 0:
        period = 2 * math.pi / math.sqrt(-disc)
        return PERIODS * period, period / SAMPLES_PER_PERIOD
    slow = abs(-0.5 * damping + math.sqrt(disc)) if s2 < 0 else math.sqrt(disc) - 0.5 * damping
    slow = max(slow, 1e-12)
    return 5.0 / slow, 5.0 / slow / 2000


def _time_grid(duration: float, dt: float) -> np.ndarray:
    n = int(round(duration / dt)) + 1
    if n > MAX_SAMPLES:
        raise BeamError(
            "duration", duration,
            f"duration/dt gives {n} samples, more than {MAX_SAMPLES}: raise dt or shorten duration"
        )
    if n < 8:
        raise BeamError("duration", duration,
                        f"duration={duration!r} with dt={dt!r} gives fewer than 8 samples")
    return np.arange(n) * dt


def modal_response(
    eq: Equilibrium,
    t: np.ndarray,
    *,
    kick: float,
    kick_position: float = 0.25,
    probe: float = 0.25,
    damping: float = 0.0,
    kick_width: float = 0.0,
    n: int = DEFAULT_N,
    max_omega: float | None = None,
) -> tuple[np.ndarray, dict]:
    """Linear impulse response at the probe by modal superposition (response only).

    Parameters
    ----------
    eq : Equilibrium
    t : ndarray, shape (m,)
        Times (time units), t >= 0.
    kick, kick_position, probe, damping, kick_width : float
        See ``Scene``; ``kick_width`` > 0 spreads the impulse as a Gaussian of that width.
    n : int
        Galerkin size (modes kept: the well-resolved two thirds, below ``max_omega``).
    max_omega : float, optional
        Highest angular frequency kept (default: all resolved modes).

    Returns
    -------
    response : ndarray, shape (m,)
        W(probe, t) - W_eq(probe).
    info : dict
        ``modes`` used, their ``sigma2``.
    """
    keep = max(1, (2 * (n - 1)) // 3)
    sp = spectrum_of(eq, modes=n - 1, n=n)
    idx = np.arange(keep)
    if max_omega is not None:
        idx = idx[sp.omega[:keep] <= max_omega]
        if idx.size == 0:
            idx = np.arange(1)
    B = galerkin.basis(n)
    modes_c = sp.coeffs[:, idx]
    v0 = kick_load(B, kick_position, kick_width) @ modes_c
    at_probe = B.eval(np.array([probe]))[0] @ modes_c
    amp = kick * v0 * at_probe
    out = np.empty_like(t, dtype=float)
    _kernels.modal_sum(
        np.ascontiguousarray(t, float),
        np.ascontiguousarray(sp.sigma2[idx]),
        float(damping),
        amp,
        out,
    )
    return out, {"modes": int(idx.size), "sigma2": sp.sigma2[idx].tolist()}


def nonlinear_response(
    eq: Equilibrium,
    t: np.ndarray,
    *,
    kick: float,
    kick_position: float = 0.25,
    probe: float = 0.25,
    damping: float = 0.0,
    kick_width: float = 0.0,
    n: int = DEFAULT_N,
    substeps: int | None = None,
) -> tuple[np.ndarray, dict]:
    """Impulse response at the probe by nonlinear time integration (absolute position W).

    The step is the sampling step divided by ``substeps`` (default: enough for the
    fundamental's phase error (omega dt)^2 / 12 to stay below 1e-6).

    Returns
    -------
    w : ndarray, shape (m,)
        Absolute W(probe, t) (NaN after a Newton failure, reported in ``info``).
    info : dict
        ``lambda2`` history, ``substeps``, ``completed``.
    """
    D = discretize(eq, n)
    dt = float(t[1] - t[0])
    if substeps is None:
        w1 = math.sqrt(abs(spectrum_of(eq, modes=1, n=n).sigma2[0]))
        substeps = max(1, int(math.ceil(w1 * dt / math.sqrt(12e-6))))
    a = D.a_eq.copy()
    v = _kick_velocity(D, a, kick, kick_position, kick_width)
    out_w = np.full(t.size, np.nan)
    out_lam = np.full(t.size, np.nan)
    B = D.basis
    probe_phi = B.eval(np.array([probe]))[0]
    rec = _kernels.midpoint_integrate(
        B.M, B.K4, B.K2, D.k4, D.k2, D.c0, float(damping), dt / substeps, a, v, D.lam_eq,
        (t.size - 1) * substeps, substeps, probe_phi, float(D.lift(np.array([probe]))[0]),
        out_w, out_lam,
    )  # fmt: skip
    return out_w, {"lambda2": out_lam, "substeps": substeps, "completed": rec == t.size}


def impulse_response(scene: Scene, *, method: str = "modal", n: int = DEFAULT_N) -> Signal:
    """Simulate a scene with the Euler-beam model and return the probe's record.

    Parameters
    ----------
    scene : Scene
        Uses actuation, mu, branch, damping, kick, kick_position, probe, duration, dt,
        snr_db, seed.
    method : {"modal", "nonlinear"}
    n : int
        Galerkin basis size.
    """
    if method not in ("modal", "nonlinear"):
        raise BeamError("method", method, f"method must be 'modal' or 'nonlinear', got {method!r}")
    eq = equilibrium(scene.actuation, scene.mu, scene.branch)
    sp = spectrum_of(eq, modes=3, n=n)
    duration, dt = default_sampling(sp, scene.damping)
    duration = scene.duration if scene.duration is not None else duration
    dt = scene.dt if scene.dt is not None else dt
    t = _time_grid(duration, dt)
    growth = math.sqrt(max(float(np.max(sp.sigma2)), 0.0)) * float(t[-1])
    if growth > MAX_GROWTH:
        raise SimulationError(
            "mu", scene.mu,
            f"branch {scene.branch!r} at mu={scene.mu!r} is unstable (sigma^2 = "
            f"{float(np.max(sp.sigma2)):.6g} > 0): a kick grows by e^{growth:.0f} over the record, "
            "the strip would snap; shorten the duration or use snap_through"
        )
    w_static = float(eq.shape(np.array([scene.probe]))[0])
    common = dict(
        kick=scene.kick,
        kick_position=scene.kick_position,
        probe=scene.probe,
        damping=scene.damping,
        n=n,
    )
    if method == "modal":
        resp, info = modal_response(eq, t, max_omega=0.8 * math.pi / dt, **common)
        w = w_static + resp
    else:
        w, info = nonlinear_response(eq, t, **common)
        info = {k: v for k, v in info.items() if k != "lambda2"}
    info.update({"lambda": eq.lam, "sigma2": sp.sigma2.tolist(), "method": method, "galerkin_n": n})
    if scene.snr_db is not None:
        w = add_noise(w, w_static, scene.snr_db, scene.seed)
    return Signal(t=t, w=w, w_static=w_static, model="euler-beam", scene=scene, info=info)


@dataclass(frozen=True)
class SnapThrough:
    """Record of a snap-through: time, probe position, Lambda^2, and the start/end levels."""

    t: np.ndarray
    w: np.ndarray
    lambda2: np.ndarray
    w_start: float
    completed: bool


def snap_through(
    actuation: str,
    dmu: float,
    *,
    duration: float = 5.0,
    dt: float = 1e-3,
    damping: float = 2e-4,
    probe: float = 0.5,
    perturbation: float = 1e-6,
    n: int = DEFAULT_N,
) -> SnapThrough:
    """Release the strip from the critical shape at mu* + dmu (paper, "nonlinear snap-through").

    The initial shape is the U_A equilibrium at mu* (the bifurcation shape) with the end
    rotation raised to mu* + dmu, projected on the constraint; it starts at rest but for a
    tiny antisymmetric-breaking velocity ``perturbation`` (kick at X = 1/4) that lets a
    pitchfork leave its unstable symmetric state, as numerical noise does in the paper.
    """
    from sim.euler_beam.bifurcation import bifurcation

    bif = bifurcation(actuation)
    eq_star = equilibrium(actuation, bif.mu_star * (1 - 1e-12), "U_A")
    mu = bif.mu_star + dmu
    D0 = discretize(eq_star, n)
    B = D0.basis
    s = ACTUATION_SLOPE[actuation]
    k4, k2, c0 = _lift_terms(B, mu, s)
    # same physical interior shape: W_old = lift_old + phi a_old; keep a, new lift, then
    # project on c(a) = 2 along M^{-1} grad c
    a = D0.a_eq.copy()
    D = Discrete(B, mu, s, k4, k2, c0, a, D0.lam_eq)
    for _ in range(50):
        g = B.K2 @ a + k2
        dirn = np.linalg.solve(B.M, g)
        F = D.constraint(a) - 2.0
        alpha = -F / (2 * g @ dirn)
        a = a + alpha * dirn
        if abs(F) < 1e-14:
            break
    v = _kick_velocity(D, a, perturbation, 0.25, 0.0)
    t = _time_grid(duration, dt)
    w1 = math.sqrt(abs(D0.lam_eq)) ** 2
    substeps = max(1, int(math.ceil(w1 * dt / math.sqrt(12e-6) / 10)))
    out_w = np.full(t.size, np.nan)
    out_lam = np.full(t.size, np.nan)
    probe_phi = B.eval(np.array([probe]))[0]
    w_start = float(D.shape(a, np.array([probe]))[0])
    rec = _kernels.midpoint_integrate(
        B.M, B.K4, B.K2, k4, k2, c0, float(damping), dt / substeps, a, v, D0.lam_eq,
        (t.size - 1) * substeps, substeps, probe_phi, float(D.lift(np.array([probe]))[0]),
        out_w, out_lam,
    )  # fmt: skip
    return SnapThrough(t, out_w, out_lam, w_start, rec == t.size)
