"""Brent's minimisation, the bookkeeping its three searches share.

The fold parameter's refinement (:mod:`._kernels.fold`), the search over mu*
(:mod:`._kernels.profile`) and the free exponent's (a Python objective,
:mod:`.exponents`) each choose their own trial point (their tolerances,
starts and guards differ) from the parabola of :func:`brent_parabola` or a golden section, and
keep the bracket and the three best points with :func:`brent_keep` (Brent 1973, ch. 5; the
steps of scipy's ``fminbound``).
"""

from __future__ import annotations

import math

from numba import njit

__all__ = ["GOLD", "brent_keep", "brent_parabola", "brent_step"]

GOLD = 0.3819660112501051  # (3 - sqrt(5)) / 2: the golden section's step
_SQRT_EPS = 1.4901161193847656e-08  # fminbound's relative tolerance


@njit(cache=True, inline="always")
def brent_keep(
    a: float, b: float, x: float, fx: float, w: float, fw: float, v: float, fv: float,
    u: float, fu: float,
) -> tuple[float, float, float, float, float, float, float, float]:
    """The bracket ``[a, b]`` and the lowest, second and third lowest points ``x``, ``w``,
    ``v`` (values ``fx``, ``fw``, ``fv``) after the trial ``u`` gave ``fu``; returns
    ``(a, b, x, fx, w, fw, v, fv)``."""
    if fu <= fx:
        if u < x:
            b = x
        else:
            a = x
        return a, b, u, fu, x, fx, w, fw
    if u < x:
        a = u
    else:
        b = u
    if fu <= fw or w == x:
        return a, b, x, fx, u, fu, w, fw
    if fu <= fv or v == x or v == w:
        return a, b, x, fx, w, fw, u, fu
    return a, b, x, fx, w, fw, v, fv


@njit(cache=True, inline="always")
def brent_parabola(
    x: float, fx: float, w: float, fw: float, v: float, fv: float
) -> tuple[float, float]:
    """``(p, q)``, ``q >= 0``: the step ``p / q`` from ``x`` to the vertex of the parabola
    through the three lowest points (``q = 0``: they make none)."""
    r = (x - w) * (fx - fv)
    q = (x - v) * (fx - fw)
    p = (x - v) * q - (x - w) * r
    q = 2.0 * (q - r)
    if q > 0.0:
        p = -p
    return p, abs(q)


@njit(cache=True, inline="always")
def brent_step(
    a: float, b: float, x: float, fx: float, w: float, fw: float, v: float, fv: float,
    d: float, e: float, xatol: float,
) -> tuple[float, float, float]:
    """The next trial point of a bounded minimisation on ``[a, b]`` (lowest points ``x``,
    ``w``, ``v``; last steps ``d``, ``e``; tolerance ``xatol``, scipy's ``fminbound``): the
    parabola's vertex where it is acceptable, else a golden section. Returns ``(u, d, e)``;
    ``u`` NaN once ``x`` is converged."""
    xm = 0.5 * (a + b)
    tol1 = _SQRT_EPS * abs(x) + xatol / 3.0
    tol2 = 2.0 * tol1
    if abs(x - xm) <= tol2 - 0.5 * (b - a):
        return math.nan, d, e
    golden = True
    if abs(e) > tol1:
        p, q = brent_parabola(x, fx, w, fw, v, fv)
        e_old = e
        e = d
        if abs(p) < abs(0.5 * q * e_old) and p > q * (a - x) and p < q * (b - x):
            d = p / q
            u = x + d
            if u - a < tol2 or b - u < tol2:
                d = tol1 if xm >= x else -tol1
            golden = False
    if golden:
        e = (b - x) if x < xm else (a - x)
        d = GOLD * e
    return x + (d if abs(d) >= tol1 else (tol1 if d > 0.0 else -tol1)), d, e
