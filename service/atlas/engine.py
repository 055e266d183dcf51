"""Run an atlas on dask.distributed: one future per cell, each row persisted as it arrives.

- Without a scheduler address a ``LocalCluster`` is started: worker *processes*, one thread
  each, one BLAS/OpenMP/numba thread per process (the cluster is the parallelism).
- With ``scheduler=`` (or ``SNAPWARN_DASK_SCHEDULER``) the cells go to a running cluster
  (``dask scheduler`` + ``dask worker``, dask-jobqueue on HPC, dask-kubernetes...).
- Each cell is a task keyed by its stable hash (``snapwarn-<kind>-<hash>``). A task lost with
  its worker is rescheduled by the scheduler; the client persists a row only when its future
  finishes, through a sink that refuses a key it already holds: every cell is counted once.
- A restarted atlas asks its sink which keys are done and submits only the others.

``serial=True`` runs the same cells in a plain loop in this process (the reference of the
tests and of the engine-overhead benchmark).
"""

from __future__ import annotations

import json
import logging
import multiprocessing
import os
import time
import warnings
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any, Protocol

from service.analysis.errors import ParameterError
from service.atlas.cells import CellResult, run_cell
from service.atlas.results import AtlasResult, summarise
from service.atlas.spec import AtlasSpec

ONE_THREAD_ENV = {"OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1",
                  "NUMBA_NUM_THREADS": "1", "MPLBACKEND": "Agg"}  # fmt: skip
SCHEDULER_ENV = "SNAPWARN_DASK_SCHEDULER"

Progress = Callable[[int, int, CellResult | None], None]


class EngineError(ParameterError):
    """The cluster cannot be reached or started (names the address or worker count)."""


# --------------------------------------------------------------------------- sinks
class CellSink(Protocol):
    """Where finished cells are persisted (a JSON-lines file, a database table...)."""

    def load(self) -> dict[str, CellResult]:
        """The cells already finished, by key."""
        ...

    def put(self, row: CellResult) -> bool:
        """Persist ``row``; False (and nothing written) when its key is already there."""
        ...


class MemorySink:
    """Keeps the rows in memory (nothing survives the process)."""

    def __init__(self) -> None:
        self.rows: dict[str, CellResult] = {}

    def load(self) -> dict[str, CellResult]:
        return dict(self.rows)

    def put(self, row: CellResult) -> bool:
        if row.key in self.rows:
            return False
        self.rows[row.key] = row
        return True


class JsonlSink:
    """One JSON line per finished cell in ``path`` (flushed and fsynced line by line).

    A line cut short by a crash is ignored when read back, and the next line starts on a new
    line; a key present twice (two runs racing on one file) counts once.
    """

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._keys: set[str] = set()
        self.skipped_lines = 0

    def load(self) -> dict[str, CellResult]:
        rows: dict[str, CellResult] = {}
        if self.path.exists():
            for line in self.path.read_text().splitlines():
                if not line.strip():
                    continue
                try:
                    row = CellResult.from_dict(json.loads(line))
                except (ValueError, KeyError, TypeError):
                    self.skipped_lines += 1
                    continue
                rows.setdefault(row.key, row)
        self._keys = set(rows)
        return rows

    def put(self, row: CellResult) -> bool:
        if row.key in self._keys:
            return False
        from service import convert

        line = json.dumps(convert.atlas_cell(row).model_dump(mode="json"), allow_nan=False,
                          sort_keys=True)  # fmt: skip
        with self.path.open("a+b") as fh:
            fh.seek(0, os.SEEK_END)
            if fh.tell() > 0:
                fh.seek(-1, os.SEEK_END)
                if fh.read(1) != b"\n":
                    fh.write(b"\n")
            fh.write(line.encode() + b"\n")
            fh.flush()
            os.fsync(fh.fileno())
        self._keys.add(row.key)
        return True


# --------------------------------------------------------------------------- cluster
def scheduler_address(scheduler: str | None = None) -> str | None:
    """The scheduler to use: the argument, else ``SNAPWARN_DASK_SCHEDULER``, else None."""
    addr = scheduler or os.environ.get(SCHEDULER_ENV) or None
    return addr.strip() if addr else None


