"""``/v1/sweeps``: a sweep of measurements (recorded or simulated) -> a job -> the warning."""

from __future__ import annotations

import math
from typing import Any

from anyio import to_thread
from fastapi import APIRouter, Response
from fastapi.responses import JSONResponse

from service.api import numerics, plots
from service.api.auth import CallerDep
from service.api.jobs import JobContext, job_handler
from service.api.problems import ApiProblem, invalid, not_found, too_large
from service.api.routers._common import problems
from service.api.state import AppState, StateDep, job_doc
from service.api.storage import as_utc
from service.schemas import Sweep, SweepRequest

router = APIRouter(prefix="/v1/sweeps", tags=["sweeps"])


_PREDICTION_KEYS = (
    "mu_star",
    "mu_star_interval",
    "mu_star_std",
    "a",
    "transition",
    "probabilities",
    "stopped",
    "n_measurements",
)


def sweep_doc(sweep: Any, job: Any) -> dict[str, Any]:
    """The sweep resource: the pipeline's document and its main parts, picked (not computed)."""
    result = job.result if job.status == "succeeded" else None
    r = result or {}
    prediction = r.get("prediction")
    if prediction is None and r.get("mu_star", None) is not None or "mu_star" in r:
        prediction = {k: r[k] for k in _PREDICTION_KEYS if k in r}
    alarm = r.get("alarm")
    if isinstance(alarm, list):
        alarm = alarm[-1] if alarm else None
    return {
        "id": sweep.id,
        "name": sweep.name,
        "status": job.status,
        "request": sweep.request,
        "job": job_doc(job),
        "result": result,
        "measurements": r.get("measurements"),
        "classification": r.get("classification"),
        "prediction": prediction,
        "alarm": alarm,
        "created_at": as_utc(sweep.created_at),
    }


async def _resolve_measurements(req: SweepRequest, state: AppState) -> list[dict[str, Any]]:
    ms = req.measurements or []
    limit = state.settings.max_sweep_signals
    if len(ms) > limit:
        raise too_large(
            "measurements",
            len(ms),
            f"{len(ms)} measurements exceed the limit of "
            f"{limit} (setting SNAPWARN_MAX_SWEEP_SIGNALS)",
        )
    out = []
    for k, m in enumerate(ms):
        row = await to_thread.run_sync(state.store.get_signal_meta, m.signal_id)
        if row is None:
            raise invalid(f"measurements[{k}].signal_id", m.signal_id, "is not a stored signal")
        value = m.control_value if m.control_value is not None else row.control_value
        if value is None:
            raise invalid(
                f"measurements[{k}].control_value",
                None,
                "is required: the signal was stored without a control value",
            )
        if not math.isfinite(value):
            raise invalid(f"measurements[{k}].control_value", value, "must be finite")
        out.append({"signal_id": m.signal_id, "control_value": float(value)})
    return out


@router.post(
    "",
    status_code=202,
    response_model=Sweep,
    summary="Start a sweep: recorded signals with their control values, or a simulated one",
    responses=problems(401, 413, 422, 501),
)
async def create_sweep(req: SweepRequest, state: StateDep, caller: CallerDep) -> JSONResponse:
    """Answers 202 with the sweep and its job; poll ``/v1/sweeps/{id}`` or ``/v1/jobs/{id}``.

    With ``"mode": "live"`` answers 201 with an open sweep (``service.api.routers.live``)."""
    if req.mode == "live":
        from service.api.routers.live import create_live

        return await create_live(req, state, caller)
    if (req.measurements is None) == (req.simulate is None):
        raise invalid("measurements", None, "give exactly one of 'measurements' or 'simulate'")
    if req.measurements is not None:
        if len(req.measurements) < 2:
            raise invalid("measurements", len(req.measurements), "need at least 2 signals")
        needed = "sweep_from_signals"
        kind = "sweep-signals"
        params: dict[str, Any] = {"measurements": await _resolve_measurements(req, state)}
    else:
        needed = "warn"
        kind = "sweep-simulated"
        params = req.simulate.model_dump(exclude_none=True)
    await state.run(numerics.load_ok, needed)
    sweep, job = await to_thread.run_sync(
        state.store.create_sweep,
        kind,
        req.model_dump(mode="json", exclude_none=True),
        params,
        req.name,
    )
    if state.runner is not None:
        state.runner.wake()
    doc = Sweep.model_validate(sweep_doc(sweep, job)).model_dump(mode="json")
    return JSONResponse(doc, status_code=202, headers={"Location": f"/v1/sweeps/{sweep.id}"})


