"""The planar discrete Cosserat rod: parameters, degrees of freedom, validated kernel wrappers.

Non-dimensional units (paper eq. nonDimensionnalization): length by L, bending stiffness
B = E b h^3 / 12 = 1, mass per unit length rho b h = 1, so time is in units of
sqrt(rho b h L^4 / B). For a rectangular strip of thickness h:

- stretch stiffness  EA = E b h = 12 B / h^2                      -> ``12 / slenderness**2``
- shear stiffness    GA = kappa G b h, G = E / (2 (1 + nu)), kappa = 10 (1 + nu) / (12 + 11 nu)
                      (Cowper 1966's coefficient of a rectangle: 5/6 at nu = 0, 6/7 at
                      nu = 1/2)             -> ``shear_ratio * EA``
- rotary inertia     rho I = rho b h^3 / 12                      -> ``slenderness**2 / 12``
- damping            force -xi * rho A * velocity and torque -xi * rho I * angular velocity,
                      xi = nu L^2 / sqrt(rho b h B) (paper eq. beam_equation_damping)

Clamp conventions (``clamp``):

- ``"node"`` (default): the end node is fixed and the prescribed angle acts at the end node
  itself, s = 0 and s = L, through a half-Voronoi bending spring of stiffness 2 B / ds to the
  first element. Second-order accurate (shown in the tests and bench/cosserat.py).
- ``"element"``: the end node and the end element's director are fixed (PyElastica's
  ``OneEndFixedBC`` / ``FixedConstraint``): the prescribed angle acts half an element inside the
  rod, a first-order clamp (its frequency bias is about +2/n).
- ``"centre"``: the end elements straddle the clamp points: both nodes and the director of each
  end element are fixed, their centres at s = 0 and s = L (nodes at s_i = (i - 1/2) ds,
  ds = L / (n - 1)). Second order, with a smaller constant than the node clamp.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from sim.errors import ParameterError
from sim.scene import ACTUATION_ENDS, check_actuation

from . import _kernels as K

ACTUATION_SIGNS = ACTUATION_ENDS  # (left, right) end-angle signs, from sim.scene's table
CLAMPS = ("node", "element", "centre")


def cowper_rectangle(poisson: float) -> float:
    """Shear coefficient of a rectangular section, 10 (1 + nu) / (12 + 11 nu) (Cowper 1966)."""
    return 10.0 * (1.0 + poisson) / (12.0 + 11.0 * poisson)


def shear_ratio(poisson: float, shear_coefficient: float | None = None) -> float:
    """GA / EA = kappa / (2 (1 + nu)); kappa defaults to the rectangle's (Cowper)."""
    kappa = cowper_rectangle(poisson) if shear_coefficient is None else shear_coefficient
    return kappa / (2.0 * (1.0 + poisson))


class CosseratWarning(UserWarning):
    """A result that is usable but doubtful (e.g. a Newton solve that converged slowly)."""


def _check_actuation(actuation: str) -> str:
    return check_actuation(actuation)