def default_workers() -> int:
    """Worker processes of the embedded LocalCluster: the CPUs this process may use."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # pragma: no cover - not Linux
        return max(1, os.cpu_count() or 1)


@contextmanager
def dask_client(scheduler: str | None = None, workers: int | None = None) -> Iterator[Any]:
    """A ``distributed.Client``: to ``scheduler`` if given (or in the environment), else to a
    new LocalCluster of ``workers`` processes with one thread each (closed on exit)."""
    import distributed

    addr = scheduler_address(scheduler)
    if addr:
        try:
            client = distributed.Client(addr, timeout="20s")
        except (OSError, TimeoutError) as exc:
            raise EngineError("scheduler", addr, f"scheduler {addr!r} cannot be reached: "
                              f"{exc}") from None  # fmt: skip
        try:
            yield client
        finally:
            client.close()
        return
    n = default_workers() if workers is None else workers
    if isinstance(n, bool) or not isinstance(n, int) or not 1 <= n <= 512:
        raise EngineError("workers", n, f"workers must be an integer in [1, 512], got {n!r}")
    with warnings.catch_warnings():  # "Port 8787 is already in use": another cluster's
        warnings.filterwarnings("ignore", message="Port .* is already in use", category=UserWarning)
        if multiprocessing.current_process().daemon:
            # a daemonic process (a job of the service's process pool) may not fork
            # multiprocessing children: scheduler and workers in their own subprocesses
            from distributed.deploy.subprocess import SubprocessCluster

            cluster = SubprocessCluster(
                n_workers=n, threads_per_worker=1, host="127.0.0.1", dashboard_address=None,
                silence_logs=logging.ERROR, worker_kwargs={"env": dict(ONE_THREAD_ENV)},
            )  # fmt: skip
        else:
            cluster = distributed.LocalCluster(
                n_workers=n, threads_per_worker=1, processes=True, host="127.0.0.1",
                dashboard_address=None, silence_logs=logging.ERROR, env=dict(ONE_THREAD_ENV),
            )  # fmt: skip
    client = distributed.Client(cluster)
    client.wait_for_workers(n, timeout=300)
    try:
        yield client
    finally:
        client.close()
        cluster.close()


def describe(client: Any) -> str:
    """``dask <scheduler address> (<n> workers)``."""
    try:
        n = len(client.scheduler_info().get("workers", {}))
    except Exception:  # noqa: BLE001 - informative only
        n = -1
    return f"dask {client.scheduler.address} ({n} workers)"


# --------------------------------------------------------------------------- run
def run_atlas(
    spec: AtlasSpec,
    *,
    scheduler: str | None = None,
    workers: int | None = None,
    sink: CellSink | None = None,
    progress: Progress | None = None,
    serial: bool = False,
    client: Any = None,
) -> AtlasResult:
    """Compute the cells of ``spec`` that ``sink`` does not hold yet, persisting each.

    Parameters
    ----------
    spec : AtlasSpec
    scheduler : str, optional
        Address of a running dask scheduler (``tcp://host:8786``); default
        ``SNAPWARN_DASK_SCHEDULER``, else an embedded LocalCluster.
    workers : int, optional
        Worker processes of the embedded LocalCluster (default: the usable CPUs).
    sink : CellSink, optional
        Where rows are persisted and read back on restart (default: memory only).
    progress : callable(done, total, row), optional
        Called once with the resumed count (row None), then after each persisted cell.
    serial : bool
        Run the cells in a plain loop in this process (no dask).
    client : distributed.Client, optional
        Use this client (its cluster is left running).

    Returns
    -------
    AtlasResult
        Rows in the spec's order (resumed and new), the summary, and the keys still missing.
    """
    sink = sink if sink is not None else MemorySink()
    keys = {c.key for c in spec.cells}
    rows = {k: r for k, r in sink.load().items() if k in keys}
    resumed = len(rows)
    todo = [c for c in spec.cells if c.key not in rows]
    total = len(spec.cells)
    t0 = time.perf_counter()
    if progress is not None:
        progress(len(rows), total, None)

    def record(row: CellResult) -> None:
        if row.key in rows or not sink.put(row):
            return
        rows[row.key] = row
        if progress is not None:
            progress(len(rows), total, row)

    if not todo:
        engine = "none (all cells resumed)"
    elif serial:
        engine = "serial"
        deadline = t0 + spec.timeout_s
        for c in todo:
            if time.perf_counter() > deadline:
                break
            record(run_cell(spec.kind, c.key, c.index, c.inputs))
    elif client is not None:
        engine = _run_dask(client, spec, todo, record, t0)
    else:
        with dask_client(scheduler, workers) as cl:
            engine = _run_dask(cl, spec, todo, record, t0)
    wall = time.perf_counter() - t0
    ordered = tuple(sorted(rows.values(), key=lambda r: r.index))
    missing = tuple(c.key for c in spec.cells if c.key not in rows)
    summary = summarise(spec.name, spec.kind, total, ordered, resumed=resumed, wall_s=wall,
                        engine=engine)  # fmt: skip
    return AtlasResult(spec.name, spec.kind, spec.varied, ordered, summary, missing)


def task_key(kind: str, cell_key: str) -> str:
    """The dask key of a cell: the same cell is one task, whoever submits it."""
    return f"snapwarn-{kind}-{cell_key}"


def _run_dask(client: Any, spec: AtlasSpec, todo: list, record: Callable, t0: float) -> str:
    import distributed

    engine = describe(client)
    futures = [
        client.submit(run_cell, spec.kind, c.key, c.index, c.inputs,
                      key=task_key(spec.kind, c.key), retries=spec.retries, pure=False)
        for c in todo
    ]  # fmt: skip
    remaining = max(1e-3, spec.timeout_s - (time.perf_counter() - t0))
    log = logging.getLogger("snapwarn.atlas")
    try:
        for fut in distributed.as_completed(futures, timeout=remaining):
            if fut.status == "finished":
                record(fut.result())
            else:  # lost more often than the scheduler allows (KilledWorker) or cancelled
                try:
                    why = repr(fut.exception())
                except Exception as exc:  # noqa: BLE001 - cancelled
                    why = repr(exc)
                log.warning("cell %s not done: %s", fut.key, why)
            fut.release()
    except TimeoutError:
        log.warning("atlas %r hit its time bound of %g s", spec.name, spec.timeout_s)
        client.cancel([f for f in futures if not f.done()])
    return engine
