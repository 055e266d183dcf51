"""Wire model of a prediction request: a sweep table already measured (the document is
``analysis.Prediction``, the one ``snapwarn predict TABLE --json`` prints)."""

from __future__ import annotations

import math
from typing import Annotated, Any, Literal, get_args

from pydantic import BaseModel, ConfigDict, Field, field_validator

from service.schemas.analysis import Prediction
from service.schemas.common import Number

#: A number of a table: finite (``NaN`` and ``Infinity`` are refused naming the item, ``mu[3]``).
Finite = Annotated[Number, Field(allow_inf_nan=False)]

#: The laws a caller may name (``transition``, the CLI's ``--transition``); a custom exponent
#: is ``a`` (``--a``), alone or with one of them.
PredictTransition = Literal[
    "saddle-node", "subcritical-pitchfork", "supercritical-pitchfork", "pitchfork"
]
PREDICT_TRANSITIONS: tuple[str, ...] = get_args(PredictTransition)

#: Units of ``omega`` (and ``omega_std``): the header units ``snapwarn predict`` converts
#: (``omega [Hz]``). Hz, kHz, MHz and rpm are cycles per second or per minute, read as
#: ``2 pi f`` rad/s; ``rad/s`` is taken as it is.
OmegaUnit = Literal["rad/s", "Hz", "kHz", "MHz", "rpm"]
#: rad/s per unit of each :data:`OmegaUnit`.
OMEGA_UNIT_FACTORS: dict[str, float] = {
    "rad/s": 1.0,
    "Hz": 2.0 * math.pi * 1.0,
    "kHz": 2.0 * math.pi * 1e3,
    "MHz": 2.0 * math.pi * 1e6,
    "rpm": 2.0 * math.pi * (1.0 / 60.0),
}
_OMEGA_UNITS: dict[str, str] = {u.lower(): u for u in OMEGA_UNIT_FACTORS}

#: The table columns (top-level arrays of the body), in the order they are checked.
TABLE_FIELDS = ("mu", "sigma2", "sigma2_std", "omega", "omega_std", "w_static", "w_static_std")


class PredictionRequest(BaseModel):
    """A sweep table measured elsewhere: ``mu`` with ``sigma2`` or ``omega``.

    The columns of ``snapwarn predict TABLE``: the same numbers give the same document.
    ``mu`` is increasing (rows repeating a value are averaged into one point, flag
    ``repeated_points_averaged``), in any unit (mu* comes in that unit); ``sigma2`` in 1/time^2
    (negative on the stable branch), ``omega`` in rad/time (or see ``omega_unit``). Both
    ``sigma2`` and ``omega`` may be given when they agree (``sigma2`` is then used); rows where
    they disagree are a 422 naming ``omega`` (the numerics judge, as for the CLI's table).
    """

    model_config = ConfigDict(extra="forbid")

    mu: list[Finite] = Field(
        description="Control values, increasing (an upward sweep), at least 3 distinct; rows "
        "repeating the previous value are averaged into one point."
    )
    sigma2: list[Finite] | None = Field(
        default=None, description="Undamped eigenvalue of the fundamental, 1/time^2, < 0."
    )
    sigma2_std: list[Finite] | None = Field(
        default=None, description="Standard deviations of sigma2 (> 0); estimated when absent."
    )
    omega: list[Finite] | None = Field(
        default=None,
        description="Observed rate of the fundamental instead of sigma2, > 0: the modulus "
        "sqrt(omega_d^2 + (xi/2)^2) of its poles while it oscillates (omega_d the damped "
        "frequency), its slow decay rate once over-damped. Given with sigma2 it must agree "
        "with it on every row (sigma2 = -omega^2, or -omega (xi - omega) below xi/2 with "
        "damping given; within 5 standard deviations of sigma2_std and omega_std and 1e-4 "
        "relative): sigma2 is then used, else a 422 naming omega and the worst row.",
    )
    omega_std: list[Finite] | None = Field(
        default=None, description="Standard deviations of omega (> 0), in omega's unit."
    )
    omega_unit: OmegaUnit | None = Field(
        default=None,
        description="Unit of omega and omega_std (the CLI's 'omega [Hz]' header): Hz, kHz, MHz "
        "and rpm are read as 2 pi f rad/s (case-insensitive); absent or 'rad/s': as given "
        "(rad per time unit).",
    )
    w_static: list[Finite] | None = Field(
        default=None, description="Static deflection at the probe (used by the classification)."
    )
    w_static_std: list[Finite] | Finite | None = Field(
        default=None, description="Its standard deviation (> 0): one per point, or one for all."
    )
    damping: Finite | None = Field(
        default=None,
        description="Damping xi (1/time) of the rates omega when known (the CLI's --damping): "
        "the records' envelope decays as exp(-xi t/2), twice the decay rate a detection "
        "reports as 'damping'; without it a damping is inferred only on decisive evidence.",
    )
    transition: PredictTransition | None = Field(
        default=None, description="Fit this law only (the CLI's --transition)."
    )
    a: Finite | None = Field(
        default=None,
        description="Time exponent of the law to fit, > 0: |sigma2| ~ (mu* - mu)^(2a) (the "
        "CLI's --a). Alone it fits that exponent (the document's transition is then "
        "'saddle-node' for 0.25, 'pitchfork' for 0.5, else 'undetermined' with the law "
        "named 'custom' in probabilities); with transition it must be that law's a or its "
        "over-damped double (any a with 'pitchfork').",
    )
    level: Finite = Field(
        default=0.95, description="Confidence level of mu_star_interval, in (0, 1)."
    )

    @field_validator("omega_unit", mode="before")
    @classmethod
    def _unit_any_case(cls, v: Any) -> Any:
        """``hz``, ``KHZ``... as the CLI reads header units (case-insensitive)."""
        return _OMEGA_UNITS.get(v.strip().lower(), v) if isinstance(v, str) else v


__all__ = [
    "OMEGA_UNIT_FACTORS",
    "OmegaUnit",
    "PREDICT_TRANSITIONS",
    "Prediction",
    "PredictionRequest",
    "PredictTransition",
    "TABLE_FIELDS",
]
