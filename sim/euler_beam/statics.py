"""Static equilibria of the compressed, end-rotated Euler beam and their bifurcations.

Model (paper, eqs. beam_equation_nodim_static, sol_general_static, BC, geometrical_constraint):

    W'''' + Lambda^2 W'' = 0  on X in [0, 1],   integral_0^1 W'^2 dX = 2,
    W(0) = W(1) = 0,  W'(0) = mu,  W'(1) = s mu,  s = 0 | -1 | +1 (asym | sym | antisym).

We write lam = Lambda^2 (compression; lam < 0 is tension, reached by some branches at large mu)
and use the basis {C(X), S(X), X, 1} with

    C(X) = (1 - cos(Lambda X)) / lam,    S(X) = (Lambda X - sin(Lambda X)) / (lam Lambda),

which are entire functions of lam (no degeneration at lam = 0, real for lam < 0). The boundary
conditions at X = 0 give D = 0, C = mu; the two at X = 1 leave a 2x2 system for (a, b) whose
determinant vanishes at the Euler eigenvalues (Lambda = 2 pi k, or tan(Lambda/2) = Lambda/2).

A *generic* branch is the curve mu(lam) = sqrt(2 / J(lam)), J = integral of Wh'^2 for the
solution Wh per unit mu; its folds (minima of J) are saddle-nodes. Where the forcing is
orthogonal to an Euler mode (symmetric forcing and an antisymmetric mode, or the reverse), a
pair of *constant-Lambda* branches W = mu Wp + c Phi exists for mu < mu_c = sqrt(2 / J_p): the
pitchfork at mu_c.

Branch names (fixed at mu -> 0+ by the Euler mode reached and its sign):
U (first mode, Lambda = 2 pi), S (second, antisymmetric), W (third, Lambda = 4 pi);
U_A has W(1/2) < 0 (the inverted state, pushed towards the transition by mu > 0),
S_B and W_B have W(1/4) > 0. With these names the paper's statements hold and are tested:
asymmetric U_A meets S_B at the fold mu* = 1.7818; symmetric S_A, S_B meet U_A at mu* = 2 and
U_A meets W_B at mu2* = 2.0119; antisymmetric U_A, U_B meet S_B at mu* = 2.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cache

import numpy as np
from scipy.optimize import brentq

from sim.errors import ParameterError, SimulationError
from sim.euler_beam._kernels import entire_basis
from sim.euler_beam._quadrature import _WQ, _XQ
from sim.scene import ACTUATION_ENDS, check_actuation

ACTUATION_SLOPE = {a: ends[1] for a, ends in ACTUATION_ENDS.items()}  # W_X(1) / W_X(0)
_H = 1e-30  # complex-step size


class BeamError(ParameterError):
    """Bad input to the beam model (``.parameter``, ``.value``; the message names both)."""


def _slope(actuation: str) -> float:
    return ACTUATION_SLOPE[check_actuation(actuation, BeamError)]


# --------------------------------------------------------------------------------------------
# Entire basis functions of lam (complex arithmetic so that complex-step derivatives work)
# --------------------------------------------------------------------------------------------
def basis(lam: complex, X: np.ndarray) -> tuple[np.ndarray, ...]:
    """Basis functions and derivatives at points X for compression lam = Lambda^2.

    Returns ``(C, S, S1, Co)`` with C = (1 - cos)/lam, S = (Lambda X - sin)/(lam Lambda),
    S1 = sin(Lambda X)/Lambda = C', Co = cos(Lambda X) = S1'. Also C = S'. All are entire in lam
    and evaluated in complex arithmetic (take ``.real`` for real lam), each of X's shape, by
    the compiled kernel :func:`sim.euler_beam._kernels.entire_basis` (the numpy version cost
    some 0.1 ms a call in the equilibria's root finding, half of a warn sweep's CPU).
    """
    X = np.asarray(X, dtype=float)
    flat = np.ascontiguousarray(X.reshape(-1))
    out = np.empty((4, flat.size), dtype=complex)
    entire_basis(complex(lam), flat, out[0], out[1], out[2], out[3])
    return tuple(o.reshape(X.shape) for o in out)


def _coeffs(lam: complex, s: float) -> tuple[complex, complex]:
    """(a, b) per unit mu of the generic solution W = a C + b S + X (lam not an eigenvalue)."""
    C1, S1v, Si1, _ = basis(lam, np.array([1.0]))
    C1, S1v, Si1 = C1[0], S1v[0], Si1[0]
    det = C1 * C1 - S1v * Si1
    # [[C, S], [S1, C]] (a, b) = (-1, s - 1)
    a = (-C1 - S1v * (s - 1.0)) / det
    b = (C1 * (s - 1.0) + Si1) / det
    return a, b


def _J(lam: complex, s: float) -> complex:
    """J(lam) = integral_0^1 Wh'^2 dX for the unit-mu generic solution (complex-analytic)."""
    a, b = _coeffs(lam, s)
    C, S, S1, _ = basis(lam, _XQ)
    dW = a * S1 + b * C + 1.0
    return np.sum(_WQ * dW * dW)


