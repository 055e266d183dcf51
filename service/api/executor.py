"""Pools that keep CPU-bound work off the event loop.

The numerics hold the GIL (numpy partly, numba kernels unless compiled ``nogil``), so the
default is *processes* started with ``spawn`` (safe next to uvicorn's threads):

- the request path's analysis pool is a :class:`LightPool`: the event loop writes each call to
  a worker's socket and reads its answer itself (no feeder or result thread, no GIL hand-off);
  a call past its time limit has its worker killed and replaced;
- jobs run in a ``ProcessPoolExecutor`` (:func:`make_pool`) driven by the job runner's threads.

Workers exit as soon as their parent is gone, so a killed server leaves no orphan finishing a
job behind its back.

Detections are not run inline on the event loop, even small ones: detect's cost depends on the
record, not only on its length (a 1e4-sample random walk takes ~240 ms, a 2.5e4-sample one ~1 s,
against ~3 ms for a ringing record), and a call on the event loop cannot be stopped.
"""

from __future__ import annotations

import asyncio
import atexit
import functools
import logging
import multiprocessing as mp
import os
import pickle
import signal
import socket
import struct
import threading
import time
import traceback
import weakref
from collections import deque
from collections.abc import Callable
from concurrent.futures import (
    CancelledError,
    Executor,
    Future,
    ProcessPoolExecutor,
    ThreadPoolExecutor,
)
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass, field
from multiprocessing.process import BaseProcess
from typing import Any, TypeVar

T = TypeVar("T")
log = logging.getLogger("snapwarn.api")


def _die_with_parent(parent: int, period: float = 0.25) -> None:
    """Exit as soon as ``parent`` is gone (we get re-parented), even if it was SIGKILLed.

    A watchdog thread, not ``PR_SET_PDEATHSIG``: that one fires when the *thread* that
    spawned us exits, and pools spawn workers from whichever thread submits first.
    """
    if os.getppid() != parent:
        os._exit(70)

    def watch() -> None:
        while True:
            time.sleep(period)
            if os.getppid() != parent:
                os._exit(70)

    threading.Thread(target=watch, name="snapwarn-parent-watch", daemon=True).start()


_ONE_THREAD = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS")


def _init_worker(parent: int) -> None:
    for var in _ONE_THREAD:  # the pool is the parallelism: one BLAS thread per worker
        os.environ.setdefault(var, "1")
    _die_with_parent(parent)
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    os.environ.setdefault("MPLBACKEND", "Agg")


def make_pool(kind: str, workers: int, name: str) -> Executor:
    """A process pool (``spawn``) or a thread pool of ``workers`` workers."""
    if kind == "thread":
        return ThreadPoolExecutor(max_workers=workers, thread_name_prefix=name)
    return ProcessPoolExecutor(
        max_workers=workers,
        mp_context=mp.get_context("spawn"),
        initializer=_init_worker,
        initargs=(os.getpid(),),
    )


def warm_pool(
    pool: Executor, workers: int, on_ready: Callable[[dict[str, bool]], None] | None = None
) -> None:
    """Start every worker and load the numerics' kernels there (best effort; returns when
    every worker is warm or has failed to warm).

    One worker warms first: on a cache that lacks kernels it compiles them once and fills the
    cache, then the others load them (instead of every worker compiling the same kernels at
    once on the same cores). ``on_ready`` receives which numerics entry points are installed.
    """
    from service.api import warm

    def wait(futs: list[Future[dict[str, bool]]]) -> None:
        nonlocal on_ready
        for f in futs:
            try:
                avail = f.result(timeout=_WARM_TIMEOUT_S)
                if on_ready is not None:
                    on_ready(avail)
                    on_ready = None
            except Exception:  # noqa: BLE001 - warming is an optimisation
                pass

    wait([pool.submit(warm.warm)])
    wait([pool.submit(warm.warm) for _ in range(2 * workers - 1)])


#: How long one worker's warm-up may take (a cold cache on a loaded machine: minutes).
_WARM_TIMEOUT_S = 900.0


