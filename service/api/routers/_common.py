"""Shared bits of the routers: problem responses for the OpenAPI document."""

from __future__ import annotations

from typing import Any

from fastapi.exceptions import RequestValidationError
from pydantic import ValidationError

from service import recordings
from service.schemas.common import PROBLEM_MEDIA_TYPE

#: Largest ``offset`` of a page (an SQL OFFSET beyond 64-bit integers is a database error).
MAX_OFFSET = 1_000_000_000

#: Multipart fields that read a recording file (the signal upload and a live sweep's record).
RECORDING_FORM_FIELDS: dict[str, dict[str, Any]] = {
    "file": {
        "type": "string",
        "format": "binary",
        "description": "CSV with a header, .npy, .npz, .wav or .mat",
    },
    "format": {
        "type": "string",
        "enum": list(recordings.FORMATS),
        "description": "Overrides the file extension.",
    },
    "dt": {"type": "number", "description": "Sampling step when the file has no time."},
    "t0": {"type": "number"},
    "unit": {"type": "string", "description": "Time unit (CSV headers may carry it)."},
    "column": {"type": "string", "description": "Column/variable holding w."},
    "time_column": {"type": "string", "description": "Column/variable holding t."},
    "channel": {"type": "integer", "description": "WAV channel (default 0)."},
    "name": {"type": "string"},
}

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
