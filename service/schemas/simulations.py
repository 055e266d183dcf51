"""Wire models of simulations (a scene run by a simulator backend)."""

from __future__ import annotations

from typing import Literal

from pydantic import BaseModel, ConfigDict, Field

from service.schemas.jobs import Job
from service.schemas.signals import SignalMeta

Actuation = Literal["asymmetric", "symmetric", "antisymmetric"]
Model = Literal["normal-form", "euler-beam", "cosserat", "auto"]


class SimulationRequest(BaseModel):
    """A scene (see ``sim.scene.Scene``) and the backend to run it; non-dimensional units."""

    model_config = ConfigDict(extra="forbid")

    model: Model = "auto"
    actuation: Actuation = "asymmetric"
    mu: float = 0.0
    branch: str = "U_A"
    damping: float = 2e-4
    kick: float = 1e-2
    kick_position: float = 0.25
    probe: float = 0.25
    duration: float | None = None
    dt: float | None = None
    snr_db: float | None = None
    seed: int | None = None
    end_shortening: float = 1e-2
    slenderness: float = 1e-3
    width: float = Field(default=1e-1, description="b/L of the rectangular strip (>= h/L).")
    poisson: float = Field(default=0.5, description="Poisson ratio (the rod's shear).")
    rtol: float = Field(default=2e-4, description="Requested relative accuracy of mu* and "
                        "sigma^2: the rod's resolution when elements is null and, for "
                        "model='auto', the backend (the signal's metadata.info names the "
                        "backend, the estimate and the reason).")
    elements: int | None = 50
    background: bool | None = Field(
        default=None,
        description="Force a job (true) or an immediate answer (false); by default cheap "
        "models answer at once and expensive ones become a job.",
    )
    name: str | None = Field(default=None, max_length=500)


class SimulationResult(BaseModel):
    """Either the stored signal (ran at once, 201) or the job that will store it (202)."""

    signal: SignalMeta | None = None
    job: Job | None = None
