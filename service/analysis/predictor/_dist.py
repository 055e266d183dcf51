"""The normal and chi-square functions the predictor uses, from ``scipy.special``.

``scipy.stats.norm.ppf``/``cdf`` and ``scipy.stats.chi2.ppf`` are these special functions,
times scale 1 plus loc 0, inside a distribution machinery: the values here are scipy.stats' bit
for bit (``tests/analysis/test_predictor_dist.py``), without importing ``scipy.stats`` (~0.25 s
CPU at the start of every command that predicts).
"""

from __future__ import annotations

import math
from typing import Any

from scipy import special


def norm_ppf(q: Any) -> Any:
    """``scipy.stats.norm.ppf(q)``: the standard normal quantile (``special.ndtri``)."""
    return special.ndtri(q)


def norm_cdf(x: Any) -> Any:
    """``scipy.stats.norm.cdf(x)``: the standard normal distribution function (``special.ndtr``),
    elementwise on arrays."""
    return special.ndtr(x)


def chi2_ppf(q: float, df: float) -> float:
    """``scipy.stats.chi2.ppf(q, df)`` for scalars: ``2 gammaincinv(df/2, q)``; 0 at ``q = 0``,
    inf at ``q = 1``, NaN outside ``[0, 1]`` or for ``df <= 0`` (as scipy.stats)."""
    if not (df > 0 and 0 <= q <= 1):
        return math.nan
    if q == 0:
        return 0.0
    if q == 1:
        return math.inf
    return float(2 * special.gammaincinv(df / 2, q))
