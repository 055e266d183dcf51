"""The exact inextensible, unshearable elastica: an independent reference for the rod.

Static equilibria of the clamped elastica of unit length and end-to-end distance 1 - dL, in
the theta(s) form (B = 1; (Nx, Ny) the constant internal force)::

    theta'' = Nx sin(theta) - Ny cos(theta),   x' = cos(theta),   y' = sin(theta),
    theta(0) = alphaL, theta(1) = alphaR, x(0) = y(0) = y(1) = 0, x(1) = 1 - dL.

It is solved by shooting from s = 0 (``scipy.integrate.solve_ivp``, DOP853, rtol 1e-12) on
the unknowns (theta'(0), Nx, Ny) with ``scipy.optimize.root``; a midpoint condition
y(1/2) = c or theta(1/2) = c can replace mu as the parameter of the branch (mu becomes an
unknown), which is regular through folds. This shares no code with the discrete rod.

mu* of the elastica:

- asymmetric: the fold, max over c of mu(c) along U_A with c = y(1/2);
- antisymmetric: U_A -> S_B as c = y(1/2) -> 0, mu(c) = mu* - k c^2 + O(c^4): Richardson;
- symmetric: the S branches leave U_A at mu*; along them c = theta(1/2) -> 0 and
  mu(c) = mu* - k c^2 + O(c^4): Richardson.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.integrate import solve_ivp
from scipy.optimize import brentq, minimize_scalar, root

from .rod import ACTUATION_SIGNS, _check_actuation

_RTOL = 1e-12


def _rhs(s, Y, nx, ny):
    th, k = Y[0], Y[1]
    return [k, nx * math.sin(th) - ny * math.cos(th), math.cos(th), math.sin(th)]


class ElasticaBranch:
    """One branch of the clamped elastica, followed by continuation (shooting method).

    Parameters
    ----------
    actuation : str
    end_shortening : float
        dL / L.
    branch : {"U_A", "U_B"}
        First-mode state buckled to negative (U_A) or positive (U_B) w at mu = 0.
    """

    def __init__(self, actuation: str, end_shortening: float = 1e-2, branch: str = "U_A"):
        self.sl, self.sr = ACTUATION_SIGNS[_check_actuation(actuation)]
        self.d = float(end_shortening)
        self.r = math.sqrt(self.d)
        sign = -1.0 if branch == "U_A" else 1.0
        amp = sign * self.r / math.pi
        # unknowns: theta'(0), Nx, Ny
        self.u = np.array([4.0 * math.pi**2 * amp, -4.0 * math.pi**2, 0.0])
        self.mu = 0.0
        self._solve(0.0, None)

    def _shoot(self, k0, nx, ny, mu):
        y0 = [self.sl * mu * self.r, k0, 0.0, 0.0]
        return solve_ivp(_rhs, (0.0, 1.0), y0, args=(nx, ny), method="DOP853", rtol=_RTOL,
                         atol=1e-14, dense_output=True)

    def _solve(self, mu: float, pin: tuple[str, float] | None) -> None:
        def F(v):
            k0, nx, ny = v[:3]
            m = v[3] if pin is not None else mu
            sol = self._shoot(k0, nx, ny, m)
            e = sol.y[:, -1]
            res = [e[0] - self.sr * m * self.r, e[2] - (1.0 - self.d), e[3]]
            if pin is not None:
                kind, c = pin
                mid = sol.sol(0.5)
                res.append((mid[3] - c) if kind == "y" else (mid[0] - c))
            return res

        v0 = self.u if pin is None else np.concatenate([self.u, [self.mu]])
        out = root(F, v0, method="hybr", options={"xtol": 1e-13})
        if np.max(np.abs(F(out.x))) > 1e-10:
            raise RuntimeError(f"elastica shooting failed at mu={mu!r}, pin={pin!r}: "
                               f"{out.message}")
        self.u = out.x[:3].copy()
        self.mu = float(out.x[3]) if pin is not None else float(mu)
        self.sol = self._shoot(*self.u, self.mu)

    def to(self, mu: float, steps: int | None = None) -> ElasticaBranch:
        """Natural continuation in mu to ``mu`` (``steps`` equal steps, default 0.05 each)."""
        steps = steps or max(1, int(math.ceil(abs(mu - self.mu) / 0.05)))
        for m in np.linspace(self.mu, mu, steps + 1)[1:]:
            self._solve(float(m), None)
        return self

    def pinned(self, kind: str, c: float) -> float:
        """Solve with y(1/2) = c (kind "y") or theta(1/2) = c (kind "theta"); returns mu."""
        self._solve(self.mu, (kind, float(c)))
        return self.mu

    def symmetric_solve(self, mu: float) -> None:
        """Solve for the symmetric state at ``mu`` on the half strip s in [0, 1/2]:
        mirror symmetry (theta(1/2) = 0, Ny = 0) for the symmetric actuation, half-turn
        symmetry (y(1/2) = 0, theta'(1/2) = 0) for the antisymmetric one."""
        half = 0.5 * (1.0 - self.d)
        mirror = self.sr == -1.0

        def F(v):
            k0, nx = v[0], v[1]
            ny = 0.0 if mirror else v[2]
            y0 = [self.sl * mu * self.r, k0, 0.0, 0.0]
            e = solve_ivp(_rhs, (0.0, 0.5), y0, args=(nx, ny), method="DOP853", rtol=_RTOL,
                          atol=1e-14).y[:, -1]
            if mirror:
                return [e[0], e[2] - half]
            return [e[3], e[1], e[2] - half]

        v0 = self.u[:2] if mirror else self.u
        out = root(F, v0, method="hybr", options={"xtol": 1e-13})
        if np.max(np.abs(F(out.x))) > 1e-10:
            raise RuntimeError(f"symmetric elastica solve failed at mu={mu!r}: {out.message}")
        self.u = np.array([out.x[0], out.x[1], 0.0 if mirror else out.x[2]])
        self.mu = float(mu)
        self.sol = self._shoot(*self.u, self.mu)

    def jacobian_det(self, h: float = 1e-5) -> float:
        """det of d(theta(1) - alphaR, x(1) - (1 - dL), y(1)) / d(theta'(0), Nx, Ny), by central
        differences: it vanishes where the branch bifurcates or folds."""
        J = np.zeros((3, 3))
        for j in range(3):
            du = np.zeros(3)
            du[j] = h * max(1.0, abs(self.u[j]))
            ep = self._shoot(*(self.u + du), self.mu).y[[0, 2, 3], -1]
            em = self._shoot(*(self.u - du), self.mu).y[[0, 2, 3], -1]
            J[:, j] = (ep - em) / (2.0 * du[j])
        return float(np.linalg.det(J))

    def w(self, X: float) -> float:
        """Transverse deflection at arclength X, units of sqrt(L dL)."""
        return float(self.sol.sol(float(X))[3] / self.r)

    @property
    def lambda_(self) -> float:
        """sqrt(compressive end force L^2 / B) = sqrt(-Nx)."""
        return math.sqrt(-float(self.u[1]))


def equilibrium_w(actuation: str, mu: float, X: np.ndarray, *, end_shortening: float = 1e-2,
                  branch: str = "U_A") -> tuple[np.ndarray, float]:
    """W(X) (units of sqrt(L dL)) and Lambda of the elastica on ``branch`` at ``mu``."""
    b = ElasticaBranch(actuation, end_shortening, branch).to(mu)
    return np.array([b.w(float(x)) for x in np.atleast_1d(X)]), b.lambda_


def mu_star(actuation: str, end_shortening: float = 1e-2) -> float:
    """mu* of the inextensible elastica (see the module docstring)."""
    _check_actuation(actuation)
    r = math.sqrt(end_shortening)
    if actuation == "asymmetric":
        b = ElasticaBranch(actuation, end_shortening).to(1.6, steps=16)
        c0 = b.w(0.5) * r  # the bracket starts well before the fold
        res = minimize_scalar(lambda c: -b.pinned("y", c), bounds=(c0, 0.2 * c0),
                              method="bounded", options={"xatol": 1e-10 * r})
        return -float(res.fun)
    # pitchforks: follow the symmetric branch (U_A for "symmetric", S_B for "antisymmetric")
    # and find where the determinant of the full shooting Jacobian changes sign
    b = ElasticaBranch(actuation, end_shortening).to(1.9, steps=19)
    b.symmetric_solve(1.9)
    mus = np.arange(1.9, 2.2, 0.005)
    dets, us = [], []
    for m in mus:
        b.symmetric_solve(float(m))
        dets.append(b.jacobian_det())
        us.append(b.u.copy())
        if len(dets) > 1 and np.sign(dets[-1]) != np.sign(dets[-2]):
            break
    else:
        raise RuntimeError("no pitchfork found on the symmetric branch in [1.9, 2.2]")
    ma, mb = float(mus[len(dets) - 2]), float(mus[len(dets) - 1])
    ua, ub = us[-2], us[-1]

    def f(m: float) -> float:
        b.u = ua + (m - ma) / (mb - ma) * (ub - ua)
        b.symmetric_solve(m)
        return b.jacobian_det()

    return float(brentq(f, ma, mb, xtol=1e-13))
