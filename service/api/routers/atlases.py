"""``/v1/atlases``: an atlas spec -> a job that runs its cells on dask.distributed.

The job submits the cells to ``SNAPWARN_DASK_SCHEDULER`` when set (a running cluster), else to
a LocalCluster of ``SNAPWARN_ATLAS_WORKERS`` processes (default: the usable CPUs). Each
finished cell is stored at once (``atlas_cells``); a job resumed after a crash skips the
stored cells. Bounds: ``SNAPWARN_MAX_ATLAS_CELLS`` cells (default 10000) and the spec's
``timeout_s`` capped by ``SNAPWARN_ATLAS_TIME_LIMIT_S`` (default 86400 s).
"""

from __future__ import annotations

import os
from typing import Annotated, Any, Literal

from anyio import to_thread
from fastapi import APIRouter, Query, Response
from fastapi.responses import JSONResponse

from service import convert
from service.api import limits
from service.api.auth import CallerDep
from service.api.jobs import JobContext, job_handler
from service.api.problems import ApiProblem, invalid, not_found, too_large
from service.api.routers._common import MAX_OFFSET, problems
from service.api.state import AppState, StateDep, job_doc
from service.api.storage import as_utc
from service.api.storage import atlases as store_atlases
from service.schemas.atlases import Atlas, AtlasCellPage, AtlasMetric, AtlasPage, AtlasRequest

router = APIRouter(prefix="/v1/atlases", tags=["atlases"])

API_KINDS = ("bifurcation", "warn")


def _env_int(name: str, default: int) -> int:
    try:
        return int(os.environ.get(name, default))
    except ValueError:
        return default


def max_cells() -> int:
    return _env_int("SNAPWARN_MAX_ATLAS_CELLS", 10_000)


def time_limit_s() -> float:
    return float(_env_int("SNAPWARN_ATLAS_TIME_LIMIT_S", 86_400))


def atlas_doc(atlas: Any, job: Any, done: int) -> dict[str, Any]:
    """The atlas resource (its summary once the job succeeded)."""
    summary = (job.result or {}).get("summary") if job.status == "succeeded" else None
    doc = Atlas(id=atlas.id, name=atlas.name, kind=atlas.kind, status=job.status,
                spec=atlas.spec, cells_total=atlas.cells_total, cells_done=done,
                job=job_doc(job), summary=summary, created_at=as_utc(atlas.created_at))  # fmt: skip
    return doc.model_dump(mode="json")


def _parse(doc: dict[str, Any]) -> Any:
    from service.atlas import SpecError, parse_spec

    try:
        return parse_spec(doc)
    except SpecError as exc:
        raise invalid(f"spec.{exc.parameter}", exc.value, str(exc)) from None


def _check_elements(doc: Any, limit: int) -> None:
    """422 for an ``elements`` anywhere in the spec (fixed, an axis, a cell) beyond the
    server's limit, before the spec's own (wider, the CLI's) bound speaks."""
    stack = [doc]
    while stack:
        node = stack.pop()
        if isinstance(node, dict):
            for k, v in node.items():
                vals = v if isinstance(v, list) else [v]
                for x in vals if k == "elements" else ():
                    if isinstance(x, (int, float)) and not isinstance(x, bool) and x > limit:
                        raise invalid("spec.elements", x, f"exceeds the limit of {limit} "
                                      "(setting SNAPWARN_MAX_ELEMENTS)")  # fmt: skip
                stack.append(v)
        elif isinstance(node, list):
            stack.extend(node)


