"""Independent one-degree-of-freedom structures with exact truths (helpers of tests/structures).

Written from the mechanics alone (numpy and scipy, nothing of ``sim`` or ``service``), so that
the predictor can be tried on structures it was not built from. Each model has its own energy
``V(q; P)`` under a dead control load ``P``, its equilibrium path, its stiffness ``V''`` along
that path and its inertia; the fundamental's ``omega^2 = V'' / I`` (the product's convention:
``sigma^2 = -omega^2`` for a stable undamped mode) and the static level ``q`` (angle or
deflection) are what a lab measures.

Link columns (a rigid bar of length ``L`` hinged at its foot, axial dead load ``P``, the angle
``theta`` from the vertical, load potential ``-P L (1 - cos theta)``):

* ``"rotational"``: a rotational spring ``M = k phi (1 + beta phi^2)`` about the stress-free
  angle ``eps`` (``phi = theta - eps``). Perfect (``eps = 0``): pitchfork at ``P_c = k / L``,
  post-buckling load ``P = P_c (1 + kappa theta^2 + ...)`` with ``kappa = beta + 1/6``:
  supercritical (stiffening) for ``kappa > 0``, subcritical (softening) for ``kappa < 0``.
* ``"lateral"``: a horizontal spring at the top, ``U = k L^2 (sin theta - sin eps)^2 / 2``
  (Koiter's geometric softening): ``P_c = k L``, ``kappa = -1/2``.

Both reduce near ``P_c`` to ``(1 - p) theta + kappa theta^3 = eps`` (``p = P / P_c``), so an
imperfect softening column (``kappa < 0``) snaps at a limit point ``P_f`` with Koiter's
two-thirds power law ``P_f / P_c = 1 - c eps^(2/3)``, ``c = 3 |kappa|^(1/3) / 2^(2/3)``
(``c = 3/2`` for the lateral spring), and an imperfect stiffening one never loses stability;
its least stiffness ``~ eps^(2/3)`` lies just above ``P_c``.

Von Mises truss (two bars of stress-free length ``L0`` and axial stiffness ``k = EA / L0``,
supports at ``+-b``, apex mass ``m``, vertical dead load ``F`` at the apex, deflection ``w``):
``V = k (l - L0)^2 - F w``, ``l = sqrt(b^2 + (h - w)^2)``; it snaps at the saddle-node
``F_f = 2 k (L0^(2/3) - b^(2/3))^(3/2)`` (where ``l^3 = L0 b^2``).

Equilibria are found on the path parametrised by the coordinate (the load is explicit in it:
``P(q) = U'(q) / g'(q)``), folds as roots of the stiffness along the path (``V' = V'' = 0``
together), each by Brent's method to ``xtol = 1e-15`` (relative ``4.4e-16``).
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np
from scipy import optimize

XTOL = 1e-15  # absolute tolerance of every root (angles in rad, deflections in m)


def _brent(f, a: float, b: float) -> float:
    return float(optimize.brentq(f, a, b, xtol=XTOL, rtol=4 * np.finfo(float).eps, maxiter=500))


@functools.lru_cache(maxsize=4096)
def _fold_of(model):  # noqa: ANN001, ANN202 - any frozen model with a _fold()
    """A model's fold, computed once (the models are frozen, hence hashable)."""
    return model._fold()


def _first_sign_change(f, lo: float, hi: float, n: int = 4000) -> tuple[float, float] | None:
    """The first bracket ``(a, b)`` of ``(lo, hi]`` (grid geometric from ``lo``) where ``f``
    changes sign, or None."""
    span = hi - lo
    grid = lo + span * np.geomspace(1e-9, 1.0, n)
    prev_x, prev_f = lo, f(lo)
    for x in grid:
        fx = f(x)
        if np.sign(fx) != np.sign(prev_f):
            return prev_x, float(x)
        prev_x, prev_f = float(x), fx
    return None


