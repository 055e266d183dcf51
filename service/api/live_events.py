"""The server-sent events of a live sweep: its stored updates, then ``closed``.

Behind ``GET /v1/sweeps/{id}/events`` (:mod:`service.api.routers.live`) and the live sweep's
page (:mod:`service.api.pages.routes`, authenticated by its cookie). A stream reads the updates
stored in :mod:`service.api.storage.live`; the process that stores one wakes its own streams at
once (:func:`notify`), other processes' streams find it within :data:`POLL_S`.
"""

from __future__ import annotations

import asyncio
import json
import time
from typing import Any

from anyio import to_thread
from fastapi import Request
from fastapi.responses import StreamingResponse

from service.api.problems import invalid
from service.api.state import AppState
from service.api.storage import live as store_live

__all__ = ["KEEPALIVE_S", "MAX_SEQ", "POLL_S", "event_stream", "notify"]

#: Largest record number a query may name (records per sweep are far fewer).
MAX_SEQ = 2**31 - 1
#: How often an event stream looks for updates another process stored (s; this process's own
#: wake its streams at once), and its keep-alive comment.
POLL_S = 0.25
KEEPALIVE_S = 15.0


def _sse(event: str, ident: int, data: Any) -> bytes:
    body = json.dumps(data, separators=(",", ":"), allow_nan=False)
    return f"id: {ident}\nevent: {event}\ndata: {body}\n\n".encode()


def event_stream(
    request: Request, state: AppState, sweep_id: str, after: int | None,
    last_event_id: str | None, timeout: float,
) -> StreamingResponse:  # fmt: skip
    """The event stream of a live sweep the caller may read (also behind the sweep's page,
    which authenticates with its cookie): updates after ``after`` or ``Last-Event-ID``."""
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
        _stream(request, state, sweep_id, start, timeout),
        media_type="text/event-stream",
        headers={"Cache-Control": "no-cache", "X-Accel-Buffering": "no"},
    )


async def _stream(request: Request, state: AppState, sweep_id: str, last: int, timeout: float):  # noqa: ANN202
    """Stored updates with seq > last, then new ones as they are stored: at once when this
    process stored them (:func:`notify`), within :data:`POLL_S` when another process did."""
    deadline = time.monotonic() + timeout
    quiet_since = time.monotonic()
    yield b"retry: 1000\n\n"
    known = -1
    wake = asyncio.Event()
    listeners = _listeners.setdefault(sweep_id, set())
    listeners.add(wake)
    try:
        while True:
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
                    yield _sse("closed", version + 1, {"status": status, "n_records": version})
                return
            now = time.monotonic()
            if now >= deadline or await request.is_disconnected():
                return
            if now - quiet_since >= KEEPALIVE_S:
                yield b": keep-alive\n\n"
                quiet_since = now
            try:
                await asyncio.wait_for(wake.wait(), timeout=POLL_S)
            except TimeoutError:
                pass
    finally:
        listeners.discard(wake)
        if not listeners:
            _listeners.pop(sweep_id, None)


#: The event streams of this process waiting for a sweep's next update, by sweep id.
_listeners: dict[str, set[asyncio.Event]] = {}


def notify(sweep_id: str) -> None:
    """Wake this process's streams of ``sweep_id``: an update or a close was stored."""
    for ev in list(_listeners.get(sweep_id, ())):
        ev.set()
