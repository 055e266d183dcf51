"""The SDK's methods are declared once and driven by two transports: the blocking and the
asyncio client send the same requests, parse the same answers, and fail the same way.

Reference: a mock server (``httpx2.MockTransport``) that records every request.
"""

from __future__ import annotations

import inspect
import json
from typing import Any

import anyio
import httpx2
import pytest

from service.client import AsyncClient, Client, JobFailed, NotFound, WaitTimeout
from service.client.live import AsyncLiveSweep, LiveSweep

JOB = {"id": "j1", "kind": "sweep-signals", "status": "running",
       "progress": {"fraction": 0.5, "message": "half"}, "attempts": 1,
       "created_at": "2026-01-01T00:00:00Z"}  # fmt: skip


def _server(seen: list[tuple[str, str, bytes]], jobs: list[str]) -> httpx2.MockTransport:
    def handle(request: httpx2.Request) -> httpx2.Response:
        seen.append((request.method, str(request.url), request.content))
        path = request.url.path
        if path.startswith("/v1/jobs/"):
            status = jobs.pop(0) if jobs else "running"
            return httpx2.Response(200, json={**JOB, "status": status})
        if path.startswith("/v1/signals/missing"):
            return httpx2.Response(404, json={"title": "Not Found", "status": 404,
                                              "detail": "no signal with id 'missing'"})  # fmt: skip
        return httpx2.Response(200, content=b"PNG")

    return httpx2.MockTransport(handle)


def _calls(c: Any) -> list[Any]:
    return [
        lambda: c.get_job("j1"),
        lambda: c.signal_plot("s1"),
        lambda: c.sweep_plot("w1", format="svg"),
        lambda: c.download_signal("s1", format="npy"),
    ]


def test_both_clients_send_the_same_requests_and_parse_the_same() -> None:
    seen_sync: list = []
    with Client("http://x", transport=_server(seen_sync, [])) as c:
        got_sync = [f() for f in _calls(c)]

    seen_async: list = []

    async def main() -> list:
        async with AsyncClient("http://x", transport=_server(seen_async, [])) as ac:
            return [await f() for f in _calls(ac)]

    got_async = anyio.run(main)
    assert seen_sync == seen_async and len(seen_sync) == 4
    assert got_sync == got_async
    assert got_sync[0].status == "running" and got_sync[1] == b"PNG"


def test_wait_polls_then_fails_or_times_out_alike() -> None:
    for jobs, error in ((["running", "failed"], JobFailed), ([], WaitTimeout)):
        seen: list = []
        with Client("http://x", transport=_server(seen, list(jobs))) as c:
            with pytest.raises(error):
                c.wait("j1", poll=0.01, timeout=0.2)
        n_sync = len(seen)

        async def main(jobs: list = jobs, error: type = error) -> int:
            seen_a: list = []
            async with AsyncClient("http://x", transport=_server(seen_a, list(jobs))) as ac:
                with pytest.raises(error):
                    await ac.wait("j1", poll=0.01, timeout=0.2)
            return len(seen_a)

        n_async = anyio.run(main)
        if error is JobFailed:  # two polls each, the second one failed
            assert n_sync == n_async == 2
        else:
            assert n_sync > 2 and n_async > 2


def test_problem_answers_raise_in_both() -> None:
    with Client("http://x", transport=_server([], [])) as c:
        with pytest.raises(NotFound) as e:
            c.signal_plot("missing")
    assert e.value.status == 404

    async def main() -> None:
        async with AsyncClient("http://x", transport=_server([], [])) as ac:
            with pytest.raises(NotFound):
                await ac.signal_plot("missing")

    anyio.run(main)


@pytest.mark.parametrize("sync, asyn", [(Client, AsyncClient), (LiveSweep, AsyncLiveSweep)])
def test_one_declaration_two_kinds_of_method(sync: type, asyn: type) -> None:
    """Every public method exists in both, with one signature; the asyncio one is awaitable."""
    names = {n for n, f in inspect.getmembers(sync, inspect.isfunction) if not n.startswith("_")}
    names.discard("close")  # the blocking client's close(), the asyncio client's aclose()
    for name in sorted(names):
        f, g = getattr(sync, name), getattr(asyn, name)
        assert not inspect.iscoroutinefunction(f), name
        assert inspect.iscoroutinefunction(g) or inspect.isasyncgenfunction(g), name
        sf, sg = inspect.signature(f), inspect.signature(g)
        if name not in ("live_sweep", "events"):  # (their return types name their own kind)
            assert sf == sg, name
        assert f.__doc__, name
    assert json.dumps(str(inspect.signature(Client.upload_signal))).count("control") == 1
