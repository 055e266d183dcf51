"""Public door of the classification: the transition's type ahead of an upward sweep.

The engine lives in :mod:`service.analysis.predictor` (its ``__init__`` docstring is the map);
this module keeps the import path every caller uses.
"""

from service.analysis.predictor.classification import (
    CANDIDATES,
    MIN_T_RATIO,
    REGIMES,
    TRANSITIONS,
    Classification,
    classify,
    classify_sweep,
)
from service.analysis.predictor.sweep import Sweep, prepare_sweep

__all__ = [
    "CANDIDATES",
    "MIN_T_RATIO",
    "REGIMES",
    "TRANSITIONS",
    "Classification",
    "Sweep",
    "classify",
    "classify_sweep",
    "prepare_sweep",
]
