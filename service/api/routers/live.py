"""Live sweeps: ``/v1/sweeps/{id}/records``, ``/close`` and ``/events`` (server-sent events).

A live sweep is created by ``POST /v1/sweeps`` with ``"mode": "live"`` (:func:`create_live`,
called by the sweeps router) and is an ordinary sweep resource: while it is open its status is
``"open"``; once closed (or its budget spent) it is a finished sweep with the pipeline's
document, for ``GET /v1/sweeps/{id}``, its charts, pages and listings.

The numerics of an update live in :mod:`service.analysis.live` and run in the analysis pool
(one call per record: detection, assessment and the wire document); this module reads the
record (:mod:`service.api.routers._live_input`), stores it while the numerics run, serialises
concurrent writers (see :mod:`service.api.storage.live`) and streams the stored updates
(:mod:`service.api.live_events`).
"""

from __future__ import annotations

import asyncio
import json
import math
import threading
import time
from collections import OrderedDict
from dataclasses import dataclass
from functools import partial
from typing import Annotated, Any

from anyio import to_thread
from fastapi import APIRouter, Header, Path, Query, Request
from fastapi.responses import JSONResponse, Response, StreamingResponse

from service import convert, recordings
from service.analysis import live as numerics
from service.analysis import live_store
from service.api.auth import Caller, CallerDep
from service.api.live_events import MAX_SEQ, event_stream, notify
from service.api.problems import ApiProblem, invalid, not_found
from service.api.routers import _live_input
from service.api.routers._common import problems
from service.api.state import AppState, StateDep
from service.api.storage import as_utc, utcnow
from service.api.storage import live as store_live
from service.api.sweep_views import sweep_doc
from service.schemas import Sweep
from service.schemas.live import LiveRecordIn, LiveUpdate, LiveUpdatePage

router = APIRouter(prefix="/v1/sweeps", tags=["sweeps"])

#: Attempts of the optimistic append before answering 503 (each loser recomputes).
MAX_ATTEMPTS = 50


# ---------------------------------------------------------------------------------- creation
async def create_live(req: Any, state: AppState, caller: Caller) -> JSONResponse:
    """``POST /v1/sweeps`` with ``"mode": "live"``: answers 201 with the open sweep."""
    if req.measurements is not None or req.simulate is not None:
        raise invalid("mode", "live", "a live sweep takes no 'measurements' nor 'simulate'")
    opts = req.live.model_dump() if req.live is not None else {}
    # the user's hand on the detector, as in a batch sweep: the fundamental's band for every
    # record, and the notch frequencies of records that give none of their own
    if req.band is not None:
        opts["band"] = [float(v) for v in req.band]
    if req.notch is not None:
        opts["notch"] = [float(v) for v in req.notch]
    control = req.control.model_dump() if req.control is not None else {"name": "mu"}
    _plan(opts)  # validated once here (the options' own checks)
    sweep, job, _ = await to_thread.run_sync(
        lambda: store_live.create_live_sweep(
            state.store,
            name=req.name,
            request=req.model_dump(mode="json", exclude_none=True),
            control_name=control.get("name") or "mu",
            control_unit=control.get("unit"),
            options=opts,
            owner=caller.owner,
        )
    )
    doc = Sweep.model_validate(sweep_doc(sweep, job)).model_dump(mode="json")
    return JSONResponse(doc, status_code=201, headers={"Location": f"/v1/sweeps/{sweep.id}"})


def _plan(opts: dict[str, Any]) -> numerics.LivePlan:
    try:
        return numerics.LivePlan(
            step=opts.get("step"),
            margin=float(opts.get("margin") or 0.0),
            target_width=opts.get("target_width"),
            control_resolution=opts.get("control_resolution"),
            method=opts.get("method") or "auto",
            band=tuple(opts["band"]) if opts.get("band") else None,
        )
    except ValueError as exc:
        name = getattr(exc, "parameter", "options")
        raise invalid(name if name == "band" else f"live.{name}",
                      getattr(exc, "value", None), str(exc)) from None  # fmt: skip


