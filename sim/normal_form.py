"""Amplitude equations (normal forms) near the transition, with coefficients from the beam.

Paper, eqs. saddleNodeFinalForm and pitchforkFinalForm, with the damping of eq.
beam_equation_damping carried over to the mode amplitude:

    saddle-node (asymmetric):       A'' + xi A' = a1 dmu + a2 A^2
    pitchfork (sym., antisym.):     A'' + xi A' = b1 dmu A + b2 A^3

with W(X, T) ~ W*(X) + A(T) Phi0(X) and dmu = mu - mu*.

Coefficients are computed from the Euler beam at mu* (never typed in):

* saddle-node: Phi0 is the critical (sigma^2 = 0) constrained mode of U_A at the fold,
  normalised so that its Lambda_p = 1 (the paper's Lambda_0 = A); I1 = int Phi0^2,
  I2 = int Phi0'^2; a1 = 4 Lambda* / (mu* I1), a2 = 3 Lambda* I2 / I1 (paper, Appendix).
* pitchforks: Phi0 is the paper's eq. leadingOrderSolPF (symmetric:
  sin(L X) - L X + K (cos(L X) - 1), K = (L - sin L)/(cos L - 1); antisymmetric:
  cos(L X) - 1); b1, b2 = 2 Lambda* I2 C_{1,2} / I1 (eq. c1Andc2) where Lambda_0 = C1 + C2 A^2
  is obtained by solving the O(dmu) problem (eq. O2) numerically.

Corrections to the paper found by the numerical checks (tests/sim/test_normal_form.py):
* eq. O2 states dW1/dX(0) = 0; the boundary condition W'(0) = mu* + dmu gives dW1/dX(0) = 1,
  which is what the paper's own solution (eq. secondOrderSolPitchfork) satisfies. We use 1.
* eq. constantsLambda0Symm's closed form of C2 is off: it gives b2 = 3.1966e6 while the
  equilibrium branches S_A, S_B (and our O(dmu) solve) give b2 = 3.19087e6 (0.18%). We use the
  O(dmu) solve; C1 = 4 L / (2 mu*) is right. The antisymmetric closed forms (eq. b1Andb2) and
  the asymmetric a1, a2 agree with the beam to the accuracy of the limits.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import cache

import numpy as np
from scipy.integrate import solve_ivp

from sim.errors import SimulationError
from sim.euler_beam import galerkin
from sim.euler_beam._quadrature import WQ as _WQ
from sim.euler_beam._quadrature import XQ as _XQ
from sim.euler_beam.bifurcation import bifurcation
from sim.euler_beam.stability import spectrum_of
from sim.euler_beam.statics import ACTUATION_SLOPE, BeamError, equilibrium
from sim.scene import Scene, Signal, add_noise

#: Absolute tolerance of the integration relative to the response's amplitude (see
#: :meth:`NormalForm.integrate`).
ATOL_OF_RESPONSE = 1e-12


@dataclass(frozen=True)
class NormalForm:
    """The amplitude equation of one actuation's transition.

    Attributes
    ----------
    actuation, transition : str
    mu_star, lambda_star : float
    coefficients : dict
        {"a1", "a2"} (saddle-node) or {"b1", "b2"} (pitchfork), in units of the amplitude A
        (deflection units) and time.
    I1, I2 : float
        int Phi0^2 and int Phi0'^2.
    w_star_probe, phi0_probe, phi0_kick : float
        W*(1/4) and Phi0 at the default probe and kick position (X = 1/4).
    """

    actuation: str
    transition: str
    mu_star: float
    lambda_star: float
    coefficients: dict
    I1: float
    I2: float
    phi0: tuple = field(repr=False)  # (X nodes, values) on the quadrature grid

    @property
    def saddle_node(self) -> bool:
        return self.transition == "saddle-node"

    def phi(self, X: np.ndarray) -> np.ndarray:
        """Phi0 at points X (interpolated from its exact nodal values)."""
        Xn, vals = self.phi0
        return np.interp(np.asarray(X, float), np.concatenate([[0.0], Xn, [1.0]]),
                         np.concatenate([[0.0], vals, [0.0]]))  # fmt: skip

    def force(self, dmu: float, A: np.ndarray) -> np.ndarray:
        """Right-hand side a1 dmu + a2 A^2 or b1 dmu A + b2 A^3."""
        c = self.coefficients
        if self.saddle_node:
            return c["a1"] * dmu + c["a2"] * A * A
        return c["b1"] * dmu * A + c["b2"] * A**3

    def equilibria(self, dmu: float) -> dict[str, float]:
        """Equilibrium amplitudes by branch name at this dmu (paper eqs. saddleEquilibriums,
        pitchforkEquilibriums), with the beam's branch names."""
        c = self.coefficients
        if self.saddle_node:
            if dmu > 0:
                return {}
            r = math.sqrt(c["a1"] * (-dmu) / c["a2"])
            return {"U_A": -r, "S_B": r}
        out = {}
        trivial = "U_A" if self.actuation == "symmetric" else "S_B"
        out[trivial] = 0.0
        r2 = -c["b1"] * dmu / c["b2"]
        if r2 > 0:
            r = math.sqrt(r2)
            if self.actuation == "symmetric":  # S_B has W(1/4) > 0
                sgn = 1.0 if self.phi(np.array([0.25]))[0] > 0 else -1.0
                out["S_B"], out["S_A"] = sgn * r, -sgn * r
            else:  # U_A has W(1/2) < 0
                sgn = 1.0 if self.phi(np.array([0.5]))[0] > 0 else -1.0
                out["U_A"], out["U_B"] = -sgn * r, sgn * r
        return out

    def sigma2(self, dmu: float, branch: str = "U_A") -> float:
        """Linearised sigma^2 about an equilibrium (paper eqs. saddleGrowthRate,
        pitchforkGrowthRate)."""
        eqs = self.equilibria(dmu)
        if branch not in eqs:
            raise SimulationError(
                "mu",
                self.mu_star + dmu,
                f"branch {branch!r} has no normal-form equilibrium at mu={self.mu_star + dmu!r} "
                f"(dmu={dmu!r} from the {self.transition} at mu*={self.mu_star:.10g})",
            )
        A = eqs[branch]
        c = self.coefficients
        if self.saddle_node:
            return 2.0 * c["a2"] * A
        return c["b1"] * dmu + 3.0 * c["b2"] * A * A

    def integrate(self, dmu: float, A0: float, V0: float, t: np.ndarray, damping: float = 0.0):
        """A(t) from A(0) = A0, A'(0) = V0 (DOP853, rtol 1e-10); stops on blow-up (|A| > 1e3).

        The absolute tolerance follows the response: ``ATOL_OF_RESPONSE`` times its amplitude
        ``|V0| / rate`` (and that times the rate for A'), at most 1e-14. A fixed 1e-14 let a
        kick scaled with the rate cubed (responses of 1e-9 near mu*) carry relative errors of
        1e-5: sigma^2 read 1.5-2e-5 too soft 1e-5 from mu*, 3-4 of its standard errors, and
        the warn sweep's converged interval missed mu* by 3e-11 and 9e-11.

        Returns
        -------
        A : ndarray, shape (len(t),)
            NaN after a blow-up (a snap the normal form cannot follow).
        """

        def rhs(_, y):
            return [y[1], self.force(dmu, y[0]) - damping * y[1]]

        def blow(_, y):
            return abs(y[0]) - 1e3

        blow.terminal = True
        c = self.coefficients
        k = 2.0 * c["a2"] * A0 if self.saddle_node else c["b1"] * dmu + 3.0 * c["b2"] * A0 * A0
        rate = math.sqrt(abs(k) + 0.25 * damping * damping)
        amp = abs(V0) / rate if rate > 0 else 0.0
        atol = [min(1e-14, ATOL_OF_RESPONSE * amp) or 1e-14,
                min(1e-14, ATOL_OF_RESPONSE * amp * rate) or 1e-14]  # fmt: skip
        sol = solve_ivp(rhs, (t[0], t[-1]), [A0, V0], t_eval=t, method="DOP853",
                        rtol=1e-10, atol=atol, events=blow)  # fmt: skip
        out = np.full(t.shape, np.nan)
        out[: sol.y.shape[1]] = sol.y[0]
        return out


