"""Errors raised in worker processes come back whole: same class, parameter and value."""

from __future__ import annotations

import pickle

import pytest

from service.analysis.errors import ParameterError as AnalysisParameterError
from service.recordings._errors import RecordingError, RecordingTooLarge, UnsupportedFormat
from sim.cosserat.statics import ConvergenceError
from sim.errors import ParameterError, SimulationError


@pytest.mark.parametrize(
    "exc",
    [
        ParameterError("mu", 1.5, "mu=1.5: out of range"),
        SimulationError("mu", 1.79, "mu=1.79 is past the fold at 1.7818"),
        AnalysisParameterError("dt", -1.0, "dt=-1.0: must be > 0"),
        ConvergenceError("Newton did not converge at mu=1.9", 1.9),
        RecordingError("t[17]", 0.5, "is not uniformly sampled"),
        UnsupportedFormat("file", "x.xyz", "has an unknown format"),
        RecordingTooLarge("w", 10**9, "has too many samples"),
    ],
)
def test_errors_pickle_round_trip(exc: Exception) -> None:
    back = pickle.loads(pickle.dumps(exc))
    assert type(back) is type(exc)
    assert str(back) == str(exc)
    assert back.parameter == exc.parameter  # type: ignore[attr-defined]
    assert back.value == exc.value  # type: ignore[attr-defined]
