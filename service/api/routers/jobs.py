"""``GET /v1/jobs/{id}``: status, progress, result, error of background work."""

from __future__ import annotations

from typing import Any

from anyio import to_thread
from fastapi import APIRouter

from service.api.problems import not_found
from service.api.routers._common import problems
from service.api.state import StateDep, job_doc
from service.schemas import Job

router = APIRouter(prefix="/v1/jobs", tags=["jobs"])


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
