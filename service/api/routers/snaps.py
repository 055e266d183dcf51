"""``POST /v1/snaps``: a snap-through past the transition (``sim.snap``), answered at once.

Bounded: the record holds at most 4001 samples and lasts at most 500 time units; the
nonlinear backends (euler-beam, cosserat) refuse dmu < 1e-4, whose slow passage would need
a long integration (use the CLI for those).
"""

from __future__ import annotations

from anyio import to_thread
from fastapi import APIRouter

from service.api.auth import CallerDep
from service.api.routers._common import problems
from service.schemas.snaps import SnapRequest, SnapResult

router = APIRouter(prefix="/v1/snaps", tags=["snaps"])

MIN_DMU_NONLINEAR = 1e-4


def _run(req: SnapRequest) -> dict:
    from sim.errors import ParameterError
    from sim.scene import Scene
    from sim.snap import snap

    if req.model != "normal-form" and req.dmu < MIN_DMU_NONLINEAR:
        raise ParameterError("dmu", req.dmu, f"dmu must be >= {MIN_DMU_NONLINEAR:g} for "
                             f"model={req.model!r} over the API, got {req.dmu!r}")
    fields = req.model_dump(exclude={"model", "dmu", "duration"}, exclude_none=True)
    r = snap(Scene(**fields), req.model, req.dmu, duration=req.duration)
    return r.to_dict()


@router.post("", response_model=SnapResult, summary="Snap-through past the transition",
             responses=problems(401, 422))  # fmt: skip
async def create_snap(req: SnapRequest, caller: CallerDep) -> SnapResult:
    """The strip released past mu* (or left of it, antisymmetric): snap time and record."""
    doc = await to_thread.run_sync(_run, req)
    return SnapResult.model_validate(doc)