async def run_in_pool(pool: Executor, fn: Callable[..., T], *args: Any) -> T:
    """Await ``fn(*args)`` run in ``pool`` (a :class:`LightPool` or any executor)."""
    if isinstance(pool, LightPool):
        return await pool.run(fn, *args)
    loop = asyncio.get_running_loop()
    return await loop.run_in_executor(pool, fn, *args)


def make_analysis_pool(kind: str, workers: int) -> Executor:
    """The request path's pool: a :class:`LightPool` (``kind="process"``, call it from the event
    loop that will use it) or a thread pool (``kind="thread"``)."""
    if kind == "thread":
        return make_pool(kind, workers, "snapwarn-analysis")
    return LightPool(workers, name="snapwarn-analysis")


# ------------------------------------------------------------------------------- light pool
_HEADER = struct.Struct("!Q")  # every frame: its length (bytes), then a pickle
#: A worker that ends sooner than this after its start is replaced only after a pause (a
#: worker that cannot start must not be re-spawned in a tight loop).
_QUICK_DEATH_S = 2.0


class TimeLimitExceeded(Exception):  # noqa: N818 - reads as the event
    """A call passed its time limit; the worker running it was stopped (SIGKILL)."""


class RemoteTraceback(Exception):  # noqa: N818 - carries a traceback's text, as in futures
    """The traceback of an exception raised in a worker (its ``__cause__``, for the logs)."""

    def __init__(self, tb: str) -> None:
        super().__init__(tb)
        self.tb = tb

    def __str__(self) -> str:
        return self.tb


def _recv_exact(sock: socket.socket, n: int) -> bytearray | None:
    """``n`` bytes from a blocking socket; None at end of stream."""
    buf = bytearray(n)
    view = memoryview(buf)
    got = 0
    while got < n:
        k = sock.recv_into(view[got:])
        if k == 0:
            return None
        got += k
    return buf


def _frame_parts(obj: object) -> tuple[bytes, bytes]:
    """``obj`` pickled, and its length header (written together: one copy of a large body)."""
    data = pickle.dumps(obj, protocol=pickle.HIGHEST_PROTOCOL)
    return _HEADER.pack(len(data)), data


def _frame(obj: object) -> bytes:
    """``obj`` pickled behind its length, in one buffer."""
    head, data = _frame_parts(obj)
    return head + data


def _answer(data: bytearray) -> bytes:
    """Run one call frame's ``fn(*args)``; the answer frame ``(ok, value, traceback text)``."""
    try:
        fn, args = pickle.loads(data)
        del data
        return _frame((True, fn(*args), None))
    except Exception as exc:  # noqa: BLE001 - every failure goes back to the caller
        tb = "".join(traceback.format_exception(exc))
        try:
            return _frame((False, exc, tb))
        except Exception:  # noqa: BLE001 - an exception that does not pickle
            return _frame((False, RuntimeError(f"{type(exc).__name__}: {exc}"), tb))


def _worker_main(sock: socket.socket, parent: int) -> None:
    """A :class:`LightPool` worker: answer call frames until the server closes its end."""
    _init_worker(parent)
    sock.setblocking(True)
    while True:
        head = _recv_exact(sock, _HEADER.size)
        data = _recv_exact(sock, _HEADER.unpack(head)[0]) if head is not None else None
        if data is None:
            return  # the server closed its end (shut down, or gone)
        try:
            sock.sendall(_answer(data))
        except OSError:
            return


@dataclass(eq=False)
class _Call:
    fn: Callable[..., Any]
    args: tuple[Any, ...]
    future: asyncio.Future[Any]
    timer: asyncio.TimerHandle | None = None
    worker: _Worker | None = None
    sent: float = 0.0  # when its frame was written to its worker (monotonic s)


@dataclass(eq=False)
class _Worker:
    proc: BaseProcess
    started: float
    transport: asyncio.Transport | None = None
    #: calls written to the worker, in order: the first runs, the others wait in its socket
    calls: deque[_Call] = field(default_factory=deque)
    alive: bool = True