def _pitchfork_phi0(actuation: str, L: float) -> tuple[np.ndarray, np.ndarray]:
    X = _XQ
    if actuation == "symmetric":
        K = (L - math.sin(L)) / (math.cos(L) - 1.0)
        return (np.sin(L * X) - L * X + K * (np.cos(L * X) - 1.0),
                L * np.cos(L * X) - L - K * L * np.sin(L * X))  # fmt: skip
    return np.cos(L * X) - 1.0, -L * np.sin(L * X)


def lambda0_coefficients(actuation: str) -> tuple[float, float]:
    """(C1, C2) of Lambda_0 = C1 + C2 A^2 from the O(dmu) problem (paper eq. O2, with
    dW1/dX(0) = 1), solved numerically.

    W1 = A1 (sin LX - LX) + B1 (cos LX - 1) + X + (Lambda_0 / L) X (W*' - mu*) satisfies the
    ODE and the two conditions at X = 0; W1(1) = 0, W1'(1) = s and
    int W*' W1' = -A^2 I2 / 2 remain. Phi0 solves the homogeneous problem, so one of A1, B1 is
    fixed (the one Phi0 leans on most) and the best-conditioned pair of conditions is kept.
    """
    bif = bifurcation(actuation)
    L, mus, s = bif.lambda_star, bif.mu_star, ACTUATION_SLOPE[actuation]
    trivial = "U_A" if actuation == "symmetric" else "S_B"
    eq = equilibrium(actuation, mus * (1 - 1e-15), trivial)
    X = _XQ
    one = np.array([1.0])
    dW, d2W = eq.shape(X, 1), eq.shape(X, 2)
    dW1, d2W1 = eq.shape(one, 1)[0], eq.shape(one, 2)[0]
    phi, dphi = _pitchfork_phi0(actuation, L)
    I2 = float(np.sum(_WQ * dphi**2))
    M = np.empty((3, 3))
    M[0] = [math.sin(L) - L, math.cos(L) - 1.0, (dW1 - mus) / L]
    M[1] = [L * math.cos(L) - L, -L * math.sin(L), (dW1 - mus + d2W1) / L]
    cols = [L * np.cos(L * X) - L, -L * np.sin(L * X), (dW - mus + X * d2W) / L]
    M[2] = [np.sum(_WQ * dW * c) for c in cols]
    r0 = np.array([-1.0, s - 1.0, -np.sum(_WQ * dW)])
    r1 = np.array([0.0, 0.0, -0.5 * I2])
    # Phi0's coefficients on (sin - LX, cos - 1): drop the unknown it leans on most
    if actuation == "symmetric":
        K = (L - math.sin(L)) / (math.cos(L) - 1.0)
        drop = 0 if abs(1.0) >= abs(K) else 1
    else:
        drop = 1
    keep_cols = [j for j in (0, 1) if j != drop] + [2]
    best = None
    for rows in ((0, 2), (1, 2)):
        sub = M[np.ix_(rows, keep_cols)]
        det = abs(np.linalg.det(sub))
        if best is None or det > best[0]:
            best = (det, rows, sub)
    _, rows, sub = best
    x0 = np.linalg.solve(sub, r0[list(rows)])
    x1 = np.linalg.solve(sub, (r0 + r1)[list(rows)])
    return float(x0[-1]), float(x1[-1] - x0[-1])


