"""What a running app holds (store, pools, job runner) and the dependencies that reach it."""

from __future__ import annotations

import asyncio
import logging
import time
import uuid
from collections.abc import Callable
from concurrent.futures import Executor
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass, field
from typing import Annotated, Any, TypeVar

from fastapi import Depends, Request
from scipy.sparse.linalg import ArpackError

from service.api.executor import LightPool, TimeLimitExceeded, make_analysis_pool, run_in_pool
from service.api.jobs import JobRunner
from service.api.problems import ApiProblem
from service.api.settings import Settings
from service.api.storage import JobRow, SignalRow, Store, as_utc

T = TypeVar("T")
log = logging.getLogger("snapwarn.api")

#: How long an analysis request waits for the workers' warm-up before its 503 (seconds), and
#: the ``Retry-After`` it then gets.
WARM_WAIT_S = 60.0
WARM_RETRY_AFTER_S = 10


@dataclass
class AppState:
    settings: Settings
    store: Store
    pool: Executor
    runner: JobRunner | None = None
    numerics_cache: tuple[float, dict[str, bool]] | None = None
    extra: dict[str, Any] = field(default_factory=dict)
    #: The analysis workers have loaded (or compiled) their kernels (``service.api.warm``);
    #: False from start-up until then when the pool is warmed (``/healthz`` reports it).
    kernels_ready: bool = True
    #: The analysis functions that have answered once in this process's pool (their kernels
    #: compiled): a time limit passed by any other is the first compilation's, not the input's.
    warm_fns: set[str] = field(default_factory=set)

    async def run(self, fn: Callable[..., T], *args: Any) -> T:
        """Await ``fn(*args)`` in the analysis pool, within ``request_time_limit_s``.

        A call whose worker died is run once more (a broken thread or process pool is
        replaced; a :class:`LightPool` replaces its dead worker itself). Work past the time
        limit is stopped (its worker killed; a process pool of another kind is replaced whole)
        and answered 422: send the work as a job.
        Arithmetic errors of the numerics (overflow, division by zero) are the input's doing:
        422 too, with a correlation id in the log.
        While the workers warm up (start-up: their kernels load, or compile when numba's
        cache lacks them) a call waits up to :data:`WARM_WAIT_S`, then is answered 503 with
        ``Retry-After``: a server that is not ready is not the client's error, and its time
        limit never counts the compiler's time.
        """
        if not self.kernels_ready:
            await self._wait_warm()
        try:
            return await self._run_limited(fn, *args)
        except BrokenProcessPool:
            if not isinstance(self.pool, LightPool):
                self._replace_pool()
            return await self._run_limited(fn, *args)
        except (ArithmeticError, ArpackError) as exc:
            cid = uuid.uuid4().hex[:12]
            log.warning("numerics failed on the input [correlation id %s]", cid, exc_info=exc)
            raise ApiProblem(
                422,
                f"the numerics failed on these values ({type(exc).__name__}): the input is out "
                f"of the range they handle (correlation id {cid})",
                slug="numerics-out-of-range",
                field="body",
                value=None,
            ) from None

    async def _wait_warm(self) -> None:
        t0 = time.monotonic()
        while not self.kernels_ready:
            if time.monotonic() - t0 > WARM_WAIT_S:
                raise ApiProblem(
                    503,
                    "the service is starting: its analysis workers are still loading (or, on "
                    "a fresh install, compiling) their numerical kernels; retry shortly",
                    slug="warming-up",
                    headers={"Retry-After": str(WARM_RETRY_AFTER_S)},
                )
            await asyncio.sleep(0.05)

    async def _run_limited(self, fn: Callable[..., T], *args: Any) -> T:
        limit = self.settings.request_time_limit_s
        name = _name(fn)
        if isinstance(self.pool, LightPool):  # it kills the worker of a call past its limit
            try:
                out = await self.pool.run(fn, *args, timeout=limit)
            except TimeLimitExceeded:
                raise self._time_limit(fn, limit, name not in self.warm_fns) from None
            self.warm_fns.add(name)
            return out
        try:
            out = await asyncio.wait_for(run_in_pool(self.pool, fn, *args), timeout=limit)
        except TimeoutError:
            self._replace_pool(kill=True)
            raise self._time_limit(fn, limit, name not in self.warm_fns) from None
        self.warm_fns.add(name)
        return out

    @staticmethod
    def _time_limit(fn: Callable[..., Any], limit: float, cold: bool = False) -> ApiProblem:
        """422 for work past the limit; 503 with Retry-After when it was the function's first
        call here (the numerics' kernels compiling, tens of seconds on a busy machine: not the
        input's fault; a retry finds them compiled in the on-disk cache)."""
        log.warning("%s passed the request time limit of %g s", _name(fn), limit)
        if cold:
            return ApiProblem(
                503,
                f"the computation passed the request time limit of {limit:g} s on its first "
                "use since the server started (the numerics compiling their kernels); retry "
                "in a minute",
                title="Warming up",
                slug="warming-up",
                headers={"Retry-After": "60"},
            )
        return ApiProblem(
            422,
            f"the computation passed the request time limit of {limit:g} s (setting "
            "SNAPWARN_REQUEST_TIME_LIMIT_S) and was stopped; run it as a job "
            '(e.g. "background": true) or ask for less',
            slug="time-limit",
            field="body",
            value=None,
        )

    def _replace_pool(self, kill: bool = False) -> None:
        old = self.pool
        self.pool = make_analysis_pool(self.settings.executor, self.settings.analysis_workers)
        if kill:
            for p in list((getattr(old, "_processes", None) or {}).values()):
                try:
                    p.kill()
                except Exception:  # noqa: BLE001 - already gone
                    pass
        old.shutdown(wait=False, cancel_futures=True)

    def numerics_status(self, max_age: float = 60.0) -> dict[str, bool]:
        """Which numerics the workers can load, as last seen ({} until known).

        A refresh runs in the pool in the background when the value is missing or old.
        """
        cached = self.numerics_cache
        if cached is None or time.monotonic() - cached[0] > max_age:
            if not self.extra.get("numerics_pending"):
                self.extra["numerics_pending"] = True
                from service.api import warm

                def done(fut: Any) -> None:
                    self.extra["numerics_pending"] = False
                    if not fut.cancelled() and fut.exception() is None:
                        self.numerics_cache = (time.monotonic(), fut.result())

                try:
                    self.pool.submit(warm.available).add_done_callback(done)
                except Exception:  # noqa: BLE001 - a broken pool is replaced on next use
                    self.extra["numerics_pending"] = False
        return dict(cached[1]) if cached else {}


