"""Wire models of sweeps: measurements at increasing control values -> type, mu*, alarm."""

from __future__ import annotations

from datetime import datetime
from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field

from service.schemas.analysis import (
    Alarm,
    Classification,
    Measurement,
    Prediction,
    Quantity,
    SweepResult,
)
from service.schemas.common import Integer, Number
from service.schemas.jobs import Job
from service.schemas.live import LiveControl, LiveOptions
from service.schemas.simulations import Actuation, Model


class SweepMeasurement(BaseModel):
    """A stored signal and the control value it was recorded at (default: its own control)."""

    model_config = ConfigDict(extra="forbid")

    signal_id: str
    control_value: Number | None = None
    quantity: Quantity | None = Field(
        default=None, description="What the record measures (default: its value unit says, "
        "else a displacement); the static level only from a displacement.")  # fmt: skip
    start: Number | None = Field(
        default=None, ge=0, description="Time from the record's first sample where its free "
        "response starts (default: the kick is located).")  # fmt: skip
    notch: list[Number] | None = Field(
        default=None, max_length=16, description="Frequencies of stationary lines in this record "
        "(cycles per time unit; default: the sweep's notch, else found).")  # fmt: skip
    exclude: bool = Field(
        default=False, description="Leave this record out (listed as set aside, 'excluded by "
        "the user').")  # fmt: skip

    def detect_options(self, notch: list[float] | None = None) -> dict[str, Any]:
        """The detector's options of this record (``notch``: the sweep's, when it has none)."""
        opts = {"quantity": self.quantity, "start": self.start, "notch": self.notch or notch,
                "exclude": self.exclude or None}  # fmt: skip
        return {k: v for k, v in opts.items() if v is not None}


class SimulatedSweep(BaseModel):
    """The warn pipeline on simulated impulse responses (``snapwarn warn``)."""

    model_config = ConfigDict(extra="forbid")

    actuation: Actuation = "asymmetric"
    model: Model | None = Field(default=None, description="Simulator (pipeline default).")
    damping: Number | None = Field(default=None, ge=0)
    snr_db: Number | None = None
    seed: Integer | None = None
    max_measurements: Integer | None = Field(default=None, ge=5, le=200)


class SweepRequest(BaseModel):
    """Exactly one of ``measurements`` (recorded signals) or ``simulate``; or ``"mode": "live"``
    (an open sweep that records are added to one by one, see ``service.schemas.live``)."""

    model_config = ConfigDict(extra="forbid")

    measurements: list[SweepMeasurement] | None = Field(
        default=None, min_length=3, description="At least 3 recorded signals (the pipeline's)."
    )
    simulate: SimulatedSweep | None = None
    name: str | None = Field(default=None, max_length=500)
    mode: Literal["batch", "live"] = Field(
        default="batch", description="'live': an open sweep fed by POST /v1/sweeps/{id}/records."
    )
    control: LiveControl | None = Field(
        default=None,
        description="The control parameter's name and unit: the one a live sweep steps, or the "
        "one a batch sweep of recorded signals was measured along (refused on simulated sweeps).",
    )
    live: LiveOptions | None = Field(
        default=None, description="Live sweeps only (refused in batch mode): margin, step, budget."
    )
    band: tuple[Number, Number] | None = Field(
        default=None,
        description="The fundamental's band of sqrt|sigma2| (rad per time unit of the records): "
        "each record's fundamental is its slowest mode inside; a record with none is set "
        "aside. Default: the mode that softens continuously across the sweep.",
    )
    notch: list[Number] | None = Field(
        default=None, max_length=16,
        description="Frequencies of stationary lines (cycles per time unit, e.g. 50 Hz mains "
        "and its harmonics) in every record: fitted as lines, never the fundamental. Default: "
        "lines present before the kick or not decaying are found.",
    )  # fmt: skip


class Sweep(BaseModel):
    """A sweep, its job, and (once done) the sweep document and its main parts.

    ``result`` is the document ``snapwarn warn --json`` and ``snapwarn sweep --json`` print;
    ``measurements``, ``prediction``, ``classification`` and ``alarm`` (after the last
    measurement) are its parts, repeated for convenience.
    """

    id: str
    name: str | None = None
    status: str
    request: dict[str, Any]
    job: Job
    result: SweepResult | None = None
    measurements: list[Measurement] | None = None
    classification: Classification | None = None
    prediction: Prediction | None = None
    alarm: Alarm | None = None
    created_at: datetime


class SweepPage(BaseModel):
    """A page of sweeps, newest first."""

    items: list[Sweep]
    total: int
    limit: int
    offset: int
