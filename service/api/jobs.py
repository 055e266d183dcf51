"""Persistent jobs: a runner claims queued jobs from the database and runs them in a pool.

The state machine lives in the ``jobs`` table (queued -> running -> succeeded | failed):
- a runner (the API's embedded one, or ``snapwarn worker``) claims a job atomically, bumping
  ``attempts`` (the fencing token) and heartbeats it while it runs;
- the job itself runs in a worker process, reports progress and writes its result or error
  fenced by its attempt, so a write from an attempt that was superseded is dropped;
- any runner re-queues running jobs whose lease expired or whose owner process is dead on this
  host (restart after a crash), up to ``job_max_attempts``; beyond it they fail with a reason.
A job that succeeded is never touched again: nothing completed is lost.
"""

from __future__ import annotations

import logging
import os
import threading
import time
import traceback
from collections.abc import Callable
from concurrent.futures import Executor, Future
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from service.api.problems import ApiProblem
from service.api.settings import Settings
from service.api.storage import Store, runner_identity

log = logging.getLogger("snapwarn.jobs")

_stores: dict[str, Store] = {}


def _store_for(db_url: str) -> Store:
    st = _stores.get(db_url)
    if st is None:
        st = _stores[db_url] = Store(db_url)
    return st


def _problem_dict(exc: BaseException) -> dict[str, Any]:
    if isinstance(exc, ApiProblem):
        return exc.to_dict()
    return {
        "type": "urn:snapwarn:problem:internal-error",
        "title": "Internal error",
        "status": 500,
        "detail": f"{type(exc).__name__}: {exc}",
        "traceback": traceback.format_exception(exc)[-5:],
    }


class _Superseded(Exception):  # noqa: N818
    """This attempt no longer owns its job: stop working on it."""


@dataclass(frozen=True)
class JobContext:
    """What a job handler gets: its parameters, the store, and a progress callback.

    Attributes
    ----------
    job_id : str
        The job's id.
    kind : str
        The job's kind (the key of its handler in :data:`JOB_HANDLERS`).
    params : dict
        The parameters stored with the job when it was created.
    store : Store
        The store of the runner's database (the handler may read and write resources).
    progress : Callable[[float, str], None]
        Report the fraction done (0..1) and a message; raises when the attempt was superseded
        (the job was cancelled, failed or resumed elsewhere meanwhile), which ends the handler.
    """

    job_id: str
    kind: str
    params: dict[str, Any]
    store: Store
    progress: Callable[[float, str], None]


JobHandler = Callable[[JobContext], dict[str, Any]]
JOB_HANDLERS: dict[str, JobHandler] = {}
"""Job kind -> handler. Each resource registers its kinds with :func:`job_handler` next to the
router that creates them; :func:`load_handlers` imports those modules (also in worker
processes)."""

_HANDLER_MODULES = ("service.api.routers",)


def job_handler(kind: str) -> Callable[[JobHandler], JobHandler]:
    """Register ``fn`` as the handler of jobs of ``kind`` (a decorator)."""

    def deco(fn: JobHandler) -> JobHandler:
        JOB_HANDLERS[kind] = fn
        return fn

    return deco


def load_handlers() -> dict[str, JobHandler]:
    """Import every module that registers job handlers; returns the table."""
    import importlib
    import pkgutil

    for name in _HANDLER_MODULES:
        pkg = importlib.import_module(name)
        for info in pkgutil.iter_modules(getattr(pkg, "__path__", [])):
            importlib.import_module(f"{name}.{info.name}")
    return JOB_HANDLERS


def run_job(db_url: str, job_id: str, attempt: int) -> str:
    """Run one claimed job to its end (called in a worker process); returns its status."""
    store = _store_for(db_url)
    job = store.get_job(job_id)
    if job is None or job.attempts != attempt or job.status != "running":
        return "superseded"
    last = [0.0]

    def progress(fraction: float, message: str = "") -> None:
        now = time.monotonic()
        if now - last[0] >= 0.2 or fraction >= 1.0:
            last[0] = now
            if not store.job_progress(job_id, attempt, fraction, message):
                raise _Superseded  # failed/cancelled meanwhile, or resumed elsewhere

    try:
        handler = load_handlers().get(job.kind)
        if handler is None:
            raise ApiProblem(422, f"unknown job kind {job.kind!r}", field="kind", value=job.kind)
        ctx = JobContext(
            job_id=job_id, kind=job.kind, params=job.params, store=store, progress=progress
        )
        result = handler(ctx)
    except _Superseded:
        return "superseded"
    except Exception as exc:  # noqa: BLE001 - every failure is recorded on the job
        store.fail_job(job_id, attempt, _problem_dict(exc))
        return "failed"
    return "succeeded" if store.finish_job(job_id, attempt, result) else "superseded"


@job_handler("diagnostic-sleep")
def _diagnostic_sleep(ctx: JobContext) -> dict[str, Any]:
    """A job that only waits (no API creates it): exercises the job machinery in tests and
    deployments (``Store.create_job("diagnostic-sleep", {"seconds": 2})``)."""
    params, progress = ctx.params, ctx.progress
    seconds = float(params.get("seconds", 1.0))
    steps = max(1, int(params.get("steps", 10)))
    if params.get("fail"):
        raise ApiProblem(422, "asked to fail", field="fail", value=True)
    for k in range(steps):
        time.sleep(seconds / steps)
        progress((k + 1) / steps, f"step {k + 1} of {steps}")
    return {"slept": seconds, "pid": os.getpid(), "echo": params.get("echo")}