def J(lam: float, actuation: str) -> float:
    """Constraint integral per unit mu^2 of the generic branch at compression lam = Lambda^2."""
    return float(_J(lam, _slope(actuation)).real)


def dJ(lam: float, actuation: str) -> float:
    """dJ/dlam by complex step (exact to round-off)."""
    return float(_J(complex(lam, _H), _slope(actuation)).imag / _H)


def mu_of_lambda2(lam: float, actuation: str) -> float:
    """mu on the generic branch through compression lam: mu = sqrt(2 / J(lam))."""
    return math.sqrt(2.0 / J(lam, actuation))


# --------------------------------------------------------------------------------------------
# Euler eigenvalues and modes
# --------------------------------------------------------------------------------------------
@cache
def euler_eigenvalues(count: int = 6) -> tuple[tuple[float, str], ...]:
    """The first ``count`` Euler buckling eigenvalues Lambda with their symmetry.

    Symmetric modes: Lambda = 2 pi k, Phi = 1 - cos(Lambda X). Antisymmetric: tan(L/2) = L/2.
    Returns ((Lambda, "sym" | "anti"), ...) in increasing order.
    """
    out: list[tuple[float, str]] = []
    k = 1
    while len(out) < count + 2:
        out.append((2.0 * math.pi * k, "sym"))
        # antisymmetric root of tan(x) = x with x = L/2 in (pi k, pi k + pi/2)
        f = lambda x: math.sin(x) - x * math.cos(x)  # noqa: E731
        x = brentq(f, math.pi * k + 1e-9, math.pi * k + math.pi / 2 - 1e-12, xtol=1e-15, rtol=1e-15)
        out.append((2.0 * x, "anti"))
        k += 1
    out.sort()
    return tuple(out[:count])


def _mode_family(index: int) -> str:
    return "USW"[index] if index < 3 else f"M{index + 1}"


def _euler_mode_coeffs(lam: float) -> tuple[float, float]:
    """(a, b) of the Euler mode a C + b S at an eigenvalue (null vector of the 2x2 system)."""
    C1, S1v, Si1, _ = (v[0].real for v in basis(lam, np.array([1.0])))
    A = np.array([[C1, S1v], [Si1, C1]])
    _, _, vt = np.linalg.svd(A)
    a, b = vt[-1]
    return float(a), float(b)


def _compatible(sym: str, s: float) -> bool:
    """Whether end-rotation forcing with slope ratio s is orthogonal to a mode of this symmetry."""
    return (sym == "sym" and s == 1.0) or (sym == "anti" and s == -1.0)


