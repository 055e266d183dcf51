"""Pools that keep CPU-bound work off the event loop.

The numerics hold the GIL (numpy partly, numba kernels unless compiled ``nogil``), so the
default is a *process* pool started with ``spawn`` (safe next to uvicorn's threads). Workers
die with their parent (Linux ``PR_SET_PDEATHSIG``), so a killed server leaves no orphan
finishing a job behind its back.
"""

from __future__ import annotations

import asyncio
import ctypes
import multiprocessing as mp
import os
import signal
import sys
from collections.abc import Callable
from concurrent.futures import Executor, ProcessPoolExecutor, ThreadPoolExecutor
from typing import Any, TypeVar

T = TypeVar("T")


def _die_with_parent() -> None:
    if sys.platform.startswith("linux"):
        try:
            libc = ctypes.CDLL("libc.so.6", use_errno=True)
            libc.prctl(1, signal.SIGKILL)  # PR_SET_PDEATHSIG
        except OSError:  # pragma: no cover
            pass


def _init_worker() -> None:
    _die_with_parent()
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    os.environ.setdefault("MPLBACKEND", "Agg")


def make_pool(kind: str, workers: int, name: str) -> Executor:
    """A process pool (``spawn``) or a thread pool of ``workers`` workers."""
    if kind == "thread":
        return ThreadPoolExecutor(max_workers=workers, thread_name_prefix=name)
    return ProcessPoolExecutor(
        max_workers=workers, mp_context=mp.get_context("spawn"), initializer=_init_worker
    )


def warm_pool(pool: Executor, workers: int,
              on_ready: Callable[[dict[str, bool]], None] | None = None) -> None:
    """Start every worker and import the numerics there (best effort).

    ``on_ready`` receives which numerics entry points are installed.
    """
    from service.api import numerics

    futs = [pool.submit(numerics.warm) for _ in range(2 * workers)]
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