@dataclass(frozen=True)
class LinkColumn:
    """A rigid-bar link column on a spring (see the module docstring).

    Attributes
    ----------
    spring : str
        ``"rotational"`` (linear plus cubic rotational spring at the hinge) or ``"lateral"``
        (horizontal linear spring at the top: Koiter-type geometric softening).
    k : float
        Spring stiffness: N m / rad (rotational) or N / m (lateral).
    L : float
        Bar length (m).
    inertia : float
        Moment of inertia about the hinge (kg m^2).
    beta : float
        Cubic coefficient of the rotational spring (1/rad^2); ignored for ``"lateral"``.
    eps : float
        Stress-free angle (rad), the imperfection; 0 is the perfect column.
    """

    spring: str = "rotational"
    k: float = 100.0
    L: float = 1.0
    inertia: float = 0.1
    beta: float = 0.0
    eps: float = 0.0

    def __post_init__(self) -> None:
        if self.spring not in ("rotational", "lateral"):
            raise ValueError(f"spring must be 'rotational' or 'lateral', got {self.spring!r}")

    # ---------------------------------------------------------------- energy and its derivatives
    def spring_derivs(self, theta: float) -> tuple[float, float, float, float]:
        """``(U, U', U'', U''')`` of the spring energy at ``theta``."""
        k, L, e = self.k, self.L, self.eps
        if self.spring == "rotational":
            phi, b = theta - e, self.beta
            return (
                k * (0.5 * phi**2 + 0.25 * b * phi**4),
                k * (phi + b * phi**3),
                k * (1.0 + 3.0 * b * phi**2),
                k * 6.0 * b * phi,
            )
        s, c, se = math.sin(theta), math.cos(theta), math.sin(e)
        kl2 = k * L * L
        return (
            0.5 * kl2 * (s - se) ** 2,
            kl2 * (s - se) * c,
            kl2 * (c * c - (s - se) * s),
            kl2 * (-3.0 * c * s - (s - se) * c),
        )

    def energy(self, theta: float, P: float) -> float:
        """Total potential ``V(theta; P) = U - P L (1 - cos theta)`` (J)."""
        return self.spring_derivs(theta)[0] - P * self.L * (1.0 - math.cos(theta))

    def dV(self, theta: float, P: float) -> float:
        return self.spring_derivs(theta)[1] - P * self.L * math.sin(theta)

    def d2V(self, theta: float, P: float) -> float:
        return self.spring_derivs(theta)[2] - P * self.L * math.cos(theta)

    # ---------------------------------------------------------------- the equilibrium path
    @property
    def p_c(self) -> float:
        """The perfect column's critical load ``U''(0) / L`` at ``eps = 0`` (N)."""
        return self.k / self.L if self.spring == "rotational" else self.k * self.L

    @property
    def kappa(self) -> float:
        """Post-buckling curvature of the perfect column: ``P / P_c = 1 + kappa theta^2``."""
        return self.beta + 1.0 / 6.0 if self.spring == "rotational" else -0.5

    @property
    def koiter_c(self) -> float:
        """Koiter's constant ``c`` of ``P_f / P_c ~ 1 - c |eps|^(2/3)`` (softening only)."""
        if self.kappa >= 0:
            raise ValueError("a stiffening column has no limit point")
        return 3.0 * (-self.kappa) ** (1.0 / 3.0) / 2.0 ** (2.0 / 3.0)

    @property
    def softening(self) -> bool:
        return self.kappa < 0

    def _sign(self) -> float:
        return -1.0 if self.eps < 0 else 1.0

    def _mirror(self) -> LinkColumn:
        """The same column with ``eps >= 0`` (the path of ``-eps`` is the mirror image)."""
        return LinkColumn(self.spring, self.k, self.L, self.inertia, self.beta, abs(self.eps))

    def load_on_path(self, theta: float) -> float:
        """The load that holds the column in equilibrium at ``theta`` (``theta != 0``)."""
        return self.spring_derivs(theta)[1] / (self.L * math.sin(theta))

    def stiffness_on_path(self, theta: float) -> float:
        """``V''`` at the equilibrium ``theta`` (``U'' - U' cot theta``; N m / rad)."""
        _, d1, d2, _ = self.spring_derivs(theta)
        return d2 - d1 * math.cos(theta) / math.sin(theta)

    def _dstiffness_on_path(self, theta: float) -> float:
        _, d1, d2, d3 = self.spring_derivs(theta)
        s = math.sin(theta)
        return d3 - d2 * math.cos(theta) / s + d1 / (s * s)

    def fold(self) -> tuple[float, float] | None:
        """``(theta_f, P_f)`` of the limit point of an imperfect softening column (cached)."""
        return _fold_of(self)

    def _fold(self) -> tuple[float, float] | None:
        """``(theta_f, P_f)`` of the limit point of an imperfect softening column (``V' = V''
        = 0``; ``theta_f`` signed like ``eps``), None when there is none (perfect or
        stiffening)."""
        if self.eps == 0.0 or not self.softening:
            return None
        m = self._mirror()
        e = m.eps
        br = _first_sign_change(m.stiffness_on_path, e, 0.5 * math.pi - 1e-9)
        if br is None:  # pragma: no cover - every softening model here has one
            return None
        th = _brent(m.stiffness_on_path, *br)
        return self._sign() * th, m.load_on_path(th)

    def least_stiffness(self) -> tuple[float, float, float] | None:
        """``(theta_min, P_min, K_min)``: the least stiffness ``V''`` along the path of an
        imperfect stiffening column and where it occurs; None otherwise."""
        if self.eps == 0.0 or self.softening:
            return None
        m = self._mirror()
        br = _first_sign_change(m._dstiffness_on_path, m.eps, math.pi - 1e-6)
        if br is None:  # pragma: no cover
            return None
        th = _brent(m._dstiffness_on_path, *br)
        return self._sign() * th, m.load_on_path(th), m.stiffness_on_path(th)

    def critical_load(self) -> float | None:
        """The load a lab must not cross: ``P_c`` (perfect), ``P_f`` (imperfect softening),
        None (imperfect stiffening: no loss of stability)."""
        if self.eps == 0.0:
            return self.p_c
        f = self.fold()
        return None if f is None else f[1]

    def equilibrium(self, P: float) -> float:
        """The angle on the fundamental path (the one through ``eps`` at ``P = 0``) at load
        ``P`` (rad). Raises ValueError past the critical load."""
        if P < 0:
            raise ValueError(f"P must be >= 0, got {P!r}")
        if self.eps == 0.0:
            if P >= self.p_c:
                raise ValueError(f"P={P!r} >= P_c={self.p_c!r}: the trivial path is unstable")
            return 0.0
        if P == 0.0:
            return self.eps
        m = self._mirror()
        f = m.fold()
        if f is not None:
            if P >= f[1]:
                raise ValueError(f"P={P!r} >= the fold load {f[1]!r}")
            hi = f[0]
        else:
            hi = m.eps
            while m.load_on_path(hi) < P:  # the stiffening path rises to infinity at pi
                hi = hi + 0.5 * (math.pi - hi)
        th = _brent(lambda t: m.load_on_path(t) - P, m.eps, hi)
        return self._sign() * th

    def stiffness(self, P: float) -> float:
        """``V''`` at the fundamental equilibrium under ``P`` (N m / rad)."""
        th = self.equilibrium(P)
        return self.d2V(th, P)

    def omega2(self, P: float) -> float:
        """The fundamental's ``omega^2 = V'' / I`` (1/s^2) at ``P``."""
        return self.stiffness(P) / self.inertia


