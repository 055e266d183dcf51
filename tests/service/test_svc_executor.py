"""The analysis pool (``LightPool``): real spawned processes fed over socket pairs.

Answers and errors come back whole; a call past its time limit is stopped by killing its
worker (even when its caller has gone), which is replaced; a worker that dies fails its call
and is replaced; ``submit`` works from any thread; a shut-down pool leaves no process behind.
Pipelining (a call written behind a busy worker's): the call waiting behind one that passes
its limit or kills its worker runs on the replacement, and one whose own limit passes while
it waits fails at its limit and is never started (its worker is replaced).
The callables are the standard library's, so that the workers import nothing from the tests.
"""

from __future__ import annotations

import asyncio
import math
import operator
import os
import threading
import time
from concurrent.futures.process import BrokenProcessPool

import pytest
from _svc_helpers import alive

from service.api.executor import LightPool, RemoteTraceback, TimeLimitExceeded

pytestmark = pytest.mark.anyio


async def _until(cond, timeout: float, what: str) -> None:  # noqa: ANN001
    end = time.monotonic() + timeout
    while not cond():
        if time.monotonic() > end:
            raise AssertionError(f"timed out waiting for {what}")
        await asyncio.sleep(0.05)


@pytest.fixture
async def pool():  # noqa: ANN201
    p = LightPool(2, name="test-pool")
    await _until(lambda: len(p.pids) == 2 and p.idle == 2, 60, "two workers")
    try:
        yield p
    finally:
        p.shutdown(wait=False)


async def test_answers_and_errors_come_back_whole(pool: LightPool) -> None:
    assert await pool.run(math.fsum, [0.1] * 10) == 1.0
    body = os.urandom(300_000)  # larger than a socket buffer: written in several pieces
    assert await pool.run(bytes.hex, body) == body.hex()
    with pytest.raises(ZeroDivisionError) as info:
        await pool.run(operator.truediv, 1, 0)
    assert isinstance(info.value.__cause__, RemoteTraceback)
    assert "ZeroDivisionError" in str(info.value.__cause__)
    with pytest.raises(ValueError, match="invalid literal"):
        await pool.run(int, "x")


async def test_calls_beyond_the_workers_wait_and_all_answer(pool: LightPool) -> None:
    pids = await asyncio.gather(*(pool.run(os.getpid) for _ in range(40)))
    assert set(pids) <= set(pool.pids) and len(pids) == 40


async def test_a_call_past_its_time_limit_is_killed_and_its_worker_replaced(
    pool: LightPool,
) -> None:
    before = set(pool.pids)
    t0 = time.monotonic()
    slow = asyncio.ensure_future(pool.run(time.sleep, 60, timeout=0.5))
    quick = await pool.run(math.sqrt, 4.0, timeout=5)  # the other worker still answers
    with pytest.raises(TimeLimitExceeded):
        await slow
    assert quick == 2.0 and time.monotonic() - t0 < 10
    await _until(lambda: len(pool.pids) == 2 and set(pool.pids) != before, 60, "a new worker")
    gone = before - set(pool.pids)
    assert len(gone) == 1
    await _until(lambda: not any(alive(p) for p in gone), 10, "the killed worker to end")
    assert await pool.run(math.sqrt, 9.0) == 3.0


async def test_a_caller_that_goes_away_does_not_unbound_its_call(pool: LightPool) -> None:
    before = set(pool.pids)
    task = asyncio.ensure_future(pool.run(time.sleep, 60, timeout=1.0))
    await asyncio.sleep(0.3)
    task.cancel()  # e.g. the request's task is cancelled: the work still has its limit
    await _until(lambda: set(pool.pids) != before, 30, "the worker past its limit killed")


async def test_a_worker_that_dies_fails_its_call_and_is_replaced(pool: LightPool) -> None:
    before = set(pool.pids)
    with pytest.raises(BrokenProcessPool):
        await pool.run(os._exit, 3)
    await _until(lambda: len(pool.pids) == 2 and set(pool.pids) != before, 60, "a new worker")
    assert await pool.run(math.sqrt, 16.0) == 4.0


@pytest.fixture
async def one():  # noqa: ANN201
    p = LightPool(1, name="test-pool", depth=2)
    await _until(lambda: p.idle == 1, 60, "a worker")
    try:
        yield p
    finally:
        p.shutdown(wait=False)


async def test_a_call_behind_one_past_its_limit_runs_on_the_replacement(one: LightPool) -> None:
    (first,) = one.pids
    slow = asyncio.ensure_future(one.run(time.sleep, 60, timeout=0.5))
    await asyncio.sleep(0.05)
    behind = asyncio.ensure_future(one.run(os.getpid, timeout=60))  # written behind the slow
    await asyncio.sleep(0.05)
    assert len(one._queue) == 0  # pipelined: in the worker's socket, not in the queue
    with pytest.raises(TimeLimitExceeded):
        await slow
    pid = await behind
    assert pid != first and pid in one.pids


