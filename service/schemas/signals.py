"""Wire models of recorded signals."""

from __future__ import annotations

from collections.abc import Mapping
from datetime import datetime
from typing import Annotated, Any

from pydantic import (
    BaseModel,
    ConfigDict,
    Discriminator,
    Field,
    Tag,
    ValidationError,
    model_validator,
)

from service.schemas.common import Control, Number
from service.schemas.sim import SimulationMetadata


class SignalIn(BaseModel):
    """A uniformly sampled record given inline: ``t`` (sample times) or ``dt``, and ``w``.

    Values must be finite; ``t`` strictly increasing and uniformly spaced (timestamps rounded to
    their written digits are accepted: ``dt`` is then their least-squares step); ``t`` and ``w``
    of equal length. The server checks all of it and answers 422 naming the field and the
    value.
    """

    model_config = ConfigDict(extra="forbid")

    w: list[Number] = Field(
        min_length=2, description="Samples (absolute position at the probe); at least 2."
    )
    t: list[Number] | None = Field(
        default=None,
        min_length=2,
        description="Sample times (same length as w), within +-1e100.",
    )
    dt: Number | None = Field(
        default=None, ge=1e-100, le=1e100, description="Sampling step, when t is not given."
    )
    t0: Number | None = Field(
        default=None, ge=-1e100, le=1e100, description="Time of the first sample (with dt)."
    )
    unit: str | None = Field(default=None, max_length=100, description="Time unit, e.g. 's'.")
    value_unit: str | None = Field(default=None, max_length=100, description="Unit of w.")
    control: Control | None = None
    metadata: dict[str, Any] = Field(default_factory=dict)
    name: str | None = Field(default=None, max_length=500)
    resample: bool = Field(
        default=False,
        description="Interpolate non-uniform sample times onto a uniform grid (else 422).",
    )


def _metadata_kind(value: Any) -> str:
    return "simulation" if isinstance(value, SimulationMetadata) else "data"


def _any_of(schema: dict[str, Any]) -> None:
    # a simulation's document is an object too: either may match, so anyOf (oneOf would not
    # hold for a simulation's metadata)
    schema["anyOf"] = schema.pop("oneOf")


Metadata = Annotated[
    Annotated[SimulationMetadata, Tag("simulation")] | Annotated[dict[str, Any], Tag("data")],
    Discriminator(_metadata_kind),
]
"""A signal's metadata: typed for a simulated signal, the uploader's own JSON object
otherwise."""


class SignalMeta(BaseModel):
    """What the server keeps about a stored signal (the samples are at ``/data``).

    ``metadata`` is a :class:`~service.schemas.sim.SimulationMetadata` for a simulated signal
    (``source`` 'simulation'; :attr:`simulation` gives it or ``None``) and the uploader's own
    JSON object otherwise. A simulated signal stored in a form the model does not read (an
    older server's) is served as stored.
    """

    id: str
    name: str | None = None
    n: int = Field(description="Number of samples.")
    dt: float
    t0: float
    duration: float
    unit: str | None = None
    value_unit: str | None = None
    control: Control | None = None
    metadata: Metadata = Field(
        default_factory=dict,
        description="A simulated signal's scene, backend and the backend's report "
        "(SimulationMetadata); for an upload, the uploader's JSON object (plus the reader's "
        "notes: 'recording_flags', and 'file' for a file).",
        json_schema_extra=_any_of,
    )
    source: str = Field(description="'json', 'csv', 'npy', 'npz', 'wav', 'mat' or 'simulation'.")
    has_t: bool = Field(description="Whether explicit sample times are stored (else t0 + k dt).")
    sha256: str = Field(description="SHA-256 of the stored little-endian float64 samples.")
    created_at: datetime

    @model_validator(mode="before")
    @classmethod
    def _typed_simulation(cls, data: Any) -> Any:
        """A simulated signal's metadata as :class:`SimulationMetadata` (kept as stored when
        it does not read as one)."""
        if not isinstance(data, Mapping) or data.get("source") != "simulation":
            return data
        meta = data.get("metadata")
        if not isinstance(meta, Mapping):
            return data
        try:
            typed = SimulationMetadata.model_validate(meta)
        except ValidationError:
            return data
        return {**data, "metadata": typed}

    @property
    def simulation(self) -> SimulationMetadata | None:
        """The typed metadata of a simulated signal (``None`` for an upload)."""
        return self.metadata if isinstance(self.metadata, SimulationMetadata) else None


class SignalData(BaseModel):
    """The samples of a stored signal, exactly as stored (float64 round-trips through JSON)."""

    id: str
    t: list[float]
    w: list[float]
    dt: float
    unit: str | None = None
    value_unit: str | None = None


class SignalPage(BaseModel):
    """A page of stored signals, newest first."""

    items: list[SignalMeta]
    total: int
    limit: int
    offset: int