# --------------------------------------------------------------------------------------------
# Equilibria
# --------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Equilibrium:
    """One static equilibrium of the beam.

    Attributes
    ----------
    actuation : str
    mu : float
    branch : str
        U_A, U_B, S_A, S_B, W_A or W_B.
    lambda2 : float
        Lambda^2, the non-dimensional compression F L^2 / B (negative: tension).
    coeffs : tuple of float
        (a, b, c, d) of W = a C(X) + b S(X) + c X + d in the entire basis of ``basis``.
    kind : str
        "generic" (on a curve mu(Lambda)) or "constant" (constant-Lambda pitchfork pair).
    """

    actuation: str
    mu: float
    branch: str
    lambda2: float
    coeffs: tuple[float, float, float, float]
    kind: str = "generic"

    @property
    def lam(self) -> float:
        """Lambda (signed: negative values mean tension, Lambda^2 < 0)."""
        return math.copysign(math.sqrt(abs(self.lambda2)), self.lambda2)

    def shape(self, X: np.ndarray, derivative: int = 0) -> np.ndarray:
        """W_eq or its first/second derivative at points X in [0, 1]."""
        a, b, c, d = self.coeffs
        C, S, S1, Co = (v.real for v in basis(self.lambda2, np.atleast_1d(X)))
        if derivative == 0:
            return a * C + b * S + c * np.asarray(X, float) + d
        if derivative == 1:
            return a * S1 + b * C + c
        if derivative == 2:
            return a * Co + b * S1
        if derivative == 3:
            return -a * self.lambda2 * S1 + b * Co
        raise BeamError("derivative", derivative, f"derivative must be 0..3, got {derivative!r}")

    @property
    def w_half(self) -> float:
        return float(self.shape(np.array([0.5]))[0])

    @property
    def w_quarter(self) -> float:
        return float(self.shape(np.array([0.25]))[0])

    @property
    def energy(self) -> float:
        """Bending energy (1/2) integral W''^2 dX (units of B dL / L^2)."""
        return float(0.5 * np.sum(_WQ * self.shape(_XQ, 2) ** 2))

    @property
    def constraint(self) -> float:
        """integral W'^2 dX (= 2 on every equilibrium)."""
        return float(np.sum(_WQ * self.shape(_XQ, 1) ** 2))


@dataclass(frozen=True)
class _Interval:
    lo: float  # lam bounds (lo may be -inf)
    hi: float
    pole: float  # lam of the Euler mode this interval tends to as mu -> 0
    family: str  # U, S, W
    rising: bool  # J increasing in lam on the interval
    name: str = "?"  # branch name, fixed by the shape's sign as mu -> 0 on this piece


@cache
def _structure(actuation: str) -> tuple[tuple[_Interval, ...], tuple[tuple[float, str], ...]]:
    """Generic intervals (monotone pieces of J between poles and folds) and constant branches."""
    s = _slope(actuation)
    modes = euler_eigenvalues(7)
    fam_of = {L: _mode_family(i) for i, (L, _) in enumerate(modes)}
    poles = [L * L for L, sym in modes if not _compatible(sym, s)]
    consts = tuple((L * L, fam_of[L]) for L, sym in modes[:3] if _compatible(sym, s))
    fam = {L * L: fam_of[L] for L, _ in modes}
    intervals = [_Interval(-math.inf, poles[0], poles[0], fam[poles[0]], True)]
    for p, q in zip(poles[:-1], poles[1:]):
        if fam[p] not in "USW" and fam[q] not in "USW":
            break
        eps = 1e-9 * q
        f = _fold_between(p, q, s)
        intervals.append(_Interval(p, f, p, fam[p], False))
        intervals.append(_Interval(f, q, q, fam[q], True))
        _ = eps
    keep = tuple(_named(iv, actuation) for iv in intervals if iv.family in "USW")
    return keep, consts


def _named(iv: _Interval, actuation: str) -> _Interval:
    """Name a generic piece by the sign of its shape next to its Euler pole (mu -> 0+)."""
    d = 1e-6 * iv.pole
    lam = iv.pole - d if iv.hi == iv.pole else iv.pole + d
    e = _generic_eq(actuation, mu_of_lambda2(lam, actuation), lam, "?")
    return _Interval(
        iv.lo, iv.hi, iv.pole, iv.family, iv.rising, _sign_name(iv.family, (e.w_half, e.w_quarter))
    )


def _fold_between(p: float, q: float, s: float) -> float:
    """lam of the minimum of J between consecutive poles p < q (dJ/dlam = 0)."""
    g = lambda lam: _J(complex(lam, _H), s).imag / _H  # noqa: E731
    d = 1e-7 * (q - p)
    return brentq(g, p + d, q - d, xtol=1e-14, rtol=1e-15, maxiter=200)


