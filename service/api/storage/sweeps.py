"""The sweeps aggregate: a sweep is a request plus the job (same id) that computes it."""

from __future__ import annotations

from typing import Any

from sqlalchemy import func, select

from service.api.storage import idempotency
from service.api.storage.jobs import reserve
from service.api.storage.models import (
    DEFAULT_OWNER,
    JobRow,
    SweepRow,
    new_id,
    sanitize,
    utcnow,
)


class SweepsMixin:
    """Sweep access of :class:`~service.api.storage.Store` (``scope``: see ``SignalsMixin``)."""

    def create_sweep(
        self,
        kind: str,
        request: dict[str, Any],
        params: dict[str, Any],
        name: str | None,
        *,
        owner: str = DEFAULT_OWNER,
        time_limit_s: float | None = None,
        max_active: int | None = None,
    ) -> tuple[SweepRow, JobRow]:
        sid = new_id()
        now = utcnow()
        sweep = SweepRow(
            id=sid, owner=owner, name=sanitize(name), request=sanitize(request), created_at=now
        )
        job = JobRow(
            id=sid,
            kind=kind,
            status="queued",
            params=sanitize(params),
            fraction=0.0,
            message="queued",
            attempts=0,
            owner=owner,
            time_limit_s=time_limit_s,
            run_s=0.0,
            created_at=now,
        )
        with self.session() as s:  # type: ignore[attr-defined]
            reserve(s, owner, max_active)
            s.add(job)
            s.add(sweep)
            idempotency.bind(s, f"/v1/sweeps/{sid}", 202)
        return sweep, job

    def get_sweep(self, sweep_id: str, scope: str | None = None) -> tuple[SweepRow, JobRow] | None:
        with self.session() as s:  # type: ignore[attr-defined]
            sweep = s.get(SweepRow, sweep_id)
            if sweep is None or (scope is not None and sweep.owner != scope):
                return None
            job = s.get(JobRow, sweep_id)
            return sweep, job

    def list_sweeps(
        self, limit: int, offset: int, scope: str | None = None
    ) -> tuple[list[tuple[SweepRow, JobRow]], int]:
        """A page of sweeps with their jobs (newest first) and the total count."""
        cond = [] if scope is None else [SweepRow.owner == scope]
        with self.session() as s:  # type: ignore[attr-defined]
            rows = s.execute(
                select(SweepRow, JobRow)
                .join(JobRow, JobRow.id == SweepRow.id)
                .where(*cond)
                .order_by(SweepRow.created_at.desc(), SweepRow.id)
                .limit(limit)
                .offset(offset)
            ).all()
            total = s.execute(select(func.count()).select_from(SweepRow).where(*cond)).scalar_one()
        return [(r[0], r[1]) for r in rows], int(total)