class _ArchPath:
    """The fundamental path of an arch loaded at its apex, parametrised by the apex deflection
    ``w`` (shared by the trusses): the snap is the fold ``(w_f, F_f)`` of ``_fold()``, the
    equilibrium at ``F`` inverts ``load_on_path`` on ``[0, w_f]``."""

    def load_on_path(self, w: float) -> float:  # pragma: no cover - each truss has its own
        raise NotImplementedError

    def _fold(self) -> tuple[float, float]:  # pragma: no cover - each truss has its own
        raise NotImplementedError

    def fold(self) -> tuple[float, float]:
        """``(w_f, F_f)``: the saddle-node along the path (Brent, once per model)."""
        return _fold_of(self)

    def critical_load(self) -> float:
        return self.fold()[1]

    def equilibrium(self, F: float) -> float:
        """Apex deflection ``w`` on the fundamental path at ``F`` (the static level; m)."""
        w_f, F_f = self.fold()
        if not 0 <= F < F_f:
            raise ValueError(f"F={F!r} outside [0, F_f={F_f!r})")
        if F == 0.0:
            return 0.0
        return _brent(lambda w: self.load_on_path(w) - F, 0.0, w_f)


@dataclass(frozen=True)
class VonMisesTruss(_ArchPath):
    """Two-bar shallow arch under a vertical apex load (see the module docstring).

    Attributes
    ----------
    k : float
        Axial stiffness of one bar ``EA / L0`` (N/m).
    L0 : float
        Stress-free bar length (m).
    rise : float
        Initial rise angle of the bars (rad): supports at ``+-b = +-L0 cos rise``, apex height
        ``h = L0 sin rise``.
    mass : float
        Apex mass (kg); the bars are massless.
    """

    k: float = 2.0e4
    L0: float = 1.0
    rise: float = 0.2
    mass: float = 1.0

    @property
    def b(self) -> float:
        return self.L0 * math.cos(self.rise)

    @property
    def h(self) -> float:
        return self.L0 * math.sin(self.rise)

    def _l(self, w: float) -> float:
        return math.hypot(self.b, self.h - w)

    def energy(self, w: float, F: float) -> float:
        return self.k * (self._l(w) - self.L0) ** 2 - F * w

    def dV(self, w: float, F: float) -> float:
        y, l = self.h - w, self._l(w)
        return -2.0 * self.k * (l - self.L0) * y / l - F

    def d2V(self, w: float, F: float = 0.0) -> float:
        """``V''`` (N/m); the load is dead, so it does not enter."""
        y, l = self.h - w, self._l(w)
        return 2.0 * self.k * (y * y / (l * l) + (l - self.L0) * self.b**2 / l**3)

    def load_on_path(self, w: float) -> float:
        y, l = self.h - w, self._l(w)
        return 2.0 * self.k * y * (self.L0 / l - 1.0)

    def snap_load_closed_form(self) -> float:
        """``F_f = 2 k (L0^(2/3) - b^(2/3))^(3/2)``: the saddle-node load (N)."""
        return 2.0 * self.k * (self.L0 ** (2 / 3) - self.b ** (2 / 3)) ** 1.5

    def _fold(self) -> tuple[float, float]:
        """By root finding of ``V''`` along the path (``V' = V'' = 0``)."""
        w_f = _brent(self.d2V, 0.0, self.h)
        return w_f, self.load_on_path(w_f)

    def stiffness(self, F: float) -> float:
        return self.d2V(self.equilibrium(F))

    def omega2(self, F: float) -> float:
        return self.stiffness(F) / self.mass


