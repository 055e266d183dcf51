"""Errors of the simulators, as data.

Every bad input to a backend raises :class:`ParameterError` (a ``ValueError``) that carries the
offending parameter's name and value, so that the CLI and the API can name the field without
parsing prose. :class:`SimulationError` is raised when valid inputs have no answer (past a fold,
an unstable or absent equilibrium, a Newton iteration that does not converge); it also names
the parameter that put the scene there (usually ``mu``).
"""

from __future__ import annotations

from typing import Any


class ParameterError(ValueError):
    """A parameter is out of its domain.

    Parameters
    ----------
    parameter : str
        The parameter's name as the caller spelled it (``"mu"``, ``"elements"``, ...).
    value : Any
        The value that was refused (kept as given).
    message : str
        One human sentence; it names the parameter and echoes the value.
    """

    def __init__(self, parameter: str, value: Any, message: str) -> None:
        super().__init__(message)
        self.parameter = parameter
        self.value = value

    def __reduce__(self) -> tuple[Any, ...]:
        # raised in worker processes (job and analysis pools): keep the three arguments
        return (type(self), (self.parameter, self.value, str(self)))


class SimulationError(ParameterError):
    """Valid inputs without an answer: past a fold, no stable equilibrium, no convergence."""
