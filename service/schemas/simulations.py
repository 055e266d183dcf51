"""Wire models of simulations (a scene run by a simulator backend)."""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import BaseModel, ConfigDict, Field

from service.schemas.common import Integer, Number
from service.schemas.jobs import Job
from service.schemas.signals import SignalMeta

Actuation = Literal["asymmetric", "symmetric", "antisymmetric"]
Model = Literal["normal-form", "euler-beam", "cosserat", "auto"]

# The strip, its damping and its resolution: the same wire bounds at every door that runs a
# scene (POST /v1/simulations, POST /v1/snaps); the server's settings may bound tighter
# (SNAPWARN_MAX_ELEMENTS, SNAPWARN_MAX_SIM_DURATION, SNAPWARN_MAX_SIM_WORK; see
# service.api.limits.check_scene, which both doors call).
Damping = Annotated[Number, Field(ge=0.0, le=1e3, description="Non-dimensional viscous "
                                 "damping xi.")]
EndShortening = Annotated[Number, Field(gt=0.0, le=1.0, description="dL/L.")]
Slenderness = Annotated[Number, Field(gt=0.0, le=1.0, description="Thickness h/L.")]
Poisson = Annotated[Number, Field(ge=0.0, le=0.5, description="Poisson ratio (the rod's "
                                 "shear stiffness).")]
Rtol = Annotated[Number, Field(gt=0.0, lt=0.1, description="Requested relative accuracy of mu* "
                              "and sigma^2: the rod's resolution when elements is null and, "
                              "for model='auto', the backend (the signal's metadata.info names "
                              "the backend, the estimate and the reason).")]
Elements = Annotated[Integer | None, Field(ge=4, le=100_000, multiple_of=2, description="Elements "
                                       "of the Cosserat rod (even); null: chosen from rtol "
                                       "(as sim.Scene and the CLI).")]


class SimulationRequest(BaseModel):
    """A scene (see ``sim.scene.Scene``) and the backend to run it; non-dimensional units."""

    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)

    # The bounds are the wire's hard limits; the server's settings may bound tighter
    # (SNAPWARN_MAX_ELEMENTS, SNAPWARN_MAX_SIM_DURATION, SNAPWARN_MAX_SIM_WORK).
    model: Model = "auto"
    actuation: Actuation = "asymmetric"
    mu: Number = Field(default=0.0, ge=-1e3, le=1e3)
    branch: str = Field(default="U_A", max_length=20)
    damping: Damping = 2e-4
    kick: Number = Field(default=1e-2, ge=-10.0, le=10.0)
    kick_position: Number = Field(default=0.25, gt=0.0, lt=1.0)
    probe: Number = Field(default=0.25, gt=0.0, lt=1.0)
    duration: Number | None = Field(default=None, gt=0.0, le=1e6)
    dt: Number | None = Field(default=None, gt=1e-12, le=1e3)
    snr_db: Number | None = Field(default=None, ge=-100.0, le=400.0)
    seed: Integer | None = Field(default=None, ge=0, le=2**63 - 1)
    end_shortening: EndShortening = 1e-2
    slenderness: Slenderness = 1e-3
    width: Number = Field(default=1e-1, gt=0.0, le=1.0,
                         description="b/L of the rectangular strip (>= h/L).")
    poisson: Poisson = 0.5
    rtol: Rtol = 2e-4
    elements: Elements = None
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
