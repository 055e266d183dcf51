"""``/v1/signals``: recorded signals in (JSON or a file), metadata, data, plot, delete."""

from __future__ import annotations

import json
from dataclasses import dataclass
from typing import Annotated, Any

from anyio import to_thread
from fastapi import APIRouter, Query, Request, Response
from fastapi.responses import JSONResponse

from service import convert, recordings
from service.api import jsonbody, limits, plots
from service.api.auth import CallerDep
from service.api.problems import ApiProblem, invalid, not_found
from service.api.routers._common import MAX_OFFSET, RECORDING_FORM_FIELDS
from service.api.state import AppState, StateDep, signal_meta
from service.schemas import Control, SignalData, SignalIn, SignalMeta, SignalPage
from service.schemas.common import PROBLEM_MEDIA_TYPE

router = APIRouter(prefix="/v1/signals", tags=["signals"])

PROBLEM = {"content": {PROBLEM_MEDIA_TYPE: {"schema": {"$ref": "#/components/schemas/Problem"}}}}
ERRORS = {
    404: {"description": "No such signal.", **PROBLEM},
    413: {"description": "Payload over the limits.", **PROBLEM},
    415: {"description": "Unknown file format.", **PROBLEM},
    422: {"description": "Invalid input (the field and the value are named).", **PROBLEM},
}

UPLOAD_FORM_SCHEMA = {
    "type": "object",
    "required": ["file"],
    "properties": {
        **RECORDING_FORM_FIELDS,
        "value_unit": {"type": "string"},
        "resample": {
            "type": "boolean",
            "description": "Interpolate non-uniform sample times onto a uniform grid.",
        },
        "control_name": {"type": "string"},
        "control_value": {"type": "number"},
        "control_unit": {"type": "string"},
        "metadata": {"type": "string", "description": "A JSON object."},
    },
}


def _form_float(form: Any, name: str) -> float | None:
    v = form.get(name)
    if v is None or v == "":
        return None
    try:
        return float(v)
    except (TypeError, ValueError):
        raise invalid(name, v, "is not a number") from None


#: Longest text of each form field (the database columns' sizes, as in the JSON schema).
_FORM_MAX = {
    "name": 500,
    "control_name": 200,
    "unit": 100,
    "value_unit": 100,
    "control_unit": 100,
    "column": 200,
    "time_column": 200,
    "format": 10,
}


def _form_str(form: Any, name: str) -> str | None:
    v = form.get(name)
    if v is None or v == "":
        return None
    if not isinstance(v, str):
        raise invalid(name, getattr(v, "filename", "<file>"), "must be a text field")
    limit = _FORM_MAX.get(name)
    if limit is not None and len(v) > limit:
        raise invalid(name, v, f"is longer than {limit} characters")
    return v


@dataclass
class CleanSignal:
    """A validated recording on its way to the store (with the request's name and control)."""

    w: Any
    t: Any
    dt: float
    t0: float
    unit: str | None
    value_unit: str | None
    source: str
    metadata: dict[str, Any]

    @classmethod
    def of(cls, rec: recordings.Recording, metadata: dict[str, Any]) -> CleanSignal:
        meta = dict(metadata)
        if rec.flags:  # what the reader noticed (rounded timestamps...): detections repeat it
            meta["recording_flags"] = [convert.plain(f) for f in rec.flags]
        return cls(rec.w, rec.t, rec.dt, rec.t0, rec.unit, rec.value_unit, rec.source, meta)


async def _from_json(request: Request, state: AppState) -> CleanSignal:
    doc = await jsonbody.read_model(request, SignalIn, state.settings)
    s = state.settings
    rec = await to_thread.run_sync(
        lambda: recordings.from_arrays(
            doc.w, doc.t, doc.dt, doc.t0, unit=doc.unit, value_unit=doc.value_unit,
            source="json", max_samples=s.max_samples, uniform_rtol=s.uniform_rtol,
            resample=doc.resample,
        )
    )  # fmt: skip
    limits.check_finite_json(doc.metadata, "metadata")
    clean = CleanSignal.of(rec, doc.metadata)
    clean.metadata.setdefault("_name", doc.name)
    clean.metadata.setdefault("_control", doc.control.model_dump() if doc.control else None)
    return clean


