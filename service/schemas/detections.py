"""Wire models of detections: the request and the `snapwarn detect --json` document."""

from __future__ import annotations

from typing import Any

from pydantic import BaseModel, ConfigDict, Field


class DetectionRequest(BaseModel):
    """Detect the modes of a stored signal (``signal_id``) or of an inline one (``w`` + t/dt)."""

    model_config = ConfigDict(extra="forbid")

    signal_id: str | None = None
    w: list[float] | None = None
    t: list[float] | None = None
    dt: float | None = None
    method: str = Field(default="auto", max_length=50)


class DetectionFlag(BaseModel):
    code: str
    message: str


class Detection(BaseModel):
    """The document of ``snapwarn detect --json`` (modes, fundamental, flags...)."""

    model_config = ConfigDict(extra="allow")

    modes: list[dict[str, Any]]
    fundamental: dict[str, Any] | None = None
    flags: list[DetectionFlag] = Field(default_factory=list)
    static_level: float | None = None
    method: str