def store_simulated_signal(store: Store, sim: dict[str, Any], params: dict[str, Any]) -> Any:
    """Store a simulated signal with its scene (no physics: just the numbers)."""
    scene = params["scene"]
    t = sim["t"]
    n = len(sim["w"])
    dt = (float(t[-1]) - float(t[0])) / (n - 1)
    return store.add_signal(
        w=sim["w"],
        dt=dt,
        t0=float(t[0]),
        t=t,
        source="simulation",
        name=params.get("name"),
        unit=None,
        value_unit=None,
        control={"name": "mu", "value": float(scene.get("mu", 0.0)), "unit": None},
        metadata={
            "scene": scene,
            "model": sim["model"],
            "w_static": sim["w_static"],
            "info": sim["info"],
        },
    )


def _terminate_workers(pool: Executor) -> None:
    """End the worker processes of a process pool now (their jobs were handed back)."""
    procs = getattr(pool, "_processes", None) or {}
    for p in list(procs.values()):
        try:
            p.terminate()
        except Exception:  # noqa: BLE001
            pass


class JobRunner:
    """Claims and runs jobs in a background thread; one per process that runs jobs."""

    def __init__(self, store: Store, settings: Settings, pool_factory: Any) -> None:
        self.store = store
        self.settings = settings
        self._pool_factory = pool_factory
        self.pool: Executor = pool_factory()
        self.owner = runner_identity()
        self._running: dict[str, tuple[int, Future]] = {}
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._wake = threading.Event()
        self._thread: threading.Thread | None = None

    def start(self) -> None:
        self._recover()
        self._thread = threading.Thread(target=self._loop, name="snapwarn-jobs", daemon=True)
        self._thread.start()

    def wake(self) -> None:
        """Look for queued jobs now (called after a job is created)."""
        self._wake.set()

    def stop(self, timeout: float = 5.0) -> None:
        """Stop claiming; hand the running jobs back to the queue (resumed by any runner)."""
        self._stop.set()
        self._wake.set()
        if self._thread is not None:
            self._thread.join(timeout)
        with self._lock:
            ids = list(self._running)
        try:
            n = self.store.release_jobs(ids, self.owner)
            if n:
                log.warning("stopping: %d running job(s) handed back to the queue", n)
        except Exception:  # noqa: BLE001 - recovery by lease will do it
            log.exception("could not hand back the running jobs")
        _terminate_workers(self.pool)
        self.pool.shutdown(wait=False, cancel_futures=True)
        try:
            self.store.worker_gone(self.owner)
        except Exception:  # noqa: BLE001
            pass

    def _recover(self) -> None:
        for job_id, new in self.store.recover_jobs(
            lease_s=self.settings.job_lease_s, max_attempts=self.settings.job_max_attempts
        ):
            log.warning("job %s was interrupted: now %s", job_id, new)

    def _loop(self) -> None:
        s = self.settings
        last_beat = 0.0
        last_recover = time.monotonic()
        while not self._stop.is_set():
            try:
                now = time.monotonic()
                if now - last_beat >= s.job_heartbeat_s:
                    last_beat = now
                    with self._lock:
                        ids = list(self._running)
                    self.store.heartbeat_jobs(ids, self.owner)
                    self.store.worker_heartbeat(self.owner)
                    if s.heartbeat_file:
                        Path(s.heartbeat_file).touch()
                if now - last_recover >= min(s.job_lease_s / 2, 5.0):
                    last_recover = now
                    self._recover()
                    self.store.prune_workers(max(3600.0, 10 * s.job_lease_s))
                self._claim()
            except Exception:  # noqa: BLE001 - keep the runner alive (db hiccups)
                log.exception("job runner iteration failed")
            self._wake.wait(s.job_poll_s)
            self._wake.clear()

    def _claim(self) -> None:
        while True:
            with self._lock:
                if len(self._running) >= self.settings.job_workers:
                    return
            job = self.store.claim_job(self.owner)
            if job is None:
                return
            try:
                fut = self.pool.submit(run_job, self.store.url, job.id, job.attempts)
            except (BrokenProcessPool, RuntimeError):
                self.pool = self._pool_factory()
                fut = self.pool.submit(run_job, self.store.url, job.id, job.attempts)
            with self._lock:
                self._running[job.id] = (job.attempts, fut)
            fut.add_done_callback(lambda f, jid=job.id, a=job.attempts: self._done(jid, a, f))

    def _done(self, job_id: str, attempt: int, fut: Future) -> None:
        with self._lock:
            self._running.pop(job_id, None)
        exc = fut.exception() if not fut.cancelled() else None
        if exc is not None and self._stop.is_set():
            return  # stopping: the job was handed back to the queue, not failed
        if exc is not None:
            log.error("job %s attempt %d crashed: %r", job_id, attempt, exc)
            try:
                self.store.fail_job(job_id, attempt, _problem_dict(exc))
            except Exception:  # noqa: BLE001
                log.exception("could not record the failure of job %s", job_id)
            if isinstance(exc, BrokenProcessPool):
                self.pool = self._pool_factory()
        self._wake.set()
