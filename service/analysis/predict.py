"""Public door of the predictor: mu* ahead of an upward sweep, with its interval and alarm.

The engine lives in :mod:`service.analysis.predictor` (its ``__init__`` docstring is the map;
docs/predictor.md the ledger); this module keeps the import path every caller uses.
"""

from service.analysis.predictor.paper_rule import PaperRule, paper_rule
from service.analysis.predictor.prediction import Prediction, bounded_by, predict

__all__ = ["PaperRule", "Prediction", "bounded_by", "paper_rule", "predict"]