async def _live_row(state: AppState, sweep_id: str, caller: Caller) -> Any:
    row = await to_thread.run_sync(store_live.get_live, state.store, sweep_id, caller.scope)
    if row is None:
        raise not_found("live sweep", sweep_id)
    return row


def _conflict(sweep_id: str, status: str) -> ApiProblem:
    return ApiProblem(
        409,
        f"live sweep {sweep_id!r} is {status}: it takes no more records",
        field="status",
        value=status,
    )


@router.post(
    "/{sweep_id}/records",
    status_code=201,
    response_model=LiveUpdate,
    summary="Add one record to an open live sweep; answers the updated warning",
    responses=problems(401, 404, 409, 413, 415, 422),
    openapi_extra={
        "requestBody": {
            "required": True,
            "content": {
                "application/json": {"schema": LiveRecordIn.model_json_schema()},
                "multipart/form-data": {"schema": _live_input.RECORD_FORM_SCHEMA},
            },
        }
    },
)
async def add_record(
    sweep_id: str, request: Request, state: StateDep, caller: CallerDep
) -> Response:
    """A stored ``signal_id``, inline ``w`` with ``t``/``dt``, or a multipart file, with its
    ``control`` value. Answers 201: the record's detection, the classification, mu* with its
    interval, the alarm and the next safe control value. A file that cannot be read is
    answered with the reader's problem (422, 415) and kept in the sweep as a record set aside
    by its name with the reason (as a batch sweep of the same files sets it aside); the
    problem's detail names that record. A file over the server's limits (413) is not kept.

    The ``Server-Timing`` header splits the server time: ``read`` (the body), ``state`` (the
    sweep's records: only those this process has not seen are read), ``detect``,
    ``classify_predict``, ``policy`` (alarm, advice, sampling) and ``serialise`` (the wire
    document) as measured in the analysis worker, ``pool`` (the hand-off to it), ``store``
    (the update's append, and any wait for the record's own storage, which overlaps the
    numerics) and ``app`` (the whole)."""
    t_start = time.perf_counter()
    timing: dict[str, float] = {}
    st = await _read_state(state, sweep_id, caller, timing)
    if st.row.status != store_live.OPEN:
        raise _conflict(sweep_id, st.row.status)
    t0 = time.perf_counter()
    ctype = request.headers.get("content-type", "").lower()
    if ctype.startswith("multipart/form-data"):
        try:
            item = await _live_input.record_from_form(request, state)
        except _live_input.Unreadable as bad:
            raise await _set_aside_unreadable(state, st, bad, timing) from None
    elif ctype.startswith("application/json") or ctype == "":
        item = await _live_input.record_from_json(request, state, caller)
    else:
        raise ApiProblem(415, f"send application/json or multipart/form-data, not {ctype!r}",
                         field="content-type", value=ctype)  # fmt: skip
    unit = item.get("control_unit")  # the unit of a control value read from a stored signal
    if unit is not None and st.row.control_unit is not None and unit != st.row.control_unit:
        raise invalid(
            "control", None,
            f"is required: signal {item['signal_id']!r} stored its control value in {unit!r}, "
            f"the sweep's control is in {st.row.control_unit!r}; give control in "
            f"{st.row.control_unit!r}",
        )  # fmt: skip
    notch = st.row.options.get("notch")
    if notch and "notch" not in (item.get("options") or {}):  # the sweep's, as in a batch
        item["options"] = {**(item.get("options") or {}), "notch": list(notch)}
    stored = None
    if "recording" in item:  # its signal's row made while the numerics run; stored with it
        stored = asyncio.ensure_future(_live_input.signal_for(item, st.row, caller))
        item["w"], item["dt"] = item["recording"].w, item["recording"].dt
        item["unit"] = item["recording"].unit
    timing["read"] = time.perf_counter() - t0
    try:
        doc = await _append(state, st, item, stored, timing)
    finally:
        if stored is not None:
            _settle(stored)
    t0 = time.perf_counter()
    body = _json({**doc, "server_ms": 1e3 * (t0 - t_start)})
    wall, cpu = timing.get("serialise", (0.0, 0.0))
    timing["serialise"] = (wall + time.perf_counter() - t0, cpu)
    notify(sweep_id)
    ms = 1e3 * (time.perf_counter() - t_start)
    parts = ", ".join(_timing_entry(k, v) for k, v in timing.items())
    return Response(
        body,
        status_code=201,
        media_type="application/json",
        headers={
            "Location": f"/v1/sweeps/{sweep_id}/records/{doc['seq']}",
            "Server-Timing": f"{parts}, app;dur={ms:.2f}",
        },
    )


