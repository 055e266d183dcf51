"""The interval of a sweep's prediction as the lab's records bound it (:mod:`.sweep_policy`).

The predictor's interval is taken as the records allow: a record that grew bounds mu* from
above (:func:`_growth`; one record alone is not confirmed), and no side is finer than the
lab can set its control (:func:`resolution`, :func:`_resolution_floor`); the lab's step
(:func:`lab_step`) is the unit the alarm counts danger in.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import replace
from typing import TYPE_CHECKING

import numpy as np

from service.analysis.common import Flag
from service.analysis.measurement import Measurement
from service.analysis.predict import Prediction, bounded_by

if TYPE_CHECKING:
    from service.analysis.sweep_plan import SweepPlan

__all__ = ["RESOLUTION_OF_STEP", "lab_step", "resolution"]

#: Default control resolution: this fraction of the lab's step, unless the controls are
#: written with fewer decimals.
RESOLUTION_OF_STEP = 1e-4


def _growth(
    pred: Prediction | None, ms: Sequence[Measurement], past: float, n_beyond: int,
    n_grew: int, flags: list[Flag],
) -> tuple[Prediction | None, bool]:  # fmt: skip
    """The prediction with the records that grew (``past``: the lowest of them) taken in, and
    whether that growth is unconfirmed.

    One record that grew below the lower end of the interval the stable records give is
    unconfirmed (one record must not derail a sweep: a detector can read a spurious growing
    pole): the interval spans both readings, from the last stable control to its upper end,
    and the lab records again at that control. Two records that grew, or one the interval does
    not contradict, confirm the transition: mu* and the interval end at ``past`` (between the
    last stable record and ``past`` when the interval lay wholly above it)."""
    if not math.isfinite(past):
        return pred, False
    has_pred = pred is not None and math.isfinite(pred.mu_star)
    if has_pred and n_grew == 1 and ms and pred.mu_star_interval[0] > past:
        lo, hi = pred.mu_star_interval
        flags.append(Flag(
            "growth_unconfirmed",
            f"the record at control {past:.6g} grows (flag unstable), but the stable records "
            f"put mu* in [{lo:.6g}, {hi:.6g}], above it: one record is not enough; record "
            f"again at {past:.6g} (a second record that grows confirms the transition, a "
            "stable one sets this one aside); meanwhile the interval spans both readings",
        ))  # fmt: skip
        return replace(pred, mu_star_interval=(ms[-1].mu, hi)), True
    flags.append(Flag(
        "past_transition",
        f"the record at control {past:.6g} grows (flag unstable): the strip is unstable "
        f"there, past its transition (mu* < {past:.6g}); it"
        + (f" and the {n_beyond} record(s) beyond it are" if n_beyond else " is")
        + " left out of the prediction",
    ))  # fmt: skip
    if not has_pred:
        return pred, False
    out = bounded_by(pred, past)
    if pred.mu_star_interval[0] >= past and ms:  # the bracket the records give, not a point
        out = replace(out, mu_star_interval=(ms[-1].mu, past))
    return out, False


def lab_step(ms: Sequence[Measurement], plan: SweepPlan) -> float:
    """The lab's step: the plan's, else the largest step between the usable controls."""
    if plan.step is not None:
        return float(plan.step)
    mu = [m.mu for m in ms]
    return float(np.max(np.diff(mu))) if len(mu) >= 2 else math.nan


def _decimals(controls: Iterable[float]) -> float:
    """The finest decimal the controls are written with (0 when more than 9 decimals)."""
    controls = list(controls)  # (read once per decimal: a generator would be spent)
    for k in range(10):
        q = 10.0**-k
        if all(abs(c / q - round(c / q)) < 1e-6 for c in controls):
            return q
    return 0.0


def resolution(ms: Sequence[Measurement], plan: SweepPlan, step: float) -> float:
    """The control resolution: the plan's, else the decimals of the controls, at least
    :data:`RESOLUTION_OF_STEP` times the lab's step."""
    if plan.control_resolution is not None:
        return float(plan.control_resolution)
    floor = RESOLUTION_OF_STEP * step if math.isfinite(step) else 0.0
    return max(_decimals(m.mu for m in ms), floor)


def _resolution_floor(
    pred: Prediction | None, ms: Sequence[Measurement], res: float, past: float,
    flags: list[Flag],
) -> Prediction | None:  # fmt: skip
    """The prediction with each side of its interval at least half the control resolution
    ``res`` (:func:`resolution`: the lab's, else its controls' grid) from mu*: a lab that sets
    its control to that resolution knows each control only to half of it, and so mu* (never
    below the last stable control, never above a record that grew: ``past``). Flag
    ``resolution_floor`` when it widens a side."""
    if not (res > 0) or pred is None or not math.isfinite(pred.mu_star) or not ms:
        return pred
    lo, hi = pred.mu_star_interval
    m, half = pred.mu_star, 0.5 * float(res)
    new = (max(min(lo, m - half), min(lo, ms[-1].mu)), max(hi, min(m + half, past)))
    if new == (lo, hi):
        return pred
    flags.append(Flag(
        "resolution_floor",
        f"the interval [{lo:.6g}, {hi:.6g}] is finer than the control resolution {res:.3g} "
        f"allows: each side is at least half of it from mu* (now [{new[0]:.6g}, "
        f"{new[1]:.6g}]); give control_resolution when your control is set more finely",
    ))  # fmt: skip
    return replace(pred, mu_star_interval=new)
