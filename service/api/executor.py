"""Pools that keep CPU-bound work off the event loop.

The numerics hold the GIL (numpy partly, numba kernels unless compiled ``nogil``), so the
default is a *process* pool started with ``spawn`` (safe next to uvicorn's threads). Workers
exit as soon as their parent is gone, so a killed server leaves no orphan finishing a job
behind its back.
"""

from __future__ import annotations

import asyncio
import multiprocessing as mp
import os
import signal
import threading
import time
from collections.abc import Callable
from concurrent.futures import Executor, ProcessPoolExecutor, ThreadPoolExecutor
from typing import Any, TypeVar

T = TypeVar("T")


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
    """Start every worker and import the numerics there (best effort).

    ``on_ready`` receives which numerics entry points are installed.
    """
    from service.api import warm

    futs = [pool.submit(warm.warm) for _ in range(2 * workers)]
    for f in futs:
        try:
            avail = f.result(timeout=300)
            if on_ready is not None:
                on_ready(avail)
                on_ready = None
        except Exception:  # noqa: BLE001 - warming is an optimisation
            pass


async def run_in_pool(pool: Executor, fn: Callable[..., T], *args: Any) -> T:
    """Await ``fn(*args)`` run in ``pool``."""
    loop = asyncio.get_running_loop()
    return await loop.run_in_executor(pool, fn, *args)
