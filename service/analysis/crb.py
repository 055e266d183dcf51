"""Cramer-Rao bounds for damped modes in white Gaussian noise, and the matching synthesiser.

Shared by the detector's tests and ``bench/detector.py``. The model is written in the
classical parametrisation (amplitude, phase, angular frequency, decay rate for an underdamped
mode; two amplitudes and two decay rates for an overdamped one), independently of the
detector's internal ``(p, q)`` parametrisation, so that the bound is an independent reference::

    w(t) = c + sum_k a_k exp(-gamma_k t) cos(omega_k t + phi_k)
             + sum_j [b1_j exp(-r1_j t) + b2_j exp(-r2_j t)] + noise,   noise ~ N(0, noise_std^2)

The bound on any function ``g`` of the parameters is ``grad(g)^T F^-1 grad(g)`` with the
Fisher information ``F = J^T J / noise_std^2`` (``J`` the Jacobian of the noise-free samples).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Underdamped:
    """An underdamped mode ``amplitude * exp(-damping t) * cos(omega t + phase)``.

    Attributes
    ----------
    omega : float
        Angular frequency, rad per time unit.
    damping : float
        Decay rate ``gamma``, 1 per time unit (pole ``s = -gamma +- i omega``).
    amplitude : float
        Initial amplitude, units of the record.
    phase : float
        Phase at ``t = 0``, rad.
    """

    omega: float
    damping: float
    amplitude: float
    phase: float = 0.0

    @property
    def sigma2(self) -> float:
        """Undamped eigenvalue ``-s1 s2 = -(gamma^2 + omega^2)``."""
        return -(self.damping**2 + self.omega**2)


@dataclass(frozen=True)
class Overdamped:
    """An overdamped mode ``b1 exp(-r1 t) + b2 exp(-r2 t)`` (two real poles ``-r1, -r2``).

    With ``gamma = (r1 + r2) / 2`` and ``delta = (r2 - r1) / 2``: ``sigma^2 = -r1 r2``.
    """

    rate_slow: float
    rate_fast: float
    amplitude_slow: float
    amplitude_fast: float

    @property
    def damping(self) -> float:
        return 0.5 * (self.rate_slow + self.rate_fast)

    @property
    def sigma2(self) -> float:
        return -self.rate_slow * self.rate_fast

    @staticmethod
    def kicked(sigma2: float, xi: float, velocity: float) -> Overdamped:
        """Impulse response ``x(0) = 0, x'(0) = velocity`` of ``x'' + xi x' - sigma2 x = 0``."""
        disc = 0.25 * xi * xi + sigma2
        if disc <= 0:
            raise ValueError(f"sigma2={sigma2!r}, xi={xi!r}: the mode is not overdamped")
        lam = np.sqrt(disc)
        r1, r2 = 0.5 * xi - lam, 0.5 * xi + lam
        b = velocity / (r2 - r1)
        return Overdamped(float(r1), float(r2), float(b), float(-b))


ModeSpec = Underdamped | Overdamped


def synthesize(t: np.ndarray, modes: Sequence[ModeSpec], static_level: float = 0.0) -> np.ndarray:
    """Noise-free record ``w(t)`` of ``modes`` on top of ``static_level``.

    Parameters
    ----------
    t : ndarray, shape (N,)
        Sample times (time units of the record).
    modes : sequence of Underdamped or Overdamped
    static_level : float
        Constant offset (the equilibrium deflection).

    Returns
    -------
    ndarray, shape (N,)
    """
    t = np.asarray(t, dtype=float)
    w = np.full_like(t, float(static_level))
    for m in modes:
        if isinstance(m, Underdamped):
            w += m.amplitude * np.exp(-m.damping * t) * np.cos(m.omega * t + m.phase)
        else:
            w += m.amplitude_slow * np.exp(-m.rate_slow * t)
            w += m.amplitude_fast * np.exp(-m.rate_fast * t)
    return w


@dataclass(frozen=True)
class CRB:
    """Cramer-Rao standard deviations (square roots of the bounds), one entry per mode.

    ``omega_std`` is 0 for an overdamped mode's omega (not a parameter there); for an
    overdamped mode ``damping`` is ``(r1 + r2)/2``. ``fisher`` and ``names`` give the full
    information matrix in the classical parametrisation.
    """

    omega_std: np.ndarray
    frequency_std: np.ndarray
    damping_std: np.ndarray
    sigma2_std: np.ndarray
    static_level_std: float
    fisher: np.ndarray
    names: tuple[str, ...]


def crb(
    t: np.ndarray,
    modes: Sequence[ModeSpec],
    noise_std: float,
    *,
    static: bool = True,
    common_damping: bool = False,
) -> CRB:
    """Cramer-Rao bounds on each mode's omega, damping and sigma^2.

    Parameters
    ----------
    t : ndarray, shape (N,)
        Sample times.
    modes : sequence of Underdamped or Overdamped
        True parameters.
    noise_std : float
        Standard deviation of the white Gaussian noise (units of the record).
    static : bool
        Whether the static level is an unknown parameter (the detector estimates it).
    common_damping : bool
        Whether all modes share one ``gamma`` (the detector's ``common_damping=True``; for
        an overdamped mode ``gamma = (r1 + r2)/2``).

    Returns
    -------
    CRB
    """
    t = np.asarray(t, dtype=float)
    if not noise_std > 0:
        raise ValueError(f"noise_std={noise_std!r}: must be > 0")
    J, names, layout = _jacobian(t, modes, static=static, common_damping=common_damping)
    fisher = J.T @ J / noise_std**2
    scale = np.sqrt(np.diag(fisher))
    scale[scale == 0] = 1.0
    cov = np.linalg.pinv(fisher / np.outer(scale, scale), rcond=1e-15) / np.outer(scale, scale)
    om, ga, s2 = _mode_bounds(modes, layout, cov)
    st = float(np.sqrt(cov[0, 0])) if static else 0.0
    return CRB(om, om / (2 * np.pi), ga, s2, st, fisher, tuple(names))


def _jacobian(
    t: np.ndarray, modes: Sequence[ModeSpec], *, static: bool, common_damping: bool
) -> tuple[np.ndarray, list[str], list[dict[str, int]]]:
    """Columns d(response)/d(parameter) of the modal model at the true parameters.

    Returns the Jacobian (N, P), the parameter names and, per mode, the column index of each
    of its parameters (``gamma`` shared by all modes when ``common_damping``).
    """
    cols: list[np.ndarray] = []
    names: list[str] = []
    gamma_cols: list[np.ndarray] = []
    # index of (omega, gamma-or-delta) per mode in the final parameter vector
    layout: list[dict[str, int]] = []
    if static:
        cols.append(np.ones_like(t))
        names.append("static_level")
    for k, m in enumerate(modes):
        idx: dict[str, int] = {}
        if isinstance(m, Underdamped):
            e = np.exp(-m.damping * t)
            c = np.cos(m.omega * t + m.phase)
            s = np.sin(m.omega * t + m.phase)
            for name, col in (
                ("amplitude", e * c),
                ("phase", -m.amplitude * e * s),
                ("omega", -m.amplitude * t * e * s),
            ):
                idx[name] = len(cols)
                cols.append(col)
                names.append(f"{name}[{k}]")
            g = -m.amplitude * t * e * c
        else:
            # r1 = gamma - delta, r2 = gamma + delta
            e1 = np.exp(-m.rate_slow * t)
            e2 = np.exp(-m.rate_fast * t)
            d1 = -m.amplitude_slow * t * e1  # d/dr1
            d2 = -m.amplitude_fast * t * e2  # d/dr2
            for name, col in (("b1", e1), ("b2", e2), ("delta", -d1 + d2)):
                idx[name] = len(cols)
                cols.append(col)
                names.append(f"{name}[{k}]")
            g = d1 + d2
        if common_damping:
            gamma_cols.append(g)
        else:
            idx["gamma"] = len(cols)
            cols.append(g)
            names.append(f"gamma[{k}]")
        layout.append(idx)
    if common_damping and gamma_cols:
        gidx = len(cols)
        cols.append(np.sum(gamma_cols, axis=0))
        names.append("gamma")
        for idx in layout:
            idx["gamma"] = gidx
    return np.column_stack(cols), names, layout


def _mode_bounds(
    modes: Sequence[ModeSpec], layout: list[dict[str, int]], cov: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per-mode bounds on omega, damping and sigma^2 (delta method) from the covariance."""
    n = len(modes)
    om = np.zeros(n)
    ga = np.zeros(n)
    s2 = np.zeros(n)
    for k, (m, idx) in enumerate(zip(modes, layout, strict=True)):
        ig = idx["gamma"]
        ga[k] = np.sqrt(cov[ig, ig])
        if isinstance(m, Underdamped):
            io = idx["omega"]
            om[k] = np.sqrt(cov[io, io])
            # sigma2 = -(gamma^2 + omega^2)
            grad = np.zeros(cov.shape[0])
            grad[ig] = -2 * m.damping
            grad[io] += -2 * m.omega
        else:
            idl = idx["delta"]
            gam = m.damping
            dl = 0.5 * (m.rate_fast - m.rate_slow)
            # sigma2 = -(gamma^2 - delta^2)
            grad = np.zeros(cov.shape[0])
            grad[ig] = -2 * gam
            grad[idl] += 2 * dl
        s2[k] = np.sqrt(max(grad @ cov @ grad, 0.0))
    return om, ga, s2
