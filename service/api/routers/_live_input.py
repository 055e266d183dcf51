"""A live sweep's record as it arrives: a stored signal, inline samples (JSON) or a file
(multipart), with its control value; read into a recording and stored as a signal.

Part of the live-sweep door (:mod:`service.api.routers.live`); errors are problem answers
naming the field and value.
"""

from __future__ import annotations

import math
from typing import Any

from anyio import to_thread
from fastapi import Request

from service import convert, recordings
from service.api import jsonbody
from service.api.auth import Caller
from service.api.problems import ApiProblem, invalid
from service.api.routers._common import RECORDING_FORM_FIELDS
from service.api.state import AppState
from service.schemas.live import LiveRecordIn

__all__ = ["RECORD_FORM_SCHEMA", "Unreadable", "record_from_form", "record_from_json",
           "signal_for"]  # fmt: skip

RECORD_FORM_SCHEMA = {
    "type": "object",
    "required": ["file"],
    "properties": {
        **RECORDING_FORM_FIELDS,
        "control": {"type": "number", "description": "Control value of the record."},
        "quantity": {"type": "string", "enum": ["displacement", "velocity", "acceleration"],
                     "description": "What the record measures (default: the file's value "
                     "unit says, else a displacement)."},
        "start": {"type": "number", "description": "Time from the record's first sample where "
                  "its free response starts (default: the kick is located)."},
        "notch": {"type": "string", "description": "Frequencies of stationary lines, comma- or "
                  "space-separated or a JSON list (cycles per time unit; default: found)."},
        "exclude": {"type": "boolean", "description": "Leave this record out of the sweep "
                    "(listed as set aside, 'excluded by the user')."},
    },
}  # fmt: skip
_QUANTITIES = ("displacement", "velocity", "acceleration")
_TRUE, _FALSE = ("1", "true", "yes", "on"), ("0", "false", "no", "off")


def _recording_problem(exc: recordings.RecordingError) -> ApiProblem:
    status = 422
    if isinstance(exc, recordings.UnsupportedFormat):
        status = 415
    elif isinstance(exc, recordings.RecordingTooLarge):
        status = 413
    return ApiProblem(status, str(exc), field=exc.field, value=exc.value)


class Unreadable(Exception):
    """A record's file that cannot be read: the door answers ``problem`` (4xx naming the
    field), and the sweep keeps the record set aside by ``name`` with ``why`` at ``control``
    (as a batch sweep sets such a file aside). A file over the server's limits (413) is not
    one: the request is refused, the lab sends the record cut or resampled."""

    def __init__(self, problem: ApiProblem, control: float, name: str | None, why: str) -> None:
        super().__init__(problem.detail)
        self.problem, self.control, self.name, self.why = problem, control, name, why


def _finite_control(value: Any, field: str = "control") -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise invalid(field, value, "is not a number") from None
    if not math.isfinite(v):
        raise invalid(field, value, "must be finite")
    return v


async def record_from_json(request: Request, state: AppState, caller: Caller) -> dict[str, Any]:
    # a large record is parsed as a stream (samples straight into float64, bounded memory)
    doc = await jsonbody.read_model(request, LiveRecordIn, state.settings)
    if doc.signal_id is not None:
        if doc.w is not None or doc.t is not None:
            raise invalid("signal_id", doc.signal_id, "give a signal_id or samples, not both")
        sig = await to_thread.run_sync(state.store.get_signal, doc.signal_id, caller.scope)
        if sig is None:
            raise invalid("signal_id", doc.signal_id, "is not a stored signal")
        value = doc.control if doc.control is not None else sig.row.control_value
        if value is None:
            raise invalid("control", None, "is required: the signal has no control value")
        opts = doc.detect_options()
        q = recordings.quantity_of(sig.row.value_unit)
        if q is not None:
            opts.setdefault("quantity", q)
        return {"w": sig.w, "dt": float(sig.row.dt), "control": _finite_control(value),
                "signal_id": sig.row.id, "unit": sig.row.unit, "options": opts,
                "name": doc.name or sig.row.name or sig.row.id,
                "control_unit": sig.row.control_unit if doc.control is None else None}  # fmt: skip
    if doc.w is None:
        raise invalid("w", None, "give 'signal_id', or 'w' with 't' or 'dt'")
    if doc.control is None:
        raise invalid("control", None, "is required with inline samples")
    control = _finite_control(doc.control)
    limit = state.settings.max_samples

    def read() -> recordings.Recording:
        return recordings.from_arrays(doc.w, doc.t, doc.dt, doc.t0, max_samples=limit,
                                      unit=doc.unit, source="json")  # fmt: skip

    try:
        rec = await to_thread.run_sync(read)
    except recordings.RecordingError as exc:
        raise _recording_problem(exc) from None
    return {"recording": rec, "control": control, "name": doc.name,
            "options": doc.detect_options()}  # fmt: skip


