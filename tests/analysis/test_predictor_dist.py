"""The predictor's normal and chi-square functions (``predictor._dist``, from scipy.special, so
that a command does not import scipy.stats) equal scipy.stats' bit for bit, at the levels and
degrees of freedom the predictor asks and on wide grids, edges included."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import stats

from service.analysis.predictor._dist import chi2_ppf, norm_cdf, norm_ppf


def _same(a: object, b: object) -> bool:
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    return a.shape == b.shape and bool(np.all((a == b) | (np.isnan(a) & np.isnan(b))))


def test_norm_ppf_and_cdf_are_scipy_stats() -> None:
    rng = np.random.default_rng(1)
    q = np.r_[0.5 + np.array([0.68, 0.9, 0.95, 0.99, 0.999]) / 2, rng.random(2000),
              0.0, 1.0, 0.5, 1e-300, 1 - 1e-16, -0.1, 1.1, np.nan]  # fmt: skip
    for v in q:
        assert _same(norm_ppf(v), stats.norm.ppf(v)), v
    assert _same(norm_ppf(q), stats.norm.ppf(q))
    x = np.r_[rng.normal(scale=5, size=2000), 0.0, -0.0, 40.0, -40.0, np.inf, -np.inf, np.nan]
    assert _same(norm_cdf(x), stats.norm.cdf(x))
    for v in x[:50]:
        assert _same(norm_cdf(v), stats.norm.cdf(v))


@pytest.mark.parametrize("df", [1, 2, 3, 5, 8, 17, 40, 0, -1, 2.5])
def test_chi2_ppf_is_scipy_stats(df: float) -> None:
    rng = np.random.default_rng(int(abs(df) * 10))
    for q in [0.68, 0.9, 0.95, 0.99, *rng.random(300), 0.0, 1.0, -0.5, 1.5, math.nan]:
        assert _same(chi2_ppf(q, df), stats.chi2.ppf(q, df)), (q, df)