async def _set_aside_unreadable(
    state: AppState, st: _State, bad: _live_input.Unreadable, timing: dict[str, Any]
) -> ApiProblem:
    """A file that cannot be read: the sweep keeps it as a record set aside by its name with
    the reason (as a batch sweep of the same files does, and ``snapwarn watch``), and the
    upload is answered with the reader's problem (4xx naming the field), its detail saying
    where the record is."""
    item = {"unreadable": bad.why, "control": bad.control, "name": bad.name, "dt": math.nan,
            "unit": None}  # fmt: skip
    doc = await _append(state, st, item, None, timing)
    notify(st.row.id)
    p = bad.problem
    seq = doc["seq"]
    return ApiProblem(
        p.status,
        f"{p.detail}; the record is kept in the sweep set aside, as record {seq} "
        f"(/v1/sweeps/{st.row.id}/records/{seq})",
        title=p.title, errors=p.errors,
    )  # fmt: skip


def _settle(task: asyncio.Future) -> None:
    """Cancel the record's storage when the update failed first (else retrieve its error)."""
    if not task.done():
        task.cancel()
    elif not task.cancelled():
        task.exception()


def _json(doc: Any) -> bytes:
    return json.dumps(doc, ensure_ascii=False, allow_nan=False, separators=(",", ":")).encode()


def _timing_entry(name: str, value: float | tuple[float, float]) -> str:
    """``name;dur=<ms>`` (and ``desc="cpu <ms>"`` for what the worker measured)."""
    if isinstance(value, tuple):
        return f'{name};dur={1e3 * value[0]:.2f};desc="cpu {1e3 * value[1]:.2f}"'
    return f"{name};dur={1e3 * value:.2f}"


# ---------------------------------------------------------------------------------- the update
@dataclass
class _State:
    """The sweep as the next update sees it: its row (status, version, options) and records."""

    row: Any
    records: list[numerics.LiveRecord]


class _RecordCache:
    """The parsed records of recently fed live sweeps in this process, by sweep id.

    Records are immutable once stored and a sweep's ``version`` only grows, so a cached prefix
    stays valid: a later update reads only the records stored after it (by any process).
    """

    def __init__(self, size: int = 256) -> None:
        self._items: OrderedDict[str, tuple[int, list[numerics.LiveRecord]]] = OrderedDict()
        self._lock = threading.Lock()
        self._size = size

    def get(self, sweep_id: str) -> tuple[int, list[numerics.LiveRecord]] | None:
        with self._lock:
            hit = self._items.get(sweep_id)
            if hit is not None:
                self._items.move_to_end(sweep_id)
            return hit

    def put(self, sweep_id: str, version: int, records: list[numerics.LiveRecord]) -> None:
        with self._lock:
            old = self._items.get(sweep_id)
            if old is None or old[0] <= version:
                self._items[sweep_id] = (version, records)
                self._items.move_to_end(sweep_id)
            while len(self._items) > self._size:
                self._items.popitem(last=False)


def _cache(state: AppState) -> _RecordCache:
    cache = state.extra.get("live_records")
    if cache is None:
        cache = state.extra.setdefault("live_records", _RecordCache())
    return cache