async def _from_form(request: Request, state: AppState) -> CleanSignal:
    s = state.settings
    form = await request.form(max_files=1, max_fields=32, max_part_size=s.max_body_bytes)
    upload = form.get("file")
    if upload is None or isinstance(upload, str):
        raise invalid("file", None, "is required (a multipart file field named 'file')")
    data = await upload.read()
    fmt = recordings.guess_format(
        upload.filename, upload.content_type, _form_str(form, "format")
    )
    channel = _form_float(form, "channel")
    column, time_column = _form_str(form, "column"), _form_str(form, "time_column")
    dt, t0 = _form_float(form, "dt"), _form_float(form, "t0")
    meta_text = _form_str(form, "metadata")
    metadata: dict[str, Any] = {}
    if meta_text:
        metadata = limits.loads_bounded(meta_text, "metadata", s.max_json_depth)
        if not isinstance(metadata, dict):
            raise invalid("metadata", meta_text, "must be a JSON object")
        limits.check_finite_json(metadata, "metadata")

    resample = (_form_str(form, "resample") or "false").lower() in ("1", "true", "yes", "on")

    def work() -> recordings.Recording:
        return recordings.read_bytes(
            data, fmt, dt=dt, t0=t0, column=column, time_column=time_column,
            channel=0 if channel is None else channel, uniform_rtol=s.uniform_rtol,
            resample=resample, max_samples=s.max_samples,
            max_decompressed_bytes=s.max_decompressed_bytes,
        )  # fmt: skip

    clean = CleanSignal.of(await to_thread.run_sync(work), {})
    for name in ("unit", "value_unit"):  # a unit the file states is not overridden
        given, read = _form_str(form, name), getattr(clean, name)
        if given and read and given != read:
            raise invalid(name, given, f"contradicts the file's own {name} {read!r}")
        setattr(clean, name, given or read)
    notes = clean.metadata.pop("recording_flags", None)
    file_meta = {"filename": upload.filename, **clean.metadata}
    clean.metadata = {**metadata, "file": file_meta}
    if notes:
        clean.metadata["recording_flags"] = notes
    cname, cval, cunit = (
        _form_str(form, "control_name"),
        _form_float(form, "control_value"),
        _form_str(form, "control_unit"),
    )
    if cval is not None and cval != cval or (cval is not None and abs(cval) == float("inf")):
        raise invalid("control_value", cval, "must be finite")
    control = None
    if cname or cval is not None or cunit:
        control = Control(name=cname or "mu", value=cval, unit=cunit).model_dump()
    clean.metadata["_name"] = _form_str(form, "name") or (upload.filename or "")[:500] or None
    clean.metadata["_control"] = control
    return clean


@router.post(
    "",
    status_code=201,
    response_model=SignalMeta,
    summary="Store a recorded signal (JSON or a file)",
    responses=ERRORS,
    openapi_extra={
        "requestBody": {
            "required": True,
            "content": {
                "application/json": {"schema": {"$ref": "#/components/schemas/SignalIn"}},
                "multipart/form-data": {"schema": UPLOAD_FORM_SCHEMA},
            },
        }
    },
)
async def create_signal(request: Request, state: StateDep, caller: CallerDep) -> JSONResponse:
    """JSON ``{"t": [...]}`` or ``{"dt": x}`` with ``{"w": [...]}``, or a multipart file.

    Answers 201 with the signal's metadata and ``Location``.
    """
    ctype = request.headers.get("content-type", "").lower()
    if ctype.startswith("multipart/form-data"):
        clean = await _from_form(request, state)
    elif ctype.startswith("application/json") or ctype == "":
        clean = await _from_json(request, state)
    else:
        raise ApiProblem(
            415,
            f"send application/json or multipart/form-data, not {ctype!r}",
            field="content-type",
            value=ctype,
        )
    name = clean.metadata.pop("_name", None)
    control = clean.metadata.pop("_control", None)
    limits.check_time_axis(len(clean.w), clean.dt, clean.t0, clean.t)
    limits.check_depth(clean.metadata, "metadata", state.settings.max_json_depth)
    if control is not None and control.get("value") is not None:
        v = control["value"]
        if v != v or abs(v) == float("inf"):
            raise invalid("control.value", v, "must be finite")
    row = await to_thread.run_sync(
        lambda: state.store.add_signal(
            w=clean.w,
            dt=clean.dt,
            t0=clean.t0,
            t=clean.t,
            source=clean.source,
            name=name,
            unit=clean.unit,
            value_unit=clean.value_unit,
            control=control,
            metadata=clean.metadata,
            owner=caller.owner,
        )
    )
    meta = SignalMeta.model_validate(signal_meta(row))
    return JSONResponse(
        meta.model_dump(mode="json"), status_code=201, headers={"Location": f"/v1/signals/{row.id}"}
    )


