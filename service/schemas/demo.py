"""Wire model of ``snapwarn demo --json``: the beam in brief and three early-warning sweeps."""

from __future__ import annotations

from pydantic import BaseModel, ConfigDict, Field

from service.schemas.analysis import SweepResult
from service.schemas.sim import BeamSummary


class Demo(BaseModel):
    """The main job on embedded defaults: the Euler beam's transitions and spectra, then one
    simulated sweep per actuation (xi = 2e-4, 40 dB)."""

    model_config = ConfigDict(extra="ignore", frozen=True)

    beam: BeamSummary
    warn: list[SweepResult] = Field(description="One sweep per actuation, in the order "
                                    "asymmetric, symmetric, antisymmetric.")
    seconds: float = Field(description="Wall time of the whole demo, s.")
