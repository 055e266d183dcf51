"""The cusp law's kernels with their work arrays allocated once per search give the numbers
the previous kernels gave, to the bit.

The previous module is kept verbatim in ``_cusp_kernels_before.py`` (compiled without a
cache). Every entry point :mod:`service.analysis.predictor.cusp` calls (and ``cusp_nll``,
``nll_point``) runs on the same random windows of softening and stiffening records, with 0-2
corrections, on grids that cross the fold (infinite values) and the perfect law (``g =
-inf``), and must return identical arrays.
"""

from __future__ import annotations

import math

import _cusp_kernels_before as before
import numpy as np
import pytest

from service.analysis.predictor._kernels import cusp as after

_TS = np.linspace(math.log(1e-7), math.log(3.0), 40)
_GS = np.linspace(math.log(1e-7), math.log(1.0), 26)
_TS_C = np.linspace(math.log(1e-7), math.log(3.0), 22)
_GS_C = np.linspace(math.log(1e-6), math.log(1.0), 12)
_PERFECT = np.array([-math.inf])


def _window(rng: np.random.Generator, soft: bool) -> tuple:
    """A window of |sigma^2| along an imperfect pitchfork's branch, noisy, and its scale."""
    n = int(rng.integers(4, 15))
    mu_star = 1.0 + rng.uniform(0.0, 0.5)
    G = 10 ** rng.uniform(-4, -1)
    span = rng.uniform(0.2, 0.9)
    mu = np.sort(mu_star - (R := after.R_FOLD if soft else after.R_MIN) * G
                 - span * rng.uniform(0.02, 1.0, n))  # fmt: skip
    k = np.array([after.stiffness(mu_star - m, G, soft) for m in mu])
    y = np.abs(k * (1.0 + 0.1 * (mu_star - mu))) * (1.0 + 1e-3 * rng.standard_normal(n))
    wt = 1.0 / (1e-3 * np.abs(y) + 1e-9)
    scale = float(mu[-1] - mu[0]) or 1.0
    del R
    return mu, y, wt, scale


def _same(a: object, b: object) -> bool:
    return bool(np.array_equal(np.asarray(a), np.asarray(b), equal_nan=True))


CASES = [(seed, soft, K) for seed in range(6) for soft in (True, False) for K in (0, 1, 2)]


@pytest.mark.parametrize(("seed", "soft", "K"), CASES)
def test_cusp_kernels_are_the_previous_ones_to_the_bit(seed: int, soft: bool, K: int) -> None:
    rng = np.random.default_rng(1000 * seed + 10 * K + soft)
    mu, y, wt, scale = _window(rng, soft)
    shift = 0.0 if soft else 0.5
    for fn, args in (
        ("scan2", (_TS, _GS, soft, K, shift)),
        ("scan2", (_TS, _PERFECT, soft, K, shift)),
        ("scan2", (_TS_C, _GS_C, soft, K, shift)),
        ("profile_scan", (_TS, _GS, soft, K, shift, True)),
        ("profile_scan", (_TS, np.empty(0), True, K, 0.0, False)),
    ):
        assert _same(getattr(before, fn)(mu, y, wt, scale, *args),
                     getattr(after, fn)(mu, y, wt, scale, *args)), fn  # fmt: skip
    F = after.scan2(mu, y, wt, scale, _TS, _GS, soft, K, shift)
    box = np.array([_TS[0], _TS[-1], _GS[0], _GS[-1]])
    i, j = np.unravel_index(np.argmin(np.where(np.isfinite(F), F, np.inf)), F.shape)
    starts = [(float(_TS[i]), float(_GS[j])), (float(_TS[5]), float(_GS[20]))]
    for t0, g0 in starts:
        args = (t0, g0, soft, K, shift, 0.3, 1e-7, 2000, box)
        assert _same(before.polish(mu, y, wt, scale, *args), after.polish(mu, y, wt, scale, *args))
        pb = before.profile_g(mu, y, wt, scale, t0, _GS, soft, K, shift, True)
        assert _same(pb, after.profile_g(mu, y, wt, scale, t0, _GS, soft, K, shift, True))
        G = scale * math.exp(g0)
        mu_p = mu[-1] + scale * math.exp(t0) - shift * G
        for d in (0.0, 1e-6, 1e-3, 0.1, -0.05):
            m = mu_p + d * scale
            args = (m, soft, K, shift, g0, 0.7, float(_GS[-1]))
            assert _same(before.profile_point(mu, y, wt, scale, *args),
                         after.profile_point(mu, y, wt, scale, *args))  # fmt: skip
            for g in (g0, -math.inf, g0 - 3.0):
                a = (m, g, soft, K, shift)
                assert _same(before.nll_point(mu, y, wt, scale, *a),
                             after.nll_point(mu, y, wt, scale, *a))  # fmt: skip
                ms = m + (after.R_FOLD if soft else after.R_MIN) * (
                    scale * math.exp(g) if g > -700 else 0.0)  # fmt: skip
                a = (ms, scale * math.exp(g) if g > -700 else 0.0, soft, K)
                assert _same(before.cusp_nll(mu, y, wt, scale, *a),
                             after.cusp_nll(mu, y, wt, scale, *a))  # fmt: skip