def _form_text(form: Any, name: str, limit: int = 200) -> str | None:
    v = form.get(name)
    if v is None or v == "":
        return None
    if not isinstance(v, str):
        raise invalid(name, getattr(v, "filename", "<file>"), "must be a text field")
    if len(v) > limit:
        raise invalid(name, v, f"is longer than {limit} characters")
    return v


async def record_from_form(request: Request, state: AppState) -> dict[str, Any]:
    s = state.settings
    form = await request.form(max_files=1, max_fields=16, max_part_size=s.max_body_bytes)
    upload = form.get("file")
    if upload is None or isinstance(upload, str):
        raise invalid("file", None, "is required (a multipart file field named 'file')")
    data = await upload.read()
    text = _form_text(form, "control")
    if text is None:
        raise invalid("control", None, "is required (the record's control value)")
    control = _finite_control(text)
    nums = {}
    for k in ("dt", "t0", "channel"):
        t = _form_text(form, k)
        nums[k] = None if t is None else _finite_control(t, k)
    opts = {k: _form_text(form, k) for k in ("column", "time_column")}

    def read() -> recordings.Recording:
        fmt = recordings.guess_format(upload.filename, upload.content_type,
                                      _form_text(form, "format", 10))  # fmt: skip
        return recordings.read_bytes(data, fmt, dt=nums["dt"], t0=nums["t0"],
                                     channel=int(nums["channel"] or 0), max_samples=s.max_samples,
                                     max_decompressed_bytes=s.max_decompressed_bytes,
                                     uniform_rtol=s.uniform_rtol, **opts)  # fmt: skip

    name = _form_text(form, "name", 500) or (upload.filename or "")[:500] or None
    try:
        rec = await to_thread.run_sync(read)
    except recordings.RecordingTooLarge as exc:
        raise _recording_problem(exc) from None
    except recordings.RecordingError as exc:
        from service.analysis.sweep_policy import file_unreadable

        raise Unreadable(_recording_problem(exc), control, name, file_unreadable(exc)) from None
    unit = _form_text(form, "unit", 100)
    if unit and rec.unit and unit != rec.unit:  # a unit the file states is not overridden
        raise invalid("unit", unit, f"contradicts the file's own time unit {rec.unit!r}")
    if unit:
        rec = recordings.Recording(rec.w, rec.t, rec.dt, rec.t0, unit, rec.value_unit,
                                   rec.source, rec.flags, rec.metadata)  # fmt: skip
    return {"recording": rec, "control": control, "name": name,
            "options": _form_options(form, rec.quantity),
            "metadata": {"file": {"filename": upload.filename, **rec.metadata}}}  # fmt: skip


def _form_options(form: Any, quantity: str | None) -> dict[str, Any]:
    """The detector's lab options of a multipart record (the JSON record's fields of the same
    names): ``quantity`` (default: the file's value unit says), ``start``, ``notch`` (numbers
    separated by commas or spaces, or a JSON list) and ``exclude``."""
    opts: dict[str, Any] = {}
    q = _form_text(form, "quantity", 20) or quantity
    if q is not None:
        if q not in _QUANTITIES:
            raise invalid("quantity", q, f"must be one of {', '.join(_QUANTITIES)}")
        opts["quantity"] = q
    start = _form_text(form, "start")
    if start is not None:
        v = _finite_control(start, "start")
        if v < 0:
            raise invalid("start", start, "must be >= 0")
        opts["start"] = v
    notch = _form_text(form, "notch", 400)
    if notch is not None:
        text = notch.strip().removeprefix("[").removesuffix("]")  # (the SDK sends a list)
        freqs = [_finite_control(x, "notch") for x in text.replace(",", " ").split()]
        if not freqs or len(freqs) > 16 or not all(f > 0 for f in freqs):
            raise invalid("notch", notch, "must be 1 to 16 positive frequencies")
        opts["notch"] = freqs
    exclude = _form_text(form, "exclude", 10)
    if exclude is not None:
        if exclude.lower() not in _TRUE + _FALSE:
            raise invalid("exclude", exclude, "must be true or false")
        if exclude.lower() in _TRUE:
            opts["exclude"] = True
    return opts


async def signal_for(item: dict[str, Any], live_row: Any, caller: Caller) -> Any:
    """The row of the record's samples as a new signal (encoded off the event loop), to be
    stored in the record's own transaction (``storage.live.append_record``)."""
    from service.api.storage.signals import signal_row

    rec: recordings.Recording = item["recording"]
    control = {"name": live_row.control_name, "value": item["control"],
               "unit": live_row.control_unit}  # fmt: skip
    meta = dict(item.get("metadata") or {})
    meta["live_sweep"] = live_row.id
    if rec.flags:
        meta["flags"] = [convert.flag(f).model_dump() for f in rec.flags]
    return await to_thread.run_sync(
        lambda: signal_row(
            w=rec.w, dt=rec.dt, t0=rec.t0, t=rec.t, source=rec.source, name=item.get("name"),
            unit=rec.unit, value_unit=rec.value_unit, control=control, metadata=meta,
            owner=caller.owner,
        )
    )  # fmt: skip
