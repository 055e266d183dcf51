"""``POST /v1/simulations``: run a scene; cheap models answer at once, others become jobs."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from anyio import to_thread
from fastapi import APIRouter
from fastapi.responses import JSONResponse

import sim
from service import convert
from service.api import limits
from service.api.auth import CallerDep
from service.api.jobs import JobContext, job_handler, store_simulated_signal
from service.api.problems import as_problems
from service.api.routers._common import problems
from service.api.state import StateDep, job_doc, signal_meta
from service.schemas import Job, SignalMeta, SimulationRequest, SimulationResult

router = APIRouter(prefix="/v1/simulations", tags=["simulations"])

_NOT_SCENE = {"model", "background", "name"}


@router.post(
    "",
    status_code=201,
    response_model=SimulationResult,
    summary="Simulate an impulse response and store it as a signal",
    responses={
        202: {"description": "Became a job (see /v1/jobs/{id}).", "model": SimulationResult},
        **problems(401, 413, 422),
    },
)
async def create_simulation(
    req: SimulationRequest, state: StateDep, caller: CallerDep
) -> JSONResponse:
    """201 with the stored signal, or 202 with the job that will store it."""
    scene = req.model_dump(exclude=_NOT_SCENE)
    limits.check_simulation(scene, req.model, state.settings)  # cheap bounds, no numerics
    await to_thread.run_sync(limits.check_scene, scene, req.model, state.settings)
    background = req.background
    if background is None:
        background = req.model not in state.settings.sync_simulation_models
    params: dict[str, Any] = {"scene": scene, "model": req.model, "name": req.name}
    if background:
        await to_thread.run_sync(limits.check_queue, state.store, caller.owner, state.settings)
        row = await to_thread.run_sync(
            lambda: state.store.create_job(
                "simulation",
                params,
                owner=caller.owner,
                time_limit_s=state.settings.job_time_limit_s,
                max_active=state.settings.max_active_jobs_per_owner,
            )
        )
        if state.runner is not None:
            state.runner.wake()
        job = Job.model_validate(job_doc(row))
        return JSONResponse(
            SimulationResult(job=job).model_dump(mode="json"),
            status_code=202,
            headers={"Location": f"/v1/jobs/{row.id}"},
        )
    out = await state.run(simulate, scene, req.model)
    row = await to_thread.run_sync(store_simulated_signal, state.store, out, params, caller.owner)
    meta = SignalMeta.model_validate(signal_meta(row))
    return JSONResponse(
        SimulationResult(signal=meta).model_dump(mode="json"),
        status_code=201,
        headers={"Location": f"/v1/signals/{row.id}"},
    )


@job_handler("simulation")
def run_simulation_job(ctx: JobContext) -> dict[str, Any]:
    """Simulate the stored scene and store the signal (the job behind a 202)."""
    params = ctx.params
    ctx.progress(0.0, f"simulating ({params['model']})")
    out = simulate(params["scene"], params["model"])
    row = store_simulated_signal(ctx.store, out, params, ctx.owner)
    return {"signal_id": row.id}


def simulate(params: dict[str, Any], model: str) -> dict[str, Any]:
    """Run ``sim.simulate(Scene(**params), model=model)`` (in the analysis pool): the arrays,
    the static level and the backend's report (the document of
    :class:`~service.schemas.sim.SimulationInfo`, stored as the signal's ``metadata.info``)."""
    with as_problems("scene"):
        out = sim.simulate(sim.Scene(**params), model=model)
    w_static = float(out.w_static)
    return {
        "t": np.asarray(out.t, dtype=np.float64),
        "w": np.asarray(out.w, dtype=np.float64),
        "w_static": w_static if math.isfinite(w_static) else None,
        "model": str(out.model),
        "info": convert.simulation_info(out.info or {}).model_dump(mode="json"),
    }
