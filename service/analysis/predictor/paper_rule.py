"""The paper's early-warning rule (Discussion, Fig. "Anticipate shape transitions" and Table 2),
kept as published: the baseline every prediction is compared with.

Measure ``T = 1/sqrt|sigma^2|`` at increasing ``mu``; at the first point where ``T > 10 T(0)``
extrapolate ``T^(-1/a)`` linearly to zero through that point and the previous one. Unit-agnostic
like :func:`service.analysis.predict.predict`: ``mu`` in any unit, ``sigma2`` in 1/time^2.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from service.analysis.common import Flag
from service.analysis.errors import ParameterError
from service.analysis.predictor.sweep import prepare_sweep

__all__ = ["PaperRule", "check_exponent", "paper_rule"]

_PAPER_FACTOR = 10.0


@dataclass(frozen=True)
class PaperRule:
    """Result of :func:`paper_rule`.

    Attributes
    ----------
    mu_star : float
        Extrapolated mu* (unit of ``mu``).
    stop_index : int
        Index of the first point with ``T > 10 T(0)`` (the red dot of the paper's figure); the
        last index when the threshold was never reached (flag ``threshold_not_reached``).
    t_ratio : float
        ``T / T(0)`` at ``stop_index``.
    a : float
        Exponent used.
    flags : tuple of Flag
    """

    mu_star: float
    stop_index: int
    t_ratio: float
    a: float
    flags: tuple[Flag, ...] = ()


def check_exponent(a: Any) -> float:
    """``a`` as a positive finite float (a time exponent), else :class:`ParameterError` on ``a``."""
    try:
        af = float(a)
    except (TypeError, ValueError) as exc:
        raise ParameterError("a", a, f"a must be a positive number, got a={a!r}") from exc
    if not math.isfinite(af) or af <= 0:
        raise ParameterError("a", a, f"a must be a positive number, got a={a!r}")
    return af


def paper_rule(
    mu: Sequence[float] | np.ndarray,
    sigma2: Sequence[float] | np.ndarray,
    a: float,
    *,
    factor: float = _PAPER_FACTOR,
) -> PaperRule:
    """The paper's early-warning rule (Discussion; Table 2), as published.

    Parameters
    ----------
    mu : array_like, shape (n,)
        Control parameter, strictly increasing (the first point plays ``mu = 0``).
    sigma2 : array_like, shape (n,)
        Eigenvalue of the fundamental (1/time^2), negative.
    a : float
        Time exponent (1/4 saddle-node, 1/2 pitchfork; doubled when over-damped).
    factor : float
        Threshold on ``T / T(0)`` (10 in the paper).

    Returns
    -------
    PaperRule
        ``mu* = mu_i + f_i (mu_i - mu_{i-1}) / (f_{i-1} - f_i)`` with ``f = T^(-1/a)
        = |sigma^2|^(1/(2a))`` and ``i`` the first index with ``T_i > factor T_0``.
    """
    af = check_exponent(a)
    if not (math.isfinite(factor) and factor > 1):
        raise ParameterError("factor", factor, f"factor must be > 1, got factor={factor!r}")
    sw = prepare_sweep(mu, sigma2)
    T = 1.0 / np.sqrt(sw.y)
    ratio = T / T[0]
    hit = np.flatnonzero(ratio > factor)
    flags: list[Flag] = []
    if hit.size:
        i = int(hit[0])
    else:
        i = sw.mu.size - 1
        flags.append(
            Flag(
                "threshold_not_reached",
                f"T never exceeded {factor:g} T(0) (max {ratio.max():.3g} T(0)): extrapolated "
                "through the last two points",
            )
        )
    f = sw.y ** (1.0 / (2.0 * af))  # T^(-1/a)
    df = f[i - 1] - f[i]
    if df <= 0:
        flags.append(
            Flag("not_decreasing", f"T^(-1/a) does not decrease between points {i - 1} and {i}")
        )
        m = math.nan
    else:
        m = float(sw.mu[i] + f[i] * (sw.mu[i] - sw.mu[i - 1]) / df)
    return PaperRule(m, i, float(ratio[i]), af, tuple(flags))
