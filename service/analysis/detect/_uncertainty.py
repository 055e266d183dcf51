"""Honest standard errors on a lab window: the sandwich covariance of the fitted modes.

The fit's standard errors are the Gauss-Newton ones, ``s^2 (J^T J)^-1``: right when the
residual is white noise of one variance and every sample is an observation. A lab window
breaks both: what the free-decay model cannot hold (the hammer's contact at its head, a
drift's wobble, a hum harmonic left in, a later kick's foot) stays in the residual as a
misfit that is neither white nor of one size, and a clipped sample replaced by its expected
value beyond the range (:mod:`._censored`) is no observation, yet counts as one in ``J^T J``.

The sandwich (Huber 1967, White 1980) gives the covariance of a least-squares estimate whatever
the residual's size and colour::

    C = B^-1 M B^-1,   B = J^T J,   M = sum_b g_b g_b^T,   g_b = sum_{i in block b} J_i r_i,

with ``J`` the Jacobian of the fitted waveform (every mode's amplitude, phase, decay rate and
frequency, or an overdamped pair's two amplitudes and two rates, plus a level and a slope) and
``r`` the residual, summed over contiguous blocks (the cluster-robust meat: a residual
correlated within a block, a misfit's or a coloured noise's, counts with its correlation). The
clipped samples' rows are left out (no observation: the estimate is as good as one without
them, a bound on the side of caution). Each mode's standard errors are then multiplied by
``sqrt(C_kk / C0_kk)``, ``C0 = s^2 B0^-1`` the Gauss-Newton covariance of the same
parametrisation over every sample, when that ratio exceeds 1: the reported errors never
shrink below the fit's own (a sandwich estimated from one record scatters; for a white residual
its ratio is near 1).
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from service.analysis.detect._results import Mode

#: The meat's blocks: the window cut in this many contiguous blocks (at least BLOCK_MIN
#: samples each). A block as long as a misfit's or a coloured noise's correlation counts it;
#: more blocks make the meat's own scatter smaller (measured on lab records of known truth,
#: 16 to 256 blocks give the same coverage within 2 %).
BLOCKS, BLOCK_MIN = 64, 8
#: Block lags of the meat's Bartlett weights.
LAGS = 1


def _columns(m: Mode, u: np.ndarray) -> tuple[np.ndarray, ...]:
    """The mode's Jacobian columns at the times ``u`` and the gradient map: for an underdamped
    mode ``d/dA, d/dphase, d/dgamma, d/domega`` of ``A e^{-gamma u} cos(omega u + phase)``, for
    an overdamped one ``d/db1, d/db2, d/ds1, d/ds2`` of ``b1 e^{s1 u} + b2 e^{s2 u}``."""
    with np.errstate(over="ignore", invalid="ignore"):
        if m.regime == "overdamped" and m.real_poles is not None and m.real_amplitudes:
            (s1, s2), (b1, b2) = m.real_poles, m.real_amplitudes
            e1 = np.exp(np.minimum(s1 * u, 700.0))
            e2 = np.exp(np.minimum(s2 * u, 700.0))
            return e1, e2, b1 * u * e1, b2 * u * e2
        env = np.exp(np.minimum(-m.damping * u, 700.0))
        c = env * np.cos(m.omega * u + m.phase)
        s = env * np.sin(m.omega * u + m.phase)
        return c, -m.amplitude * s, -m.amplitude * u * c, -m.amplitude * u * s


def _gradients(m: Mode) -> dict[str, np.ndarray]:
    """Gradients of the reported quantities in the mode's 4 parameters (:func:`_columns`)."""
    if m.regime == "overdamped" and m.real_poles is not None and m.real_amplitudes:
        (s1, s2), (b1, b2) = m.real_poles, m.real_amplitudes
        big = 0 if abs(b1) >= abs(b2) else 1
        amp = np.zeros(4)
        amp[big] = 1.0
        return {
            "sigma2": np.array([0.0, 0.0, -s2, -s1]),  # sigma^2 = -s1 s2
            "damping": np.array([0.0, 0.0, -0.5, -0.5]),  # mean decay rate
            "amplitude": amp,
        }
    return {
        "sigma2": np.array([0.0, 0.0, -2.0 * m.damping, -2.0 * m.omega]),
        "damping": np.array([0.0, 0.0, 1.0, 0.0]),
        "omega": np.array([0.0, 0.0, 0.0, 1.0]),
        "amplitude": np.array([1.0, 0.0, 0.0, 0.0]),
    }


