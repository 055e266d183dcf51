"""Persistence: SQLAlchemy 2 over SQLite (default) or PostgreSQL (by URL).

Samples are stored losslessly as little-endian float64 bytes (``LargeBinary``: BLOB / bytea),
never as JSON text. Jobs carry a lease (``heartbeat_at``) and a fencing token (``attempts``):
a job whose runner died is resumed (or failed with a reason) and a late write from the dead
attempt is ignored.
"""

from __future__ import annotations

import hashlib
import math
import os
import socket
import time
import uuid
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from datetime import UTC, datetime, timedelta
from pathlib import Path
from typing import Any

import numpy as np
from sqlalchemy import (
    JSON,
    Boolean,
    DateTime,
    Double,
    Engine,
    Integer,
    LargeBinary,
    String,
    Text,
    create_engine,
    delete,
    event,
    func,
    select,
    update,
)
from sqlalchemy.exc import IntegrityError, OperationalError, ProgrammingError
from sqlalchemy.orm import (
    DeclarativeBase,
    Mapped,
    Session,
    defer,
    mapped_column,
    sessionmaker,
)

F64 = np.dtype("<f8")


def utcnow() -> datetime:
    """Naive UTC now (stored naive; read back as UTC)."""
    return datetime.now(UTC).replace(tzinfo=None)


def as_utc(dt: datetime | None) -> datetime | None:
    if dt is None:
        return None
    return dt.replace(tzinfo=UTC) if dt.tzinfo is None else dt.astimezone(UTC)


def new_id() -> str:
    return uuid.uuid4().hex


