"""Wire models of detections: the request (the document is ``analysis.Detection``)."""

from __future__ import annotations

from typing import Literal

from pydantic import BaseModel, ConfigDict, Field, StrictFloat

from service.schemas.analysis import Detection, Flag


class DetectionRequest(BaseModel):
    """Detect the modes of a stored signal (``signal_id``) or of an inline one (``w`` + t/dt)."""

    model_config = ConfigDict(extra="forbid")

    signal_id: str | None = None
    w: list[StrictFloat] | None = Field(default=None, min_length=2)
    t: list[StrictFloat] | None = Field(default=None, min_length=2)
    dt: StrictFloat | None = Field(default=None, ge=1e-100, le=1e100)
    method: Literal["auto", "varpro", "esprit", "fft", "fft-parabolic"] = Field(
        default="auto", description="Detector method ('auto' resolves to 'varpro')."
    )


DetectionFlag = Flag  # the flag of any result (kept under its older name)

__all__ = ["Detection", "DetectionFlag", "DetectionRequest"]
