"""Wire models shared by the API and the SDK: problems (RFC 9457), controls, health."""

from __future__ import annotations

from typing import Annotated, Any

from pydantic import BaseModel, ConfigDict, Field, Strict

PROBLEM_MEDIA_TYPE = "application/problem+json"
PROBLEM_TYPE_PREFIX = "urn:snapwarn:problem:"

Number = Annotated[float, Strict()]
"""A number of a request: a JSON integer or float. ``true``/``false`` and numbers written as
strings are refused (422 naming the field and the value), never read as 1/0: pydantic's lax
mode would accept them. Every numeric field of the request models uses it (or :data:`Integer`);
its JSON schema is a plain ``number`` with the field's bounds."""

Integer = Annotated[int, Strict()]
"""An integer of a request (see :data:`Number`): booleans, strings and floats are refused."""


class FieldError(BaseModel):
    """One invalid input: which field (dotted path, ``w[3]`` for an element), its value, why."""

    field: str = Field(description="Dotted path of the field, e.g. 'w[12]' or 'control.value'.")
    value: Any = Field(default=None, description="The offending value (NaN/inf as strings).")
    message: str


class Problem(BaseModel):
    """An RFC 9457 problem document (``application/problem+json``) with snapwarn extensions."""

    model_config = ConfigDict(extra="allow")

    type: str = Field(default="about:blank", description="URI naming the problem type.")
    title: str
    status: int
    detail: str | None = None
    instance: str | None = None
    errors: list[FieldError] = Field(default_factory=list)


class Control(BaseModel):
    """The control parameter at which a signal was recorded (any quantity, any unit)."""

    name: str = Field(default="mu", max_length=200)
    value: Number | None = None
    unit: str | None = Field(default=None, max_length=100)


class Health(BaseModel):
    """Liveness and readiness of the service."""

    status: str
    version: str
    database: str
    workers: int = Field(description="Job workers seen alive (heartbeat within the lease).")
    numerics: dict[str, bool] = Field(
        default_factory=dict, description="Which numerics entry points are installed."
    )
    ready: bool = Field(
        default=True,
        description="The analysis workers have loaded their numerical kernels (compiled once, "
        "at install; a fresh install without them compiles at start-up). Until then analysis "
        "requests wait up to 60 s, then get 503 with Retry-After.",
    )
