"""Wire models of snap-throughs (``POST /v1/snaps``; ``snapwarn snap --json``)."""

from __future__ import annotations

from typing import Literal

from pydantic import BaseModel, ConfigDict, Field

from service.schemas.common import Number
from service.schemas.jobs import Job
from service.schemas.sim import Resolution
from service.schemas.simulations import (
    Actuation,
    Damping,
    Elements,
    EndShortening,
    Poisson,
    Rtol,
    Slenderness,
)

SnapModel = Literal["normal-form", "euler-beam", "cosserat"]


class SnapRequest(BaseModel):
    """The strip, the backend and the distance from mu* (see ``sim.snap``).

    The strip, damping and resolution fields have the bounds of ``SimulationRequest``'s (one
    definition) and are checked at the door as a simulation's are (the settings'
    SNAPWARN_MAX_ELEMENTS, elements chosen from rtol included).
    """

    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)

    model: SnapModel = "euler-beam"
    actuation: Actuation = "asymmetric"
    dmu: Number = Field(gt=0.0, lt=0.5, description="Distance from mu*: to the right "
                       "(asymmetric, symmetric, from U_A), to the left (antisymmetric, from S_B).")
    duration: Number | None = Field(default=None, ge=1e-3, le=500.0)
    damping: Damping = 2e-4
    end_shortening: EndShortening = 1e-2
    slenderness: Slenderness = 1e-3
    poisson: Poisson = 0.5
    rtol: Rtol | None = Field(default=None, description="As a simulation's rtol; null: the "
                              "default 2e-4.")
    elements: Elements = None


class SnapResult(BaseModel):
    """A snap-through: where it starts and ends, its snap time and the record A(t).

    Non-dimensional units: mu = alpha sqrt(L / dL), time T in units of sqrt(rho b h L^4 / B),
    amplitudes in units of sqrt(L dL); a number that is not finite is null.
    """

    model_config = ConfigDict(extra="ignore")

    actuation: str = Field(description="'asymmetric', 'symmetric' or 'antisymmetric'.")
    model: str = Field(description="Backend that integrated it.")
    dmu: float = Field(description="Distance from mu* (> 0; to the left of mu* for the "
                       "antisymmetric actuation), units of mu.")
    mu: float = Field(description="The control set, units of mu.")
    mu_star: float = Field(description="The backend's own mu*, units of mu.")
    from_branch: str = Field(description="Branch the strip starts on.")
    to_branch: str = Field(description="Branch it snaps to.")
    snap_time: float | None = Field(description="First time |A| reaches half the distance to "
                                    "to_branch, T (null: not within the record).")
    probe: float = Field(description="Probe position X_p in [0, 1] where A is read.")
    samples: int = Field(description="Samples of the record.")
    duration: float = Field(description="Time of the last sample, T (0 without samples).")
    t: list[float] = Field(description="Sample times, T.")
    amplitude: list[float | None] = Field(description="A(t) = W(probe, t) - W*(probe), units "
                                          "of sqrt(L dL) (null after a blow-up).")
    resolution: Resolution | None = Field(default=None, description="Discretisation used and "
                                          "its estimated error of mu* (null: normal form).")


class SnapReport(SnapResult):
    """``snapwarn snap --json``: the snap and the CSV file written (``--out``)."""

    path: str | None = Field(default=None, description="CSV file (t, amplitude) written "
                             "(null: none asked for).")


class SnapAnswer(BaseModel):
    """Either the snap (the normal form, 200) or the job computing it (202)."""

    snap: SnapResult | None = None
    job: Job | None = None