@dataclass(frozen=True)
class AsymmetricTruss(_ArchPath):
    """A two-bar arch with unequal bars and a free apex: two degrees of freedom.

    The apex (mass ``m`` in both directions) moves by ``u`` (horizontal) and ``w`` (down) under
    the vertical dead load ``F``; bar ``j`` (stiffness ``k_j``, stress-free length ``L0``)
    runs from the support at ``x = -b`` (``j = 1``) or ``+b`` (``j = 2``)::

        V(u, w; F) = k1 (l1 - L0)^2 / 2 + k2 (l2 - L0)^2 / 2 - F w,
        l1 = sqrt((b + u)^2 + (h - w)^2),  l2 = sqrt((b - u)^2 + (h - w)^2)

    (with ``k1 = k2 = 2 k`` it is :class:`VonMisesTruss` with ``u = 0``). The path is
    parametrised by ``w``: ``u(w)`` from ``dV/du = 0``, the load ``F(w) = dU/dw`` there; the
    snap is the saddle-node where ``det V'' = 0`` (equivalently ``dF/dw = 0`` along the path),
    and the fundamental's ``omega^2`` is the least eigenvalue of ``V'' / m``.
    """

    k1: float = 4.0e4
    k2: float = 3.0e4
    L0: float = 1.0
    rise: float = 0.2
    mass: float = 1.0

    @property
    def b(self) -> float:
        return self.L0 * math.cos(self.rise)

    @property
    def h(self) -> float:
        return self.L0 * math.sin(self.rise)

    def _bars(self, u: float, w: float) -> tuple[tuple[float, float, float, float], ...]:
        """Per bar ``(k, dx, dy, l)``: stiffness, the apex's offsets from the support, length."""
        y = self.h - w
        out = []
        for k, dx in ((self.k1, self.b + u), (self.k2, -(self.b - u))):
            out.append((k, dx, y, math.hypot(dx, y)))
        return tuple(out)

    def energy(self, u: float, w: float, F: float) -> float:
        return sum(0.5 * k * (l - self.L0) ** 2 for k, _, _, l in self._bars(u, w)) - F * w

    def gradient(self, u: float, w: float, F: float) -> np.ndarray:
        """``(dV/du, dV/dw)`` (N)."""
        g = np.zeros(2)
        for k, dx, y, l in self._bars(u, w):
            n = k * (l - self.L0) / l  # bar force over length
            g += n * np.array([dx, -y])  # dl/du = dx / l, dl/dw = -y / l
        return g - np.array([0.0, F])

    def hessian(self, u: float, w: float) -> np.ndarray:
        """``V''`` in ``(u, w)`` (N/m); the dead load does not enter."""
        H = np.zeros((2, 2))
        for k, dx, y, l in self._bars(u, w):
            e = np.array([dx, -y]) / l  # dl/d(u, w)
            n = k * (l - self.L0) / l
            H += k * np.outer(e, e) + n * (np.eye(2) - np.outer(e, e))
        return H

    def u_on_path(self, w: float) -> float:
        """The horizontal apex displacement in equilibrium at deflection ``w``."""
        f = lambda u: self.gradient(u, w, 0.0)[0]  # noqa: E731 - the load has no u part
        lo, hi = -0.5 * self.b, 0.5 * self.b
        return _brent(f, lo, hi)

    def load_on_path(self, w: float) -> float:
        return float(self.gradient(self.u_on_path(w), w, 0.0)[1])

    def det_on_path(self, w: float) -> float:
        return float(np.linalg.det(self.hessian(self.u_on_path(w), w)))

    def _fold(self) -> tuple[float, float]:
        """``det V'' = 0`` along the path: ``det V'' > 0`` unloaded, ``< 0`` at the flat
        position (both bars compressed, ``w = h``): a shallow arch has one fold between
        (checked by the tests against two other methods)."""
        w_f = _brent(self.det_on_path, 0.0, self.h)
        return w_f, self.load_on_path(w_f)

    def omega2(self, F: float) -> float:
        w = self.equilibrium(F)
        return float(np.linalg.eigvalsh(self.hessian(self.u_on_path(w), w))[0] / self.mass)


