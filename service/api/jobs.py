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
import multiprocessing as mp
import os
import threading
import time
import uuid
from collections.abc import Callable
from concurrent.futures import Executor, Future
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from service.api.problems import ApiProblem
from service.api.settings import Settings
from service.api.storage import DEFAULT_OWNER, Store, runner_identity
from service.api.storage.jobs import time_limit_error

log = logging.getLogger("snapwarn.jobs")

_stores: dict[str, Store] = {}


def _store_for(db_url: str) -> Store:
    st = _stores.get(db_url)
    if st is None:
        st = _stores[db_url] = Store(db_url)
    return st


def _problem_dict(exc: BaseException, job_id: str | None = None) -> dict[str, Any]:
    """The error stored on a failed job: the reason, never a traceback or a server path.

    Problems and parameter errors (``ParameterError``: ``parameter``, ``value``) are shown as
    they are; anything else is logged here with its traceback under a correlation id, and the
    client sees only the exception's class and that id.
    """
    if isinstance(exc, ApiProblem):
        return {**exc.to_dict(), "reason": "invalid-input" if exc.status < 500 else "error"}
    if isinstance(exc, ValueError) and hasattr(exc, "parameter"):
        field = str(exc.parameter)
        p = ApiProblem(422, str(exc)[:2000], field=field, value=getattr(exc, "value", None))
        return {**p.to_dict(), "reason": "invalid-input"}
    cid = uuid.uuid4().hex[:12]
    log.error("job %s failed [correlation id %s]", job_id, cid, exc_info=exc)
    return {
        "type": "urn:snapwarn:problem:internal-error",
        "title": "Internal error",
        "status": 500,
        "detail": f"the job failed on an internal error ({type(exc).__name__}); the server "
        f"log has the details under correlation id {cid}",
        "reason": "internal-error",
        "correlation_id": cid,
    }


class _TimeLimit(Exception):  # noqa: N818
    """The job passed its time limit (noticed at a progress report)."""


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
    owner: str = DEFAULT_OWNER


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
    t_start = time.monotonic()
    budget = None if job.time_limit_s is None else job.time_limit_s - float(job.run_s or 0.0)

    def progress(fraction: float, message: str = "") -> None:
        now = time.monotonic()
        if budget is not None and now - t_start > budget:
            raise _TimeLimit
        if now - last[0] >= 0.2 or fraction >= 1.0:
            last[0] = now
            if not store.job_progress(job_id, attempt, fraction, message):
                raise _Superseded  # failed/cancelled meanwhile, or resumed elsewhere

    try:
        handler = load_handlers().get(job.kind)
        if handler is None:
            raise ApiProblem(422, f"unknown job kind {job.kind!r}", field="kind", value=job.kind)
        ctx = JobContext(
            job_id=job_id,
            kind=job.kind,
            params=job.params,
            store=store,
            progress=progress,
            owner=job.owner or DEFAULT_OWNER,
        )
        result = handler(ctx)
    except _Superseded:
        return "superseded"
    except _TimeLimit:
        elapsed = float(job.run_s or 0.0) + time.monotonic() - t_start
        store.fail_job(job_id, attempt, time_limit_error(job, elapsed))
        return "failed"
    except Exception as exc:  # noqa: BLE001 - every failure is recorded on the job
        store.fail_job(job_id, attempt, _problem_dict(exc, job_id))
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
    child = None
    if params.get("child"):  # a process of its own, as an atlas starts dask's (tests)
        import subprocess
        import sys

        child = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(600)"])
        progress(0.0, f"child {child.pid}")
    for k in range(steps):
        time.sleep(seconds / steps)
        progress((k + 1) / steps, f"step {k + 1} of {steps}")
    if child is not None:
        child.kill()
        child.wait()
    return {"slept": seconds, "pid": os.getpid(), "echo": params.get("echo")}


def store_simulated_signal(
    store: Store, sim: dict[str, Any], params: dict[str, Any], owner: str = DEFAULT_OWNER
) -> Any:
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
        owner=owner,
    )


