"""Wire models of the scientific results: one typed contract for the API, the CLI and the SDK.

The numerics (``service.analysis``) return frozen dataclasses; ``service.convert`` turns them
into these models, and nothing else builds them. ``snapwarn detect/predict/warn/sweep --json``
print their ``model_dump(mode="json")``, the API's routes return them, and the SDK parses its
answers into them (``det.modes[0].sigma2``).

Strict JSON: a number that is missing or not finite (NaN, an infinite bound) is ``null``.
Units follow the record: ``omega`` in rad per time unit of the record, ``sigma2`` in 1/time^2,
``mu`` in the unit of the control. Models ignore fields they do not know, so that an older SDK
reads a newer server's documents.
"""

from __future__ import annotations

from typing import Literal

from pydantic import BaseModel, ConfigDict, Field

Num = float | None
"""A float on the wire: ``null`` when missing or not finite."""

Regime = Literal["underdamped", "overdamped"]
Quantity = Literal["displacement", "velocity", "acceleration"]
Transition = Literal[
    "saddle-node",
    "subcritical-pitchfork",
    "supercritical-pitchfork",
    "pitchfork",
    "undetermined",
    "custom",  # a prediction with the caller's own exponent a (neither 1/4 nor 1/2)
    "none",  # no loss of stability (an imperfect stiffening pitchfork): never a snap
]
AlarmLevel = Literal["insufficient", "clear", "watch", "warning", "critical"]


class _Result(BaseModel):
    model_config = ConfigDict(extra="ignore", frozen=True)


class Flag(_Result):
    """A machine-readable reason to doubt a result (stable ``code``) and one sentence."""

    code: str = Field(description="Stable snake_case identifier, e.g. 'few_periods'.")
    message: str = Field(description="One sentence with the numbers that triggered it.")


class Mode(_Result):
    """One mode (a pair of poles ``s = -damping +- i omega``) of a record."""

    omega: Num = Field(description="Damped angular frequency, rad/time (0 when overdamped).")
    frequency: Num = Field(description="omega / (2 pi), cycles/time.")
    damping: Num = Field(description="Decay rate gamma, 1/time.")
    sigma2: Num = Field(description="Undamped eigenvalue -s1 s2, 1/time^2 (< 0 when stable).")
    amplitude: Num = Field(description="Initial amplitude, record units.")
    phase: Num = Field(description="Phase at the first sample, rad.")
    omega_std: Num = None
    damping_std: Num = None
    sigma2_std: Num = None
    amplitude_std: Num = None
    regime: Regime = "underdamped"
    real_poles: tuple[Num, Num] | None = Field(
        default=None, description="Overdamped mode: its two real poles (slow first), 1/time."
    )
    real_amplitudes: tuple[Num, Num] | None = None
    snr_db: Num = Field(default=None, description="Record-integrated SNR of this mode, dB.")
    combination: str | None = Field(
        default=None,
        description="When the mode is a combination tone of stronger modes, which one "
        "(e.g. 'omega_2 - omega_1'); it is never the fundamental.",
    )
    kind: Literal["mode", "line", "drift", "trend", "transient"] = Field(
        default="mode",
        description="'mode' (of the structure), or set aside and never the fundamental: "
        "'line' (a stationary line: mains hum, a line present before the kick or not "
        "decaying), 'drift' (a slow baseline not kicked from rest), 'trend' (slower than the "
        "record), 'transient' (the hammer's contact, gone early in the record).",
    )


class Fundamental(Mode):
    """The fundamental: a mode of ``Detection.modes`` and its ``index`` there."""

    index: int = Field(default=0, ge=0, description="Its position in Detection.modes.")


class Detection(_Result):
    """The poles of one record (``snapwarn detect --json``, ``POST /v1/detections``)."""

    modes: list[Mode] = Field(description="Significant modes, increasing |sigma2|.")
    fundamental: Fundamental | None = Field(description="None when no mode was found.")
    static_level: Num = Field(description="Equilibrium offset of the record, record units.")
    static_level_std: Num = None
    flags: list[Flag] = Field(default_factory=list)
    method: str = Field(description="The method actually used ('auto' resolves).")
    noise_std: Num = None
    snr_db: Num = None
    n_samples: int = 0
    dt: Num = None
    kind: str = "impulse"
    iterations: int = 0
    start: int = Field(
        default=0,
        description="Index of the first sample analysed: 0, or the kick after a quiet "
        "pre-trigger (flag 'pretrigger'); amplitudes and phases are at that sample.",
    )
    quantity: Quantity = Field(
        default="displacement",
        description="What the record measures; poles come from any, the static level only "
        "from a displacement (NaN otherwise, flag 'no_static_level').",
    )
    time_unit: str | None = Field(
        default=None,
        description="Time unit of the record as its file or upload named it (e.g. 'ms'): "
        "omega is in rad per this unit, damping in 1/unit, sigma2 in 1/unit^2, dt in it. "
        "None: the record named no unit (the numbers are in its time axis's unit).",
    )
    value_unit: str | None = Field(
        default=None, description="Unit of the samples (amplitudes, static level), if named."
    )


class RecordDetection(Detection):
    """A detection inside a sweep of records: which record and at which control value."""

    control: Num = Field(default=None, description="Control value of the record.")
    name: str | None = Field(default=None, description="The record's label (file, signal id).")
    record_name: str | None = Field(
        default=None, description="The record's file name (a stored signal: the name it was "
        "uploaded with), as set-aside reasons name it.")  # fmt: skip


