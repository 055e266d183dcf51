"""``POST /v1/detections``: the modes of a stored or inline signal (the detect document)."""

from __future__ import annotations

from typing import Any

import numpy as np
from anyio import to_thread
from fastapi import APIRouter, Request

from service import convert, recordings
from service.analysis.detect import detect
from service.api import jsonbody, limits
from service.api.auth import CallerDep
from service.api.problems import as_problems, invalid, not_found
from service.api.routers._common import problems
from service.api.state import StateDep
from service.schemas import Detection, DetectionRequest

router = APIRouter(prefix="/v1/detections", tags=["detections"])

_INLINE_IN_LOOP = 100_000  # validate small inline signals on the loop, big ones in a thread


@router.post(
    "",
    response_model=Detection,
    summary="Detect the modes of a signal (the `snapwarn detect --json` document)",
    responses=problems(401, 404, 413, 422),
    openapi_extra={
        "requestBody": {
            "required": True,
            "content": {
                "application/json": {"schema": {"$ref": "#/components/schemas/DetectionRequest"}}
            },
        }
    },
)
async def create_detection(
    request: Request, state: StateDep, caller: CallerDep
) -> dict[str, Any]:
    """Give ``signal_id`` (a stored signal) or ``w`` with ``t`` or ``dt`` (inline).

    The body is parsed by pydantic-core straight from the bytes (8x faster than
    ``json.loads`` then validation for a 1e4-sample signal: this is the hot path).
    """
    # Bodies over ``json_stream_bytes`` are parsed as they arrive instead, the samples straight
    # into float64 (service.api.jsonbody): bounded memory for big inline signals.
    req = await jsonbody.read_model(request, DetectionRequest, state.settings)
    if req.signal_id is not None:
        if req.w is not None or req.t is not None or req.dt is not None:
            raise invalid(
                "signal_id",
                req.signal_id,
                "must not be given together with an inline signal (w, t, dt)",
            )
        sig = await to_thread.run_sync(state.store.get_signal, req.signal_id, caller.scope)
        if sig is None:
            raise not_found("signal", req.signal_id)
        w, dt = sig.w, sig.row.dt
        notes = (sig.row.meta or {}).get("recording_flags") or []
    else:
        if req.w is None:
            raise invalid("w", None, "is required (or give signal_id)")
        s = state.settings

        def clean() -> recordings.Recording:
            return recordings.from_arrays(
                req.w, req.t, req.dt, source="json", max_samples=s.max_samples,
                uniform_rtol=s.uniform_rtol,
            )  # fmt: skip

        if len(req.w) <= _INLINE_IN_LOOP:
            rec = clean()
        else:
            rec = await to_thread.run_sync(clean)
        w, dt, notes = rec.w, rec.dt, [convert.plain(f) for f in rec.flags]
        limits.check_time_axis(len(w), dt, rec.t0, rec.t)
    return await state.run(detection_doc, w, dt, req.method, notes)


def detection_doc(
    w: Any, dt: float, method: str = "auto", notes: list[dict[str, str]] | None = None
) -> dict[str, Any]:
    """``detect(w, dt=dt, method=method)`` as the wire document (runs in the analysis pool);
    ``notes``: the reader's flags about the record (rounded timestamps...), listed first."""
    with as_problems("w"):
        det = detect(np.asarray(w, dtype=np.float64), dt=float(dt), method=method)
    return convert.detection(det, extra_flags=notes or ()).model_dump(mode="json")
