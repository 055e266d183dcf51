"""The free exponent's one-dimensional searches against scipy (the slow reference).

``_brent_min`` is Brent's bounded minimisation started from a bracket's three known values: it
must find scipy's ``fminbound`` minimum (to the tolerance) on smooth, flat-bottomed and
asymmetric functions (in about as many evaluations: the bracket's values spare its first
golden sections, a creeping parabola may cost one or two more), and the curvature of a
parabola; ``_crossing_distance`` must find where the function rises by 1, with or without
the curvature's guess.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import optimize

from service.analysis.predictor.exponents import _brent_min, _crossing_distance

_FUNCS = {
    "parabola": lambda x: 4e6 * (x - 1.00003) ** 2 + 7.0,
    "quartic": lambda x: 1e9 * (x - 0.6) ** 4 + 1e3 * (x - 0.6) ** 2,
    "asymmetric": lambda x: math.exp(40 * (x - 0.81)) - 40 * (x - 0.81),
    "log": lambda x: 30 * math.log(1 + 1e4 * (x - 0.52) ** 2),
}
_BRACKETS = {"parabola": (0.995, 1.0, 1.005), "quartic": (0.5, 0.61, 0.7),
             "asymmetric": (0.7, 0.8, 0.9), "log": (0.4, 0.5, 0.6)}  # fmt: skip


@pytest.mark.parametrize("name", list(_FUNCS))
def test_brent_from_a_bracket_finds_scipys_minimum(name: str) -> None:
    fn, x3 = _FUNCS[name], _BRACKETS[name]
    calls = {"n": 0}

    def counted(x: float) -> float:
        calls["n"] += 1
        return fn(x)

    x, fx, curv = _brent_min(counted, x3, tuple(fn(v) for v in x3), 1e-4)
    ref = optimize.minimize_scalar(fn, bounds=(x3[0], x3[2]), method="bounded",
                                   options={"xatol": 1e-4})  # fmt: skip
    assert abs(x - ref.x) < 2e-4
    # as low as the function within the tolerance of scipy's minimum
    assert fx <= max(fn(ref.x - 1e-4), fn(ref.x + 1e-4))
    assert fx == fn(x)
    assert calls["n"] <= ref.nfev + 2
    if name == "parabola":
        assert curv == pytest.approx(8e6, rel=1e-6)


@pytest.mark.parametrize("use_curvature", [True, False])
def test_crossing_distance_is_where_the_function_rises_by_one(use_curvature: bool) -> None:
    """A parabola 4e6 (e - 1)^2 with grid points 5e-3 apart: the crossing is 5e-4 from the
    minimum on either side."""
    fn = _FUNCS["parabola"]
    grid = np.arange(0.98, 1.02 + 1e-12, 5e-3)
    f = np.array([fn(g) for g in grid])
    eh, fh = 1.00003, 7.0
    curv = 8e6 if use_curvature else math.nan
    for sign in (1, -1):
        d = _crossing_distance(fn, grid, f, eh, fh, curv, sign)
        assert d == pytest.approx(5e-4, abs=1e-5)


def test_crossing_beyond_the_grid_is_infinite() -> None:
    fn = _FUNCS["parabola"]
    grid = np.array([0.9999, 1.0, 1.0001])
    f = np.array([fn(g) for g in grid])
    assert _crossing_distance(fn, grid, f, 1.00003, 7.0, 8e6, 1) == math.inf