async def test_a_call_behind_a_dying_worker_runs_on_the_replacement(one: LightPool) -> None:
    (first,) = one.pids
    dying = asyncio.ensure_future(one.run(os._exit, 3))
    behind = asyncio.ensure_future(one.run(os.getpid))
    with pytest.raises(BrokenProcessPool):
        await dying
    assert await behind not in (first, None)


async def test_a_waiting_call_past_its_own_limit_fails_alone(one: LightPool) -> None:
    (first,) = one.pids
    busy = asyncio.ensure_future(one.run(time.sleep, 1.0, timeout=30))
    await asyncio.sleep(0.05)
    t0 = time.monotonic()
    with pytest.raises(TimeLimitExceeded):
        await one.run(time.sleep, 60, timeout=0.2)  # would run 60 s with no limit left
    assert time.monotonic() - t0 < 0.9  # failed at its limit, not when the worker got to it
    assert await busy is None  # the call ahead ends normally
    # the worker is replaced instead of starting the expired call
    await _until(lambda: one.pids and one.pids != [first], 60, "a new worker")
    assert await one.run(math.sqrt, 9.0) == 3.0


async def test_submit_from_another_thread(pool: LightPool) -> None:
    out: list[object] = []

    def other() -> None:
        out.append(pool.submit(operator.add, 2, 3).result(timeout=60))
        try:
            pool.submit(operator.truediv, 1, 0).result(timeout=60)
        except ZeroDivisionError as exc:
            out.append(type(exc))

    t = threading.Thread(target=other)
    t.start()
    await _until(lambda: not t.is_alive(), 60, "the thread")
    assert out == [5, ZeroDivisionError]


async def test_shutdown_ends_every_worker_and_fails_queued_calls() -> None:
    p = LightPool(1, name="test-pool")
    await _until(lambda: p.idle == 1, 60, "a worker")
    pids = p.pids
    busy = asyncio.ensure_future(p.run(time.sleep, 60))
    queued = asyncio.ensure_future(p.run(math.sqrt, 1.0))
    await asyncio.sleep(0.2)
    p.shutdown(wait=False)
    for fut in (busy, queued):
        with pytest.raises((RuntimeError, BrokenProcessPool)):
            await fut
    await _until(lambda: not any(alive(x) for x in pids), 10, "the workers to end")
    with pytest.raises(RuntimeError, match="shut down"):
        await p.run(math.sqrt, 1.0)


async def test_a_detection_past_the_request_time_limit_is_a_422_and_the_pool_recovers(
    tmp_path,  # noqa: ANN001
) -> None:
    """Over the real app: a random walk (a costly record for detect: ~1 s for 25,000 samples
    on the 2-core development machine) against a 50 ms limit is a 422, once detect has answered
    here before (its kernels compiled); then a record answers again. On its first call the same
    time-out is the compilation's: a 503 with Retry-After, not the input's 422."""
    import httpx2
    import numpy as np
    from _svc_helpers import test_settings

    from service.api import create_app

    settings = test_settings(
        f"sqlite:///{tmp_path / 'limit.db'}", run_jobs=False, request_time_limit_s=0.05
    )
    app = create_app(settings)
    walk = np.cumsum(np.random.default_rng(0).standard_normal(25_000))
    ring = np.sin(0.3 * np.arange(2000)) * np.exp(-0.002 * np.arange(2000))
    async with app.router.lifespan_context(app):
        state = app.state.snapwarn
        await _until(lambda: state.pool.idle == 1, 60, "the analysis worker")
        async with httpx2.AsyncClient(
            transport=httpx2.ASGITransport(app=app), base_url="http://limit", timeout=60
        ) as c:
            r = await c.post("/v1/detections", json={"dt": 0.01, "w": walk.tolist()})
            assert r.status_code == 503 and int(r.headers["retry-after"]) > 0, r.text
            await _until(lambda: state.pool.idle == 1, 60, "a new worker")
            state.settings.request_time_limit_s = 120.0
            r = await c.post("/v1/detections", json={"dt": 0.01, "w": ring.tolist()})
            assert r.status_code == 200, r.text
            state.settings.request_time_limit_s = 0.05
            before = set(state.pool.pids)
            r = await c.post("/v1/detections", json={"dt": 0.01, "w": walk.tolist()})
            assert r.status_code == 422, r.text
            assert "time limit" in r.json()["detail"], r.text
            await _until(
                lambda: set(state.pool.pids) and set(state.pool.pids) != before, 60, "a new worker"
            )
            state.settings.request_time_limit_s = 120.0
            r = await c.post("/v1/detections", json={"dt": 0.01, "w": ring.tolist()})
            assert r.status_code == 200, r.text
            assert r.json()["modes"], r.text
