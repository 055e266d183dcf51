"""Wire models of background jobs."""

from __future__ import annotations

from datetime import datetime
from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field

# open: a live sweep; cancelled: by POST /v1/jobs/{id}/cancel (never re-run)
JobStatus = Literal["queued", "running", "succeeded", "failed", "cancelled", "open"]
TERMINAL_STATUSES = ("succeeded", "failed", "cancelled")


class Progress(BaseModel):
    fraction: float = Field(ge=0.0, le=1.0)
    message: str = ""


class JobError(BaseModel):
    """Why a job failed (an RFC 9457 problem: type, title, detail, maybe errors)."""

    model_config = ConfigDict(extra="allow")

    type: str = "about:blank"
    title: str
    detail: str | None = None
    reason: str | None = Field(
        default=None,
        description="'invalid-input', 'time-limit', 'cancelled', 'interrupted', 'crashed' or "
        "'internal-error'.",
    )
    correlation_id: str | None = Field(
        default=None, description="Names the failure in the server log (internal errors)."
    )


class Job(BaseModel):
    """A unit of background work: status, progress, and its result or error."""

    id: str
    kind: str = Field(description="'sweep' or 'simulation'.")
    status: JobStatus
    progress: Progress
    result: dict[str, Any] | None = None
    error: JobError | None = None
    attempts: int = Field(description="Times the job was started (a restart resumes it).")
    created_at: datetime
    started_at: datetime | None = None
    finished_at: datetime | None = None

    @property
    def done(self) -> bool:
        return self.status in TERMINAL_STATUSES


class JobPage(BaseModel):
    """A page of jobs, newest first."""

    items: list[Job]
    total: int
    limit: int
    offset: int
