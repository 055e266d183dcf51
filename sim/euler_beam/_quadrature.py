"""Gauss-Legendre quadrature on [0, 1] shared by the beam's statics and the normal form."""

from __future__ import annotations

import numpy as np

_QN = 96  # nodes: exact to round-off for |Lambda| < ~40
_XQ, _WQ = np.polynomial.legendre.leggauss(_QN)
_XQ = 0.5 * (_XQ + 1.0)
_WQ = 0.5 * _WQ

XQ, WQ = _XQ, _WQ  # public names
