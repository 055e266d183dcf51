"""How a sweep advises: the lab's plan (step, margin, target width, control resolution).

Kept apart from :mod:`.sweep_policy` so that the modules the policy is split into
(:mod:`.sweep_interval`, :mod:`.sweep_records`) can name it without an import circle; the
public door stays ``service.analysis.sweep_policy.SweepPlan``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from service.analysis.errors import ParameterError

__all__ = ["SweepPlan"]


@dataclass(frozen=True)
class SweepPlan:
    """How a sweep advises (control units throughout).

    Attributes
    ----------
    step : float or None
        The lab's step: the largest step before the interval is trusted, and the unit the
        alarm counts danger in. Default: the largest step between the records so far (and
        then a step grows at most ``max_step_growth`` times the last one).
    margin : float
        Distance kept below the safe bound on mu* (>= 0).
    target_width : float or None
        ``converged`` once the trusted interval is narrower after two records in a row;
        default :data:`service.analysis.sweep_policy.TARGET_OF_SPAN` times the controls
        travelled.
    control_resolution : float or None
        The finest control step the lab can set: ``converged`` once the advised step is
        smaller, and no side of the interval is nearer mu* than half of it (flag
        ``resolution_floor``). Default: the decimals the controls are written with, at least
        ``1e-4 * step`` (:func:`resolution`).
    step_fraction : float
        Fraction of the room to the bound that a step takes, in (0, 1).
    max_step_growth : float or None
        A step is at most this multiple of the previous one. Default: none with ``step`` (the
        cap is the step), 2 without.
    method : str
        Detector method.
    level : float
        Confidence level of the interval.
    band : (lo, hi) or None
        The user's band for the fundamental's ``sqrt|sigma^2|`` (rad per time unit of the
        records): each record's fundamental is its slowest mode inside
        (:func:`service.analysis.reconcile.reconcile`).
    """

    step: float | None = None
    margin: float = 0.0
    target_width: float | None = None
    control_resolution: float | None = None
    step_fraction: float = 0.5
    max_step_growth: float | None = None
    method: str = "auto"
    level: float = 0.95
    band: tuple[float, float] | None = None

    def __post_init__(self) -> None:
        if self.band is not None:
            lo, hi = (float(v) for v in self.band)
            if not (math.isfinite(lo) and math.isfinite(hi) and 0 <= lo < hi):
                msg = f"band must be finite 0 <= lo < hi, got {self.band!r}"
                raise ParameterError("band", list(self.band), msg)
        for name in ("step", "target_width", "control_resolution"):
            v = getattr(self, name)
            if v is not None and not (math.isfinite(v) and v > 0):
                raise ParameterError(name, v, f"{name} must be > 0, got {name}={v!r}")
        if not (math.isfinite(self.margin) and self.margin >= 0):
            raise ParameterError(
                "margin", self.margin, f"margin must be finite and >= 0, got margin={self.margin!r}"
            )
        if not 0 < self.step_fraction < 1:
            raise ParameterError(
                "step_fraction",
                self.step_fraction,
                f"step_fraction must be in (0, 1), got step_fraction={self.step_fraction!r}",
            )
        if self.max_step_growth is not None and not self.max_step_growth > 0:
            raise ParameterError(
                "max_step_growth",
                self.max_step_growth,
                f"max_step_growth must be > 0, got max_step_growth={self.max_step_growth!r}",
            )
        if not 0 < self.level < 1:
            raise ParameterError(
                "level", self.level, f"level must be in (0, 1), got level={self.level!r}"
            )
