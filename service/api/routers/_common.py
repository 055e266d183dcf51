"""Shared bits of the routers: problem responses for the OpenAPI document."""

from __future__ import annotations

from typing import Any

from fastapi.exceptions import RequestValidationError
from pydantic import ValidationError

from service.schemas.common import PROBLEM_MEDIA_TYPE

#: Largest ``offset`` of a page (an SQL OFFSET beyond 64-bit integers is a database error).
MAX_OFFSET = 1_000_000_000

_PROBLEM = {"content": {PROBLEM_MEDIA_TYPE: {"schema": {"$ref": "#/components/schemas/Problem"}}}}


def problems(*codes: int) -> dict[int | str, dict[str, Any]]:
    """``responses=`` entries documenting problem answers for ``codes``."""
    text = {
        401: "Missing or wrong API key.",
        404: "No such resource.",
        409: "The resource is not in a state that allows this.",
        413: "Payload over the limits (settings).",
        415: "Unsupported media type or file format.",
        422: "Invalid input: the field and the value are named.",
        429: "Too many queued or running jobs of this owner (settings); retry later.",
        501: "The numerics this resource needs are not installed yet.",
    }
    return {c: {"description": text.get(c, "Error."), **_PROBLEM} for c in codes}


def body_validation_error(exc: ValidationError) -> RequestValidationError:
    """A pydantic error on a body parsed by hand, as FastAPI's own (``loc`` under "body")."""
    errs = []
    for e in exc.errors():
        e = dict(e)
        e["loc"] = ("body", *e.get("loc", ()))
        errs.append(e)
    return RequestValidationError(errs)
