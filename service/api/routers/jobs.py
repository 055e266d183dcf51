"""``/v1/jobs``: status, progress, result, error of background work."""

from __future__ import annotations

from typing import Annotated, Any

from anyio import to_thread
from fastapi import APIRouter, Query

from service.api.auth import CallerDep
from service.api.problems import ApiProblem, not_found
from service.api.routers._common import MAX_OFFSET, problems
from service.api.state import StateDep, job_doc
from service.schemas import Job, JobPage, JobStatus

router = APIRouter(prefix="/v1/jobs", tags=["jobs"])


@router.get(
    "",
    response_model=JobPage,
    summary="Jobs, newest first (filter by status and kind)",
    responses=problems(401, 422),
)
async def list_jobs(
    state: StateDep,
    caller: CallerDep,
    status: Annotated[JobStatus | None, Query()] = None,
    kind: Annotated[str | None, Query(max_length=40)] = None,
    limit: Annotated[int, Query(ge=1, le=500)] = 50,
    offset: Annotated[int, Query(ge=0, le=MAX_OFFSET)] = 0,
) -> dict[str, Any]:
    rows, total = await to_thread.run_sync(
        state.store.list_jobs, status, kind, limit, offset, caller.scope
    )
    return {
        "items": [job_doc(r) for r in rows],
        "total": total,
        "limit": limit,
        "offset": offset,
    }


@router.get(
    "/{job_id}",
    response_model=Job,
    summary="A job: status, progress, result, error",
    responses=problems(401, 404),
)
async def get_job(job_id: str, state: StateDep, caller: CallerDep) -> dict[str, Any]:
    row = await to_thread.run_sync(state.store.get_job, job_id, caller.scope)
    if row is None:
        raise not_found("job", job_id)
    return job_doc(row)


@router.post(
    "/{job_id}/cancel",
    response_model=Job,
    summary="Cancel a queued or running job (it ends 'cancelled' and is never re-run)",
    responses=problems(401, 404, 409),
)
async def cancel_job(job_id: str, state: StateDep, caller: CallerDep) -> dict[str, Any]:
    """A running job's process is stopped within a heartbeat; a finished job answers 409."""
    who = caller.owner if caller.key_id is None else f"{caller.owner} (key {caller.key_id})"
    row = await to_thread.run_sync(
        state.store.cancel_job, job_id, f"cancelled by {who}", caller.scope
    )
    if row is None:
        raise not_found("job", job_id)
    if row.status != "cancelled":
        raise ApiProblem(
            409,
            f"job {job_id!r} is {row.status}: only queued or running jobs can be cancelled",
            field="status",
            value=row.status,
        )
    if state.runner is not None:
        state.runner.wake()
    return job_doc(row)