def sanitize(obj: Any) -> Any:
    """Make ``obj`` strict JSON: non-finite floats -> None, numpy scalars/arrays -> Python."""
    if isinstance(obj, dict):
        return {str(k): sanitize(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [sanitize(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return sanitize(obj.tolist())
    if isinstance(obj, (bool, np.bool_)):
        return bool(obj)
    if isinstance(obj, (np.integer,)):
        return int(obj)
    if isinstance(obj, (float, np.floating)):
        v = float(obj)
        return v if math.isfinite(v) else None
    return obj


def encode_f64(a: np.ndarray) -> bytes:
    return np.ascontiguousarray(a, dtype=F64).tobytes()


def decode_f64(b: bytes) -> np.ndarray:
    return np.frombuffer(b, dtype=F64).copy()


class Base(DeclarativeBase):
    pass


class SignalRow(Base):
    __tablename__ = "signals"

    id: Mapped[str] = mapped_column(String(32), primary_key=True)
    name: Mapped[str | None] = mapped_column(String(500))
    n: Mapped[int] = mapped_column(Integer)
    dt: Mapped[float] = mapped_column(Double)
    t0: Mapped[float] = mapped_column(Double)
    unit: Mapped[str | None] = mapped_column(String(100))
    value_unit: Mapped[str | None] = mapped_column(String(100))
    control_name: Mapped[str | None] = mapped_column(String(200))
    control_value: Mapped[float | None] = mapped_column(Double)
    control_unit: Mapped[str | None] = mapped_column(String(100))
    meta: Mapped[dict] = mapped_column("metadata", JSON, default=dict)
    source: Mapped[str] = mapped_column(String(20))
    w: Mapped[bytes] = mapped_column(LargeBinary)
    t: Mapped[bytes | None] = mapped_column(LargeBinary)
    has_t: Mapped[bool] = mapped_column(Boolean, default=False)
    sha256: Mapped[str] = mapped_column(String(64))
    created_at: Mapped[datetime] = mapped_column(DateTime)


class JobRow(Base):
    __tablename__ = "jobs"

    id: Mapped[str] = mapped_column(String(32), primary_key=True)
    kind: Mapped[str] = mapped_column(String(40))
    status: Mapped[str] = mapped_column(String(20), index=True)
    params: Mapped[dict] = mapped_column(JSON, default=dict)
    fraction: Mapped[float] = mapped_column(Double, default=0.0)
    message: Mapped[str] = mapped_column(Text, default="")
    result: Mapped[dict | None] = mapped_column(JSON)
    error: Mapped[dict | None] = mapped_column(JSON)
    attempts: Mapped[int] = mapped_column(Integer, default=0)
    owner: Mapped[str | None] = mapped_column(String(200))
    heartbeat_at: Mapped[datetime | None] = mapped_column(DateTime)
    created_at: Mapped[datetime] = mapped_column(DateTime)
    started_at: Mapped[datetime | None] = mapped_column(DateTime)
    finished_at: Mapped[datetime | None] = mapped_column(DateTime)


class SweepRow(Base):
    __tablename__ = "sweeps"

    id: Mapped[str] = mapped_column(String(32), primary_key=True)  # = its job's id
    name: Mapped[str | None] = mapped_column(String(500))
    request: Mapped[dict] = mapped_column(JSON)
    created_at: Mapped[datetime] = mapped_column(DateTime)


class WorkerRow(Base):
    __tablename__ = "workers"

    id: Mapped[str] = mapped_column(String(200), primary_key=True)
    started_at: Mapped[datetime] = mapped_column(DateTime)
    heartbeat_at: Mapped[datetime] = mapped_column(DateTime)


def make_engine(url: str) -> Engine:
    """An engine for ``url``; SQLite files get their folder, WAL and a busy timeout."""
    if url.startswith("sqlite"):
        prefix = "sqlite:///"
        if url.startswith(prefix) and url[len(prefix) :] not in ("", ":memory:"):
            Path(url[len(prefix) :]).parent.mkdir(parents=True, exist_ok=True)
        engine = create_engine(
            url, connect_args={"timeout": 30, "check_same_thread": False}, pool_pre_ping=True
        )

        @event.listens_for(engine, "connect")
        def _pragmas(dbapi_conn: Any, _record: Any) -> None:  # pragma: no cover - trivial
            cur = dbapi_conn.cursor()
            cur.execute("PRAGMA journal_mode=WAL")
            cur.execute("PRAGMA synchronous=NORMAL")
            cur.execute("PRAGMA busy_timeout=30000")
            cur.close()

        return engine
    return create_engine(url, pool_pre_ping=True, pool_size=10, max_overflow=20)


def runner_identity() -> str:
    """``host:pid:token`` naming this process as a job owner."""
    return f"{socket.gethostname()}:{os.getpid()}:{uuid.uuid4().hex[:8]}"


def _owner_dead_here(owner: str | None) -> bool:
    """True when ``owner`` is a process on this host that no longer exists."""
    if not owner:
        return False
    parts = owner.split(":")
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


@dataclass
class StoredSignal:
    row: SignalRow
    t: np.ndarray | None
    w: np.ndarray


class Store:
    """All database access of the service (one per process; thread-safe via sessions)."""

    def __init__(self, url: str, *, engine: Engine | None = None) -> None:
        self.url = url
        self.engine = engine or make_engine(url)
        self._sessions = sessionmaker(self.engine, expire_on_commit=False)

    def create_all(self) -> None:
        """Create missing tables (several processes may race here: retried)."""
        for attempt in range(5):
            try:
                Base.metadata.create_all(self.engine)
                return
            except (IntegrityError, ProgrammingError, OperationalError):
                if attempt == 4:
                    raise
                time.sleep(0.2 * (attempt + 1))

    def dispose(self) -> None:
        self.engine.dispose()

    @contextmanager
    def session(self) -> Iterator[Session]:
        with self._sessions() as s, s.begin():
            yield s

    def ping(self) -> bool:
        with self.engine.connect() as c:
            c.execute(select(1))
        return True

    # --- signals -----------------------------------------------------------------------------
    def add_signal(
        self,
        *,
        w: np.ndarray,
        dt: float,
        t0: float,
        t: np.ndarray | None,
        source: str,
        name: str | None = None,
        unit: str | None = None,
        value_unit: str | None = None,
        control: dict[str, Any] | None = None,
        metadata: dict[str, Any] | None = None,
    ) -> SignalRow:
        wb = encode_f64(w)
        row = SignalRow(
            id=new_id(),
            name=name,
            n=int(w.size),
            dt=float(dt),
            t0=float(t0),
            unit=unit,
            value_unit=value_unit,
            control_name=(control or {}).get("name"),
            control_value=(control or {}).get("value"),
            control_unit=(control or {}).get("unit"),
            meta=sanitize(metadata or {}),
            source=source,
            w=wb,
            t=encode_f64(t) if t is not None else None,
            has_t=t is not None,
            sha256=hashlib.sha256(wb).hexdigest(),
            created_at=utcnow(),
        )
        with self.session() as s:
            s.add(row)
        return row

    def get_signal_meta(self, signal_id: str) -> SignalRow | None:
        """The row without its samples (they are not read from the database)."""
        with self.session() as s:
            return s.execute(
                select(SignalRow)
                .where(SignalRow.id == signal_id)
                .options(defer(SignalRow.w, raiseload=True), defer(SignalRow.t, raiseload=True))
            ).scalar_one_or_none()

    def get_signal(self, signal_id: str) -> StoredSignal | None:
        with self.session() as s:
            row = s.get(SignalRow, signal_id)
        if row is None:
            return None
        t = decode_f64(row.t) if row.t is not None else None
        return StoredSignal(row=row, t=t, w=decode_f64(row.w))

    def delete_signal(self, signal_id: str) -> bool:
        with self.session() as s:
            row = s.get(SignalRow, signal_id)
            if row is None:
                return False
            s.delete(row)
        return True

    def list_signals(self, limit: int, offset: int) -> tuple[list[SignalRow], int]:
        """A page of signals (newest first, samples not read) and the total count."""
        with self.session() as s:
            rows = (
                s.execute(
                    select(SignalRow)
                    .options(defer(SignalRow.w, raiseload=True), defer(SignalRow.t, raiseload=True))
                    .order_by(SignalRow.created_at.desc(), SignalRow.id)
                    .limit(limit)
                    .offset(offset)
                )
                .scalars()
                .all()
            )
            total = s.execute(select(func.count()).select_from(SignalRow)).scalar_one()
        return list(rows), int(total)

    def count_signals(self) -> int:
        with self.session() as s:
            return int(s.execute(select(func.count()).select_from(SignalRow)).scalar_one())

    # --- jobs --------------------------------------------------------------------------------
    def create_job(self, kind: str, params: dict[str, Any], *, job_id: str | None = None) -> JobRow:
        row = JobRow(
            id=job_id or new_id(),
            kind=kind,
            status="queued",
            params=sanitize(params),
            fraction=0.0,
            message="queued",
            attempts=0,
            created_at=utcnow(),
        )
        with self.session() as s:
            s.add(row)
        return row

    def get_job(self, job_id: str) -> JobRow | None:
        with self.session() as s:
            return s.get(JobRow, job_id)

    def claim_job(self, owner: str) -> JobRow | None:
        """Atomically take the oldest queued job (None if there is none)."""
        for _ in range(5):
            with self.session() as s:
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
                        owner=owner,
                        attempts=JobRow.attempts + 1,
                        heartbeat_at=now,
                        started_at=func.coalesce(JobRow.started_at, now),
                        message="started",
                    )
                )
                if res.rowcount == 1:
                    return s.get(JobRow, jid)
        return None

    def job_progress(self, job_id: str, attempt: int, fraction: float, message: str) -> bool:
        with self.session() as s:
            res = s.execute(
                update(JobRow)
                .where(JobRow.id == job_id, JobRow.attempts == attempt, JobRow.status == "running")
                .values(
                    fraction=min(1.0, max(0.0, float(fraction))),
                    message=str(message)[:2000],
                    heartbeat_at=utcnow(),
                )
            )
            return res.rowcount == 1

    def finish_job(self, job_id: str, attempt: int, result: dict[str, Any]) -> bool:
        with self.session() as s:
            res = s.execute(
                update(JobRow)
                .where(JobRow.id == job_id, JobRow.attempts == attempt, JobRow.status == "running")
                .values(
                    status="succeeded",
                    result=sanitize(result),
                    fraction=1.0,
                    message="done",
                    finished_at=utcnow(),
                    owner=None,
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
        with self.session() as s:
            if attempt is not None:  # the runner of that attempt: only while it runs
                cond = [JobRow.id == job_id, JobRow.status == "running", JobRow.attempts == attempt]
            else:  # an operator: any job not finished yet
                cond = [JobRow.id == job_id, JobRow.status.in_(("queued", "running"))]
            res = s.execute(
                update(JobRow)
                .where(*cond)
                .values(
                    status="failed",
                    error=sanitize(error),
                    message=str(error.get("title", "failed")),
                    finished_at=utcnow(),
                    owner=None,
                )
            )
            return res.rowcount == 1

    def heartbeat_jobs(self, job_ids: list[str], owner: str) -> None:
        if not job_ids:
            return
        with self.session() as s:
            s.execute(
                update(JobRow)
                .where(JobRow.id.in_(job_ids), JobRow.owner == owner, JobRow.status == "running")
                .values(heartbeat_at=utcnow())
            )

    def recover_jobs(self, *, lease_s: float, max_attempts: int) -> list[tuple[str, str]]:
        """Resume (re-queue) or fail running jobs whose runner is gone.

        A runner is gone when its lease expired (no heartbeat for ``lease_s``) or when it was a
        process of this host that no longer exists. Returns ``(job_id, "queued"|"failed")``.
        """
        now = utcnow()
        cutoff = now - timedelta(seconds=lease_s)
        done: list[tuple[str, str]] = []
        with self.session() as s:
            rows = s.execute(select(JobRow).where(JobRow.status == "running")).scalars().all()
            for row in rows:
                hb = row.heartbeat_at or row.started_at or row.created_at
                if not (hb < cutoff or _owner_dead_here(row.owner)):
                    continue
                cond = (
                    JobRow.id == row.id,
                    JobRow.status == "running",
                    JobRow.attempts == row.attempts,
                )
                if row.attempts >= max_attempts:
                    err = {
                        "type": "urn:snapwarn:problem:job-interrupted",
                        "title": "Job interrupted",
                        "detail": f"the runner of this job stopped {row.attempts} time(s) "
                        f"(server restart or crash; max attempts {max_attempts}); giving up",
                    }
                    res = s.execute(
                        update(JobRow)
                        .where(*cond)
                        .values(
                            status="failed",
                            error=err,
                            message="interrupted",
                            finished_at=now,
                            owner=None,
                        )
                    )
                    new = "failed"
                else:
                    res = s.execute(
                        update(JobRow)
                        .where(*cond)
                        .values(
                            status="queued",
                            owner=None,
                            fraction=0.0,
                            message=f"resuming after an interruption (attempt {row.attempts + 1} "
                            f"of {max_attempts})",
                        )
                    )
                    new = "queued"
                if res.rowcount == 1:
                    done.append((row.id, new))
        return done

    def release_jobs(self, job_ids: list[str], owner: str) -> int:
        """Re-queue the running jobs of ``owner`` (it stops gracefully): another runner resumes
        them at once. Their attempt count stays, so a late write of this owner is fenced off."""
        if not job_ids:
            return 0
        with self.session() as s:
            res = s.execute(
                update(JobRow)
                .where(JobRow.id.in_(job_ids), JobRow.owner == owner, JobRow.status == "running")
                .values(
                    status="queued",
                    owner=None,
                    fraction=0.0,
                    message="resuming: its runner was stopped",
                )
            )
            return int(res.rowcount or 0)

    def prune_workers(self, older_than_s: float) -> None:
        cutoff = utcnow() - timedelta(seconds=older_than_s)
        with self.session() as s:
            s.execute(delete(WorkerRow).where(WorkerRow.heartbeat_at < cutoff))

    def list_jobs(
        self, status: str | None, kind: str | None, limit: int, offset: int
    ) -> tuple[list[JobRow], int]:
        """A page of jobs (newest first) and the total count of those matching."""
        cond = []
        if status:
            cond.append(JobRow.status == status)
        if kind:
            cond.append(JobRow.kind == kind)
        with self.session() as s:
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
        with self.session() as s:
            q = select(func.count()).select_from(JobRow)
            if status:
                q = q.where(JobRow.status == status)
            return int(s.execute(q).scalar_one())

    # --- sweeps ------------------------------------------------------------------------------
    def create_sweep(
        self, kind: str, request: dict[str, Any], params: dict[str, Any], name: str | None
    ) -> tuple[SweepRow, JobRow]:
        sid = new_id()
        now = utcnow()
        sweep = SweepRow(id=sid, name=name, request=sanitize(request), created_at=now)
        job = JobRow(
            id=sid,
            kind=kind,
            status="queued",
            params=sanitize(params),
            fraction=0.0,
            message="queued",
            attempts=0,
            created_at=now,
        )
        with self.session() as s:
            s.add(job)
            s.add(sweep)
        return sweep, job

    def get_sweep(self, sweep_id: str) -> tuple[SweepRow, JobRow] | None:
        with self.session() as s:
            sweep = s.get(SweepRow, sweep_id)
            if sweep is None:
                return None
            job = s.get(JobRow, sweep_id)
            return sweep, job

    # --- workers -----------------------------------------------------------------------------
    def worker_heartbeat(self, worker_id: str) -> None:
        with self.session() as s:
            row = s.get(WorkerRow, worker_id)
            now = utcnow()
            if row is None:
                s.add(WorkerRow(id=worker_id, started_at=now, heartbeat_at=now))
            else:
                row.heartbeat_at = now

    def worker_gone(self, worker_id: str) -> None:
        with self.session() as s:
            row = s.get(WorkerRow, worker_id)
            if row is not None:
                s.delete(row)

    def live_workers(self, lease_s: float) -> int:
        cutoff = utcnow() - timedelta(seconds=lease_s)
        with self.session() as s:
            return int(
                s.execute(
                    select(func.count())
                    .select_from(WorkerRow)
                    .where(WorkerRow.heartbeat_at >= cutoff)
                ).scalar_one()
            )