async def _get(state: AppState, sweep_id: str) -> tuple[Any, Any]:
    found = await to_thread.run_sync(state.store.get_sweep, sweep_id)
    if found is None:
        raise not_found("sweep", sweep_id)
    return found


@router.get(
    "/{sweep_id}",
    response_model=Sweep,
    summary="A sweep: measurements, classification, prediction, alarm",
    responses=problems(401, 404),
)
async def get_sweep(sweep_id: str, state: StateDep) -> dict[str, Any]:
    sweep, job = await _get(state, sweep_id)
    return sweep_doc(sweep, job)


async def _plot(sweep_id: str, state: AppState, fmt: str) -> Response:
    sweep, job = await _get(state, sweep_id)
    if job.status != "succeeded":
        raise ApiProblem(
            409,
            f"sweep {sweep_id!r} is {job.status}; its chart exists once it succeeded",
            field="status",
            value=job.status,
        )
    body = await state.run(_render, job.result, sweep.name or sweep_id, fmt)
    return Response(body, media_type=plots.MEDIA[fmt])


def _render(doc: dict[str, Any], title: str, fmt: str) -> bytes:
    return plots.sweep_plot(doc, title=title, fmt=fmt)


@router.get(
    "/{sweep_id}/plot.png",
    summary="T(mu), the extrapolation and mu*'s interval (PNG)",
    response_class=Response,
    responses={
        200: {"content": {"image/png": {}}, "description": "PNG chart."},
        **problems(401, 404, 409),
    },
)
async def plot_sweep_png(sweep_id: str, state: StateDep) -> Response:
    return await _plot(sweep_id, state, "png")


@router.get(
    "/{sweep_id}/plot.svg",
    summary="T(mu), the extrapolation and mu*'s interval (SVG)",
    response_class=Response,
    responses={
        200: {"content": {"image/svg+xml": {}}, "description": "SVG chart."},
        **problems(401, 404, 409),
    },
)
async def plot_sweep_svg(sweep_id: str, state: StateDep) -> Response:
    return await _plot(sweep_id, state, "svg")


@job_handler("sweep-simulated")
def run_simulated_sweep_job(ctx: JobContext) -> dict[str, Any]:
    """A simulated early-warning sweep (``warn``)."""
    return numerics.warn(ctx.params, ctx.progress)


@job_handler("sweep-signals")
def run_signal_sweep_job(ctx: JobContext) -> dict[str, Any]:
    """A sweep of stored recordings: detect each, then classify and predict."""
    params, progress, store = ctx.params, ctx.progress, ctx.store
    items = []
    for k, m in enumerate(params["measurements"]):
        sig = store.get_signal(m["signal_id"])
        if sig is None:
            raise ApiProblem(
                422,
                f"signal {m['signal_id']!r} was deleted",
                field=f"measurements[{k}].signal_id",
                value=m["signal_id"],
            )
        items.append((sig.w, float(sig.row.dt), float(m["control_value"])))
        progress(0.1 * (k + 1) / len(params["measurements"]), "loading signals")
    progress(0.1, f"analysing {len(items)} signals")
    names = [m["signal_id"] for m in params["measurements"]]
    return numerics.sweep_from_signals(
        items, names, lambda f, msg: progress(0.1 + 0.9 * f, msg)
    )
