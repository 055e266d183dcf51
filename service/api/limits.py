"""Bounds checked at the door, before any work: simulation cost, queue length per owner.

Each failing check is a problem naming the field, the value and the setting that bounds it.
"""

from __future__ import annotations

import math
from typing import Any

from service.api.problems import ApiProblem, invalid
from service.api.settings import Settings
from service.api.storage import Store

#: Models whose cost grows with the number of elements (the others ignore ``elements``).
DISCRETISED = ("euler-beam", "cosserat", "auto")


def check_simulation(scene: dict[str, Any], model: str | None, settings: Settings) -> None:
    """422 when a scene would cost more than the settings allow.

    Bounds: ``elements <= max_elements``, ``duration <= max_sim_duration``, ``duration / dt <=
    max_samples`` and, for discretised models, ``duration x elements <= max_sim_work``.
    """
    elements = scene.get("elements")
    if elements is not None and elements > settings.max_elements:
        raise invalid(
            "elements",
            elements,
            f"exceeds the limit of {settings.max_elements} (setting SNAPWARN_MAX_ELEMENTS)",
        )
    duration = scene.get("duration")
    dt = scene.get("dt")
    if duration is not None:
        if not math.isfinite(duration) or duration > settings.max_sim_duration:
            raise invalid(
                "duration",
                duration,
                f"exceeds the limit of {settings.max_sim_duration:g} time units "
                "(setting SNAPWARN_MAX_SIM_DURATION)",
            )
        if dt is not None and dt > 0 and duration / dt > settings.max_samples:
            raise invalid(
                "dt",
                dt,
                f"gives {duration / dt:.3g} samples over duration={duration:g}, more than "
                f"{settings.max_samples} (setting SNAPWARN_MAX_SAMPLES)",
            )
        work = duration * float(elements or 50)
        if (model or "auto") in DISCRETISED and work > settings.max_sim_work:
            raise invalid(
                "duration",
                duration,
                f"x elements={elements} = {work:.3g} exceeds the simulation budget "
                f"{settings.max_sim_work:g} (setting SNAPWARN_MAX_SIM_WORK)",
            )


def check_queue(store: Store, owner: str, settings: Settings) -> None:
    """429 when ``owner`` already has ``max_active_jobs_per_owner`` queued or running jobs."""
    n = store.count_active_jobs(owner)
    if n >= settings.max_active_jobs_per_owner:
        raise ApiProblem(
            429,
            f"{n} jobs of this owner are queued or running, the limit is "
            f"{settings.max_active_jobs_per_owner} (setting SNAPWARN_MAX_ACTIVE_JOBS_PER_OWNER); "
            "retry when some have finished, or cancel some",
            title="Too many jobs",
            slug="too-many-jobs",
            field="jobs",
            value=n,
            headers={"Retry-After": "10"},
        )
