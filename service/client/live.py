"""Live sweeps in the SDK: add records one by one, read the warning, follow the event stream.

>>> with Client("http://127.0.0.1:8000") as c:                       # doctest: +SKIP
...     live = c.live_sweep("strip 7", control="angle", unit="deg", step=0.2)
...     u = live.add(t=t, w=w, control=0.0)          # or live.add("run_000.csv", control=0.0)
...     while not u.converged and u.next_control is not None:
...         u = live.add(t=t, w=w, control=u.next_control)   # measure there next
...     live.close()

``events()`` iterates over the server-sent events of the sweep (``LiveEvent``: ``update`` with
its :class:`~service.schemas.live.LiveUpdate`, then one ``closed``), resuming with
``Last-Event-ID`` when the connection drops or the server ends a long stream. The same exists
for :class:`~service.client.AsyncClient` (``AsyncLiveSweep``, ``async for ev in
live.events()``).
"""

from __future__ import annotations

import json
import os
from collections.abc import AsyncIterator, Iterator
from typing import Any, ClassVar, Literal

from service.client import _core as core
from service.client._core import Flow
from service.client._ops import Operations, operation
from service.schemas import Sweep
from service.schemas.live import LiveEvent, LiveUpdate, LiveUpdatePage

__all__ = ["AsyncLiveSweep", "LiveSweep", "SseParser", "open_or_attach"]


# ---------------------------------------------------------------------------------- calls
def create_live_sweep(
    name: str | None,
    *,
    control: str = "mu",
    unit: str | None = None,
    margin: float | None = None,
    step: float | None = None,
    budget: int | None = None,
    target_width: float | None = None,
    method: str | None = None,
    control_resolution: float | None = None,
    band: tuple[float, float] | None = None,
    notch: list[float] | None = None,
) -> core.Call:
    live = {k: v for k, v in (("margin", margin), ("step", step), ("budget", budget),
            ("target_width", target_width), ("method", method),
            ("control_resolution", control_resolution)) if v is not None}  # fmt: skip
    doc: dict[str, Any] = {"mode": "live", "control": {"name": control}, "live": live}
    if band is not None:  # the detector's options of every record, as in a batch sweep
        doc["band"] = [float(v) for v in band]
    if notch is not None:
        doc["notch"] = [float(v) for v in notch]
    if unit is not None:
        doc["control"]["unit"] = unit
    if name is not None:
        doc["name"] = name
    return core.Call("POST", "/v1/sweeps", content=core.dumps(doc),
                     headers=dict(core.JSON_HEADERS), parse=core._model(Sweep))  # fmt: skip


def add_record(
    sweep_id: str,
    file: str | os.PathLike | bytes | None = None,
    *,
    control: float | None = None,
    w: Any = None,
    t: Any = None,
    dt: float | None = None,
    signal_id: str | None = None,
    filename: str | None = None,
    **fields: Any,
) -> core.Call:
    """``POST /v1/sweeps/{id}/records``: a file (path or bytes, multipart), inline samples or a
    stored signal, with the control value."""
    path = f"/v1/sweeps/{sweep_id}/records"
    parse = core._model(LiveUpdate)
    if file is not None:
        if isinstance(file, (bytes, bytearray)):
            data, fname = bytes(file), filename or "record.csv"
        else:
            with open(file, "rb") as fh:
                data = fh.read()
            fname = filename or os.path.basename(os.fspath(file))
        form = core.form_fields({"control": control, "dt": dt, **fields})
        return core.Call("POST", path, files={"file": (fname, data)}, data=form, parse=parse)
    doc: dict[str, Any] = {}
    for k, v in (("control", control), ("signal_id", signal_id), ("w", core.as_list(w, "w")),
                 ("t", core.as_list(t, "t")), ("dt", dt), *fields.items()):  # fmt: skip
        if v is not None:
            doc[k] = v
    return core.Call("POST", path, content=core.dumps(doc), headers=dict(core.JSON_HEADERS),
                     parse=parse)  # fmt: skip


def close(sweep_id: str) -> core.Call:
    return core.Call("POST", f"/v1/sweeps/{sweep_id}/close", parse=core._model(Sweep))


def records(sweep_id: str, *, after: int = 0) -> core.Call:
    return core.Call("GET", f"/v1/sweeps/{sweep_id}/records", params={"after": after},
                     parse=core._model(LiveUpdatePage))  # fmt: skip


# ---------------------------------------------------------------------------------- events
class SseParser:
    """Server-sent events from lines (sans I/O): ``feed(line)`` returns a :class:`LiveEvent`
    when a blank line ends one; comments and ``retry:`` are skipped."""

    def __init__(self) -> None:
        self._id: str | None = None
        self._event = "message"
        self._data: list[str] = []
        self.last_id: int | None = None

    def feed(self, line: str) -> LiveEvent | None:
        line = line.rstrip("\r\n")
        if line == "":
            return self._dispatch()
        if line.startswith(":"):
            return None
        name, _, value = line.partition(":")
        value = value[1:] if value.startswith(" ") else value
        if name == "id":
            self._id = value
        elif name == "event":
            self._event = value
        elif name == "data":
            self._data.append(value)
        return None

    def _dispatch(self) -> LiveEvent | None:
        if not self._data:
            self._event = "message"
            return None
        doc = json.loads("\n".join(self._data))
        ident = int(self._id) if self._id is not None else (self.last_id or 0)
        kind = self._event
        self._id, self._event, self._data = None, "message", []
        self.last_id = ident
        if kind == "update":
            return LiveEvent(id=ident, event="update", update=LiveUpdate.model_validate(doc))
        if kind == "closed":
            return LiveEvent(id=ident, event="closed", data=doc)
        return None  # an event kind this SDK does not know