@cache
def normal_form(actuation: str) -> NormalForm:
    """The normal form of an actuation's transition, coefficients from the beam at mu*."""
    bif = bifurcation(actuation)
    L, mus = bif.lambda_star, bif.mu_star
    if bif.transition == "saddle-node":
        eq = equilibrium(actuation, mus * (1 - 1e-14), "U_A")
        sp = spectrum_of(eq, modes=1)
        B = galerkin.basis(sp.n)
        coeffs = sp.coeffs[:, 0] / sp.lambda_p[0]
        phi = B.eval(_XQ) @ coeffs
        dphi = B.eval(_XQ, 1) @ coeffs
        I1 = float(np.sum(_WQ * phi**2))
        I2 = float(np.sum(_WQ * dphi**2))
        c = {"a1": 4.0 * L / (mus * I1), "a2": 3.0 * L * I2 / I1}
    else:
        phi, dphi = _pitchfork_phi0(actuation, L)
        I1 = float(np.sum(_WQ * phi**2))
        I2 = float(np.sum(_WQ * dphi**2))
        C1, C2 = lambda0_coefficients(actuation)
        c = {"b1": 2.0 * L * I2 * C1 / I1, "b2": 2.0 * L * I2 * C2 / I1}
    return NormalForm(actuation, bif.transition, mus, L, c, I1, I2, (_XQ.copy(), phi))