def inflation(
    modes: list[Mode], residual: np.ndarray, dt: float, noise_std: float,
    censored: np.ndarray | None = None,
) -> list[dict[str, float]]:  # fmt: skip
    """Per mode, the factors (>= 1) that turn its Gauss-Newton standard errors into the
    sandwich's (module docstring): keys ``sigma2``, ``damping``, ``omega`` (underdamped
    only), ``amplitude``. ``residual``: the window less the fitted model; ``censored``: the
    window's clipped samples (boolean mask) or None. All 1 when the sandwich cannot be formed
    (too few samples for the parameters, a non-finite column)."""
    n = residual.size
    ones = [{k: 1.0 for k in _gradients(m)} for m in modes]
    P = 4 * len(modes) + 2
    if not modes or n < 4 * P or not (noise_std > 0 and math.isfinite(noise_std)):
        return ones
    u = np.arange(n, dtype=float) * dt
    cols = [np.ones(n), (u - u.mean()) / max(float(u[-1]), dt)]
    for m in modes:
        cols += list(_columns(m, u))
    J = np.column_stack(cols)
    if not np.all(np.isfinite(J)):
        return ones
    norm = np.linalg.norm(J, axis=0)
    norm[norm == 0] = 1.0
    J = J / norm
    B0 = J.T @ J
    keep = np.ones(n, dtype=bool) if censored is None else ~censored
    Jk = J[keep]
    B = Jk.T @ Jk
    L = max(BLOCK_MIN, n // BLOCKS)
    nb = n // L
    # the blocks' scores J_b^T r_b (the last block takes the remainder)
    h = (J * (residual * keep)[:, None])[: nb * L].reshape(nb, L, P).sum(axis=1)
    h[-1] += (J[nb * L :] * (residual[nb * L :] * keep[nb * L :])[:, None]).sum(axis=0)
    # Bartlett weights over the block lags (Newey and West 1987, on the blocks): a correlation
    # across a block's edge counts too, the meat stays positive semi-definite
    M = h.T @ h
    for lag in range(1, LAGS + 1):
        c = h[lag:].T @ h[:-lag]
        M += (1.0 - lag / (LAGS + 1)) * (c + c.T)
    try:
        B0i = np.linalg.pinv(B0, rcond=1e-12, hermitian=True)
        Bi = np.linalg.pinv(B, rcond=1e-12, hermitian=True)
    except np.linalg.LinAlgError:
        return ones
    C = Bi @ M @ Bi
    C0 = B0i * noise_std**2
    out = []
    for k, m in enumerate(modes):
        sl = slice(2 + 4 * k, 6 + 4 * k)
        f = {}
        for key, grad in _gradients(m).items():
            gr = grad / norm[sl]  # the columns were scaled: parameters in scaled units
            v0 = float(gr @ C0[sl, sl] @ gr)
            v = float(gr @ C[sl, sl] @ gr)
            f[key] = math.sqrt(v / v0) if v0 > 0 and v > v0 and math.isfinite(v) else 1.0
        out.append(f)
    return out


def inflated(m: Mode, f: dict[str, float]) -> Mode:
    """The mode with its standard errors multiplied by the factors ``f`` (:func:`inflation`)."""
    return replace(
        m,
        sigma2_std=m.sigma2_std * f.get("sigma2", 1.0),
        damping_std=m.damping_std * f.get("damping", 1.0),
        omega_std=m.omega_std * f.get("omega", f.get("sigma2", 1.0)),
        amplitude_std=m.amplitude_std * f.get("amplitude", 1.0),
    )
