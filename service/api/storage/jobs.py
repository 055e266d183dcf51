"""The jobs aggregate: a durable queue with leases, fencing, time limits and cancellation.

Jobs carry a lease (``heartbeat_at``) and a fencing token (``attempts``): a job whose runner
died is resumed (or failed with a reason) and a late write from the dead attempt is ignored.
``run_s`` accumulates the running time of past attempts, so a job's time limit holds across
restarts: a job past its limit is failed, never re-run. A cancelled job is never re-run either.
"""

from __future__ import annotations

import os
import socket
from datetime import datetime, timedelta
from typing import Any

from sqlalchemy import delete, func, select, text, update

from service.api.storage.models import (
    DEFAULT_OWNER,
    JobRow,
    WorkerRow,
    new_id,
    sanitize,
    utcnow,
)

ACTIVE = ("queued", "running")
FINISHED = ("succeeded", "failed", "cancelled")


def runner_identity() -> str:
    """``host:pid:token`` naming this process as a job runner."""
    import uuid

    return f"{socket.gethostname()}:{os.getpid()}:{uuid.uuid4().hex[:8]}"


def _owner_dead_here(runner: str | None) -> bool:
    """True when ``runner`` is a process on this host that no longer exists."""
    if not runner:
        return False
    parts = runner.split(":")
    if len(parts) != 3 or parts[0] != socket.gethostname():
        return False
    try:
        pid = int(parts[1])
    except ValueError:
        return False
    if pid == os.getpid():
        return False
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return True
    except PermissionError:
        return False
    # A zombie (killed, not yet reaped) counts as dead.
    try:
        with open(f"/proc/{pid}/stat") as fh:
            return fh.read().rsplit(")", 1)[1].split()[0] == "Z"
    except OSError:
        return False


def _elapsed(row: JobRow, until: datetime) -> float:
    """Seconds this job has run: past attempts plus the current one up to ``until``."""
    start = row.attempt_started_at
    cur = (until - start).total_seconds() if start is not None else 0.0
    return float(row.run_s or 0.0) + max(0.0, cur)


def time_limit_error(row: JobRow, elapsed: float) -> dict[str, Any]:
    return {
        "type": "urn:snapwarn:problem:job-time-limit",
        "title": "Job time limit exceeded",
        "detail": f"the job ran {elapsed:.1f} s, over its time limit of "
        f"{row.time_limit_s:g} s; it was stopped and is not re-run",
        "reason": "time-limit",
    }


def reserve(s: Any, owner: str, max_active: int | None) -> None:
    """Inside the transaction that queues a job: 429 when ``owner`` already has ``max_active``
    queued or running jobs. The owner's lock is taken first (PostgreSQL: a transaction-level
    advisory lock on the owner; SQLite: the database's write lock), so concurrent requests
    count and insert one after the other: the limit holds under concurrency."""
    if max_active is None:
        return
    if s.get_bind().dialect.name == "postgresql":
        s.execute(text("SELECT pg_advisory_xact_lock(hashtext(:k))"), {"k": f"jobs:{owner}"})
    else:  # a write statement takes SQLite's write lock now (it matches no row)
        s.execute(update(JobRow).where(JobRow.id == "").values(owner=JobRow.owner))
    n = int(
        s.execute(
            select(func.count())
            .select_from(JobRow)
            .where(JobRow.owner == owner, JobRow.status.in_(ACTIVE))
        ).scalar_one()
    )
    if n >= max_active:
        from service.api.limits import queue_full

        raise queue_full(n, max_active)


