"""The exception every layer of the service raises to answer with a problem document.

Plain Python (no FastAPI), so that it can cross process boundaries (pickling) and be raised
from job runners alike; ``service.api.errors`` turns it into RFC 9457 JSON. The errors of the
layers below carry their field as data (``RecordingError``, the numerics' ``ParameterError``);
:func:`problem_from` maps them, in this one place.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

from service.analysis.errors import ParameterError as AnalysisParameterError
from service.recordings import RecordingError, RecordingTooLarge, UnsupportedFormat
from service.schemas.common import PROBLEM_TYPE_PREFIX
from sim.errors import ParameterError as SimParameterError

TITLES = {
    400: "Bad request",
    401: "Unauthorized",
    404: "Not found",
    405: "Method not allowed",
    409: "Conflict",
    413: "Payload too large",
    415: "Unsupported media type",
    422: "Invalid input",
    500: "Internal error",
    501: "Not implemented",
    503: "Service unavailable",
}

SLUGS = {
    400: "bad-request",
    401: "unauthorized",
    404: "not-found",
    405: "method-not-allowed",
    409: "conflict",
    413: "payload-too-large",
    415: "unsupported-media-type",
    422: "invalid-input",
    500: "internal-error",
    501: "not-implemented",
    503: "unavailable",
}


def wire_value(value: Any) -> Any:
    """A value as it can appear in strict JSON: NaN/inf become strings, big lists are cut."""
    if isinstance(value, float) and not math.isfinite(value):
        return "NaN" if math.isnan(value) else ("Infinity" if value > 0 else "-Infinity")
    if isinstance(value, (list, tuple)):
        if len(value) > 10:
            return f"<{type(value).__name__} of {len(value)} items>"
        return [wire_value(v) for v in value]
    if isinstance(value, dict):
        if len(value) > 20:
            return f"<object with {len(value)} keys>"
        return {str(k): wire_value(v) for k, v in value.items()}
    if isinstance(value, bytes):
        return f"<{len(value)} bytes>"
    if isinstance(value, str) and len(value) > 200:
        return value[:200] + "..."
    if value is None or isinstance(value, (bool, int, float, str)):
        return value
    try:  # numpy scalars and friends
        return wire_value(value.item())
    except Exception:  # noqa: BLE001
        return repr(value)[:200]


class ApiProblem(Exception):
    """An error answered as ``application/problem+json``.

    ``field`` and ``value`` name the offending input (also listed in ``errors``).
    """

    def __init__(
        self,
        status: int,
        detail: str,
        *,
        field: str | None = None,
        value: Any = None,
        title: str | None = None,
        slug: str | None = None,
        errors: list[dict[str, Any]] | None = None,
        headers: dict[str, str] | None = None,
    ) -> None:
        super().__init__(status, detail)
        self.status = int(status)
        self.detail = detail
        self.title = title or TITLES.get(self.status, "Error")
        self.type = PROBLEM_TYPE_PREFIX + (slug or SLUGS.get(self.status, "error"))
        self.errors = list(errors or [])
        if field is not None and not self.errors:
            self.errors.append({"field": field, "value": wire_value(value), "message": detail})
        self.headers = headers or {}

    def __reduce__(self) -> Any:  # picklable across the process pool
        return (_rebuild, (self.status, self.detail, self.title, self.type, self.errors))

    def to_dict(self, instance: str | None = None) -> dict[str, Any]:
        doc: dict[str, Any] = {
            "type": self.type,
            "title": self.title,
            "status": self.status,
            "detail": self.detail,
        }
        if instance is not None:
            doc["instance"] = instance
        if self.errors:
            doc["errors"] = self.errors
        return doc


def _rebuild(status: int, detail: str, title: str, type_: str, errors: list) -> ApiProblem:
    p = ApiProblem(status, detail, title=title, errors=errors)
    p.type = type_
    return p


def invalid(field: str, value: Any, why: str) -> ApiProblem:
    """422 naming the field and echoing the value: ``w[3]: NaN must be finite``."""
    return ApiProblem(422, f"{field}: {wire_value(value)!r} {why}", field=field, value=value)


def too_large(field: str, value: Any, why: str) -> ApiProblem:
    return ApiProblem(413, f"{field}: {why}", field=field, value=value)


def not_found(kind: str, ident: str) -> ApiProblem:
    return ApiProblem(404, f"no {kind} with id {ident!r}", field="id", value=ident)


def problem_from(exc: BaseException, default_field: str | None = None) -> ApiProblem | None:
    """The problem answering an error that carries its field as data, else None.

    - :class:`~service.recordings.RecordingError`: 415 (format), 413 (too large), else 422,
      with its ``.field`` and ``.value``;
    - ``sim.errors.ParameterError`` and ``service.analysis.errors.ParameterError`` (their
      subclasses too: ``SimulationError``, ``SceneError``...): 422 with ``.parameter`` and
      ``.value``;
    - with ``default_field``, any other ``ValueError`` of the numerics: 422 naming the input
      of the door that was called (never a word guessed from the message).
    """
    if isinstance(exc, ApiProblem):
        return exc
    if isinstance(exc, RecordingError):
        status = 415 if isinstance(exc, UnsupportedFormat) else 422
        status = 413 if isinstance(exc, RecordingTooLarge) else status
        return ApiProblem(status, str(exc), field=exc.field, value=exc.value)
    if isinstance(exc, (SimParameterError, AnalysisParameterError)):
        return ApiProblem(422, str(exc), field=exc.parameter, value=exc.value)
    if default_field is not None and isinstance(exc, ValueError):
        return ApiProblem(422, str(exc), field=default_field, value=None)
    return None


@contextmanager
def as_problems(default_field: str | None = None) -> Iterator[None]:
    """Raise the errors of a numerics call as :class:`ApiProblem` (see :func:`problem_from`).

    Used around calls that run in worker processes: a problem pickles, while the numerics'
    errors (constructed with several arguments) do not cross a process boundary intact.
    """
    try:
        yield
    except Exception as exc:
        problem = problem_from(exc, default_field)
        if problem is None or problem is exc:
            raise
        raise problem from None
