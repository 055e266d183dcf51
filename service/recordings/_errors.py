"""Errors of the reader: each names the field and echoes the value."""

from __future__ import annotations

import math
from typing import Any


def _show(value: Any) -> str:
    """A value as it is echoed in a message (short; NaN and infinities spelled out)."""
    if isinstance(value, float) and not math.isfinite(value):
        return repr("NaN" if math.isnan(value) else ("Infinity" if value > 0 else "-Infinity"))
    text = repr(value)
    return text if len(text) <= 200 else text[:200] + "..."


class RecordingError(ValueError):
    """A recording that cannot be read as it is: names the field and echoes the value.

    Parameters
    ----------
    field : str
        The offending input: ``"file"``, ``"dt"``, ``"column"``, ``"t[17]"``, ...
    value : Any
        The refused value (as given, or a short description of it).
    why : str
        What is wrong, in words; the message is ``"<field>: <value> <why>"``.

    Attributes
    ----------
    field, parameter : str
        The same name (``parameter`` as on the numerics' ``ParameterError``).
    value : Any
    """

    def __init__(self, field: str, value: Any, why: str) -> None:
        super().__init__(f"{field}: {_show(value)} {why}")
        self.field = field
        self.parameter = field
        self.value = value
        self.why = why

    def __reduce__(self) -> tuple[Any, ...]:
        # raised in worker processes: keep the three arguments across pickling
        return (type(self), (self.field, self.value, self.why))


class UnsupportedFormat(RecordingError):
    """A file format this reader does not know (HTTP 415)."""


class RecordingTooLarge(RecordingError):
    """More samples than the caller allows (HTTP 413)."""
