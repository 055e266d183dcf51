"""``POST /v1/detections``: the modes of a stored or inline signal (the detect document)."""

from __future__ import annotations

from typing import Any

import numpy as np
from anyio import to_thread
from fastapi import APIRouter, Request, Response
from fastapi.exceptions import RequestValidationError
from pydantic import ValidationError

from service import convert, recordings
from service.analysis.detect import detect
from service.api import jsonbody, limits
from service.api.auth import CallerDep
from service.api.problems import as_problems, invalid, not_found
from service.api.routers._common import problems
from service.api.state import StateDep
from service.schemas import Detection, DetectionRequest

router = APIRouter(prefix="/v1/detections", tags=["detections"])

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
async def create_detection(request: Request, state: StateDep, caller: CallerDep) -> Any:
    """Give ``signal_id`` (a stored signal) or ``w`` with ``t`` or ``dt`` (inline).

    The body is parsed by pydantic-core straight from the bytes (8x faster than
    ``json.loads`` then validation for a 1e4-sample signal: this is the hot path).
    """
    # The hot path, a small inline signal, runs whole in the analysis pool: the worker parses
    # the bytes, validates, detects and serialises (the event loop only moves bytes: it was the
    # bottleneck under load, the workers idle). Bodies over ``json_stream_bytes`` are parsed
    # here as they arrive, the samples straight into float64 (bounded memory).
    s = state.settings
    got = await jsonbody.read_small_or_model(request, DetectionRequest, s)
    if isinstance(got, bytes):
        kind, out = await state.run(inline_detection, got, s.max_samples, s.uniform_rtol)
        if kind == "json":
            return Response(out, media_type="application/json")
        if kind == "invalid":
            raise RequestValidationError(out)
        req = out  # it names a stored signal
    else:
        req = got
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
        units = (sig.row.unit, sig.row.value_unit)
    else:  # a big inline signal (streamed): validated in a thread
        rec = await to_thread.run_sync(_clean, req, s.max_samples, s.uniform_rtol)
        w, dt, notes = rec.w, rec.dt, [convert.plain(f) for f in rec.flags]
        units = (None, None)
    return await state.run(detection_doc, w, dt, req.method, notes, *units,
                           req.detect_options())  # fmt: skip


def _clean(req: DetectionRequest, max_samples: int, uniform_rtol: float) -> recordings.Recording:
    """The inline signal of ``req`` validated (422/413 naming the field)."""
    if req.w is None:
        raise invalid("w", None, "is required (or give signal_id)")
    rec = recordings.from_arrays(
        req.w, req.t, req.dt, source="json", max_samples=max_samples, uniform_rtol=uniform_rtol
    )
    limits.check_time_axis(len(rec.w), rec.dt, rec.t0, rec.t)
    return rec


def inline_detection(body: bytes, max_samples: int, uniform_rtol: float) -> tuple[str, Any]:
    """The whole work of a small detection request, in an analysis worker.

    Returns ``("json", bytes)``: the answer's body (the ``Detection`` document, serialised
    here); ``("invalid", errors)``: the body's validation errors (FastAPI's form); or
    ``("request", DetectionRequest)`` when it names a stored signal (read by the server).
    Invalid samples raise as in the server (:class:`~service.recordings.RecordingError`,
    :class:`~service.api.problems.ApiProblem`: both cross the process boundary).
    """
    try:
        req = DetectionRequest.model_validate_json(body)
    except ValidationError as exc:
        errors = exc.errors(include_url=False, include_context=False)
        return "invalid", [{**e, "loc": ("body", *e["loc"])} for e in errors]
    if req.signal_id is not None:
        return "request", req
    rec = _clean(req, max_samples, uniform_rtol)
    with as_problems("w"):
        det = detect(rec.w, dt=float(rec.dt), method=req.method, **req.detect_options())
    doc = convert.detection(det, extra_flags=[convert.plain(f) for f in rec.flags])
    return "json", doc.model_dump_json().encode()


def detection_doc(
    w: Any,
    dt: float,
    method: str = "auto",
    notes: list[dict[str, str]] | None = None,
    time_unit: str | None = None,
    value_unit: str | None = None,
    options: dict[str, Any] | None = None,
) -> dict[str, Any]:
    """``detect(w, dt=dt, method=method, **options)`` as the wire document (runs in the
    analysis pool); ``notes``: the reader's flags about the record (rounded timestamps...),
    listed first; ``time_unit``, ``value_unit``: the stored signal's units (the document says
    them; the quantity defaults to the one ``value_unit`` names); ``options``: the lab options
    (quantity, start, notch)."""
    opts = dict(options or {})
    opts.setdefault("quantity", recordings.quantity_of(value_unit))
    with as_problems("w"):
        det = detect(np.asarray(w, dtype=np.float64), dt=float(dt), method=method, **opts)
    return convert.detection(
        det, extra_flags=notes or (), time_unit=time_unit, value_unit=value_unit
    ).model_dump(mode="json")