@dataclass(frozen=True)
class Rod:
    """A clamped-clamped planar Cosserat rod of unit length, compressed by ``end_shortening``.

    Parameters
    ----------
    elements : int
        Number of elements n (even, >= 4): nodes at s_i = i / n, element angles at centres.
    end_shortening : float
        dL / L in (0, 0.5): the right end node sits at x = 1 - dL, y = 0.
    slenderness : float
        h / L > 0 (sets EA = 12 / h^2, GA = shear_ratio(poisson) EA, rotary inertia h^2 / 12).
    actuation : {"asymmetric", "symmetric", "antisymmetric"}
        End angles (alphaL, alphaR) = mu sqrt(dL) (1, 0), (1, -1) or (1, 1) (paper eq. BC).
    clamp : {"node", "element"}
        Clamp convention, see the module docstring.
    poisson : float
        Poisson ratio in [0, 0.5] (shear modulus E / (2 (1 + nu))).
    shear_coefficient : float or None
        kappa of GA = kappa G A; None: the rectangle's, ``cowper_rectangle(poisson)``.
    """

    elements: int = 50
    end_shortening: float = 1e-2
    slenderness: float = 1e-3
    actuation: str = "asymmetric"
    clamp: str = "node"
    poisson: float = 0.5
    shear_coefficient: float | None = None

    def __post_init__(self) -> None:
        n = self.elements
        if isinstance(n, bool) or int(n) != n or n < 4 or n % 2:
            raise ParameterError("elements", n, f"elements must be an even integer >= 4, got {n!r}")
        object.__setattr__(self, "elements", int(n))
        d = float(self.end_shortening)
        if not (math.isfinite(d) and 0.0 < d < 0.5):
            raise ParameterError("end_shortening", self.end_shortening,
                                 f"end_shortening must lie in (0, 0.5), got {d!r}")
        h = float(self.slenderness)
        if not (math.isfinite(h) and 0.0 < h < 0.5):
            raise ParameterError("slenderness", self.slenderness,
                                 f"slenderness must lie in (0, 0.5), got {self.slenderness!r}")
        _check_actuation(self.actuation)
        if self.clamp not in CLAMPS:
            raise ParameterError("clamp", self.clamp,
                                 f"clamp must be one of {CLAMPS}, got {self.clamp!r}")
        nu = float(self.poisson)
        if not (math.isfinite(nu) and 0.0 <= nu <= 0.5):
            raise ParameterError("poisson", self.poisson,
                                 f"poisson must lie in [0, 0.5], got {self.poisson!r}")
        k = self.shear_coefficient
        if k is not None and not (math.isfinite(float(k)) and 0.0 < float(k) <= 1.0):
            raise ParameterError("shear_coefficient", k,
                                 f"shear_coefficient must lie in (0, 1], got {k!r}")

    # ---- derived constants ---------------------------------------------------------------
    @property
    def n(self) -> int:
        return self.elements

    @property
    def N(self) -> int:
        """Number of degrees of freedom, 3 n + 2."""
        return 3 * self.elements + 2

    @property
    def ds(self) -> float:
        """Element length: L / n (L / (n - 1) for the centre clamp)."""
        return 1.0 / (self.elements - 1 if self.clamp == "centre" else self.elements)

    @property
    def s_nodes(self) -> np.ndarray:
        """Reference arclength of the nodes (n+1,): i ds, or (i - 1/2) ds (centre clamp)."""
        i = np.arange(self.n + 1, dtype=float)
        return (i - 0.5) * self.ds if self.clamp == "centre" else i * self.ds

    @property
    def EA(self) -> float:
        return 12.0 / self.slenderness**2

    @property
    def GA(self) -> float:
        return shear_ratio(self.poisson, self.shear_coefficient) * self.EA

    @property
    def rotary_inertia(self) -> float:
        return self.slenderness**2 / 12.0

    @property
    def k_clamp(self) -> float:
        return 2.0 / self.ds if self.clamp == "node" else 0.0

    def end_angles(self, mu: float) -> tuple[float, float]:
        """(alphaL, alphaR) in radians for control parameter mu (alpha = mu sqrt(dL / L))."""
        sl, sr = ACTUATION_SIGNS[self.actuation]
        a = float(mu) * math.sqrt(self.end_shortening)
        return sl * a, sr * a

    # ---- layout ------------------------------------------------------------------------------
    def fixed_mask(self) -> np.ndarray:
        """Boolean (N,): end-node positions, end-element angles (element and centre clamps),
        the second and last-but-one node positions (centre clamp)."""
        m = np.zeros(self.N, dtype=bool)
        m[[0, 1, 3 * self.n, 3 * self.n + 1]] = True
        if self.clamp in ("element", "centre"):
            m[[2, 3 * (self.n - 1) + 2]] = True
        if self.clamp == "centre":
            m[[3, 4, 3 * (self.n - 1), 3 * (self.n - 1) + 1]] = True
        return m

    def mass(self) -> np.ndarray:
        """Lumped masses (N,): ds on node coordinates, (h^2 / 12) ds on element angles."""
        m = np.full(self.N, self.ds)
        m[2::3] = self.rotary_inertia * self.ds
        return m

    def apply_bc(self, z: np.ndarray, mu: float) -> np.ndarray:
        """Write the prescribed values (end nodes, clamp angles for "element") into ``z``."""
        aL, aR = self.end_angles(mu)
        if self.clamp == "centre":
            h, n, xr = 0.5 * self.ds, self.n, 1.0 - self.end_shortening
            z[0], z[1], z[3], z[4] = -h * math.cos(aL), -h * math.sin(aL), h * math.cos(aL), \
                h * math.sin(aL)
            z[3 * (n - 1)], z[3 * (n - 1) + 1] = xr - h * math.cos(aR), -h * math.sin(aR)
            z[3 * n], z[3 * n + 1] = xr + h * math.cos(aR), h * math.sin(aR)
            z[2], z[3 * (n - 1) + 2] = aL, aR
            return z
        z[0] = z[1] = 0.0
        z[3 * self.n] = 1.0 - self.end_shortening
        z[3 * self.n + 1] = 0.0
        if self.clamp == "element":
            z[2] = aL
            z[3 * (self.n - 1) + 2] = aR
        return z

    def dbc_dmu(self, z: np.ndarray | None = None) -> np.ndarray:
        """d(prescribed values)/dmu (N,), zero on free dofs (the centre clamp's depend on the
        end angles, read from ``z``)."""
        d = np.zeros(self.N)
        if self.clamp in ("element", "centre"):
            sl, sr = ACTUATION_SIGNS[self.actuation]
            r = math.sqrt(self.end_shortening)
            d[2] = sl * r
            d[3 * (self.n - 1) + 2] = sr * r
            if self.clamp == "centre":
                aL, aR = (0.0, 0.0) if z is None else (z[2], z[3 * (self.n - 1) + 2])
                h, n = 0.5 * self.ds, self.n
                dl, dr = sl * r, sr * r
                d[0], d[1] = h * math.sin(aL) * dl, -h * math.cos(aL) * dl
                d[3], d[4] = -h * math.sin(aL) * dl, h * math.cos(aL) * dl
                d[3 * (n - 1)], d[3 * (n - 1) + 1] = h * math.sin(aR) * dr, -h * math.cos(aR) * dr
                d[3 * n], d[3 * n + 1] = -h * math.sin(aR) * dr, h * math.cos(aR) * dr
        return d

    def pack(self, x: np.ndarray, y: np.ndarray, theta: np.ndarray) -> np.ndarray:
        z = np.empty(self.N)
        z[0::3] = x
        z[1::3] = y
        z[2::3] = theta
        return z

    @staticmethod
    def unpack(z: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(x, y, theta) views of ``z``: shapes (n+1,), (n+1,), (n,)."""
        return z[0::3], z[1::3], z[2::3]

    def _z(self, z: np.ndarray) -> np.ndarray:
        z = np.ascontiguousarray(z, dtype=np.float64)
        if z.shape != (self.N,):
            raise ParameterError("z", z.shape, f"z must have shape ({self.N},), got {z.shape}")
        return z

    # ---- validated kernel wrappers -----------------------------------------------------------
    def _args(self):
        return (self.n, self.ds, self.EA, self.GA, 1.0, self.k_clamp, self.k_clamp)

    def energy(self, z: np.ndarray, mu: float) -> float:
        """Elastic energy (stretch + shear + bending), units of B / L."""
        aL, aR = self.end_angles(mu)
        return float(K.energy(self._z(z), *self._args(), aL, aR))

    def gradient(self, z: np.ndarray, mu: float) -> np.ndarray:
        """Gradient of the energy with respect to ``z`` (N,)."""
        aL, aR = self.end_angles(mu)
        out = np.empty(self.N)
        K.gradient(self._z(z), *self._args(), aL, aR, out)
        return out

    def hessian_band(self, z: np.ndarray) -> np.ndarray:
        """Hessian in LAPACK band storage, shape (2 KU + 1, N), ``H[i, j] = ab[KU+i-j, j]``."""
        ab = np.empty((2 * K.KU + 1, self.N))
        K.hessian_band(self._z(z), *self._args(), ab)
        return ab

    def hessian(self, z: np.ndarray) -> np.ndarray:
        """Dense Hessian (N, N)."""
        return band_to_dense(self.hessian_band(z))

    def dgrad_dmu(self, z: np.ndarray) -> np.ndarray:
        """Partial derivative of the gradient with respect to mu at fixed free dofs (N,)."""
        d = np.zeros(self.N)
        sl, sr = ACTUATION_SIGNS[self.actuation]
        r = math.sqrt(self.end_shortening)
        d[2] -= self.k_clamp * sl * r
        d[3 * (self.n - 1) + 2] -= self.k_clamp * sr * r
        db = self.dbc_dmu(z)
        if np.any(db):
            d += self.hessian(z) @ db
        return d

    # ---- observables ---------------------------------------------------------------------------
    def interp_weights(self, X: float) -> tuple[tuple[int, int], tuple[float, float]]:
        """Indices into ``z`` of the y of the two nodes around reference arclength X, weights."""
        if not 0.0 <= X <= 1.0:
            raise ParameterError("X", X, f"X must lie in [0, 1], got {X!r}")
        u = X / self.ds + (0.5 if self.clamp == "centre" else 0.0)
        i = min(int(math.floor(u)), self.n - 1)
        f = u - i
        if abs(f - 1.0) < 1e-12:
            i, f = i + 1, 0.0
        j = min(i + 1, self.n)
        return (3 * i + 1, 3 * j + 1), (1.0 - f, f)

    def w_at(self, z: np.ndarray, X: float) -> float:
        """Transverse position y at reference arclength X in units of sqrt(L dL)."""
        (i, j), (a, b) = self.interp_weights(X)
        return float((a * z[i] + b * z[j]) / math.sqrt(self.end_shortening))

    def axial_force(self, z: np.ndarray) -> float:
        """x-component of the internal force (tension > 0), units of B / L^2, from element 0
        (element 1 with the centre clamp, whose end elements are rigid)."""
        j = 3 if self.clamp == "centre" else 0
        dx = (z[j + 3] - z[j]) / self.ds
        dy = (z[j + 4] - z[j + 1]) / self.ds
        c, s = math.cos(z[j + 2]), math.sin(z[j + 2])
        a = dx * c + dy * s - 1.0
        b = -dx * s + dy * c
        return float(self.EA * a * c - self.GA * b * s)

    def mirror(self, z: np.ndarray) -> np.ndarray:
        """The symmetry image of ``z`` for this actuation (symmetric: mirror x -> 1-dL-x;
        antisymmetric: half-turn about the centre). Asymmetric has no symmetry (ValueError)."""
        if self.actuation == "asymmetric":
            raise ValueError("the asymmetric actuation has no symmetry")
        x, y, th = self.unpack(z)
        xr = (1.0 - self.end_shortening) - x[::-1]
        if self.actuation == "symmetric":
            return self.pack(xr, y[::-1], -th[::-1])
        return self.pack(xr, -y[::-1], th[::-1])

    def guess(self, branch: str, mu: float = 0.0) -> np.ndarray:
        """First-Euler-mode initial guess: U_A buckled to negative w, U_B to positive w."""
        s = self.s_nodes
        sign = -1.0 if branch == "U_A" else 1.0
        amp = sign * math.sqrt(self.end_shortening) / math.pi
        y = amp * (1.0 - np.cos(2.0 * np.pi * s))
        sc = 0.5 * (s[:-1] + s[1:])
        th = np.arctan(amp * 2.0 * np.pi * np.sin(2.0 * np.pi * sc))
        x = np.concatenate([[0.0], np.cumsum(np.cos(th)) * self.ds])
        span = (1.0 - self.end_shortening) + (s[-1] - s[0] - 1.0)  # end-to-end of the nodes
        x = s[0] + (x - x[0]) * span / (x[-1] - x[0])
        return self.apply_bc(self.pack(x, y, th), mu)


def band_to_dense(ab: np.ndarray) -> np.ndarray:
    """Dense (N, N) matrix from LAPACK general band storage with KU = KL = 4."""
    N = ab.shape[1]
    H = np.zeros((N, N))
    for d in range(ab.shape[0]):
        off = K.KU - d  # j - i
        if off >= 0:
            idx = np.arange(0, N - off)
            H[idx, idx + off] = ab[d, idx + off]
        else:
            idx = np.arange(-off, N)
            H[idx, idx + off] = ab[d, idx + off]
    return H