def _sign_name(family: str, W: np.ndarray) -> str:
    """A/B suffix from the sign convention (W at X = 1/2 for U, at X = 1/4 for S and W)."""
    w_half, w_quarter = W
    if family == "U":
        return "U_A" if w_half < 0 else "U_B"
    return f"{family}_B" if w_quarter > 0 else f"{family}_A"


def _generic_eq(actuation: str, mu: float, lam: float, name: str) -> Equilibrium:
    s = _slope(actuation)
    a, b = (complex(v).real for v in _coeffs(lam, s))
    return Equilibrium(actuation, mu, name, lam, (a * mu, b * mu, mu, 0.0), "generic")


def _particular_at_mode(
    lam_k: float, s: float
) -> tuple[tuple[float, float], tuple[float, float], float, float]:
    """At a compatible eigenvalue: unit-mu particular (a, b), the mode (a, b), J_p, J_phi.

    The particular solution is made orthogonal to the mode in the constraint inner product,
    so that J(mu Wp + c Phi) = mu^2 J_p + c^2 J_phi.
    """
    C1, S1v, Si1, _ = (v[0].real for v in basis(lam_k, np.array([1.0])))
    A = np.array([[C1, S1v], [Si1, C1]])
    rhs = np.array([-1.0, s - 1.0])
    ab_p = np.linalg.lstsq(A, rhs, rcond=None)[0]
    if np.linalg.norm(A @ ab_p - rhs) > 1e-8:
        raise SimulationError("actuation", None,
                              "forcing is not compatible with the Euler mode (internal error)")
    ab_m = np.array(_euler_mode_coeffs(lam_k))
    C, S, S1, _ = (v.real for v in basis(lam_k, _XQ))
    dWp = ab_p[0] * S1 + ab_p[1] * C + 1.0
    dPh = ab_m[0] * S1 + ab_m[1] * C
    proj = np.sum(_WQ * dWp * dPh) / np.sum(_WQ * dPh * dPh)
    ab_p = ab_p - proj * ab_m
    dWp = ab_p[0] * S1 + ab_p[1] * C + 1.0
    return tuple(ab_p), tuple(ab_m), float(np.sum(_WQ * dWp**2)), float(np.sum(_WQ * dPh**2))


#: Below this |mu| the root Lambda of J(Lambda) = 2 / mu^2 lies within O(mu) of an Euler
#: eigenvalue (a pole of J) and the direct solve loses digits as 1 / mu: the length constraint
#: off by 7e-11 at mu = 1e-4, 6e-9 at 1e-6, branches lost below ~1e-11, 2 / mu^2 = inf at
#: 5e-324. There the states come from a parabola in mu (:func:`_near_zero`), 10-1e4x closer.
_MU_LINEAR = 1e-4
#: The parabola's nodes (-_MU_REF, 0, _MU_REF): the direct solve holds the constraint to 1e-11.
_MU_REF = 1e-3


def _near_zero(actuation: str, mu: float) -> list[Equilibrium]:
    """The states at 0 < mu < _MU_LINEAR: the parabola in mu through those at -_MU_REF, 0 and
    +_MU_REF (its error, O(mu _MU_REF^2), holds the length constraint to 1e-15 at mu = 1e-8,
    8e-13 at 1e-5)."""
    at = [{e.branch: e for e in equilibria(actuation, m)} for m in (-_MU_REF, 0.0, _MU_REF)]
    t = mu / _MU_REF

    def par(fm: float, f0: float, fp: float) -> float:
        return f0 + 0.5 * t * (fp - fm) + 0.5 * t * t * (fp - 2.0 * f0 + fm)

    out = []
    for name, ep in at[2].items():
        em, e0 = at[0].get(name), at[1].get(name)
        if em is None or e0 is None:
            continue
        co = tuple(par(*c) for c in zip(em.coeffs, e0.coeffs, ep.coeffs, strict=True))
        lam2 = par(em.lambda2, e0.lambda2, ep.lambda2)
        out.append(Equilibrium(actuation, mu, name, lam2, co, ep.kind))  # type: ignore[arg-type]
    return out


