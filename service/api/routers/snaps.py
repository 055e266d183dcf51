"""``POST /v1/snaps``: a snap-through past the transition (``sim.snap``).

The normal form answers at once (200, the ``snap``); the nonlinear backends (euler-beam,
cosserat) become a job (202, ``job``; ``GET /v1/jobs/{id}`` holds the snap document as its
result). Bounded: at most 4001 samples over at most 500 time units, and dmu >= 1e-4 for the
nonlinear backends, whose slow passage would need a long integration (the CLI has no bound).

The strip, damping and resolution are checked at the door exactly as a simulation's
(``service.api.limits.check_scene``: the wire bounds, ``sim.Scene``'s rules, elements <=
SNAPWARN_MAX_ELEMENTS whether given or chosen from rtol) and the duration against
SNAPWARN_MAX_SIM_DURATION. A snap's record is 4000 samples (``sim.snap``: duration / 4000
apart); the rod steps no coarser than its own step for its rtol (as its simulation would:
``sim.snap.rod_snap_grid``), several steps a sample over a long duration, so its cost is
elements x 4000 x steps per sample: charged against a simulation's budget
(SNAPWARN_MAX_SIM_WORK element-steps), a 422 naming the duration (and the longest that fits)
before any job. A rod whose integration still diverges fails with a 422 naming the duration,
never a truncated record passed as a snap.
"""

from __future__ import annotations

import math
from typing import Any

from anyio import to_thread
from fastapi import APIRouter
from fastapi.responses import JSONResponse

from service.api import limits
from service.api.auth import CallerDep
from service.api.jobs import JobContext, job_handler
from service.api.problems import as_problems, invalid
from service.api.routers._common import problems
from service.api.state import StateDep, job_doc
from service.schemas import Job
from service.schemas.snaps import SnapAnswer, SnapRequest, SnapResult

router = APIRouter(prefix="/v1/snaps", tags=["snaps"])

MIN_DMU_NONLINEAR = 1e-4
SNAP_SAMPLES = 4000  # sim.snap's record: duration / 4000 apart


def scene_of(params: dict[str, Any]) -> dict[str, Any]:
    """The ``sim.Scene`` fields of a snap request (null: the scene's default)."""
    return {k: v for k, v in params.items()
            if k not in ("model", "dmu", "duration") and v is not None}  # fmt: skip


def check_snap(params: dict[str, Any], settings: Any) -> None:
    """The door's checks of a snap (blocking: numerics for the rod's elements; see the module
    docstring): 422 naming the field and the value."""
    plan = limits.check_scene(scene_of(params), params["model"], settings, timed=False)
    limits.check_simulation({"duration": params.get("duration")}, params["model"], settings)
    if params["model"] == "cosserat" and plan.elements is not None:
        _check_rod_work(params, plan.elements, settings)


def _check_rod_work(params: dict[str, Any], elements: int, settings: Any) -> None:
    """422 when the rod's snap would cost more than a simulation may (``max_sim_work``
    element-steps): its 4000 samples, each as many steps as the rod's own step needs
    (``sim.snap.rod_snap_grid``), x its elements. Names the duration (with the longest that
    fits), or the elements when even one step per sample is over the budget."""
    from sim.scene import Scene
    from sim.snap import default_duration, rod_snap_grid

    with as_problems("snap"):
        scene = Scene(**scene_of(params))
        duration = params.get("duration")
        if duration is None:
            duration = default_duration(scene.actuation, params["dmu"])
        grid = rod_snap_grid(scene, elements, duration, duration / SNAP_SAMPLES)
    budget = settings.max_sim_work
    if grid.work <= budget:
        return
    charge = (
        f"{grid.samples} samples x {grid.every} steps (the rod's own step {grid.step:.3g} for "
        f"its rtol) x elements={elements} = {grid.work:.3g} element-steps, more than the budget "
        f"{budget:.3g} of the cosserat backend (setting SNAPWARN_MAX_SIM_WORK)"
    )
    every = math.floor(budget / (elements * grid.samples))
    if every < 1:
        raise invalid("elements", elements, f"gives {charge}; ask for fewer elements")
    given = "" if params.get("duration") is not None else "(the default) "
    fits = grid.samples * every * grid.step
    raise invalid("duration", duration, f"{given}gives {charge}; ask for duration <= "
                  f"{fits:.3g}")  # fmt: skip


def run_snap(params: dict[str, Any]) -> dict[str, Any]:
    """Run ``sim.snap.snap`` for a validated request's fields (the snap document, a
    :class:`~service.schemas.snaps.SnapResult` dumped)."""
    from service import convert
    from sim.errors import ParameterError
    from sim.scene import Scene
    from sim.snap import snap

    model, dmu = params["model"], params["dmu"]
    with as_problems("snap"):
        if model != "normal-form" and dmu < MIN_DMU_NONLINEAR:
            raise ParameterError("dmu", dmu, f"dmu must be >= {MIN_DMU_NONLINEAR:g} for "
                                 f"model={model!r} over the API, got {dmu!r}")
        r = snap(Scene(**scene_of(params)), model, dmu, duration=params.get("duration"))
    return convert.snap(r).model_dump(mode="json")


@router.post("", response_model=SnapAnswer, summary="Snap-through past the transition",
             responses={202: {"description": "Became a job (see /v1/jobs/{id}); its result "
                              "is the snap document.", "model": SnapAnswer},
                        **problems(401, 422)})  # fmt: skip
async def create_snap(req: SnapRequest, state: StateDep, caller: CallerDep) -> JSONResponse:
    """200 with the snap (normal form), or 202 with the job that computes it."""
    params = req.model_dump()
    await to_thread.run_sync(check_snap, params, state.settings)
    if req.model == "normal-form":  # in the analysis pool, within the request time limit
        doc = await state.run(run_snap, params)
        answer = SnapAnswer(snap=SnapResult.model_validate(doc))
        return JSONResponse(answer.model_dump(mode="json"), status_code=200)
    if req.dmu < MIN_DMU_NONLINEAR:  # refused at the door (422), not in the job
        await state.run(run_snap, params)
    await to_thread.run_sync(limits.check_queue, state.store, caller.owner, state.settings)
    row = await to_thread.run_sync(
        lambda: state.store.create_job("snap", params, owner=caller.owner,
                                       time_limit_s=state.settings.job_time_limit_s,
                                       max_active=state.settings.max_active_jobs_per_owner)
    )  # fmt: skip
    if state.runner is not None:
        state.runner.wake()
    job = Job.model_validate(job_doc(row))
    return JSONResponse(SnapAnswer(job=job).model_dump(mode="json"), status_code=202,
                        headers={"Location": f"/v1/jobs/{row.id}"})  # fmt: skip


@job_handler("snap")
def run_snap_job(ctx: JobContext) -> dict[str, Any]:
    """The snap behind a 202: its document is the job's result."""
    ctx.progress(0.0, f"snap-through ({ctx.params['model']}, dmu={ctx.params['dmu']:g})")
    return run_snap(ctx.params)
