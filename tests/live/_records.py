"""Closed-form records for the live tests: ``w = c + A exp(-g t) sin(W t)``.

Their undamped eigenvalue is ``sigma^2 = -(W^2 + g^2)``; along the sweep ``|sigma^2| = k (mu* -
mu)^(2a)`` with the saddle-node's ``a = 1/4`` and ``mu* = 1.8``, and the static level ``~ (mu* -
mu)^(1/2)``, so detections and predictions have exact references.
"""

from __future__ import annotations

import numpy as np

MU_STAR = 1.8
K = 400.0
GAMMA = 0.02
DT = 2e-3
N = 4000


def sigma2_of(mu: float) -> float:
    """The undamped eigenvalue at ``mu`` (1/time^2)."""
    return -K * (MU_STAR - mu) ** 0.5


def record(mu: float, *, n: int = N, dt: float = DT) -> tuple[np.ndarray, np.ndarray]:
    """(t, w) of a noise-free impulse response at ``mu``."""
    t = np.arange(n) * dt
    omega = np.sqrt(-sigma2_of(mu) - GAMMA**2)
    w = 0.05 * (MU_STAR - mu) ** 0.5 + 1e-2 * np.exp(-GAMMA * t) * np.sin(omega * t)
    return t, w
