"""The engine, the declarative ``Base`` and the rows of the core aggregates.

Samples are stored losslessly as little-endian float64 bytes (``LargeBinary``: BLOB / bytea),
never as JSON text. Every resource row carries the ``owner`` (the API key's owner) that made it.
The schema is created and upgraded by the Alembic migrations in ``service/api/migrations``.
"""

from __future__ import annotations

import math
import uuid
from datetime import UTC, datetime
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
    UniqueConstraint,
    create_engine,
    event,
)
from sqlalchemy.orm import DeclarativeBase, Mapped, mapped_column

F64 = np.dtype("<f8")
DEFAULT_OWNER = "local"


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
    if isinstance(obj, str) and "\x00" in obj:  # PostgreSQL text cannot hold NUL
        return obj.replace("\x00", "\ufffd")
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
    owner: Mapped[str] = mapped_column(String(200), index=True, default=DEFAULT_OWNER)
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
    owner: Mapped[str] = mapped_column(String(200), index=True, default=DEFAULT_OWNER)
    runner: Mapped[str | None] = mapped_column(String(200))
    time_limit_s: Mapped[float | None] = mapped_column(Double)
    run_s: Mapped[float] = mapped_column(Double, default=0.0)
    attempt_started_at: Mapped[datetime | None] = mapped_column(DateTime)
    heartbeat_at: Mapped[datetime | None] = mapped_column(DateTime)
    created_at: Mapped[datetime] = mapped_column(DateTime)
    started_at: Mapped[datetime | None] = mapped_column(DateTime)
    finished_at: Mapped[datetime | None] = mapped_column(DateTime)


class SweepRow(Base):
    __tablename__ = "sweeps"

    id: Mapped[str] = mapped_column(String(32), primary_key=True)  # = its job's id
    owner: Mapped[str] = mapped_column(String(200), index=True, default=DEFAULT_OWNER)
    name: Mapped[str | None] = mapped_column(String(500))
    request: Mapped[dict] = mapped_column(JSON)
    created_at: Mapped[datetime] = mapped_column(DateTime)


class WorkerRow(Base):
    __tablename__ = "workers"

    id: Mapped[str] = mapped_column(String(200), primary_key=True)
    started_at: Mapped[datetime] = mapped_column(DateTime)
    heartbeat_at: Mapped[datetime] = mapped_column(DateTime)


class IdempotencyRow(Base):
    """A POST that created something, by ``(owner, Idempotency-Key)``: a retry gets its answer."""

    __tablename__ = "idempotency_keys"
    __table_args__ = (UniqueConstraint("owner", "key", name="uq_idempotency_owner_key"),)

    id: Mapped[int] = mapped_column(Integer, primary_key=True, autoincrement=True)
    owner: Mapped[str] = mapped_column(String(200))
    key: Mapped[str] = mapped_column(String(200))
    fingerprint: Mapped[str] = mapped_column(String(64))
    status: Mapped[int] = mapped_column(Integer)
    body: Mapped[dict | None] = mapped_column(JSON)
    created_at: Mapped[datetime] = mapped_column(DateTime)
    #: The claim of a pending key: its holder's token and how long it holds it (renewed while
    #: the request runs); the resource its work committed (bound in the work's transaction)
    #: and the status that work answers.
    token: Mapped[str | None] = mapped_column(String(32), nullable=True)
    lease_until: Mapped[datetime | None] = mapped_column(DateTime, nullable=True)
    resource: Mapped[str | None] = mapped_column(String(300), nullable=True)
    resource_status: Mapped[int | None] = mapped_column(Integer, nullable=True)


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
