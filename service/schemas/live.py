"""Wire models of live sweeps: a lab adds records one by one and reads the warning after each.

A live sweep is an ordinary sweep (``/v1/sweeps/{id}``) created with ``"mode": "live"``; while
it is open its status is ``"open"``, records go to ``/v1/sweeps/{id}/records`` and every update
is also pushed on ``/v1/sweeps/{id}/events`` (server-sent events).
"""

from __future__ import annotations

from datetime import datetime
from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field

from service.schemas.analysis import (
    Alarm,
    Detection,
    Flag,
    Measurement,
    Num,
    Prediction,
    SetAside,
    Transition,
)
from service.schemas.common import Integer, Number


class LiveControl(BaseModel):
    """The control parameter a live sweep steps (any quantity, any unit)."""

    model_config = ConfigDict(extra="forbid")

    name: str = Field(default="mu", min_length=1, max_length=200)
    unit: str | None = Field(default=None, max_length=100)


class LiveOptions(BaseModel):
    """How a live sweep advises (control units). Part of ``POST /v1/sweeps`` with mode live."""

    model_config = ConfigDict(extra="forbid")

    margin: Number = Field(
        default=0.0, ge=0, allow_inf_nan=False,
        description="Distance kept below the safe bound on mu* (control units).",
    )  # fmt: skip
    step: Number | None = Field(
        default=None, gt=0, allow_inf_nan=False,
        description="Largest control step (the first steps, before any bound on mu* exists).",
    )  # fmt: skip
    budget: Integer | None = Field(
        default=None, ge=1, le=10_000,
        description="Most records; the sweep finishes when it is spent.",
    )  # fmt: skip
    target_width: Number | None = Field(
        default=None, gt=0, allow_inf_nan=False,
        description="'converged' once the trusted 95 % interval of mu* is narrower "
        "(default 1e-6 of max(|mu*|, span of the controls)).",
    )  # fmt: skip
    control_resolution: Number | None = Field(
        default=None, gt=0, allow_inf_nan=False,
        description="The finest control step the lab can set: 'converged' once the advised "
        "step is smaller (default: the decimals of the controls, at least 1e-4 of the step).",
    )  # fmt: skip
    method: Literal["auto", "varpro", "esprit", "fft", "fft-parabolic"] = "auto"


class LiveRecordIn(BaseModel):
    """One record for ``POST /v1/sweeps/{id}/records`` (JSON): a stored signal or inline samples.

    Give ``signal_id``, or ``w`` with ``t`` or ``dt``. ``control`` is the control value it was
    recorded at (default: the stored signal's own control value).
    """

    model_config = ConfigDict(extra="forbid")

    control: Number | None = Field(default=None, allow_inf_nan=True)
    signal_id: str | None = Field(default=None, max_length=64)
    w: list[Number] | None = None
    t: list[Number] | None = None
    dt: Number | None = None
    t0: Number | None = None
    unit: str | None = Field(default=None, max_length=100)
    name: str | None = Field(default=None, max_length=500)
    quantity: Literal["displacement", "velocity", "acceleration"] | None = Field(
        default=None, description="What the record measures (default: the stored signal's "
        "value unit says, else a displacement).")  # fmt: skip
    start: Number | None = Field(
        default=None, ge=0, description="Time from the record's first sample where its free "
        "response starts (default: the kick is located).")  # fmt: skip
    notch: list[Number] | None = Field(
        default=None, max_length=16, description="Frequencies of stationary lines (cycles per "
        "time unit; default: found).")  # fmt: skip
    exclude: bool = Field(
        default=False, description="Leave this record out of the sweep (listed as set aside, "
        "'excluded by the user').")  # fmt: skip

    def detect_options(self) -> dict[str, Any]:
        """The detector's options of this record (None ones left out)."""
        opts = {"quantity": self.quantity, "start": self.start, "notch": self.notch,
                "exclude": self.exclude or None}  # fmt: skip
        return {k: v for k, v in opts.items() if v is not None}


