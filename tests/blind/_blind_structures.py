"""Blind structures: small elastic structures with exact critical loads (tests/blind only).

Written from the mechanics alone with numpy and scipy (never ``sim`` or ``service``, nor the
other test generators), so that the product is tried on structures nobody on the team tuned it
on. Every structure is linearised about its equilibrium at the control ``mu`` (a load): the lab
sees its modes, each ``(omega0^2, shape at the sensor, shape at the hammer)``, and, with a
displacement sensor, the static level. Times are non-dimensional here; :mod:`_blind_recorder`
scales them to Hz.

Shallow arch (``Arch``): a pinned sinusoidal arch of span ``pi`` in two modes, ``w = q1 sin x +
q2 sin 2x``, stress-free shape ``(e, e2)``, identity modal mass, under a load ``P`` on the
symmetric mode::

    V = (q1 - e)^2 / 2 + r (q2 - e2)^2 / 2 + (kappa / 32) s^2 + P q1,
    s = q1^2 + alpha q2^2 - e^2 - alpha e2^2          (the membrane strain, times 4)

(``r = 16``, ``alpha = 4`` for the second sine). Perfect (``e2 = 0``) the symmetric path
``q2 = 0`` has ``P(q1) = e - q1 - (kappa/8)(q1^2 - e^2) q1`` and decoupled stiffnesses
``V11 = 1 + (kappa/8)(3 q1^2 - e^2)``, ``V22 = r + (kappa/8) alpha (q1^2 - e^2)``:

* a symmetric limit point (saddle-node) at ``q1_L^2 = (e^2 - 8/kappa) / 3``;
* an asymmetric bifurcation at ``q1_b^2 = e^2 - 8 r / (kappa alpha)``, ``P_b = e + (r/alpha - 1)
  q1_b``; on the bifurcated path ``P = e + (r/alpha - 1) q1`` falls as ``|q2|`` grows: a
  subcritical pitchfork whose critical mode is the antisymmetric one. It comes first when
  ``q1_b > q1_L`` (``kappa e^2 > 44`` for ``r = 16``); for ``44 < kappa e^2 < 60`` the symmetric
  mode is the LOWEST line far from ``P_b`` although it is not the one that goes soft.

With ``e2 != 0`` the bifurcation becomes a fold, found by Brent's method on ``det V'' = 0``
along the equilibrium path parametrised by ``q2`` (``P`` explicit on it).

Column on an elastic foundation (``FoundationColumn``): a pinned Euler column on a Winkler
foundation, non-dimensional load ``p``, modes ``sin(n x)`` with ``omega_n^2 = n^4 + beta - n^2
p``; it buckles at ``p* = min_n (n^2 + beta / n^2)``. For ``beta > 4`` the buckling mode is not
the first: far from ``p*`` the lowest line is the mode ``n = 1``, which does not go soft first.

Three-link column (``ThreeLinkColumn``): three rigid links of unit length between pins, axial
load ``P``, rotational springs ``k1, k2`` at the inner joints and masses ``m1, m2`` there;
lateral joint displacements ``y``: stiffness ``K - P G`` with ``K`` from the joints' rotation
changes ``(2 y1 - y2, 2 y2 - y1)`` and ``G = [[2, -1], [-1, 2]]``; buckling where ``det(K - P
G) = 0`` (a quadratic: closed form), the two loads close when the springs make the modes
interact.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np
from scipy import optimize

XTOL = 1e-14


def _brent(f, a: float, b: float) -> float:  # noqa: ANN001
    return float(optimize.brentq(f, a, b, xtol=XTOL, rtol=4 * np.finfo(float).eps, maxiter=500))


@dataclass(frozen=True)
class State:
    """A structure linearised at one control value.

    Attributes
    ----------
    omega2 : ndarray, shape (n,)
        The modes' squared undamped frequencies (non-dimensional), ascending.
    at_sensor, at_hammer : ndarray, shape (n,)
        Each mode's shape at the sensor and at the hammer (mass-normalised modes).
    static : float
        The equilibrium's displacement at the sensor.
    critical : int
        Index (in ``omega2``) of the mode that goes soft at the transition.
    branch : str
        ``"primary"`` (before the transition) or ``"remote"`` (after a snap).
    """

    omega2: np.ndarray
    at_sensor: np.ndarray
    at_hammer: np.ndarray
    static: float
    critical: int
    branch: str = "primary"


def _modal(h: np.ndarray, phi_s: np.ndarray, phi_h: np.ndarray, m: np.ndarray | None = None):
    """Eigen-pairs of ``h v = lambda m v`` (mass-normalised), ascending, with each mode's value
    at the sensor and the hammer (``phi_s . v``, ``phi_h . v``)."""
    if m is None:
        lam, v = np.linalg.eigh(h)
    else:
        # symmetric-definite pencil via Cholesky of m
        c = np.linalg.cholesky(m)
        ci = np.linalg.inv(c)
        lam, u = np.linalg.eigh(ci @ h @ ci.T)
        v = ci.T @ u
    return lam, phi_s @ v, phi_h @ v, v


# ------------------------------------------------------------------------------------------
# Shallow arch
# ------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Arch:
    """Two-mode shallow arch (module docstring). ``x_sensor``, ``x_hammer`` in ``(0, pi)``."""

    e: float = math.sqrt(50.0)
    e2: float = 0.0
    kappa: float = 1.0
    r: float = 16.0
    alpha: float = 4.0
    x_sensor: float = math.pi / 4
    x_hammer: float = math.pi / 3

    # -- energy -----------------------------------------------------------------------------
    def s(self, q1: float, q2: float) -> float:
        return q1 * q1 + self.alpha * q2 * q2 - self.e**2 - self.alpha * self.e2**2

    def gradient(self, q1: float, q2: float, p: float) -> np.ndarray:
        k8 = self.kappa / 8.0
        s = self.s(q1, q2)
        return np.array([(q1 - self.e) + k8 * s * q1 + p,
                         self.r * (q2 - self.e2) + k8 * self.alpha * s * q2])  # fmt: skip

    def hessian(self, q1: float, q2: float) -> np.ndarray:
        k8, a = self.kappa / 8.0, self.alpha
        s = self.s(q1, q2)
        h11 = 1.0 + k8 * (s + 2.0 * q1 * q1)
        h22 = self.r + k8 * a * (s + 2.0 * a * q2 * q2)
        h12 = 2.0 * k8 * a * q1 * q2
        return np.array([[h11, h12], [h12, h22]])

    # -- perfect arch: closed forms ---------------------------------------------------------
    def load_on_symmetric_path(self, q1: float) -> float:
        return self.e - q1 - self.kappa / 8.0 * (q1 * q1 - self.e**2) * q1

    def limit_point(self) -> tuple[float, float] | None:
        """``(q1_L, P_L)`` of the symmetric path, or None (no limit point)."""
        q2 = (self.e**2 - 8.0 / self.kappa) / 3.0
        if q2 <= 0:
            return None
        q1 = math.sqrt(q2)
        return q1, self.load_on_symmetric_path(q1)

    def bifurcation(self) -> tuple[float, float] | None:
        """``(q1_b, P_b)`` of the asymmetric bifurcation (perfect arch), or None."""
        q2 = self.e**2 - 8.0 * self.r / (self.kappa * self.alpha)
        if q2 <= 0:
            return None
        q1 = math.sqrt(q2)
        return q1, self.e + (self.r / self.alpha - 1.0) * q1

    def kind(self) -> str:
        """The transition's kind: ``saddle-node`` (limit point or imperfect), else
        ``subcritical-pitchfork``."""
        if self.e2 != 0.0:
            return "saddle-node"
        lp, bf = self.limit_point(), self.bifurcation()
        if bf is not None and (lp is None or bf[0] > lp[0]):
            return "subcritical-pitchfork"
        if lp is None:
            raise ValueError("this arch never loses stability (kappa e^2 <= 8)")
        return "saddle-node"

    # -- imperfect arch: the path parametrised by q2 ----------------------------------------
    def _q1_of_q2(self, q2: float) -> float:
        """``q1`` on the equilibrium path where ``V2 = 0`` (``q1 > 0`` branch)."""
        s = -8.0 * self.r * (q2 - self.e2) / (self.kappa * self.alpha * q2)
        q1sq = s + self.e**2 + self.alpha * self.e2**2 - self.alpha * q2 * q2
        return math.sqrt(q1sq) if q1sq > 0 else float("nan")

    def _p_of_q2(self, q2: float) -> float:
        q1 = self._q1_of_q2(q2)
        return -((q1 - self.e) + self.kappa / 8.0 * self.s(q1, q2) * q1)

    def _det_of_q2(self, q2: float) -> float:
        q1 = self._q1_of_q2(q2)
        return float(np.linalg.det(self.hessian(q1, q2)))

    def _q2_fold(self) -> float:
        """The first zero of ``det V''`` along the imperfect path from ``q2 = e2`` (cached)."""
        return _fold_cache(self)

    def _q2_fold_search(self) -> float:
        sgn = math.copysign(1.0, self.e2)
        lo = self.e2
        grid = self.e2 + sgn * np.geomspace(1e-9, 1.0, 4000) * 20.0
        prev = lo
        for q2 in grid:
            d = self._det_of_q2(float(q2))
            if not math.isfinite(d):
                break
            if d <= 0:
                return _brent(self._det_of_q2, prev, float(q2))
            prev = float(q2)
        raise ValueError("no fold found on the imperfect arch's path")

    def critical_load(self) -> float:
        """mu* of this arch: ``P_b`` or ``P_L`` in closed form, the fold by root finding."""
        if self.e2 != 0.0:
            return self._p_of_q2(self._q2_fold())
        if self.kind() == "subcritical-pitchfork":
            return self.bifurcation()[1]
        return self.limit_point()[1]

    def fold_by_maximum(self) -> float:
        """Second method for the imperfect fold: the maximum of ``P`` along the path
        (bounded scalar minimisation, then polished), independent of ``det V''``."""
        q2f = self._q2_fold()
        span = abs(q2f - self.e2)
        a, b = sorted((self.e2 + 0.2 * (q2f - self.e2), q2f + 0.5 * span * math.copysign(1, q2f)))
        res = optimize.minimize_scalar(lambda q: -self._p_of_q2(q), bounds=(a, b),
                                       method="bounded", options={"xatol": 1e-13})  # fmt: skip
        return -float(res.fun)

    # -- equilibria at a load --------------------------------------------------------------
    def equilibrium(self, p: float) -> tuple[float, float]:
        """The primary (unsnapped) equilibrium ``(q1, q2)`` at load ``p < mu*``."""
        if self.e2 == 0.0:
            q1_end = (self.bifurcation() if self.kind() == "subcritical-pitchfork"
                      else self.limit_point())[0]  # fmt: skip
            q1 = _brent(lambda q: self.load_on_symmetric_path(q) - p, q1_end, self.e)
            return q1, 0.0
        if p == 0.0:
            return self.e, self.e2
        q2f = self._q2_fold()
        q2 = _brent(lambda q: self._p_of_q2(q) - p, self.e2, q2f)
        return self._q1_of_q2(q2), q2

    def remote_equilibrium(self, p: float) -> tuple[float, float]:
        """The snapped (inverted, stable) equilibrium at load ``p``: the most negative real
        root of the symmetric path (perfect arch), refined by Newton on both coordinates."""
        c = self.kappa / 8.0
        # P = e - q1 - c (q1^2 - e^2) q1  ->  c q1^3 + (1 - c e^2) q1 + (p - e) = 0
        roots = np.roots([c, 0.0, 1.0 - c * self.e**2, p - self.e])
        q1 = float(min(r.real for r in roots if abs(r.imag) < 1e-9))
        x = np.array([q1, 0.0 if self.e2 == 0 else -self.e2])
        sol = optimize.root(lambda z: self.gradient(z[0], z[1], p), x,
                            jac=lambda z: self.hessian(z[0], z[1]), tol=1e-14)  # fmt: skip
        return float(sol.x[0]), float(sol.x[1])

    def state(self, p: float, remote: bool = False) -> State:
        q1, q2 = self.remote_equilibrium(p) if remote else self.equilibrium(p)
        phi_s = np.array([math.sin(self.x_sensor), math.sin(2 * self.x_sensor)])
        phi_h = np.array([math.sin(self.x_hammer), math.sin(2 * self.x_hammer)])
        lam, ys, yh, v = _modal(self.hessian(q1, q2), phi_s, phi_h)
        # the critical mode: the one whose stiffness goes to zero at mu*: the antisymmetric one
        # for the perfect pitchfork arch, else the lowest
        if self.e2 == 0.0 and self.kind() == "subcritical-pitchfork" and not remote:
            crit = int(np.argmax(np.abs(v[1, :])))
        else:
            crit = 0
        return State(lam, ys, yh, float(phi_s @ np.array([q1, q2])), crit,
                     "remote" if remote else "primary")  # fmt: skip


@functools.lru_cache(maxsize=1024)
def _fold_cache(arch: Arch) -> float:
    return arch._q2_fold_search()


# ------------------------------------------------------------------------------------------
# Column on an elastic foundation
# ------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class FoundationColumn:
    """Pinned column on a Winkler foundation, modes ``n = 1..n_modes`` (module docstring)."""

    beta: float = 10.0
    n_modes: int = 3
    x_sensor: float = 0.3 * math.pi
    x_hammer: float = 0.2 * math.pi

    def buckling_loads(self) -> np.ndarray:
        n = np.arange(1, self.n_modes + 1, dtype=float)
        return n**2 + self.beta / n**2

    def critical_mode(self) -> int:
        """``n`` of the buckling mode (1-based), from ``(n (n+1))^2 = beta`` crossings."""
        return int(np.argmin(self.buckling_loads())) + 1

    def critical_load(self) -> float:
        return float(np.min(self.buckling_loads()))

    def critical_load_by_root(self) -> float:
        """Second method: the first ``p`` where the smallest ``omega_n^2`` reaches zero."""
        return _brent(lambda p: float(np.min(self.state(p).omega2)), 0.0, 2.0 * self.beta + 50)

    def kind(self) -> str:
        return "pitchfork"

    def state(self, p: float) -> State:
        n = np.arange(1, self.n_modes + 1, dtype=float)
        om2 = n**4 + self.beta - n**2 * p
        # modes sin(n x) on (0, pi), mass-normalised with mass density 2/pi
        ys, yh = np.sin(n * self.x_sensor), np.sin(n * self.x_hammer)
        order = np.argsort(om2)
        crit = int(np.where(order == self.critical_mode() - 1)[0][0])
        return State(om2[order], ys[order], yh[order], 0.0, crit)


# ------------------------------------------------------------------------------------------
# Three-link column
# ------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class ThreeLinkColumn:
    """Three rigid links (module docstring). Sensor at joint ``sensor`` (0 or 1), hammer at
    joint ``hammer``."""

    k1: float = 1.0
    k2: float = 1.0
    m1: float = 1.0
    m2: float = 1.0
    sensor: int = 0
    hammer: int = 1

    def k(self) -> np.ndarray:
        k1, k2 = self.k1, self.k2
        return np.array([[4 * k1 + k2, -2 * k1 - 2 * k2], [-2 * k1 - 2 * k2, k1 + 4 * k2]])

    @staticmethod
    def g() -> np.ndarray:
        return np.array([[2.0, -1.0], [-1.0, 2.0]])

    def buckling_loads(self) -> tuple[float, float]:
        """Roots of ``det(K - P G) = 0`` (a quadratic in ``P``), ascending."""
        k, g = self.k(), self.g()
        a = g[0, 0] * g[1, 1] - g[0, 1] ** 2
        b = -(k[0, 0] * g[1, 1] + k[1, 1] * g[0, 0] - 2 * k[0, 1] * g[0, 1])
        c = k[0, 0] * k[1, 1] - k[0, 1] ** 2
        disc = math.sqrt(b * b - 4 * a * c)
        # the numerically stable pair
        q = -0.5 * (b + math.copysign(disc, b))
        r1, r2 = q / a, c / q
        return tuple(sorted((r1, r2)))  # type: ignore[return-value]

    def critical_load(self) -> float:
        return self.buckling_loads()[0]

    def critical_load_by_root(self) -> float:
        return _brent(lambda p: float(np.linalg.det(self.k() - p * self.g())), 0.0,
                      0.5 * sum(self.buckling_loads()))  # fmt: skip

    def kind(self) -> str:
        return "pitchfork"

    def state(self, p: float) -> State:
        e = np.eye(2)
        lam, ys, yh, _ = _modal(self.k() - p * self.g(), e[self.sensor], e[self.hammer],
                                np.diag([self.m1, self.m2]))  # fmt: skip
        return State(lam, ys, yh, 0.0, 0)
