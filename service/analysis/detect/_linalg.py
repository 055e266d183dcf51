"""Small dense linear algebra of the detector (Jacobi-scaled pseudo-inverse, Gram solves)."""

from __future__ import annotations

import threading
from collections import OrderedDict

import numpy as np

from service.analysis.detect._kernels import psd_pinv

#: The last pseudo-inverses, by their exact input (shape, ``rcond`` and the matrix's bytes):
#: a detection asks for the same one again and again (measured on a live 1e4-sample record:
#: 62 calls, 45 distinct matrices; the converged fit's Gram returns in the pruning, the mode
#: energies and the next fit's first solve). ``psd_pinv`` is deterministic in its input, so a
#: hit is the same array to the bit.
_PINV: OrderedDict[tuple, np.ndarray] = OrderedDict()
_PINV_MAX = 16
_PINV_LOCK = threading.Lock()


def _pinv_psd(A: np.ndarray, rcond: float = 1e-13) -> np.ndarray:
    """Pseudo-inverse of a symmetric positive semi-definite matrix (Jacobi-scaled, numba)."""
    A = np.ascontiguousarray(A, dtype=float)
    key = (A.shape, float(rcond), A.tobytes())
    with _PINV_LOCK:
        hit = _PINV.get(key)
        if hit is not None:
            _PINV.move_to_end(key)
            return hit.copy()
    out = np.empty_like(A)
    if A.shape[0]:
        psd_pinv(A, rcond, out)
    with _PINV_LOCK:
        _PINV[key] = out.copy()
        while len(_PINV) > _PINV_MAX:
            _PINV.popitem(last=False)
    return out


def _solve_gram(G: np.ndarray) -> tuple[np.ndarray, float]:
    """Linear least squares from the Gram matrix of ``[Phi, y]``: coefficients and RSS."""
    Gpp = G[:-1, :-1]
    gy = G[:-1, -1]
    c = _pinv_psd(Gpp) @ gy
    rss = float(G[-1, -1] - 2.0 * c @ gy + c @ Gpp @ c)
    return c, max(rss, 0.0)