class JobsMixin:
    """Job access of :class:`~service.api.storage.Store` (``scope``: see ``SignalsMixin``)."""

    def create_job(
        self,
        kind: str,
        params: dict[str, Any],
        *,
        job_id: str | None = None,
        owner: str = DEFAULT_OWNER,
        time_limit_s: float | None = None,
        max_active: int | None = None,
    ) -> JobRow:
        """Queue a job; ``max_active``: the owner's queue bound, checked atomically."""
        row = JobRow(
            id=job_id or new_id(),
            kind=kind,
            status="queued",
            params=sanitize(params),
            fraction=0.0,
            message="queued",
            attempts=0,
            owner=owner,
            time_limit_s=time_limit_s,
            run_s=0.0,
            created_at=utcnow(),
        )
        with self.session() as s:  # type: ignore[attr-defined]
            reserve(s, owner, max_active)
            s.add(row)
        return row

    def get_job(self, job_id: str, scope: str | None = None) -> JobRow | None:
        with self.session() as s:  # type: ignore[attr-defined]
            row = s.get(JobRow, job_id)
        if row is None or (scope is not None and row.owner != scope):
            return None
        return row

    def count_active_jobs(self, owner: str) -> int:
        """Queued and running jobs of ``owner`` (the per-owner queue bound)."""
        with self.session() as s:  # type: ignore[attr-defined]
            q = (
                select(func.count())
                .select_from(JobRow)
                .where(JobRow.owner == owner, JobRow.status.in_(ACTIVE))
            )
            return int(s.execute(q).scalar_one())

    def claim_job(self, runner: str) -> JobRow | None:
        """Atomically take the oldest queued job (None if there is none)."""
        for _ in range(5):
            with self.session() as s:  # type: ignore[attr-defined]
                jid = s.execute(
                    select(JobRow.id)
                    .where(JobRow.status == "queued")
                    .order_by(JobRow.created_at)
                    .limit(1)
                ).scalar_one_or_none()
                if jid is None:
                    return None
                now = utcnow()
                res = s.execute(
                    update(JobRow)
                    .where(JobRow.id == jid, JobRow.status == "queued")
                    .values(
                        status="running",
                        runner=runner,
                        attempts=JobRow.attempts + 1,
                        heartbeat_at=now,
                        attempt_started_at=now,
                        started_at=func.coalesce(JobRow.started_at, now),
                        message="started",
                    )
                )
                if res.rowcount == 1:
                    return s.get(JobRow, jid)
        return None

    def job_progress(self, job_id: str, attempt: int, fraction: float, message: str) -> bool:
        with self.session() as s:  # type: ignore[attr-defined]
            res = s.execute(
                update(JobRow)
                .where(JobRow.id == job_id, JobRow.attempts == attempt, JobRow.status == "running")
                .values(
                    fraction=min(1.0, max(0.0, float(fraction))),
                    message=sanitize(str(message)[:2000]),
                    heartbeat_at=utcnow(),
                )
            )
            return res.rowcount == 1

    def finish_job(self, job_id: str, attempt: int, result: dict[str, Any]) -> bool:
        with self.session() as s:  # type: ignore[attr-defined]
            res = s.execute(
                update(JobRow)
                .where(JobRow.id == job_id, JobRow.attempts == attempt, JobRow.status == "running")
                .values(
                    status="succeeded",
                    result=sanitize(result),
                    fraction=1.0,
                    message="done",
                    finished_at=utcnow(),
                    runner=None,
                )
            )
            return res.rowcount == 1

    def fail_job(self, job_id: str, attempt: int | None, error: dict[str, Any]) -> bool:
        """Mark a job failed with a problem-like ``error`` (type, title, detail)."""
        error = {
            "type": "urn:snapwarn:problem:job-failed",
            "title": "Job failed",
            "detail": None,
            **error,
        }
        with self.session() as s:  # type: ignore[attr-defined]
            if attempt is not None:  # the runner of that attempt: only while it runs
                cond = [JobRow.id == job_id, JobRow.status == "running", JobRow.attempts == attempt]
            else:  # an operator: any job not finished yet
                cond = [JobRow.id == job_id, JobRow.status.in_(ACTIVE)]
            res = s.execute(
                update(JobRow)
                .where(*cond)
                .values(
                    status="failed",
                    error=sanitize(error),
                    message=sanitize(str(error.get("title", "failed"))),
                    finished_at=utcnow(),
                    runner=None,
                )
            )
            return res.rowcount == 1

    def cancel_job(self, job_id: str, reason: str, scope: str | None = None) -> JobRow | None:
        """Cancel a queued or running job (its runner stops it); the row after, or None.

        A finished job is returned unchanged (the caller answers 409).
        """
        now = utcnow()
        with self.session() as s:  # type: ignore[attr-defined]
            cond = [JobRow.id == job_id, JobRow.status.in_(ACTIVE)]
            if scope is not None:
                cond.append(JobRow.owner == scope)
            err = {
                "type": "urn:snapwarn:problem:job-cancelled",
                "title": "Job cancelled",
                "detail": sanitize(reason),
                "reason": "cancelled",
            }
            s.execute(
                update(JobRow)
                .where(*cond)
                .values(status="cancelled", error=err, message="cancelled", finished_at=now)
            )
            row = s.get(JobRow, job_id)
        if row is None or (scope is not None and row.owner != scope):
            return None
        return row

    def heartbeat_jobs(self, job_ids: list[str], runner: str) -> set[str]:
        """Renew the lease of ``runner``'s running jobs; returns the ids still running there
        (the others were cancelled, failed or resumed elsewhere: the runner stops them)."""
        if not job_ids:
            return set()
        with self.session() as s:  # type: ignore[attr-defined]
            cond = (JobRow.id.in_(job_ids), JobRow.runner == runner, JobRow.status == "running")
            s.execute(update(JobRow).where(*cond).values(heartbeat_at=utcnow()))
            return set(s.execute(select(JobRow.id).where(*cond)).scalars().all())

    def _requeue_or_fail(
        self, s: Any, row: JobRow, now: datetime, max_attempts: int, message: str
    ) -> str | None:
        """Hand a running job back to the queue, or fail it past its limits."""
        cond = (JobRow.id == row.id, JobRow.status == "running", JobRow.attempts == row.attempts)
        hb = row.heartbeat_at or row.attempt_started_at or now
        run_s = _elapsed(row, hb)
        err = None
        if row.time_limit_s is not None and run_s >= row.time_limit_s:
            err = time_limit_error(row, run_s)
        elif row.attempts >= max_attempts:
            err = {
                "type": "urn:snapwarn:problem:job-interrupted",
                "title": "Job interrupted",
                "detail": f"the runner of this job stopped {row.attempts} time(s) "
                f"(server restart or crash; max attempts {max_attempts}); giving up",
                "reason": "interrupted",
            }
        if err is not None:
            values: dict[str, Any] = {
                "status": "failed",
                "error": err,
                "message": err["title"],
                "finished_at": now,
                "runner": None,
                "run_s": run_s,
            }
            new = "failed"
        else:
            values = {
                "status": "queued",
                "runner": None,
                "fraction": 0.0,
                "message": message,
                "run_s": run_s,
                "attempt_started_at": None,
            }
            new = "queued"
        res = s.execute(update(JobRow).where(*cond).values(**values))
        return new if res.rowcount == 1 else None

    def recover_jobs(self, *, lease_s: float, max_attempts: int) -> list[tuple[str, str]]:
        """Resume (re-queue) or fail running jobs whose runner is gone.

        A runner is gone when its lease expired (no heartbeat for ``lease_s``) or when it was a
        process of this host that no longer exists. Returns ``(job_id, "queued"|"failed")``.
        """
        now = utcnow()
        cutoff = now - timedelta(seconds=lease_s)
        done: list[tuple[str, str]] = []
        with self.session() as s:  # type: ignore[attr-defined]
            rows = s.execute(select(JobRow).where(JobRow.status == "running")).scalars().all()
            for row in rows:
                hb = row.heartbeat_at or row.started_at or row.created_at
                if not (hb < cutoff or _owner_dead_here(row.runner)):
                    continue
                new = self._requeue_or_fail(
                    s,
                    row,
                    now,
                    max_attempts,
                    f"resuming after an interruption (attempt {row.attempts + 1} "
                    f"of {max_attempts})",
                )
                if new is not None:
                    done.append((row.id, new))
        return done

    def release_jobs(self, job_ids: list[str], runner: str) -> int:
        """Re-queue the running jobs of ``runner`` (it stops gracefully): another runner resumes
        them at once. Their attempt count stays, so a late write of this runner is fenced off."""
        if not job_ids:
            return 0
        n = 0
        now = utcnow()
        with self.session() as s:  # type: ignore[attr-defined]
            rows = (
                s.execute(
                    select(JobRow).where(
                        JobRow.id.in_(job_ids),
                        JobRow.runner == runner,
                        JobRow.status == "running",
                    )
                )
                .scalars()
                .all()
            )
            for row in rows:
                row.heartbeat_at = now
                new = self._requeue_or_fail(s, row, now, 10**9, "resuming: its runner was stopped")
                n += new == "queued"
        return n

    def list_jobs(
        self,
        status: str | None,
        kind: str | None,
        limit: int,
        offset: int,
        scope: str | None = None,
    ) -> tuple[list[JobRow], int]:
        """A page of jobs (newest first) and the total count of those matching."""
        cond = []
        if status:
            cond.append(JobRow.status == status)
        if kind:
            cond.append(JobRow.kind == kind)
        if scope is not None:
            cond.append(JobRow.owner == scope)
        with self.session() as s:  # type: ignore[attr-defined]
            rows = (
                s.execute(
                    select(JobRow)
                    .where(*cond)
                    .order_by(JobRow.created_at.desc(), JobRow.id)
                    .limit(limit)
                    .offset(offset)
                )
                .scalars()
                .all()
            )
            total = s.execute(select(func.count()).select_from(JobRow).where(*cond)).scalar_one()
        return list(rows), int(total)

    def count_jobs(self, status: str | None = None) -> int:
        with self.session() as s:  # type: ignore[attr-defined]
            q = select(func.count()).select_from(JobRow)
            if status:
                q = q.where(JobRow.status == status)
            return int(s.execute(q).scalar_one())

    # --- runners -----------------------------------------------------------------------------
    def worker_heartbeat(self, worker_id: str) -> None:
        with self.session() as s:  # type: ignore[attr-defined]
            row = s.get(WorkerRow, worker_id)
            now = utcnow()
            if row is None:
                s.add(WorkerRow(id=worker_id, started_at=now, heartbeat_at=now))
            else:
                row.heartbeat_at = now

    def worker_gone(self, worker_id: str) -> None:
        with self.session() as s:  # type: ignore[attr-defined]
            row = s.get(WorkerRow, worker_id)
            if row is not None:
                s.delete(row)

    def live_workers(self, lease_s: float) -> int:
        cutoff = utcnow() - timedelta(seconds=lease_s)
        with self.session() as s:  # type: ignore[attr-defined]
            return int(
                s.execute(
                    select(func.count())
                    .select_from(WorkerRow)
                    .where(WorkerRow.heartbeat_at >= cutoff)
                ).scalar_one()
            )

    def prune_workers(self, older_than_s: float) -> None:
        cutoff = utcnow() - timedelta(seconds=older_than_s)
        with self.session() as s:  # type: ignore[attr-defined]
            s.execute(delete(WorkerRow).where(WorkerRow.heartbeat_at < cutoff))
