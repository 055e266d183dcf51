"""Wire models of snap-throughs (``POST /v1/snaps``; ``snapwarn snap --json``)."""

from __future__ import annotations

from typing import Literal

from pydantic import BaseModel, ConfigDict, Field

from service.schemas.jobs import Job
from service.schemas.simulations import Actuation

SnapModel = Literal["normal-form", "euler-beam", "cosserat"]


class SnapRequest(BaseModel):
    """The strip, the backend and the distance from mu* (see ``sim.snap``)."""

    model_config = ConfigDict(extra="forbid")

    model: SnapModel = "euler-beam"
    actuation: Actuation = "asymmetric"
    dmu: float = Field(gt=0.0, lt=0.5, description="Distance from mu*: to the right "
                       "(asymmetric, symmetric, from U_A), to the left (antisymmetric, from S_B).")
    duration: float | None = Field(default=None, ge=1e-3, le=500.0)
    damping: float = Field(default=2e-4, ge=0.0)
    end_shortening: float = 1e-2
    slenderness: float = 1e-3
    poisson: float = 0.5
    rtol: float | None = None
    elements: int | None = None


class SnapResult(BaseModel):
    """A snap-through: where it starts and ends, its snap time and the record A(t)."""

    model_config = ConfigDict(extra="ignore")

    actuation: str
    model: str
    dmu: float
    mu: float
    mu_star: float
    from_branch: str
    to_branch: str
    snap_time: float | None = Field(description="First time |A| reaches half the distance to "
                                    "to_branch (null: not within the record).")
    probe: float
    samples: int
    duration: float
    t: list[float]
    amplitude: list[float | None] = Field(description="W(probe, t) - W*(probe), units of "
                                          "sqrt(L dL).")
    resolution: dict | None = None


class SnapAnswer(BaseModel):
    """Either the snap (the normal form, 200) or the job computing it (202)."""

    snap: SnapResult | None = None
    job: Job | None = None