@dataclass(frozen=True)
class CoupledColumns:
    """Two rigid-bar columns side by side, tops joined by a horizontal spring, both under the
    axial dead load ``P``: two degrees of freedom ``(theta1, theta2)``.

    ``V = sum_i k_i (phi_i^2 / 2 + beta phi_i^4 / 4) + c L^2 (sin theta1 - sin theta2)^2 / 2
    - P L sum_i (1 - cos theta_i)``, ``phi_i = theta_i - eps_i`` (each bar's stress-free
    angle), each bar's moment of inertia ``I`` about its hinge. The perfect pair buckles at
    ``P_c = lambda_min(K0) / L``, ``K0 = [[k1 + c L^2, -c L^2], [-c L^2, k2 + c L^2]]``; an
    imperfect one follows the path parametrised by the angle ``theta_d`` of the bar that leads
    the critical mode (the other angle and the load from ``V' = 0`` by Newton's method), snaps
    where ``det V'' = 0`` along it (softening) or never (stiffening); the fundamental's
    ``omega^2`` is the least eigenvalue of ``V'' / I``.
    """

    k1: float = 100.0
    k2: float = 120.0
    c: float = 50.0
    L: float = 1.0
    inertia: float = 0.1
    beta: float = -0.5
    eps1: float = 1e-3
    eps2: float = 5e-4

    def _c_l2(self) -> float:
        return self.c * self.L * self.L

    def energy(self, th: np.ndarray, P: float) -> float:
        t1, t2 = th
        u = 0.0
        for k, t, e in ((self.k1, t1, self.eps1), (self.k2, t2, self.eps2)):
            phi = t - e
            u += k * (0.5 * phi**2 + 0.25 * self.beta * phi**4)
        u += 0.5 * self._c_l2() * (math.sin(t1) - math.sin(t2)) ** 2
        return u - P * self.L * (2.0 - math.cos(t1) - math.cos(t2))

    def gradient(self, th: np.ndarray, P: float) -> np.ndarray:
        t1, t2 = th
        ds = math.sin(t1) - math.sin(t2)
        g = np.empty(2)
        for i, (k, t, e) in enumerate(((self.k1, t1, self.eps1), (self.k2, t2, self.eps2))):
            phi = t - e
            g[i] = k * (phi + self.beta * phi**3) - P * self.L * math.sin(t)
        g[0] += self._c_l2() * ds * math.cos(t1)
        g[1] -= self._c_l2() * ds * math.cos(t2)
        return g

    def hessian(self, th: np.ndarray, P: float) -> np.ndarray:
        t1, t2 = th
        s1, s2, c1, c2 = math.sin(t1), math.sin(t2), math.cos(t1), math.cos(t2)
        cl2 = self._c_l2()
        b = self.beta
        h11 = self.k1 * (1 + 3 * b * (t1 - self.eps1) ** 2) + cl2 * (c1 * c1 - (s1 - s2) * s1)
        h22 = self.k2 * (1 + 3 * b * (t2 - self.eps2) ** 2) + cl2 * (c2 * c2 + (s1 - s2) * s2)
        h12 = -cl2 * c1 * c2
        return np.array([[h11 - P * self.L * c1, h12], [h12, h22 - P * self.L * c2]])

    @property
    def p_c(self) -> float:
        cl2 = self._c_l2()
        K0 = np.array([[self.k1 + cl2, -cl2], [-cl2, self.k2 + cl2]])
        return float(np.linalg.eigvalsh(K0)[0] / self.L)

    def _lead(self) -> int:
        """The bar that leads the critical mode (its largest component)."""
        cl2 = self._c_l2()
        K0 = np.array([[self.k1 + cl2, -cl2], [-cl2, self.k2 + cl2]])
        v = np.linalg.eigh(K0)[1][:, 0]
        return int(np.argmax(np.abs(v)))

    def _sign(self) -> float:
        """The side the pair leans to: the direction of the leading angle in which the path's
        load rises from the unloaded pair (it is linear in the angle there)."""
        d = self._lead()
        t0 = float(self._unloaded()[d])
        h = 1e-6
        up = self.point_on_path(t0 + h)[1]
        down = self.point_on_path(t0 - h)[1]
        if not (up > 0) ^ (down > 0):  # pragma: no cover - a degenerate pair
            raise ValueError(f"the load does not rise on one side only ({up!r}, {down!r})")
        return 1.0 if up > 0 else -1.0

    def point_on_path(self, td: float, guess: tuple[float, float] | None = None) -> tuple:
        """``(theta (2,), P)`` in equilibrium with the leading angle ``td`` (Newton on the other
        angle and the load, from ``guess`` or the unloaded pair's angles)."""
        d = self._lead()
        o = 1 - d
        if guess is None:
            th0 = self._unloaded()
            guess = (float(th0[o]), 0.0)
        x = np.array(guess, dtype=float)
        for _ in range(100):
            th = np.empty(2)
            th[d], th[o] = td, x[0]
            g = self.gradient(th, x[1])
            H = self.hessian(th, x[1])
            J = np.array([[H[d, o], -self.L * math.sin(td)], [H[o, o], -self.L * math.sin(x[0])]])
            r = np.array([g[d], g[o]])
            step = np.linalg.solve(J, -r)
            x = x + step
            if abs(step[0]) <= 1e-15 + 1e-13 * abs(x[0]) and abs(step[1]) <= 1e-13 * max(
                abs(x[1]), self.p_c
            ):
                break
        else:  # pragma: no cover
            raise RuntimeError(f"no equilibrium found at theta_d={td!r}")
        th = np.empty(2)
        th[d], th[o] = td, x[0]
        return th, float(x[1])

    def _unloaded(self) -> np.ndarray:
        """The angles at ``P = 0`` (Newton from the stress-free angles)."""
        th = np.array([self.eps1, self.eps2])
        for _ in range(100):
            step = np.linalg.solve(self.hessian(th, 0.0), -self.gradient(th, 0.0))
            th = th + step
            if np.max(np.abs(step)) < 1e-16:
                break
        return th

    def _path(self, n: int = 400) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The path on a grid of the leading angle from its unloaded value to 0.5 rad (on the
        side it leans to): ``(td, theta (n, 2), P)``, continued point to point."""
        d, o = self._lead(), 1 - self._lead()
        t0 = float(self._unloaded()[d])
        s = self._sign()
        tds = t0 + s * (np.geomspace(1e-7, 0.5, n))
        ths, Ps = [], []
        guess = None
        for td in tds:
            th, P = self.point_on_path(float(td), guess)
            guess = (float(th[o]), P)
            ths.append(th)
            Ps.append(P)
        return tds, np.array(ths), np.array(Ps)

    def _fold(self) -> tuple[np.ndarray, float] | None:
        tds, ths, Ps = self._path()
        o = 1 - self._lead()
        dets = np.array([np.linalg.det(self.hessian(th, P)) for th, P in zip(ths, Ps)])
        bad = np.flatnonzero(dets <= 0)
        if bad.size == 0 or bad[0] == 0:
            return None
        j = int(bad[0])
        a, b = float(tds[j - 1]), float(tds[j])
        g = (float(ths[j - 1][o]), float(Ps[j - 1]))

        def det_at(td: float) -> float:
            th, P = self.point_on_path(td, g)
            return float(np.linalg.det(self.hessian(th, P)))

        td_f = _brent(det_at, a, b)
        return self.point_on_path(td_f, g)

    def fold(self) -> tuple[np.ndarray, float] | None:
        """``(theta_f (2,), P_f)``: the limit point (``V' = 0``, ``det V'' = 0``), or None."""
        return _fold_of(self)

    def critical_load(self) -> float | None:
        f = self.fold()
        return None if f is None else f[1]

    def equilibrium_angles(self, P: float) -> np.ndarray:
        """Both angles on the fundamental path at ``P`` (rad)."""
        tds, ths, Ps = self._path_cached()
        f = self.fold()
        if f is not None and P >= f[1]:
            raise ValueError(f"P={P!r} >= the fold load {f[1]!r}")
        if P == 0.0:
            return self._unloaded()
        d, o = self._lead(), 1 - self._lead()
        fall = np.flatnonzero(np.diff(Ps) <= 0)
        k = int(fall[0]) if fall.size else Ps.size - 1  # the load rises up to Ps[k]
        j = int(np.searchsorted(Ps[: k + 1], P))
        if j == 0:  # between the unloaded pair and the first grid point
            j = 1
        if j <= k:
            a, b = float(tds[j - 1]), float(tds[j])
        elif f is not None:  # between the last rising grid point and the fold
            j, a, b = k + 1, float(tds[k]), float(f[0][d])
        else:
            raise ValueError(f"P={P!r} beyond the path computed (to {Ps[k]!r})")
        g = (float(ths[j - 1][o]), float(Ps[j - 1]))
        if j == 1:
            g = (float(self._unloaded()[o]), 0.0)
            a = float(self._unloaded()[d])
        td = _brent(lambda t: self.point_on_path(t, g)[1] - P, a, b)
        return self.point_on_path(td, g)[0]

    def _path_cached(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        return _path_of(self)

    def equilibrium(self, P: float) -> float:
        """The static level: the leading bar's angle (rad)."""
        return float(self.equilibrium_angles(P)[self._lead()])

    def omega2(self, P: float) -> float:
        th = self.equilibrium_angles(P)
        return float(np.linalg.eigvalsh(self.hessian(th, P))[0] / self.inertia)


@functools.lru_cache(maxsize=256)
def _path_of(model: CoupledColumns) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    return model._path()


def coupled_least_stiffness(model: CoupledColumns) -> tuple[float, float] | None:
    """``(P_min, K_min)``: the least eigenvalue of ``V''`` along the path of a pair that never
    folds, and the load where it occurs (Brent's minimisation on the leading angle, to
    ``1e-10`` rad); None when the pair folds."""
    if model.fold() is not None:
        return None
    tds, ths, Ps = model._path_cached()
    o = 1 - model._lead()
    lam = np.array([np.linalg.eigvalsh(model.hessian(th, P))[0] for th, P in zip(ths, Ps)])
    j = int(np.argmin(lam))
    if j == 0 or j == lam.size - 1:  # pragma: no cover - a minimum inside the path
        raise ValueError("the least stiffness is not inside the path computed")
    g = (float(ths[j - 1][o]), float(Ps[j - 1]))

    def lam_at(td: float) -> float:
        th, P = model.point_on_path(td, g)
        return float(np.linalg.eigvalsh(model.hessian(th, P))[0])

    lo, hi = sorted((float(tds[j - 1]), float(tds[j + 1])))
    res = optimize.minimize_scalar(lam_at, bounds=(lo, hi), method="bounded",
                                   options={"xatol": 1e-10})  # fmt: skip
    th, P = model.point_on_path(float(res.x), g)
    return P, float(res.fun)
