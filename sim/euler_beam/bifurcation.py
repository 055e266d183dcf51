"""Bifurcations of the Euler beam's U_A branch (paper Table 1, beam column).

Sits above ``statics`` (the branches) and ``stability`` (the spectra that decide a
pitchfork's criticality), mirroring ``sim.cosserat.bifurcation``; returns the one
``sim.results.Bifurcation`` type every backend returns.
"""

from __future__ import annotations

import math
from functools import cache

from sim.euler_beam.stability import DEFAULT_N, is_stable
from sim.euler_beam.statics import (
    _J,
    BeamError,
    _particular_at_mode,
    _slope,
    _structure,
    equilibria,
)
from sim.results import Bifurcation, BifurcationPoint, Resolution

#: mu* is a Brent root (xtol 1e-15) of closed-form functions integrated by 96-point
#: Gauss-Legendre quadrature (exact to round-off): its error is a few round-offs.
MU_STAR_ERROR = 1e-13


def _fold_points(actuation: str) -> list[BifurcationPoint]:
    """Folds (saddle-nodes) of the generic branches: pairs of intervals sharing a fold."""
    s = _slope(actuation)
    intervals, _ = _structure(actuation)
    out = []
    for left, right in zip(intervals[:-1], intervals[1:]):
        if left.hi == right.lo and left.hi != left.pole:  # a fold, not a pole
            lam = left.hi
            mu = math.sqrt(2.0 / _J(lam, s).real)
            out.append(BifurcationPoint(mu, math.sqrt(lam), "saddle-node", (left.name, right.name)))
    return out


def _pitchfork_points(actuation: str) -> list[BifurcationPoint]:
    s = _slope(actuation)
    _, consts = _structure(actuation)
    out = []
    for lam_k, family in consts:
        _, _, Jp, _ = _particular_at_mode(lam_k, s)
        mu_c = math.sqrt(2.0 / Jp)
        below = equilibria(actuation, mu_c * (1 - 1e-3))
        # criticality: the side branches (constant Lambda) are stable below mu_c -> supercritical
        side = [e for e in below if e.kind == "constant" and e.branch[0] == family]
        kind = (
            "supercritical-pitchfork"
            if side and all(is_stable(e) for e in side)
            else "subcritical-pitchfork"
        )
        trivial = [
            e.branch
            for e in below
            if e.kind == "generic" and abs(e.lambda2 - lam_k) < 0.05 * lam_k
        ]
        out.append(
            BifurcationPoint(
                mu_c, math.sqrt(lam_k), kind, tuple(sorted({e.branch for e in side} | set(trivial)))
            )
        )
    return out


@cache
def bifurcation(actuation: str) -> Bifurcation:
    """The shape transition of U_A under this actuation (and its secondary bifurcations).

    The primary transition is the first bifurcation met by U_A as mu increases from 0:
    asymmetric, the fold U_A/S_B (saddle-node, mu* ~ 1.7818); symmetric, the subcritical
    pitchfork at mu* = 2 (S_A, S_B on U_A), secondary fold U_A/W_B at mu2* ~ 2.0119;
    antisymmetric, the supercritical pitchfork at mu* = 2 (U_A, U_B on S_B).
    """
    _slope(actuation)
    points = [
        p for p in _fold_points(actuation) + _pitchfork_points(actuation) if "U_A" in p.branches
    ]
    points.sort(key=lambda p: p.mu_star)
    if not points:
        raise BeamError("actuation", actuation,
                        f"no bifurcation of U_A found for actuation={actuation!r}")  # fmt: skip
    first, rest = points[0], tuple(points[1:])
    res = Resolution("euler-beam", DEFAULT_N, None, MU_STAR_ERROR * first.mu_star,
                     "closed-form branches, Brent root (xtol 1e-15): round-off bound")  # fmt: skip
    return Bifurcation(actuation, first.mu_star, first.lambda_star, first.transition,
                       first.branches, rest, model="euler-beam", resolution=res)  # fmt: skip