def _job_process(db_url: str, job_id: str, attempt: int, parent: int) -> None:
    """The body of a job's own process (forked from the preloaded fork server)."""
    import signal

    from service.api.executor import _ONE_THREAD

    for var in _ONE_THREAD:
        os.environ.setdefault(var, "1")
    os.environ.setdefault("MPLBACKEND", "Agg")
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    # its own process group: the runner stops the job with every process it started (an
    # atlas's dask scheduler and workers), none left behind when the job is killed
    os.setpgrp()

    def watch() -> None:  # our parent is the fork server: watch the runner's process itself
        while True:
            time.sleep(0.25)
            try:
                os.kill(parent, 0)
            except ProcessLookupError:
                os.killpg(0, signal.SIGKILL)  # the job and its children
            except PermissionError:
                pass

    threading.Thread(target=watch, name="snapwarn-parent-watch", daemon=True).start()
    run_job(db_url, job_id, attempt)


def _kill_group(proc: Any) -> None:
    """Kill a job's process and the processes it started (its process group)."""
    import signal

    try:
        os.killpg(proc.pid, signal.SIGKILL)
    except (ProcessLookupError, PermissionError, OSError):
        proc.kill()  # not (yet) a group leader: the process alone


_MP_CONTEXT: Any = None
_PRELOAD = ["numpy", "service.api.jobs", "service.api.routers"]


def _mp_context() -> Any:
    """``forkserver`` (modules preloaded once: a job starts in milliseconds) or ``spawn``."""
    global _MP_CONTEXT
    if _MP_CONTEXT is None:
        if "forkserver" in mp.get_all_start_methods():
            ctx = mp.get_context("forkserver")
            ctx.set_forkserver_preload(_PRELOAD)
        else:  # pragma: no cover - platforms without fork
            ctx = mp.get_context("spawn")
        _MP_CONTEXT = ctx
    return _MP_CONTEXT


def _noop() -> None:
    return None


def _warm_fork_server() -> None:
    try:
        p = _mp_context().Process(target=_noop, daemon=True)
        p.start()
        p.join(120)
    except Exception:  # noqa: BLE001 - an optimisation only
        log.debug("could not warm the fork server", exc_info=True)


@dataclass
class _Running:
    attempt: int
    deadline: float | None  # time.monotonic() at which the job is stopped
    time_limit_s: float | None
    run_s: float
    proc: Any = None  # a multiprocessing.Process (executor "process")
    fut: Future | None = None  # a thread-pool future (executor "thread")