class RecordOptions(BaseModel):
    """The detector's options a record was read with: the user's (or the sweep's notch), and
    the quantity its file's value unit says when the user gave none."""

    model_config = ConfigDict(extra="ignore")

    quantity: Literal["displacement", "velocity", "acceleration"] | None = None
    start: float | None = None
    notch: list[float] | None = None
    exclude: bool = False


class LiveUpdate(BaseModel):
    """The warning after one more record of a live sweep.

    The scientific parts are the typed results of ``service.schemas.analysis`` (one contract for
    the API, the CLI and the SDK); ``mu_star``, ``mu_star_interval``, ``transition`` and
    ``probabilities`` repeat the prediction's at the top for dashboards.
    """

    model_config = ConfigDict(extra="ignore")

    sweep_id: str | None = Field(default=None, description="None in process (snapwarn watch).")
    seq: int = Field(description="Position of the record in arrival order (1, 2, ...).")
    signal_id: str | None = Field(default=None, description="The stored record.")
    record_name: str | None = Field(
        default=None, description="The record's name: the one the client gave, else its file's "
        "(a stored signal: the name it was uploaded with).")  # fmt: skip
    control: float
    record_options: RecordOptions = Field(
        default_factory=RecordOptions, description="The options the record was read with.")
    record_flags: list[Flag] = Field(
        default_factory=list,
        description="out_of_order, repeated_control, past_safe_value, no_mode (the record is "
        "kept in any case).",
    )
    used_in_fit: bool
    measurement: Measurement | None = None
    detection: Detection
    n_records: int
    n_used: int = Field(description="Records in the fit (a fundamental, distinct controls).")
    transition: Transition = "undetermined"
    probabilities: dict[str, Num] = Field(default_factory=dict)
    mu_star: Num = None
    mu_star_interval: tuple[Num, Num] | None = None
    prediction: Prediction | None = None
    alarm: Alarm
    next_control: Num = Field(
        default=None,
        description="The next safe control value: below the safe bound on mu* minus the margin "
        "(null: no safe step left, or no advice yet).",
    )
    next_bound: Num = Field(default=None, description="The safe bound on mu* it respects.")
    next_bound_source: Literal["interval", "sigma4", "past_transition", "none"] = Field(
        default="none",
        description="'interval' (the predictor's lower end), 'sigma4' (model-free), "
        "'past_transition' (a record that grew), 'none'.",
    )
    next_limited_by: str = Field(
        default="no_advice", description="'bound', 'growth', 'max_step', 'no_safe_step'..."
    )
    trusted: bool = Field(description="The predictor's interval bounded the advice.")
    converged: bool = Field(
        description="The trusted interval is narrower than the target, or the next step is "
        "below the control resolution: the lab may stop."
    )
    record_duration: Num = Field(
        default=None, description="Suggested length of the next record (record time unit)."
    )
    record_dt: Num = Field(default=None, description="Suggested sample step of the next record.")
    flags: list[Flag] = Field(default_factory=list)
    set_aside: list[SetAside] = Field(
        default_factory=list, description="Records left out of the prediction, with reasons."
    )
    n_set_aside: int = Field(default=0, description="How many records were set aside.")
    record_advice: str = Field(default="", description="How the record length was chosen.")
    finished: bool = Field(default=False, description="This record spent the budget.")
    created_at: datetime | None = None
    server_ms: float | None = Field(
        default=None, description="Server time from the upload to this answer (POST only)."
    )


class LiveUpdatePage(BaseModel):
    """The updates of a live sweep, in arrival order."""

    items: list[LiveUpdate]
    total: int
    status: str


class LiveEvent(BaseModel):
    """One server-sent event of ``/v1/sweeps/{id}/events`` as the SDK yields it.

    ``event`` is ``"update"`` (``data`` is a :class:`LiveUpdate`) or ``"closed"`` (``data``:
    ``{"status": ..., "stopped": ...}``); ``id`` is the record's ``seq`` (the closing event has
    the last ``seq`` plus one), the value to send as ``Last-Event-ID`` to resume.
    """

    id: int
    event: Literal["update", "closed"]
    update: LiveUpdate | None = None
    data: dict[str, Any] = Field(default_factory=dict)