@router.post(
    "",
    status_code=202,
    response_model=Atlas,
    summary="Start an atlas: a grid (or list) of bifurcation or warn cells, run as a job",
    responses=problems(401, 413, 422),
)
async def create_atlas(req: AtlasRequest, state: StateDep, caller: CallerDep) -> JSONResponse:
    """Answers 202 with the atlas and its job; poll ``/v1/atlases/{id}``; rows arrive in
    ``/v1/atlases/{id}/cells`` as the cells finish."""
    raw = req.spec.model_dump(mode="json", exclude_none=True, by_alias=True)
    if raw["kind"] not in API_KINDS:
        raise invalid("spec.kind", raw["kind"], f"runs from the CLI only (manifests are files "
                      f"of the client); the API runs {list(API_KINDS)}")  # fmt: skip
    _check_elements(raw, state.settings.max_elements)
    spec = await to_thread.run_sync(_parse, raw)
    if len(spec.cells) > max_cells():
        raise too_large("spec", len(spec.cells), f"{len(spec.cells)} cells exceed the limit of "
                        f"{max_cells()} (setting SNAPWARN_MAX_ATLAS_CELLS)")  # fmt: skip
    for c in spec.cells:  # the same per-scene bound as a simulation
        if (c.inputs.get("elements") or 0) > state.settings.max_elements:
            raise invalid("spec.elements", c.inputs["elements"], f"exceeds the limit of "
                          f"{state.settings.max_elements} (setting SNAPWARN_MAX_ELEMENTS)")
    await to_thread.run_sync(limits.check_queue, state.store, caller.owner, state.settings)
    # under the job time limit like every job: the engine's own bound stops it first (the
    # finished cells stored), with a grace for the summary before the job's limit
    job_limit = state.settings.job_time_limit_s
    grace = min(300.0, 0.1 * job_limit)
    limit = min(spec.timeout_s, time_limit_s(), job_limit - grace)
    run_spec = {**spec.to_dict(), "timeout_s": limit}
    atlas, job = await to_thread.run_sync(
        lambda: store_atlases.create_atlas(
            state.store, name=req.name or spec.name, kind=spec.kind, spec=spec.to_dict(),
            params={"spec": run_spec}, cells_total=len(spec.cells), owner=caller.owner,
            time_limit_s=limit + grace,
            max_active=state.settings.max_active_jobs_per_owner)  # fmt: skip
    )
    if state.runner is not None:
        state.runner.wake()
    return JSONResponse(atlas_doc(atlas, job, 0), status_code=202,
                        headers={"Location": f"/v1/atlases/{atlas.id}"})  # fmt: skip


@router.get("", response_model=AtlasPage, responses=problems(401, 422),
            summary="Atlases, newest first (the caller's own; an admin key sees all)")
async def list_atlases(
    state: StateDep,
    caller: CallerDep,
    limit: Annotated[int, Query(ge=1, le=500)] = 50,
    offset: Annotated[int, Query(ge=0, le=MAX_OFFSET)] = 0,
) -> dict[str, Any]:
    rows, total = await to_thread.run_sync(
        lambda: store_atlases.list_atlases(state.store, limit, offset, scope=caller.scope))
    return {"items": [atlas_doc(*r) for r in rows], "total": total, "limit": limit,
            "offset": offset}  # fmt: skip


async def _get(state: AppState, atlas_id: str, scope: str | None) -> tuple[Any, Any, int]:
    found = await to_thread.run_sync(store_atlases.get_atlas, state.store, atlas_id, scope)
    if found is None:
        raise not_found("atlas", atlas_id)
    return found


@router.get("/{atlas_id}", response_model=Atlas, responses=problems(401, 404),
            summary="An atlas: its spec, progress (cells done) and, once done, its summary")
async def get_atlas(atlas_id: str, state: StateDep, caller: CallerDep) -> dict[str, Any]:
    return atlas_doc(*await _get(state, atlas_id, caller.scope))


@router.get("/{atlas_id}/cells", response_model=AtlasCellPage, responses=problems(401, 404, 422),
            summary="The finished cells of an atlas, in the spec's order")
async def list_cells(
    atlas_id: str,
    state: StateDep,
    caller: CallerDep,
    limit: Annotated[int, Query(ge=1, le=5000)] = 500,
    offset: Annotated[int, Query(ge=0, le=MAX_OFFSET)] = 0,
    status: Literal["ok", "failed"] | None = None,
) -> dict[str, Any]:
    await _get(state, atlas_id, caller.scope)
    docs, total = await to_thread.run_sync(
        lambda: store_atlases.list_cells(state.store, atlas_id, limit, offset, status))
    return {"items": docs, "total": total, "limit": limit, "offset": offset}


