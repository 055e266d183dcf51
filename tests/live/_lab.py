"""A simulated lab for the live-sweep tests: the "strip" is the Euler-beam simulator.

The lab measures an impulse response where it is told to, with the record length and sample
step the update suggests, and kicks the strip the way ``warn``'s simulated experimenter does
(the kick scales with a power of the expected frequency, ``pipeline.KICK_POWER``, so that the
response stays a fixed fraction of the shrinking well). It knows nothing of the prediction.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from service.analysis.pipeline import KICK_POWER
from service.analysis.sampling import PERIODS
from sim import simulate
from sim.scene import Scene


@dataclass
class Lab:
    actuation: str
    damping: float = 2e-4
    snr_db: float | None = 40.0
    seed: int = 1
    kick: float = 1e-2
    first_dt: float = 1e-3
    first_duration: float = 2.0
    k: int = 0
    omega0: float | None = None

    def record(
        self, mu: float, duration: float | None = None, dt: float | None = None
    ) -> tuple[np.ndarray, float]:
        """(w, dt) of an impulse response at control ``mu``."""
        if duration is None or not math.isfinite(duration):
            duration = self.first_duration
        if dt is None or not math.isfinite(dt):
            dt = self.first_dt
        kick = self.kick
        if self.omega0 is not None:
            ratio = min(1.0, (2 * math.pi / duration * PERIODS) / self.omega0)
            kick = self.kick * ratio**KICK_POWER
        scene = Scene(actuation=self.actuation, mu=float(mu), damping=self.damping, kick=kick,
                      snr_db=self.snr_db, duration=duration, dt=dt, seed=self.seed + self.k)
        self.k += 1
        sig = simulate(scene, "euler-beam")
        return np.asarray(sig.w), float(sig.dt)