def equilibria(
    actuation: str, mu: float, *, branches: tuple[str, ...] | None = None
) -> list[Equilibrium]:
    """Every equilibrium on the six branches U_A, U_B, S_A, S_B, W_A, W_B at this mu.

    Parameters
    ----------
    actuation : {"asymmetric", "symmetric", "antisymmetric"}
    mu : float
        End rotation parameter (any sign: mu < 0 is the mirror image, A and B exchanged).
    branches : tuple of str, optional
        Keep only these branches.

    Returns
    -------
    list of Equilibrium
        Sorted by branch name; a branch absent at this mu (past its fold or pitchfork) is absent.
    """
    s = _slope(actuation)
    mu = float(mu)
    if not math.isfinite(mu):
        raise BeamError("mu", mu, f"mu must be finite, got {mu!r}")
    if mu < 0:
        mirrored = equilibria(actuation, -mu)
        swap = {"A": "B", "B": "A"}
        out = [
            Equilibrium(
                actuation,
                mu,
                e.branch[:2] + swap[e.branch[2]],
                e.lambda2,
                tuple(-c for c in e.coeffs),
                e.kind,
            )
            for e in mirrored
        ]
    elif 0.0 < mu < _MU_LINEAR:
        out = _near_zero(actuation, mu)
    elif mu == 0.0:
        out = []
        for i, (L, _) in enumerate(euler_eigenvalues(3)):
            a, b = _euler_mode_coeffs(L * L)
            C, S, S1, _ = (v.real for v in basis(L * L, _XQ))
            norm = math.sqrt(2.0 / np.sum(_WQ * (a * S1 + b * C) ** 2))
            for sign in (1.0, -1.0):
                e = Equilibrium(
                    actuation, 0.0, "?", L * L, (sign * norm * a, sign * norm * b, 0.0, 0.0), "mode"
                )
                name = _sign_name(_mode_family(i), (e.w_half, e.w_quarter))
                out.append(Equilibrium(actuation, 0.0, name, L * L, e.coeffs, "mode"))
    else:
        intervals, consts = _structure(actuation)
        target = 2.0 / (mu * mu)
        out = []
        for iv in intervals:
            F = lambda lam: _J(lam, s).real - target  # noqa: E731
            hi = iv.hi - 1e-12 * abs(iv.hi)
            if math.isinf(iv.lo):
                lo = min(iv.hi - 1.0, 0.0)
                while F(lo) > 0:
                    lo = 2.0 * lo - 10.0
                    if lo < -1e7:
                        break
            else:
                lo = iv.lo + 1e-12 * abs(iv.lo)
            Flo, Fhi = F(lo), F(hi)
            if Flo * Fhi > 0:
                continue  # beyond the fold: no equilibrium on this piece
            lam = brentq(F, lo, hi, xtol=1e-15, rtol=1e-15, maxiter=300)
            out.append(_generic_eq(actuation, mu, lam, iv.name))
        for lam_k, family in consts:
            ab_p, ab_m, Jp, Jphi = _particular_at_mode(lam_k, s)
            c2 = (2.0 - mu * mu * Jp) / Jphi
            if c2 <= 0:
                continue
            mode = Equilibrium(actuation, 0.0, "?", lam_k, (ab_m[0], ab_m[1], 0.0, 0.0), "mode")
            for sign in (1.0, -1.0):
                c = sign * math.sqrt(c2)
                co = (mu * ab_p[0] + c * ab_m[0], mu * ab_p[1] + c * ab_m[1], mu, 0.0)
                # named by the sign of its Euler-mode component (the pitchfork amplitude)
                name = _sign_name(family, (sign * mode.w_half, sign * mode.w_quarter))
                out.append(Equilibrium(actuation, mu, name, lam_k, co, "constant"))
    if branches is not None:
        out = [e for e in out if e.branch in branches]
    return sorted(out, key=lambda e: e.branch)


def equilibrium(actuation: str, mu: float, branch: str = "U_A") -> Equilibrium:
    """The equilibrium on one branch.

    Raises
    ------
    SimulationError
        (parameter "mu") when the branch does not exist at this mu (past its fold or
        pitchfork); ``sim.backends`` adds the bifurcation's mu* to the message.
    """
    found = [e for e in equilibria(actuation, mu) if e.branch == branch]
    if not found:
        raise SimulationError(
            "mu", mu,
            f"branch {branch!r} does not exist for {actuation} actuation at mu={mu!r} "
            "(past its bifurcation)",
        )
    return found[0]