def _load_state(store: Any, cache: _RecordCache, sweep_id: str) -> _State | None:
    """The live row and its records: the cached prefix plus what was stored after it."""
    hit = cache.get(sweep_id)
    row, records = None, None
    if hit is not None:
        row, new = store_live.records_after(store, sweep_id, hit[0], MAX_SEQ)
        if row is None:
            return None
        records = [*hit[1], *(live_store.record_from_dict(r.record) for r in new
                              if r.seq <= row.version)]  # fmt: skip
    if records is None or [r.seq for r in records] != list(range(1, row.version + 1)):
        full = store_live.live_state(store, sweep_id)  # first read here (or a gap): all of it
        if full is None:
            return None
        row, records = full.sweep, [live_store.record_from_dict(d) for d in full.records]
    cache.put(sweep_id, row.version, records)
    return _State(row, records)


async def _read_state(
    state: AppState, sweep_id: str, caller: Caller | None, timing: dict[str, Any]
) -> _State:
    t0 = time.perf_counter()
    st = await to_thread.run_sync(_load_state, state.store, _cache(state), sweep_id)
    if st is None or (caller is not None and not caller.sees(st.row.owner)):
        raise not_found("live sweep", sweep_id)
    timing["state"] = timing.get("state", 0.0) + time.perf_counter() - t0
    return st


async def _append(
    state: AppState, st: _State, item: dict[str, Any], stored: Any, timing: dict[str, Any]
) -> dict[str, Any]:
    """Detect and assess on the latest stored state (one call to the analysis pool) and
    append; when another record (or a close) came first, assess again on the new state (the
    detection is kept) and retry. ``timing`` gets the seconds of each stage."""
    sweep_id = st.row.id
    plan = _plan(st.row.options)
    measured = None
    dt0, unit0 = item["dt"], item.get("unit")
    base = None  # the sweep's time unit the detection was made in
    for _ in range(MAX_ATTEMPTS):
        if st.row.status != store_live.OPEN:
            raise _conflict(sweep_id, st.row.status)
        factor, unit = _time_factor(st.records, unit0, read="unreadable" not in item)
        if unit != base:  # (another first record came first: detect in its unit)
            measured, base, item["dt"] = None, unit, dt0 * factor
        budget = st.row.options.get("budget")
        finishing = budget is not None and len(st.records) + 1 >= int(budget)
        t0 = time.perf_counter()
        job = partial(_update, st.records, item if measured is None else None, measured,
                      item["control"], plan, finishing, sweep_id, base,
                      item.get("name") or item.get("signal_id"), item.get("options"))  # fmt: skip
        # a file that could not be read in a sweep that cannot predict yet: nothing to detect
        # and no predictor to run (the same answer, in this thread: no wait for the pool)
        light = "unreadable" in item and sum(
            r.measurement is not None for r in st.records) < numerics.MIN_PREDICT
        try:
            out = await (to_thread.run_sync(job) if light else state.run(job))
        except ValueError as exc:  # the detector's validation of the record
            raise invalid(getattr(exc, "parameter", "w"), getattr(exc, "value", None),
                          str(exc)) from None  # fmt: skip
        worker = out.pop("timing")
        in_worker = 0.0
        for k, v in worker.items():
            prev = timing.get(k, (0.0, 0.0))
            timing[k] = (prev[0] + v[0], prev[1] + v[1])
            in_worker += v[0]
        timing["pool"] = timing.get("pool", 0.0) + time.perf_counter() - t0 - in_worker
        measured = out["measured"]
        t0 = time.perf_counter()
        signal_id = item.get("signal_id")
        new_signal = None
        if stored is not None:  # the record's signal: stored with the record, or neither
            new_signal = await stored
            signal_id = new_signal.id
        out["doc"]["signal_id"] = signal_id
        append = partial(
            store_live.append_record, state.store, sweep_id, st.row.version,
            signal_id=signal_id, control=item["control"], record=out["stored"],
            doc=out["doc"], finish_result=out["final"], new_signal=new_signal,
        )  # fmt: skip
        row = await to_thread.run_sync(append)
        timing["store"] = timing.get("store", 0.0) + time.perf_counter() - t0
        if row is not None:
            _cache(state).put(sweep_id, row.seq, [*st.records, out["record"]])
            return row.doc
        st = await _read_state(state, sweep_id, None, timing)
    raise ApiProblem(503, f"live sweep {sweep_id!r} is too busy: retry the record",
                     headers={"Retry-After": "1"})  # fmt: skip


