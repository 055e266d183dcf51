"""Persistence: SQLAlchemy 2 over SQLite (default) or PostgreSQL (by URL), split by aggregate.

- :mod:`.models`: the engine, the declarative ``Base`` and the core rows;
- :mod:`.signals`, :mod:`.jobs`, :mod:`.sweeps`, :mod:`.keys`, :mod:`.idempotency`: the access
  of each aggregate, mixed into :class:`Store`.

The schema is made by the Alembic migrations of ``service/api/migrations`` (``Store.migrate``;
the server upgrades to the head at startup). New aggregates go in their own module here, on the
same ``Base``, with a migration.
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager

from sqlalchemy import Engine, select
from sqlalchemy.orm import Session, sessionmaker

from service.api.storage.idempotency import IdempotencyMixin
from service.api.storage.jobs import JobsMixin, _owner_dead_here, runner_identity
from service.api.storage.keys import ApiKeyRow, KeyInfo, KeysMixin
from service.api.storage.models import (
    DEFAULT_OWNER,
    F64,
    Base,
    IdempotencyRow,
    JobRow,
    SignalRow,
    SweepRow,
    WorkerRow,
    as_utc,
    decode_f64,
    encode_f64,
    make_engine,
    new_id,
    sanitize,
    utcnow,
)
from service.api.storage.signals import SignalsMixin, StoredSignal
from service.api.storage.sweeps import SweepsMixin

__all__ = [
    "DEFAULT_OWNER",
    "F64",
    "ApiKeyRow",
    "Base",
    "IdempotencyRow",
    "JobRow",
    "KeyInfo",
    "SignalRow",
    "Store",
    "StoredSignal",
    "SweepRow",
    "WorkerRow",
    "_owner_dead_here",
    "as_utc",
    "decode_f64",
    "encode_f64",
    "make_engine",
    "new_id",
    "runner_identity",
    "sanitize",
    "utcnow",
]


class Store(SignalsMixin, JobsMixin, SweepsMixin, KeysMixin, IdempotencyMixin):
    """All database access of the service (one per process; thread-safe via sessions)."""

    def __init__(self, url: str, *, engine: Engine | None = None) -> None:
        self.url = url
        self.engine = engine or make_engine(url)
        self._sessions = sessionmaker(self.engine, expire_on_commit=False)

    def migrate(self) -> str | None:
        """Upgrade the database to the newest migration (several processes may race here).

        Returns the revision reached.
        """
        from service.api.migrations import upgrade

        return upgrade(self.engine)

    def create_all(self) -> None:
        """The schema of this version (alias of :meth:`migrate`, kept for callers)."""
        self.migrate()

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