@router.get("", response_model=SignalPage, summary="Stored signals, newest first", responses=ERRORS)
async def list_signals(
    state: StateDep,
    caller: CallerDep,
    limit: Annotated[int, Query(ge=1, le=500)] = 50,
    offset: Annotated[int, Query(ge=0, le=MAX_OFFSET)] = 0,
) -> dict[str, Any]:
    rows, total = await to_thread.run_sync(state.store.list_signals, limit, offset, caller.scope)
    return {
        "items": [signal_meta(r) for r in rows],
        "total": total,
        "limit": limit,
        "offset": offset,
    }


async def _load(state: AppState, signal_id: str, scope: str | None) -> Any:
    sig = await to_thread.run_sync(state.store.get_signal, signal_id, scope)
    if sig is None:
        raise not_found("signal", signal_id)
    return sig


@router.get(
    "/{signal_id}", response_model=SignalMeta, summary="A signal's metadata", responses=ERRORS
)
async def get_signal(signal_id: str, state: StateDep, caller: CallerDep) -> dict[str, Any]:
    row = await to_thread.run_sync(state.store.get_signal_meta, signal_id, caller.scope)
    if row is None:
        raise not_found("signal", signal_id)
    return signal_meta(row)


@router.get(
    "/{signal_id}/data",
    response_model=SignalData,
    summary="A signal's samples: JSON, CSV or NPY",
    responses={
        **ERRORS,
        200: {
            "description": "JSON (default), CSV (t,w with a header) or NPY ((n, 2) float64).",
            "content": {"text/csv": {}, "application/x-npy": {}},
        },
    },
)
async def get_signal_data(
    signal_id: str,
    request: Request,
    state: StateDep,
    caller: CallerDep,
    format: Annotated[
        str | None, Query(pattern="^(json|csv|npy)$", description="Overrides the Accept header.")
    ] = None,
) -> Response:
    """Exactly the stored float64 samples (17 significant digits in CSV, binary in NPY)."""
    fmt = format
    if fmt is None:
        accept = request.headers.get("accept", "")
        if "text/csv" in accept:
            fmt = "csv"
        elif "application/x-npy" in accept or "application/octet-stream" in accept:
            fmt = "npy"
        else:
            fmt = "json"
    sig = await _load(state, signal_id, caller.scope)
    row = sig.row
    t = recordings.time_axis(row.n, row.dt, row.t0, sig.t)
    if fmt == "csv":
        body = await to_thread.run_sync(recordings.to_csv, t, sig.w, row.unit, row.value_unit)
        return Response(
            body,
            media_type="text/csv",
            headers={"Content-Disposition": f'attachment; filename="{row.id}.csv"'},
        )
    if fmt == "npy":
        return Response(
            recordings.to_npy(t, sig.w),
            media_type="application/x-npy",
            headers={"Content-Disposition": f'attachment; filename="{row.id}.npy"'},
        )

    def as_json() -> bytes:  # big signals: build the text off the event loop
        return json.dumps(
            {
                "id": row.id,
                "t": t.tolist(),
                "w": sig.w.tolist(),
                "dt": row.dt,
                "unit": row.unit,
                "value_unit": row.value_unit,
            }
        ).encode()

    return Response(await to_thread.run_sync(as_json), media_type="application/json")


@router.delete("/{signal_id}", status_code=204, summary="Delete a signal", responses=ERRORS)
async def delete_signal(signal_id: str, state: StateDep, caller: CallerDep) -> Response:
    if not await to_thread.run_sync(state.store.delete_signal, signal_id, caller.scope):
        raise not_found("signal", signal_id)
    return Response(status_code=204)


@router.get(
    "/{signal_id}/plot.png",
    summary="A chart of the signal",
    responses={**ERRORS, 200: {"content": {"image/png": {}}, "description": "PNG chart."}},
    response_class=Response,
)
async def plot_signal(signal_id: str, state: StateDep, caller: CallerDep) -> Response:
    sig = await _load(state, signal_id, caller.scope)
    row = sig.row
    t = recordings.time_axis(row.n, row.dt, row.t0, sig.t)
    static = (row.meta or {}).get("w_static")
    png = await state.run(_plot, t, sig.w, row.name or row.id, row.unit, row.value_unit, static)
    return Response(png, media_type="image/png")


def _plot(
    t: Any, w: Any, title: str, unit: str | None, value_unit: str | None, static: float | None
) -> bytes:
    return plots.signal_plot(
        t, w, title=title, unit=unit, value_unit=value_unit, static_level=static, fmt="png"
    )
