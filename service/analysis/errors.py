"""Errors of the analysis layer, as data.

:class:`ParameterError` (a ``ValueError``) carries ``.parameter`` and ``.value`` so that the CLI
and the API name the field without parsing prose. It mirrors :class:`sim.errors.ParameterError`
(the analysis layer may not be the one that imports ``sim``), with the same attributes; callers
that handle both catch ``ValueError`` and read the attributes.
"""

from __future__ import annotations

from typing import Any


class ParameterError(ValueError):
    """A parameter of an analysis call is out of its domain.

    Parameters
    ----------
    parameter : str
        The parameter's name as the caller spelled it (``"dt"``, ``"method"``, ``"mu"``...).
    value : Any
        The value that was refused (kept as given; may be an array summary for big inputs).
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