def impulse_response(scene: Scene) -> Signal:
    """Impulse response of the normal form about the scene's equilibrium.

    The record is W*(probe) + Phi0(probe) A(t): the bifurcation shape plus the critical mode's
    amplitude (the normal form keeps one mode, so higher harmonics are absent). The kick's
    projection on Phi0 gives A'(0) = kick Phi0(X_k) / I1.
    """
    nf = normal_form(scene.actuation)
    dmu = scene.mu - nf.mu_star
    eqs = nf.equilibria(dmu)
    if scene.branch not in eqs:
        raise SimulationError(
            "mu",
            scene.mu,
            f"branch {scene.branch!r} has no normal-form equilibrium for {scene.actuation} "
            f"actuation at mu={scene.mu!r} (normal-form branches here: {sorted(eqs)})",
        )
    A0 = eqs[scene.branch]
    s2 = nf.sigma2(dmu, scene.branch)
    xi = scene.damping
    disc = s2 + 0.25 * xi * xi
    if disc < 0:
        period = 2 * math.pi / math.sqrt(-disc)
        duration, dt = 40 * period, period / 50
    else:
        slow = max(abs(-0.5 * xi + math.sqrt(disc)), 1e-12)
        duration, dt = 5 / slow, 5 / slow / 2000
    duration = scene.duration if scene.duration is not None else duration
    dt = scene.dt if scene.dt is not None else dt
    n = int(round(duration / dt)) + 1
    if n > 400_000:
        raise BeamError("duration", duration, f"duration/dt gives {n} samples, more than 400000")
    if n < 2 or not (duration > 0 and dt > 0):
        field, value = ("dt", dt) if scene.dt is not None else ("duration", duration)
        raise BeamError(
            field,
            value,
            f"duration={duration:.6g} / dt={dt:.6g} gives {n} "
            "sample(s): a record needs at least 2 (a smaller dt or a longer duration)",
        )
    t = np.arange(n) * dt
    if s2 > 0:
        raise SimulationError(
            "mu",
            scene.mu,
            f"branch {scene.branch!r} at mu={scene.mu!r} is unstable past the {nf.transition} "
            f"at mu*={nf.mu_star:.10g} (sigma^2 = {s2:.6g} > 0): the strip would snap; "
            "use snap",
        )
    eq_star = equilibrium(scene.actuation, nf.mu_star * (1 - 1e-14), "U_A")
    w_star = float(eq_star.shape(np.array([scene.probe]))[0])
    p_probe = float(nf.phi(np.array([scene.probe]))[0])
    V0 = scene.kick * float(nf.phi(np.array([scene.kick_position]))[0]) / nf.I1
    A = nf.integrate(dmu, A0, V0, t, damping=xi)
    w_static = w_star + p_probe * A0
    w = w_star + p_probe * A
    if scene.snr_db is not None:
        w = add_noise(w, w_static, scene.snr_db, scene.seed)
    info = {"sigma2": [s2], "dmu": dmu, "coefficients": dict(nf.coefficients)}
    return Signal(t=t, w=w, w_static=w_static, model="normal-form", scene=scene, info=info)