class _Channel(asyncio.Protocol):
    """The server's end of one worker's socket: frames in, one answer per call."""

    def __init__(self, pool: LightPool, worker: _Worker) -> None:
        self.pool, self.worker = pool, worker
        self.buf = bytearray()
        self.need = -1

    def connection_made(self, transport: asyncio.BaseTransport) -> None:
        self.worker.transport = transport  # type: ignore[assignment]

    def data_received(self, data: bytes) -> None:
        buf = self.buf
        buf += data
        while True:
            if self.need < 0:
                if len(buf) < _HEADER.size:
                    return
                self.need = _HEADER.unpack_from(buf)[0]
                del buf[: _HEADER.size]
            if len(buf) < self.need:
                return
            with memoryview(buf) as view:  # one copy of a large answer, not two
                frame = bytes(view[: self.need])
            del buf[: self.need]
            self.need = -1
            self.pool._on_answer(self.worker, frame)

    def connection_lost(self, exc: Exception | None) -> None:
        self.pool._on_lost(self.worker)


_POOLS: weakref.WeakSet[LightPool] = weakref.WeakSet()


@atexit.register
def _kill_pools() -> None:  # before multiprocessing's own exit hook joins its children
    for pool in list(_POOLS):
        pool.kill_workers()


class LightPool(Executor):
    """Worker processes (``spawn``) fed by the event loop itself over one socket pair each.

    Each call is one frame each way (its length, then a pickle: ``(fn, args)`` out,
    ``(ok, value, traceback)`` back) written and read by the event loop's own transports: no
    feeder or result thread, no queue between processes, no GIL hand-off per call (what a
    ``ProcessPoolExecutor`` pays: measured 1.2 ms of the event loop's CPU per request and a
    third of the workers' overhead, bench/service.py). Calls wait in a FIFO for a free worker.

    Bounded: a call given a ``timeout`` (seconds, counted from its submission) that has not
    answered by then raises :class:`TimeLimitExceeded` and its worker is killed and replaced,
    even when its caller has gone. A worker that dies fails its call with
    ``BrokenProcessPool`` and is replaced. Workers exit when the server closes their socket or
    dies (see :func:`_die_with_parent`).

    Pipelined: when every worker is busy and calls wait, the next call is written to the busy
    worker whose call started first, up to ``depth`` calls per worker, so a worker goes from
    one answer straight to its next call without waiting for the event loop (under load the
    cores stayed 8-10 % idle at one call per worker, bench/service.py). A call waiting behind
    another never started: if the one ahead passes its time limit or its worker dies, the
    waiting calls go back to the front of the queue; one that passes its own limit while it
    waits fails then, and its worker is replaced before it would run it without a limit.

    Parameters
    ----------
    workers : int
        Worker processes (each runs one call at a time).
    name : str, optional
        Prefix of the workers' process names.
    depth : int, optional
        Calls written to one worker at most (1: no pipelining).

    Notes
    -----
    Create it, and call :meth:`run` and :meth:`shutdown`, in the event loop that owns it;
    :meth:`submit` may be called from any thread.
    """

    def __init__(self, workers: int, name: str = "snapwarn-pool", depth: int = 2) -> None:
        if workers < 1:
            raise ValueError(f"workers={workers!r}: expected >= 1")
        if depth < 1:
            raise ValueError(f"depth={depth!r}: expected >= 1")
        self._depth = depth
        self._loop = asyncio.get_running_loop()
        self._ctx = mp.get_context("spawn")
        self._name = name
        self._workers: set[_Worker] = set()
        self._idle: deque[_Worker] = deque()
        self._queue: deque[_Call] = deque()
        self._closed = False
        self._spawned = 0
        _POOLS.add(self)
        for _ in range(workers):
            self._spawn()

    # -- public
    async def run(self, fn: Callable[..., T], *args: Any, timeout: float | None = None) -> T:
        """Await ``fn(*args)`` in a worker (:class:`TimeLimitExceeded` past ``timeout`` s)."""
        call = self._enqueue(fn, args, timeout)
        return await call.future

    def submit(self, fn: Callable[..., T], /, *args: Any, **kwargs: Any) -> Future[T]:
        """``fn(*args, **kwargs)`` in a worker, from any thread (a ``concurrent`` future)."""
        if kwargs:
            fn = functools.partial(fn, **kwargs)
        out: Future[T] = Future()

        def start() -> None:
            if self._closed:
                out.set_exception(RuntimeError("the pool is shut down"))
                return
            call = self._enqueue(fn, args, None)

            def copy(f: asyncio.Future[Any]) -> None:
                if not out.set_running_or_notify_cancel():
                    return
                if f.cancelled():
                    out.set_exception(CancelledError())
                elif f.exception() is not None:
                    out.set_exception(f.exception())  # type: ignore[arg-type]
                else:
                    out.set_result(f.result())

            call.future.add_done_callback(copy)

        self._loop.call_soon_threadsafe(start)
        return out

    def shutdown(self, wait: bool = True, *, cancel_futures: bool = False) -> None:
        """Stop the workers: idle ones see their socket close, busy ones are killed.

        Queued calls fail (``cancel_futures`` is implied: no worker is left to run them);
        ``wait`` joins the processes (do not wait from the event loop).
        """
        if self._closed:
            return
        self._closed = True
        while self._queue:
            call = self._queue.popleft()
            if not call.future.done():
                call.future.set_exception(RuntimeError("the pool is shut down"))
        for w in list(self._workers):
            if w.calls:
                w.proc.kill()
            if w.transport is not None:
                w.transport.close()
        if wait:
            for w in list(self._workers):
                w.proc.join(10)

    def kill_workers(self) -> None:
        """Kill every worker at once (interpreter exit; callable from any thread)."""
        self._closed = True
        for w in list(self._workers):
            try:
                w.proc.kill()
            except Exception:  # noqa: BLE001 - already gone or never started
                pass

    @property
    def pids(self) -> list[int]:
        """The live workers' process ids."""
        return [w.proc.pid for w in self._workers if w.alive and w.proc.pid]

    @property
    def idle(self) -> int:
        """Workers started, connected and waiting for a call."""
        return len(self._idle)

    # -- internals
    def _spawn(self) -> None:
        parent_end, child_end = socket.socketpair()
        self._spawned += 1
        proc = self._ctx.Process(
            target=_worker_main,
            args=(child_end, os.getpid()),
            name=f"{self._name}-{self._spawned}",
        )
        try:
            proc.start()
        finally:
            child_end.close()
        w = _Worker(proc, time.monotonic())
        self._workers.add(w)
        self._loop.create_task(self._attach(w, parent_end))

    async def _attach(self, w: _Worker, sock: socket.socket) -> None:
        sock.setblocking(False)
        try:
            await self._loop.create_unix_connection(lambda: _Channel(self, w), sock=sock)
        except OSError:
            sock.close()
            self._on_lost(w)
            return
        if self._closed:
            assert w.transport is not None
            w.transport.close()
            return
        self._idle.append(w)
        self._dispatch()

    def _enqueue(
        self, fn: Callable[..., Any], args: tuple[Any, ...], timeout: float | None
    ) -> _Call:
        if self._closed:
            raise RuntimeError("the pool is shut down")
        call = _Call(fn, args, self._loop.create_future())
        if timeout is not None:
            call.timer = self._loop.call_later(timeout, self._expire, call, timeout)
        self._queue.append(call)
        self._dispatch()
        return call

    def _dispatch(self) -> None:
        while self._queue:
            call = self._queue.popleft()
            if call.future.done():  # its caller went away (cancelled) or it timed out
                continue
            w = self._free_worker()
            if w is None:
                self._queue.appendleft(call)
                return
            try:
                frame = _frame_parts((call.fn, call.args))
            except Exception as exc:  # noqa: BLE001 - not picklable: the caller's error
                if not w.calls:
                    self._idle.append(w)
                call.future.set_exception(exc)
                continue
            w.calls.append(call)
            call.worker, call.sent = w, time.monotonic()
            assert w.transport is not None
            w.transport.writelines(frame)

    def _free_worker(self) -> _Worker | None:
        """An idle worker (the last one to answer: its caches are the warmest); else, when
        pipelining, the busy worker with the fewest calls whose running call started first."""
        if self._idle:
            return self._idle.pop()
        best: _Worker | None = None
        if self._depth > 1:
            for w in self._workers:
                if not (w.alive and w.transport is not None and 0 < len(w.calls) < self._depth):
                    continue
                if best is None or (len(w.calls), w.calls[0].sent) < (
                    len(best.calls),
                    best.calls[0].sent,
                ):
                    best = w
        return best

    def _on_answer(self, w: _Worker, frame: bytes) -> None:
        call = w.calls.popleft() if w.calls else None
        if call is not None:
            call.worker = None
            if call.timer is not None:
                call.timer.cancel()
            if not call.future.done():
                try:
                    ok, value, tb = pickle.loads(frame)
                except Exception as exc:  # noqa: BLE001 - e.g. a class unknown here
                    call.future.set_exception(exc)
                else:
                    if ok:
                        call.future.set_result(value)
                    else:
                        value.__cause__ = RemoteTraceback(tb)
                        call.future.set_exception(value)
        if w.alive and not self._closed:
            if w.calls and w.calls[0].future.done() and w.calls[0].timer is None:
                # the next call passed its limit while it waited: it would now run without one
                log.info("a call passed its time limit while waiting: worker %s is replaced",
                         w.proc.pid)  # fmt: skip
                w.proc.kill()
                if w.transport is not None:
                    w.transport.abort()  # -> _on_lost: the calls behind it go back to the queue
                return
            if not w.calls:
                self._idle.append(w)
            self._dispatch()

    def _expire(self, call: _Call, timeout: float) -> None:
        """``call`` passed its time limit: fail it; kill its worker if it is running it (a call
        still waiting behind another fails now; its worker is replaced when it would start it,
        see ``_on_answer``)."""
        call.timer = None
        if not call.future.done():
            call.future.set_exception(
                TimeLimitExceeded(f"{getattr(call.fn, '__name__', call.fn)} passed {timeout:g} s")
            )
        w = call.worker
        if w is not None and w.calls and w.calls[0] is call:
            log.warning(
                "a call passed its time limit of %g s: its worker %s is killed", timeout, w.proc.pid
            )
            w.proc.kill()
            if w.transport is not None:
                w.transport.abort()  # -> _on_lost: replaced

    def _on_lost(self, w: _Worker) -> None:
        if not w.alive:
            return
        w.alive = False
        self._workers.discard(w)
        try:
            self._idle.remove(w)
        except ValueError:
            pass
        calls = list(w.calls)
        w.calls.clear()
        for call in calls:
            call.worker = None
        if calls:
            call = calls[0]  # the one it was running
            if call.timer is not None:
                call.timer.cancel()
            if not call.future.done():
                call.future.set_exception(
                    BrokenProcessPool(
                        "a worker of the pool ended while running "
                        f"{getattr(call.fn, '__name__', call.fn)}"
                    )
                )
            # the calls written behind it never started: back to the front of the queue
            for call in calls[1:]:
                if self._closed and not call.future.done():
                    call.future.set_exception(RuntimeError("the pool is shut down"))
            if not self._closed:
                self._queue.extendleft(reversed(calls[1:]))
        self._loop.run_in_executor(None, w.proc.join, 30)  # reap it
        if not self._closed:
            quick = time.monotonic() - w.started < _QUICK_DEATH_S
            self._loop.call_later(1.0 if quick else 0.0, self._respawn)
            self._dispatch()

    def _respawn(self) -> None:
        if not self._closed:
            self._spawn()
