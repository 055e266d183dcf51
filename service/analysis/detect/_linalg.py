"""Small dense linear algebra of the detector (Jacobi-scaled pseudo-inverse, Gram solves)."""

from __future__ import annotations

import numpy as np

from service.analysis.detect._kernels import psd_pinv


def _pinv_psd(A: np.ndarray, rcond: float = 1e-13) -> np.ndarray:
    """Pseudo-inverse of a symmetric positive semi-definite matrix (Jacobi-scaled, numba)."""
    A = np.ascontiguousarray(A, dtype=float)
    out = np.empty_like(A)
    if A.shape[0]:
        psd_pinv(A, rcond, out)
    return out


def _solve_gram(G: np.ndarray) -> tuple[np.ndarray, float]:
    """Linear least squares from the Gram matrix of ``[Phi, y]``: coefficients and RSS."""
    Gpp = G[:-1, :-1]
    gy = G[:-1, -1]
    c = _pinv_psd(Gpp) @ gy
    rss = float(G[-1, -1] - 2.0 * c @ gy + c @ Gpp @ c)
    return c, max(rss, 0.0)
