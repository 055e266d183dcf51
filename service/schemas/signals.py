"""Wire models of recorded signals."""

from __future__ import annotations

from datetime import datetime
from typing import Any

from pydantic import BaseModel, ConfigDict, Field, StrictFloat

from service.schemas.common import Control


class SignalIn(BaseModel):
    """A uniformly sampled record given inline: ``t`` (sample times) or ``dt``, and ``w``.

    Values must be finite; ``t`` strictly increasing and uniformly spaced (timestamps rounded to
    their written digits are accepted: ``dt`` is then their least-squares step); ``t`` and ``w``
    of equal length. The server checks all of it and answers 422 naming the field and the
    value.
    """

    model_config = ConfigDict(extra="forbid")

    w: list[StrictFloat] = Field(
        min_length=2, description="Samples (absolute position at the probe); at least 2."
    )
    t: list[StrictFloat] | None = Field(
        default=None,
        min_length=2,
        description="Sample times (same length as w), within +-1e100.",
    )
    dt: StrictFloat | None = Field(
        default=None, ge=1e-100, le=1e100, description="Sampling step, when t is not given."
    )
    t0: float | None = Field(
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


class SignalMeta(BaseModel):
    """What the server keeps about a stored signal (the samples are at ``/data``)."""

    id: str
    name: str | None = None
    n: int = Field(description="Number of samples.")
    dt: float
    t0: float
    duration: float
    unit: str | None = None
    value_unit: str | None = None
    control: Control | None = None
    metadata: dict[str, Any] = Field(default_factory=dict)
    source: str = Field(description="'json', 'csv', 'npy', 'npz', 'wav', 'mat' or 'simulation'.")
    has_t: bool = Field(description="Whether explicit sample times are stored (else t0 + k dt).")
    sha256: str = Field(description="SHA-256 of the stored little-endian float64 samples.")
    created_at: datetime


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
