"""Wire models of detections: the request (the document is ``analysis.Detection``)."""

from __future__ import annotations

from typing import Literal

from pydantic import BaseModel, ConfigDict, Field

from service.schemas.analysis import Detection, Flag, Quantity
from service.schemas.common import Number


class DetectionRequest(BaseModel):
    """Detect the modes of a stored signal (``signal_id``) or of an inline one (``w`` + t/dt)."""

    model_config = ConfigDict(extra="forbid")

    signal_id: str | None = None
    w: list[Number] | None = Field(default=None, min_length=2)
    t: list[Number] | None = Field(default=None, min_length=2)
    dt: Number | None = Field(default=None, ge=1e-100, le=1e100)
    method: Literal["auto", "varpro", "esprit", "fft", "fft-parabolic"] = Field(
        default="auto", description="Detector method ('auto' resolves to 'varpro')."
    )
    quantity: Quantity | None = Field(
        default=None,
        description="What the record measures (displacement, velocity, acceleration); "
        "default: read from the stored signal's value unit (mm, mm/s, m/s2, g), else a "
        "displacement. Poles come from any; the static level only from a displacement.",
    )
    start: Number | None = Field(
        default=None, ge=0,
        description="Time (from the first sample, the record's time unit) where the free "
        "response starts; default: the kick is located (after a pre-trigger, the hammer's "
        "contact).",
    )  # fmt: skip
    notch: list[Number] | None = Field(
        default=None, max_length=16,
        description="Frequencies (cycles per time unit of the record, e.g. 50 Hz and its "
        "harmonics) of stationary lines: fitted as lines, never the fundamental. Default: "
        "lines present before the kick or not decaying are found.",
    )  # fmt: skip

    def detect_options(self) -> dict:
        """The lab options as keyword arguments of ``detect`` (None ones left out)."""
        opts = {"quantity": self.quantity, "start": self.start, "notch": self.notch}
        return {k: v for k, v in opts.items() if v is not None}


DetectionFlag = Flag  # the flag of any result (kept under its older name)

__all__ = ["Detection", "DetectionFlag", "DetectionRequest"]