def get_state(request: Request) -> AppState:
    st = getattr(request.app.state, "snapwarn", None)
    if st is None:
        raise ApiProblem(503, "the service is not started (lifespan did not run)")
    return st


def signal_meta(row: SignalRow) -> dict[str, Any]:
    control = None
    if row.control_name is not None or row.control_value is not None:
        control = {
            "name": row.control_name or "mu",
            "value": row.control_value,
            "unit": row.control_unit,
        }
    return {
        "id": row.id,
        "name": row.name,
        "n": row.n,
        "dt": row.dt,
        "t0": row.t0,
        "duration": row.dt * (row.n - 1),
        "unit": row.unit,
        "value_unit": row.value_unit,
        "control": control,
        "metadata": row.meta or {},
        "source": row.source,
        "has_t": bool(row.has_t),
        "sha256": row.sha256,
        "created_at": as_utc(row.created_at),
    }


def job_doc(row: JobRow) -> dict[str, Any]:
    return {
        "id": row.id,
        "owner": row.owner,
        "kind": row.kind,
        "status": row.status,
        "progress": {"fraction": float(row.fraction or 0.0), "message": row.message or ""},
        "result": row.result,
        "error": row.error,
        "attempts": row.attempts,
        "created_at": as_utc(row.created_at),
        "started_at": as_utc(row.started_at),
        "finished_at": as_utc(row.finished_at),
    }


async def _state(request: Request) -> AppState:
    """``get_state`` as an async dependency: FastAPI runs a plain ``def`` dependency in its
    thread pool (a thread hand-off per request on the hot path)."""
    return get_state(request)


StateDep = Annotated[AppState, Depends(_state)]


def _name(fn: Any) -> str:
    """A stable name of the function a pool call runs (through ``functools.partial``)."""
    while hasattr(fn, "func"):
        fn = fn.func
    return f"{getattr(fn, '__module__', '')}.{getattr(fn, '__qualname__', repr(fn))}"
