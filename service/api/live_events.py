"""The server-sent events of a live sweep: its stored updates, then ``closed``.

Behind ``GET /v1/sweeps/{id}/events`` (:mod:`service.api.routers.live`) and the live sweep's
page (:mod:`service.api.pages.routes`, authenticated by its cookie). A stream reads the updates
stored in :mod:`service.api.storage.live`; the process that stores one wakes its own streams at
once (:func:`notify`); for updates other processes store, one watcher per sweep in this process
reads the sweep's version every :data:`POLL_S` while it has streams and wakes them all (the
streams themselves never poll the database). A caller (a key, or an owner) holds at most
:data:`MAX_STREAMS_PER_CALLER` streams at once in a process (429 beyond).
"""

from __future__ import annotations

import asyncio
import json
import time
from typing import Any

from anyio import to_thread
from fastapi import Request
from fastapi.responses import StreamingResponse

from service.api.problems import ApiProblem, invalid
from service.api.state import AppState
from service.api.storage import live as store_live

__all__ = ["KEEPALIVE_S", "MAX_SEQ", "POLL_S", "event_stream", "notify"]

#: Largest record number a query may name (records per sweep are far fewer).
MAX_SEQ = 2**31 - 1
#: How often an event stream looks for updates another process stored (s; this process's own
#: wake its streams at once), and its keep-alive comment.
POLL_S = 0.25
KEEPALIVE_S = 15.0
#: Most event streams one caller keeps open at once in this process.
MAX_STREAMS_PER_CALLER = 16
#: How often an idle stream checks that its client is still there (no database read).
_DISCONNECT_S = 1.0


def _sse(event: str, ident: int, data: Any) -> bytes:
    body = json.dumps(data, separators=(",", ":"), allow_nan=False)
    return f"id: {ident}\nevent: {event}\ndata: {body}\n\n".encode()


def event_stream(
    request: Request, state: AppState, sweep_id: str, after: int | None,
    last_event_id: str | None, timeout: float, caller: str | None = None,
) -> StreamingResponse:  # fmt: skip
    """The event stream of a live sweep the caller may read (also behind the sweep's page,
    which authenticates with its cookie): updates after ``after`` or ``Last-Event-ID``.
    ``caller``: who holds the stream (a key id or an owner), for the per-caller cap."""
    if caller is not None and _open.get(caller, 0) >= MAX_STREAMS_PER_CALLER:
        raise ApiProblem(429, f"{MAX_STREAMS_PER_CALLER} event streams of this caller are "
                         "open; close some first", title="Too many streams", slug="too-many",
                         field="events", value=_open[caller],
                         headers={"Retry-After": "5"})  # fmt: skip
    start = after or 0
    if last_event_id:
        try:
            given = int(last_event_id)
        except ValueError:
            given = -1
        if not 0 <= given <= MAX_SEQ:
            raise invalid("Last-Event-ID", last_event_id, "is not a record number")
        start = max(start, given)
    return StreamingResponse(
        _held(caller, _stream(request, state, sweep_id, start, timeout)),
        media_type="text/event-stream",
        headers={"Cache-Control": "no-cache", "X-Accel-Buffering": "no"},
    )


async def _held(caller: str | None, gen: Any):  # noqa: ANN202
    """``gen``, counted as one of ``caller``'s open streams while it runs."""
    if caller is not None:
        _open[caller] = _open.get(caller, 0) + 1
    try:
        async for chunk in gen:
            yield chunk
    finally:
        if caller is not None:
            _open[caller] -= 1
            if _open[caller] <= 0:
                _open.pop(caller, None)


async def _stream(request: Request, state: AppState, sweep_id: str, last: int, timeout: float):  # noqa: ANN202
    """Stored updates with seq > last, then new ones as they are stored: at once when this
    process stored them (:func:`notify`), within :data:`POLL_S` when another process did (the
    sweep's watcher)."""
    deadline = time.monotonic() + timeout
    quiet_since = time.monotonic()
    yield b"retry: 1000\n\n"
    known = -1
    wake = asyncio.Event()
    listeners = _listeners.setdefault(sweep_id, set())
    listeners.add(wake)
    _watch(sweep_id, state)
    woken = True  # read the state once at the start, then only when woken
    try:
        while True:
            if woken:
                wake.clear()
                vs = await to_thread.run_sync(store_live.live_version, state.store, sweep_id)
                if vs is None:
                    return
                version, status = vs
                if version > last and version != known:
                    _, recs = await to_thread.run_sync(store_live.records_after, state.store,
                                                       sweep_id, last, 500)  # fmt: skip
                    for r in recs:
                        yield _sse("update", r.seq, r.doc)
                        last = r.seq
                    known = version if last >= version else -1
                    quiet_since = time.monotonic()
                    continue
                if status != store_live.OPEN and last >= version:
                    if last == version:
                        yield _sse("closed", version + 1,
                                   {"status": status, "n_records": version})  # fmt: skip
                    return
            now = time.monotonic()
            if now >= deadline or await request.is_disconnected():
                return
            if now - quiet_since >= KEEPALIVE_S:
                yield b": keep-alive\n\n"
                quiet_since = now
            try:
                await asyncio.wait_for(wake.wait(), timeout=_DISCONNECT_S)
                woken = True
            except TimeoutError:
                woken = False
    finally:
        listeners.discard(wake)
        if not listeners:
            _listeners.pop(sweep_id, None)


#: The event streams of this process waiting for a sweep's next update, by sweep id.
_listeners: dict[str, set[asyncio.Event]] = {}
#: The sweeps' watchers of this process (one task per sweep with streams).
_watchers: dict[str, asyncio.Task] = {}
#: Open streams per caller in this process.
_open: dict[str, int] = {}


def _watch(sweep_id: str, state: AppState) -> None:
    """Start the sweep's watcher unless it runs: it reads the sweep's version every
    :data:`POLL_S` while the sweep has streams here, and wakes them when it changes."""
    task = _watchers.get(sweep_id)
    if task is not None and not task.done():
        return

    async def run() -> None:
        seen = None
        try:
            while _listeners.get(sweep_id):
                vs = await to_thread.run_sync(store_live.live_version, state.store, sweep_id)
                if vs != seen:
                    if seen is not None:
                        notify(sweep_id)
                    seen = vs
                if vs is None:
                    notify(sweep_id)
                    return
                await asyncio.sleep(POLL_S)
        finally:
            _watchers.pop(sweep_id, None)

    _watchers[sweep_id] = asyncio.get_running_loop().create_task(run())


def notify(sweep_id: str) -> None:
    """Wake this process's streams of ``sweep_id``: an update or a close was stored."""
    for ev in list(_listeners.get(sweep_id, ())):
        ev.set()