class JobRunner:
    """Claims and runs jobs; one per process that runs jobs.

    With the ``process`` executor (the default) every job runs in its own process, so a job
    that passes its time limit or is cancelled is stopped at once (the process is killed) and
    the others go on. With the ``thread`` executor (tests, debugging) jobs stop at their next
    progress report.
    """

    def __init__(self, store: Store, settings: Settings, pool_factory: Any = None) -> None:
        self.store = store
        self.settings = settings
        self._pool_factory = pool_factory
        self._threads = settings.executor == "thread"
        self.pool: Executor | None = pool_factory() if (self._threads and pool_factory) else None
        self.owner = runner_identity()
        self._running: dict[str, _Running] = {}
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._wake = threading.Event()
        self._thread: threading.Thread | None = None

    @property
    def runner(self) -> str:
        """This runner's identity (``host:pid:token``)."""
        return self.owner

    def start(self) -> None:
        self._recover()
        if not self._threads:  # start the fork server now (it imports the numerics once)
            threading.Thread(target=_warm_fork_server, name="snapwarn-fork", daemon=True).start()
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
            running = dict(self._running)
        for r in running.values():
            if r.proc is not None and r.proc.is_alive():
                _kill_group(r.proc)
        try:
            n = self.store.release_jobs(list(running), self.owner)
            if n:
                log.warning("stopping: %d running job(s) handed back to the queue", n)
        except Exception:  # noqa: BLE001 - recovery by lease will do it
            log.exception("could not hand back the running jobs")
        for r in running.values():
            if r.proc is not None:
                r.proc.join(1.0)
        if self.pool is not None:
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
                self._reap(now)
                if now - last_beat >= s.job_heartbeat_s:
                    last_beat = now
                    self._heartbeat()
                if now - last_recover >= min(s.job_lease_s / 2, 5.0):
                    last_recover = now
                    self._recover()
                    self.store.prune_workers(max(3600.0, 10 * s.job_lease_s))
                self._claim()
            except Exception:  # noqa: BLE001 - keep the runner alive (db hiccups)
                log.exception("job runner iteration failed")
            self._wake.wait(s.job_poll_s)
            self._wake.clear()

    def _heartbeat(self) -> None:
        with self._lock:
            ids = list(self._running)
        still = self.store.heartbeat_jobs(ids, self.owner)
        self.store.worker_heartbeat(self.owner)
        if self.settings.heartbeat_file:
            Path(self.settings.heartbeat_file).touch()
        for job_id in set(ids) - still:  # cancelled, failed or resumed elsewhere: stop it
            with self._lock:
                r = self._running.get(job_id)
            if r is not None and r.proc is not None:
                log.info("job %s is no longer ours (cancelled?): stopping its process", job_id)
                _kill_group(r.proc)

    def _reap(self, now: float) -> None:
        """Collect ended job processes; stop the ones past their time limit."""
        with self._lock:
            items = list(self._running.items())
        for job_id, r in items:
            if r.proc is None:
                continue
            if r.proc.is_alive():
                if r.deadline is not None and now >= r.deadline:
                    _kill_group(r.proc)
                    r.proc.join(2.0)
                    elapsed = r.run_s + (r.time_limit_s or 0.0) - max(0.0, r.deadline - now)
                    job = self.store.get_job(job_id)
                    if job is not None:
                        self.store.fail_job(job_id, r.attempt, time_limit_error(job, elapsed))
                    log.warning("job %s stopped at its time limit", job_id)
                else:
                    continue
            r.proc.join(0.1)
            code = r.proc.exitcode
            with self._lock:
                self._running.pop(job_id, None)
            if code not in (0, None) and not self._stop.is_set():
                cid = uuid.uuid4().hex[:12]
                log.error("job %s attempt %d: its process ended with code %s [%s]",
                          job_id, r.attempt, code, cid)
                self.store.fail_job(job_id, r.attempt, {
                    "type": "urn:snapwarn:problem:job-crashed",
                    "title": "Job failed",
                    "detail": f"the job's process ended unexpectedly (exit code {code}); "
                    f"correlation id {cid}",
                    "reason": "crashed",
                    "correlation_id": cid,
                })
            self._wake.set()

    def _claim(self) -> None:
        while not self._stop.is_set():
            with self._lock:
                if len(self._running) >= self.settings.job_workers:
                    return
            job = self.store.claim_job(self.owner)
            if job is None:
                return
            limit = job.time_limit_s
            run_s = float(job.run_s or 0.0)
            deadline = None if limit is None else time.monotonic() + max(0.0, limit - run_s)
            r = _Running(job.attempts, deadline, limit, run_s)
            if self._threads:
                r.fut = self._submit(job.id, job.attempts)
            else:
                ctx = _mp_context()
                r.proc = ctx.Process(
                    target=_job_process,
                    args=(self.store.url, job.id, job.attempts, os.getpid()),
                    name=f"snapwarn-job-{job.id[:8]}",
                    daemon=True,
                )
                r.proc.start()
            with self._lock:
                self._running[job.id] = r
            if r.fut is not None:
                r.fut.add_done_callback(
                    lambda f, jid=job.id, a=job.attempts: self._done(jid, a, f)
                )

    def _submit(self, job_id: str, attempt: int) -> Future:
        assert self.pool is not None
        try:
            return self.pool.submit(run_job, self.store.url, job_id, attempt)
        except RuntimeError:
            self.pool = self._pool_factory()
            return self.pool.submit(run_job, self.store.url, job_id, attempt)

    def _done(self, job_id: str, attempt: int, fut: Future) -> None:
        with self._lock:
            self._running.pop(job_id, None)
        exc = fut.exception() if not fut.cancelled() else None
        if exc is not None and not self._stop.is_set():
            try:
                self.store.fail_job(job_id, attempt, _problem_dict(exc))
            except Exception:  # noqa: BLE001
                log.exception("could not record the failure of job %s", job_id)
        self._wake.set()