def _heatmap(docs: list[dict[str, Any]], kind: str, name: str, x: str, y: str,
             metric: str, fmt: str) -> bytes:  # fmt: skip
    import tempfile
    from pathlib import Path

    from service.atlas import CellResult
    from service.atlas.charts import heatmap, render_png, write_csv

    hm = heatmap([CellResult.from_dict(d) for d in docs], x, y, metric)
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / f"heatmap.{fmt}"
        if fmt == "png":
            render_png(hm, path, title=f"{name}: {metric}")
        else:
            write_csv(hm, path)
        return path.read_bytes()


async def _chart(atlas_id: str, state: AppState, scope: str | None, metric: str,
                 x: str | None, y: str | None, fmt: str) -> Response:  # fmt: skip
    atlas, job, done = await _get(state, atlas_id, scope)
    if done == 0:
        raise ApiProblem(409, f"atlas {atlas_id!r} has no finished cell yet", field="cells_done",
                         value=0)  # fmt: skip
    chart = (atlas.spec.get("chart") or {})
    varied = list(atlas.spec.get("grid") or {})
    x = x or chart.get("x") or (varied[0] if varied else None)
    y = y or chart.get("y") or (varied[1] if len(varied) > 1 else None)
    for field, v in (("x", x), ("y", y)):
        if v is None:
            raise invalid(field, v, "is required: name a varied parameter of the atlas")
    if x == y:
        raise invalid("y", y, f"must differ from x ({x!r})")
    docs, _ = await to_thread.run_sync(store_atlases.list_cells, state.store, atlas_id)
    for field, v in (("x", x), ("y", y)):
        if not any(v in d["inputs"] for d in docs):
            raise invalid(field, v, f"is not a parameter of the atlas's cells; known: "
                          f"{sorted(docs[0]['inputs'])}")  # fmt: skip
    body = await state.run(_heatmap, docs, atlas.kind, atlas.name or atlas_id, x, y, metric, fmt)
    return Response(body, media_type="image/png" if fmt == "png" else "text/csv")


@router.get("/{atlas_id}/heatmap.png", response_class=Response,
            summary="A result of the finished cells over two parameters (PNG)",
            responses={200: {"content": {"image/png": {}}, "description": "PNG heatmap."},
                       **problems(401, 404, 409, 422)})  # fmt: skip
async def heatmap_png(atlas_id: str, state: StateDep, caller: CallerDep,
                      metric: AtlasMetric = "mu_star", x: str | None = None,
                      y: str | None = None) -> Response:  # fmt: skip
    return await _chart(atlas_id, state, caller.scope, metric, x, y, "png")


@router.get("/{atlas_id}/heatmap.csv", response_class=Response,
            summary="A result of the finished cells over two parameters (CSV matrix)",
            responses={200: {"content": {"text/csv": {}}, "description": "CSV matrix."},
                       **problems(401, 404, 409, 422)})  # fmt: skip
async def heatmap_csv(atlas_id: str, state: StateDep, caller: CallerDep,
                      metric: AtlasMetric = "mu_star", x: str | None = None,
                      y: str | None = None) -> Response:  # fmt: skip
    return await _chart(atlas_id, state, caller.scope, metric, x, y, "csv")


@job_handler("atlas")
def run_atlas_job(ctx: JobContext) -> dict[str, Any]:
    """Run the atlas's missing cells on dask (see the module docstring); store each at once."""
    from service.atlas import parse_spec, run_atlas

    spec = parse_spec(ctx.params["spec"])
    sink = store_atlases.DbCellSink(ctx.store, ctx.job_id)
    workers = _env_int("SNAPWARN_ATLAS_WORKERS", 0) or None

    def progress(done: int, total: int, row: Any) -> None:
        msg = f"{done}/{total} cells"
        if row is not None:
            msg += f"; last {row.status} in {row.seconds:.2f} s on {row.worker}"
        ctx.progress(done / max(total, 1), msg)

    result = run_atlas(spec, workers=workers, sink=sink, progress=progress)
    if result.missing:
        raise ApiProblem(503, f"{len(result.missing)} of {len(spec.cells)} cells are not done "
                         f"(time bound or lost workers); the finished cells are stored",
                         field="cells_done", value=len(spec.cells) - len(result.missing))
    return {"summary": convert.atlas_summary(result.summary).model_dump(mode="json")}
