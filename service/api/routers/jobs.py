"""``/v1/jobs``: status, progress, result, error of background work."""

from __future__ import annotations

from typing import Annotated, Any

from anyio import to_thread
from fastapi import APIRouter, Query

from service.api.problems import not_found
from service.api.routers._common import problems
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
    status: Annotated[JobStatus | None, Query()] = None,
    kind: Annotated[str | None, Query(max_length=40)] = None,
    limit: Annotated[int, Query(ge=1, le=500)] = 50,
    offset: Annotated[int, Query(ge=0)] = 0,
) -> dict[str, Any]:
    rows, total = await to_thread.run_sync(state.store.list_jobs, status, kind, limit, offset)
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
async def get_job(job_id: str, state: StateDep) -> dict[str, Any]:
    row = await to_thread.run_sync(state.store.get_job, job_id)
    if row is None:
        raise not_found("job", job_id)
    return job_doc(row)
