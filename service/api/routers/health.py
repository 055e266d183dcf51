"""``GET /healthz``: liveness, database, job workers, numerics installed, kernels ready."""

from __future__ import annotations

from importlib.metadata import PackageNotFoundError, version

from anyio import to_thread
from fastapi import APIRouter
from fastapi.responses import JSONResponse

from service.api.state import StateDep
from service.schemas import Health

router = APIRouter(tags=["health"])

try:
    VERSION = version("snapwarn")
except PackageNotFoundError:  # pragma: no cover
    VERSION = "0+unknown"


@router.get(
    "/healthz",
    response_model=Health,
    summary="Liveness and readiness",
    responses={503: {"description": "The database does not answer."}},
)
async def healthz(state: StateDep) -> JSONResponse:
    """200 when the database answers (503 otherwise); live job workers; numerics installed;
    ``ready`` once the analysis workers have loaded their kernels."""
    try:
        await to_thread.run_sync(state.store.ping)
        db = "ok"
        workers = await to_thread.run_sync(state.store.live_workers, state.settings.job_lease_s)
    except Exception as exc:  # noqa: BLE001
        db = f"error: {type(exc).__name__}"
        workers = 0
    avail = state.numerics_status()  # never waits for the pool: /healthz stays cheap
    doc = Health(
        status="ok" if db == "ok" else "degraded",
        version=VERSION,
        database=db,
        workers=workers,
        numerics=avail,
        ready=state.kernels_ready,
    )
    return JSONResponse(doc.model_dump(), status_code=200 if db == "ok" else 503)