def _clock() -> tuple[float, float]:
    return time.perf_counter(), time.process_time()


def _since(t: tuple[float, float]) -> tuple[float, float]:
    return time.perf_counter() - t[0], time.process_time() - t[1]


def _time_factor(
    records: list[numerics.LiveRecord], unit: str | None, read: bool = True
) -> tuple[float, Any]:
    """``(factor, sweep unit)``: a record written in another known time unit than the sweep's
    (its first read record's: :func:`service.analysis.live.sweep_time_unit`) has its step
    converted to the sweep's; 422 when either is missing or unknown
    (:func:`service.recordings.common_time_base`, as a batch sweep). A record whose file could
    not be read (``read`` false) has no time unit: it takes the sweep's."""
    base = numerics.sweep_time_unit(records, unit)
    if not read or unit == base:
        return 1.0, base
    a, b = recordings.seconds_per(unit), recordings.seconds_per(base)
    if a is None or b is None:
        raise invalid(
            "unit", unit,
            f"is not the time unit of the sweep's records ({base or 'none given'}), and one of "
            "them is missing or not a known time unit: write the record in the sweep's unit, "
            "or name its unit (e.g. 't [ms]')",
        )  # fmt: skip
    return a / b, base


def _update(
    previous: list[numerics.LiveRecord], item: dict[str, Any] | None, measured: Any,
    control: float, plan: numerics.LivePlan, finishing: bool, sweep_id: str,
    time_unit: str | None = None, name: str | None = None,
    options: dict[str, Any] | None = None,
) -> dict[str, Any]:  # fmt: skip
    """One update in the analysis pool: detect the record (unless ``measured`` already holds
    its detection), assess the sweep with it, and build the wire document, the stored record
    and, when the record spends the budget, the final sweep document. ``name`` and
    ``options``: the record's name and the detector's options it is read with. Each stage's
    (wall, CPU) seconds are returned under ``timing``."""
    timing: dict[str, tuple[float, float]] = {}
    if measured is None and item.get("unreadable") is not None:  # its file: set aside
        measured = numerics.unreadable(control, item["unreadable"], name=name)
    if measured is None:
        t = _clock()
        measured = numerics.measure(item["w"], dt=item["dt"], control=control,
                                    method=plan.method, options=options, name=name)  # fmt: skip
        timing["detect"] = _since(t)
    det, meas, dflags = measured
    split: dict[str, float] = {}
    t = _clock()
    u = numerics.assess(previous, det, meas, control, plan=plan, detection_flags=dflags,
                        timings=split, time_unit=time_unit, name=name)  # fmt: skip
    whole = _since(t)
    pred = split.get("predict", (0.0, 0.0))
    timing["classify_predict"] = pred
    timing["policy"] = (whole[0] - pred[0], whole[1] - pred[1])
    t = _clock()
    doc = convert.live_update(u, sweep_id=sweep_id, created_at=as_utc(utcnow()),
                              finished=finishing, options=options,
                              ).model_dump(mode="json")  # fmt: skip
    final = None
    if finishing:  # the final document reuses this update's prediction (no second fit)
        r = numerics.finish([*previous, u.record], plan=plan, stopped="budget",
                            update=u)  # fmt: skip
        final = convert.sweep_result(r).model_dump(mode="json")
    timing["serialise"] = _since(t)
    return {"doc": doc, "stored": live_store.record_to_dict(u.record), "record": u.record,
            "final": final, "measured": measured, "timing": timing}  # fmt: skip