class Measurement(_Result):
    """One analysed record of a sweep: the fundamental and the static level at ``mu``."""

    mu: Num = Field(description="Control value, its own unit.")
    omega: Num = Field(description="sqrt|sigma2|, rad/time.")
    sigma2: Num
    sigma2_std: Num = None
    w_static: Num = None
    w_static_std: Num = None
    regime: Regime = "underdamped"
    duration: Num = None
    dt: Num = None
    flags: list[Flag] = Field(default_factory=list)


class PaperRule(_Result):
    """The paper's two-point early-warning rule on the same measurements (the baseline)."""

    mu_star: Num
    stop_index: int
    t_ratio: Num = None
    a: Num = None
    flags: list[Flag] = Field(default_factory=list)


class Classification(_Result):
    """The transition type told by the data, with the free exponents."""

    transition: Transition
    a: Num = Field(description="Time exponent: sqrt|sigma2| ~ |mu* - mu|^a.")
    a_std: Num = None
    b: Num = Field(default=None, description="Static exponent (None without w_static).")
    b_std: Num = None
    mu_star: Num = None
    mu_star_std: Num = None
    probabilities: dict[str, Num] = Field(default_factory=dict)
    regime: Regime = "underdamped"
    flags: list[Flag] = Field(default_factory=list)
    window: int = 0
    damping: Num = None


class Alarm(_Result):
    """The alarm after a measurement: what the lab must do, on an ordered scale (``rank`` 0
    lowest): insufficient (too little evidence), clear, watch, warning, critical (the next
    step would reach the interval of mu*, or a record grew past the transition)."""

    level: AlarmLevel
    reason: str = ""
    mu: Num = Field(default=None, description="Last measured control value.")
    t_ratio: Num = Field(default=None, description="T / T0 at that point.")
    mu_star: Num = None
    mu_star_interval: tuple[Num, Num] = (None, None)
    distance: Num = Field(
        default=None, description="(mu* - mu) in half-widths of the interval."
    )
    rank: int = Field(default=0, ge=0, description="The level's rank (0 lowest).")
    step: Num = Field(default=None, description="The lab's step danger is counted in.")
    steps_left: Num = Field(
        default=None, description="(interval's lower end - mu) in the lab's steps."
    )
    widths_left: Num = Field(
        default=None, description="(interval's lower end - mu) in widths of the interval."
    )


class SetAside(_Result):
    """A record left out of the prediction, with the reason (named by its file)."""

    seq: int
    control: Num
    name: str | None = None
    reason: str


class Prediction(_Result):
    """mu* with its interval, the law used, the alarm and the next safe control value."""

    mu_star: Num
    mu_star_interval: tuple[Num, Num]
    mu_star_std: Num = None
    a: Num = None
    method: str = ""
    alarm: Alarm | None = None
    next_safe_mu: Num = None
    flags: list[Flag] = Field(default_factory=list)
    transition: Transition = "undetermined"
    probabilities: dict[str, Num] = Field(default_factory=dict)
    window: int = 0
    n_terms: int = 0
    baseline: PaperRule | None = None
    classification: Classification | None = None
    least_sigma2: Num = Field(
        default=None,
        description="Transition 'none' (no loss of stability): the least |sigma2| (1/time^2).",
    )
    least_sigma2_mu: Num = Field(
        default=None,
        description="Transition 'none': the control where |sigma2| is least (also mu_star).",
    )


class Truth(_Result):
    """A simulated sweep's own transition (the simulator's bifurcation), and the errors."""

    mu_star: Num
    transition: str | None = None
    model: str | None = Field(default=None, description="Backend whose bifurcation this is "
                              "(the one simulated, at the resolution simulated).")
    mu_star_error: Num = Field(default=None, description="Its estimated discretisation error.")
    error: Num = None
    covered: bool | None = None
    transition_correct: bool | None = None
    max_mu_measured: Num = None
    baseline_error: Num = None


class SweepResult(_Result):
    """A sweep: its measurements, the prediction, the alarms (``snapwarn warn/sweep --json``,
    ``GET /v1/sweeps/{id}``'s ``result``)."""

    actuation: str | None = None
    model: str | None = None
    measurements: list[Measurement] = Field(default_factory=list)
    prediction: Prediction | None = None
    alarm: list[Alarm] = Field(
        default_factory=list, description="The alarm after each measurement."
    )
    stopped: str = Field(
        description="'converged', 'budget', 'no-safe-step', 'snapped' (simulated sweeps) or "
        "'done' (recorded)."
    )
    truth: Truth | None = None
    flags: list[Flag] = Field(default_factory=list)
    detections: list[RecordDetection] = Field(
        default_factory=list, description="Per-record detections (recorded sweeps)."
    )
    set_aside: list[SetAside] = Field(
        default_factory=list, description="Records left out of the prediction, with reasons."
    )
    n_set_aside: int = Field(default=0, description="How many records were set aside.")
    next_control: Num = Field(
        default=None, description="The next safe control after the last record (null: none)."
    )
    record_duration: Num = Field(
        default=None, description="Suggested length of the next record (the records' time "
        "unit; null: no advice), as a live sweep of the same records advises it.")  # fmt: skip
    record_dt: Num = Field(default=None, description="Suggested sample step of the next record.")
    record_advice: str = Field(default="", description="How the record length was chosen.")


__all__ = [
    "Alarm",
    "AlarmLevel",
    "Classification",
    "Detection",
    "Flag",
    "Fundamental",
    "Measurement",
    "Mode",
    "Num",
    "PaperRule",
    "Prediction",
    "RecordDetection",
    "Regime",
    "SetAside",
    "SweepResult",
    "Transition",
    "Truth",
]