class _Stream:
    """One ``events()`` iteration, sans I/O: the request of each (re)connection, resuming
    after the last event received, and the events parsed from its lines."""

    def __init__(self, sweep_id: str, after: int | None, timeout: float) -> None:
        self.sweep_id, self.last, self.timeout = sweep_id, after, timeout
        self.parser = SseParser()
        self.done = False

    def request(self) -> dict[str, Any]:
        """``httpx2`` ``stream()`` arguments of the next connection (a fresh parser)."""
        import httpx2

        self.parser = SseParser()
        params: dict[str, Any] = {"timeout": self.timeout}
        headers = {"accept": "text/event-stream"}
        if self.last is not None:
            params["after"] = self.last
            headers["last-event-id"] = str(self.last)
        return {"method": "GET", "url": f"/v1/sweeps/{self.sweep_id}/events", "params": params,
                "headers": headers, "timeout": httpx2.Timeout(30.0, read=60.0)}  # fmt: skip

    def feed(self, line: str) -> LiveEvent | None:
        """The event a line completes (None: not yet); ``done`` after ``closed``."""
        ev = self.parser.feed(line)
        if ev is not None:
            self.last = ev.id
            self.done = ev.event == "closed"
        return ev

    def events(self, lines: Iterator[str]) -> Iterator[LiveEvent]:
        """The events of a connection's lines, up to ``closed``."""
        for line in lines:
            if (ev := self.feed(line)) is not None:
                yield ev
            if self.done:
                return


def _dropped() -> tuple[type[Exception], ...]:
    """A connection the server ended or lost: resumed with ``Last-Event-ID``."""
    import httpx2

    return (httpx2.ReadTimeout, httpx2.RemoteProtocolError, httpx2.ReadError)


def open_or_attach(
    name: str | None, control: str, unit: str | None, sweep_id: str | None,
    options: dict[str, Any],
) -> core.Call:  # fmt: skip
    """The call of ``live_sweep``: open a new live sweep, or read ``sweep_id`` to attach."""
    if sweep_id is not None:
        return core.get_sweep(sweep_id)
    return create_live_sweep(name, control=control, unit=unit, **options)


class _LiveOperations(Operations):
    """What a live sweep does, declared once for :class:`LiveSweep` and
    :class:`AsyncLiveSweep` (see :mod:`service.client._ops`).

    Attributes
    ----------
    id : str
        The sweep's id (``/v1/sweeps/{id}``).
    sweep : Sweep
        The sweep as created (or as closed, after :meth:`close`).
    """

    def __init__(self, client: Any, sweep: Sweep) -> None:
        self._client = client
        self.sweep = sweep
        self.id = sweep.id

    def _run(self, call: core.Call) -> Any:
        return self._client._run(call)

    @operation
    def add(self, file: str | os.PathLike | bytes | None = None, **kw: Any) -> Flow[LiveUpdate]:
        """Add one record: a file (path or bytes), ``w=`` with ``t=``/``dt=``, or
        ``signal_id=``; always ``control=`` (its control value); optionally ``name=`` and the
        detector's ``quantity=``, ``start=``, ``notch=`` (a list) and ``exclude=``. Returns
        the updated warning."""
        return (yield add_record(self.id, file, **kw))

    @operation
    def records(self, *, after: int = 0) -> Flow[LiveUpdatePage]:
        """Every update so far (arrival order)."""
        return (yield records(self.id, after=after))

    @operation
    def close(self) -> Flow[Sweep]:
        """Close the sweep (idempotent): it becomes a finished sweep."""
        self.sweep = yield close(self.id)
        return self.sweep

    @operation
    def get(self) -> Flow[Sweep]:
        """``GET /v1/sweeps/{id}``."""
        self.sweep = yield core.get_sweep(self.id)
        return self.sweep


class LiveSweep(_LiveOperations):
    """An open live sweep of a blocking :class:`~service.client.Client`."""

    _is_async: ClassVar[Literal[False]] = False

    def events(
        self, *, after: int | None = None, timeout: float = 300.0, reconnect: bool = True
    ) -> Iterator[LiveEvent]:
        """The sweep's events in order from ``after`` (default: the first), until ``closed``.

        A stream the server ends (its ``timeout``) or a dropped connection is resumed with
        ``Last-Event-ID`` when ``reconnect`` is true; nothing is lost or repeated.
        """
        s = _Stream(self.id, after, timeout)
        while not s.done:
            try:
                with self._client._http.stream(**s.request()) as r:
                    if r.status_code >= 400:
                        r.read()
                        core.raise_for_problem(r)
                    yield from s.events(r.iter_lines())
            except _dropped():
                if not reconnect:
                    raise
            if not reconnect:
                return

    def __enter__(self) -> LiveSweep:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


class AsyncLiveSweep(_LiveOperations):
    """An open live sweep of an :class:`~service.client.AsyncClient` (see :class:`LiveSweep`)."""

    _is_async: ClassVar[Literal[True]] = True

    async def events(
        self, *, after: int | None = None, timeout: float = 300.0, reconnect: bool = True
    ) -> AsyncIterator[LiveEvent]:
        """See :meth:`LiveSweep.events`."""
        s = _Stream(self.id, after, timeout)
        while not s.done:
            try:
                async with self._client._http.stream(**s.request()) as r:
                    if r.status_code >= 400:
                        await r.aread()
                        core.raise_for_problem(r)
                    async for line in r.aiter_lines():
                        if (ev := s.feed(line)) is not None:
                            yield ev
                        if s.done:
                            return
            except _dropped():
                if not reconnect:
                    raise
            if not reconnect:
                return

    async def __aenter__(self) -> AsyncLiveSweep:
        return self

    async def __aexit__(self, *exc: object) -> None:
        await self.close()