# ---------------------------------------------------------------------------------- reading
@router.get(
    "/{sweep_id}/records",
    response_model=LiveUpdatePage,
    summary="The updates of a live sweep, in arrival order",
    responses=problems(401, 404),
)
async def list_records(
    sweep_id: str,
    state: StateDep,
    caller: CallerDep,
    after: Annotated[
        int, Query(ge=0, le=MAX_SEQ, description="Only records with seq > after.")
    ] = 0,
    limit: Annotated[int, Query(ge=1, le=1000)] = 1000,
) -> dict[str, Any]:
    await _live_row(state, sweep_id, caller)
    row, recs = await to_thread.run_sync(store_live.records_after, state.store, sweep_id,
                                         after, limit)  # fmt: skip
    return {"items": [r.doc for r in recs], "total": row.version, "status": row.status}


@router.get(
    "/{sweep_id}/records/{seq}",
    response_model=LiveUpdate,
    summary="One update of a live sweep",
    responses=problems(401, 404),
)
async def get_record(
    sweep_id: str, seq: Annotated[int, Path(ge=1, le=MAX_SEQ)], state: StateDep, caller: CallerDep
) -> Any:
    await _live_row(state, sweep_id, caller)
    _, recs = await to_thread.run_sync(store_live.records_after, state.store, sweep_id,
                                       seq - 1, 1)  # fmt: skip
    if not recs or recs[0].seq != seq:
        raise not_found("record", f"{sweep_id}/{seq}")
    return recs[0].doc


@router.post(
    "/{sweep_id}/close",
    response_model=Sweep,
    summary="Close a live sweep: it becomes a finished sweep with the pipeline's document",
    responses=problems(401, 404),
)
async def close_sweep(sweep_id: str, state: StateDep, caller: CallerDep) -> dict[str, Any]:
    """Idempotent: closing a closed (or finished) sweep answers it as it is."""
    timing: dict[str, Any] = {}
    st = await _read_state(state, sweep_id, caller, timing)
    for _ in range(MAX_ATTEMPTS):
        if st.row.status != store_live.OPEN:
            break
        result = await state.run(partial(_finish, st.records, _plan(st.row.options)))
        done = await to_thread.run_sync(store_live.close_live, state.store, sweep_id,
                                        st.row.version, result)  # fmt: skip
        if done:
            notify(sweep_id)
            break
        st = await _read_state(state, sweep_id, None, timing)
    else:
        raise ApiProblem(503, f"live sweep {sweep_id!r} is too busy: retry",
                         headers={"Retry-After": "1"})  # fmt: skip
    found = await to_thread.run_sync(state.store.get_sweep, sweep_id)
    return sweep_doc(*found)


def _finish(
    records: list[numerics.LiveRecord], plan: numerics.LivePlan, stopped: str = "closed"
) -> dict[str, Any]:
    """The finished sweep's document (the one sweep document); runs in the analysis pool."""
    r = numerics.finish(records, plan=plan, stopped=stopped)
    return convert.sweep_result(r).model_dump(mode="json")


# ---------------------------------------------------------------------------------- events
@router.get(
    "/{sweep_id}/events",
    summary="Server-sent events: each update of a live sweep, then 'closed'",
    response_class=StreamingResponse,
    responses={
        200: {
            "content": {"text/event-stream": {"schema": {"type": "string"}}},
            "description": "'update' events (id = the record's seq, data = a LiveUpdate), "
            "then one 'closed' event. Resume with the Last-Event-ID header (or ?after=).",
        },
        **problems(401, 404, 422, 429),
    },
)
async def events(
    sweep_id: str,
    request: Request,
    state: StateDep,
    caller: CallerDep,
    after: Annotated[
        int | None, Query(ge=0, le=MAX_SEQ, description="Resume after this seq.")
    ] = None,
    timeout: Annotated[
        float, Query(gt=0, le=3600, description="The stream ends after this many seconds.")
    ] = 300.0,
    last_event_id: Annotated[str | None, Header(alias="Last-Event-ID")] = None,
) -> StreamingResponse:
    await _live_row(state, sweep_id, caller)
    return event_stream(request, state, sweep_id, after, last_event_id, timeout,
                        caller.key_id or caller.owner)  # fmt: skip
