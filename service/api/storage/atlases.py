"""The atlases aggregate: an atlas (its spec) is computed by the job of the same id; each
finished cell is one ``atlas_cells`` row, written as it arrives.

``UNIQUE (atlas_id, key)`` makes a cell count once whatever happens: a job resumed after a
crash reads the keys already stored and submits only the others (:class:`DbCellSink`), and a
late duplicate insert is refused by the database itself.
"""

from __future__ import annotations

from datetime import datetime
from typing import Any

from sqlalchemy import JSON, DateTime, Double, Integer, String, UniqueConstraint, func, select
from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import Mapped, mapped_column

from service.api.storage import idempotency
from service.api.storage.jobs import reserve
from service.api.storage.models import DEFAULT_OWNER, Base, JobRow, new_id, sanitize, utcnow

ATLAS_KIND = "atlas"


class AtlasRow(Base):
    __tablename__ = "atlases"

    id: Mapped[str] = mapped_column(String(32), primary_key=True)  # = its job's id
    owner: Mapped[str] = mapped_column(String(200), index=True, default=DEFAULT_OWNER)
    name: Mapped[str | None] = mapped_column(String(500))
    kind: Mapped[str] = mapped_column(String(20))
    spec: Mapped[dict] = mapped_column(JSON)
    cells_total: Mapped[int] = mapped_column(Integer)
    created_at: Mapped[datetime] = mapped_column(DateTime)


class AtlasCellRow(Base):
    __tablename__ = "atlas_cells"
    __table_args__ = (UniqueConstraint("atlas_id", "key", name="uq_atlas_cells_atlas_key"),)

    id: Mapped[int] = mapped_column(Integer, primary_key=True, autoincrement=True)
    atlas_id: Mapped[str] = mapped_column(String(32), index=True)
    key: Mapped[str] = mapped_column(String(64))
    idx: Mapped[int] = mapped_column(Integer)
    status: Mapped[str] = mapped_column(String(20))
    seconds: Mapped[float] = mapped_column(Double)
    doc: Mapped[dict] = mapped_column(JSON)  # the CellResult as a dict
    created_at: Mapped[datetime] = mapped_column(DateTime)


def create_atlas(store: Any, *, name: str | None, kind: str, spec: dict[str, Any],
                 params: dict[str, Any], cells_total: int, owner: str = DEFAULT_OWNER,
                 time_limit_s: float | None = None,
                 max_active: int | None = None) -> tuple[AtlasRow, JobRow]:  # fmt: skip
    """The atlas row and its queued job (same id), in one transaction."""
    aid = new_id()
    now = utcnow()
    atlas = AtlasRow(id=aid, owner=owner, name=sanitize(name), kind=kind, spec=sanitize(spec),
                     cells_total=int(cells_total), created_at=now)  # fmt: skip
    job = JobRow(id=aid, kind=ATLAS_KIND, status="queued", params=sanitize(params), fraction=0.0,
                 message="queued", attempts=0, owner=owner, time_limit_s=time_limit_s,
                 run_s=0.0, created_at=now)  # fmt: skip
    with store.session() as s:
        reserve(s, owner, max_active)
        s.add(job)
        s.add(atlas)
        idempotency.bind(s, f"/v1/atlases/{aid}", 202)
    return atlas, job


def _done(s: Any, atlas_id: str) -> int:
    return int(s.execute(select(func.count()).select_from(AtlasCellRow)
                         .where(AtlasCellRow.atlas_id == atlas_id)).scalar_one())  # fmt: skip


def get_atlas(store: Any, atlas_id: str,
              scope: str | None = None) -> tuple[AtlasRow, JobRow, int] | None:  # fmt: skip
    """The atlas, its job and its number of finished cells (None: absent or not ``scope``'s)."""
    with store.session() as s:
        atlas = s.get(AtlasRow, atlas_id)
        if atlas is None or (scope is not None and atlas.owner != scope):
            return None
        return atlas, s.get(JobRow, atlas_id), _done(s, atlas_id)


def list_atlases(store: Any, limit: int, offset: int, scope: str | None = None
                 ) -> tuple[list[tuple[AtlasRow, JobRow, int]], int]:  # fmt: skip
    """A page of atlases (newest first) with their jobs and cells done, and the total."""
    cond = [] if scope is None else [AtlasRow.owner == scope]
    done = (select(AtlasCellRow.atlas_id, func.count().label("n"))
            .group_by(AtlasCellRow.atlas_id).subquery())  # fmt: skip
    with store.session() as s:
        rows = s.execute(
            select(AtlasRow, JobRow, func.coalesce(done.c.n, 0))
            .join(JobRow, JobRow.id == AtlasRow.id)
            .outerjoin(done, done.c.atlas_id == AtlasRow.id)
            .where(*cond)
            .order_by(AtlasRow.created_at.desc(), AtlasRow.id)
            .limit(limit)
            .offset(offset)
        ).all()
        total = s.execute(select(func.count()).select_from(AtlasRow).where(*cond)).scalar_one()
    return [(r[0], r[1], int(r[2])) for r in rows], int(total)


def list_cells(store: Any, atlas_id: str, limit: int | None = None, offset: int = 0,
               status: str | None = None) -> tuple[list[dict[str, Any]], int]:  # fmt: skip
    """A page of the atlas's finished cells (spec order) and their total."""
    cond = [AtlasCellRow.atlas_id == atlas_id]
    if status:
        cond.append(AtlasCellRow.status == status)
    with store.session() as s:
        q = select(AtlasCellRow.doc).where(*cond).order_by(AtlasCellRow.idx).offset(offset)
        if limit is not None:
            q = q.limit(limit)
        docs = s.execute(q).scalars().all()
        total = s.execute(select(func.count()).select_from(AtlasCellRow).where(*cond)
                          ).scalar_one()  # fmt: skip
    return [dict(d) for d in docs], int(total)


class DbCellSink:
    """The engine's sink for an atlas job: one row per finished cell, refused when present."""

    def __init__(self, store: Any, atlas_id: str) -> None:
        self.store = store
        self.atlas_id = atlas_id

    def load(self) -> dict[str, Any]:
        from service.atlas import CellResult

        docs, _ = list_cells(self.store, self.atlas_id)
        return {d["key"]: CellResult.from_dict(d) for d in docs}

    def put(self, row: Any) -> bool:
        from service import convert

        doc = sanitize(convert.atlas_cell(row).model_dump(mode="json"))
        try:
            with self.store.session() as s:
                s.add(AtlasCellRow(atlas_id=self.atlas_id, key=row.key, idx=row.index,
                                   status=row.status, seconds=float(row.seconds), doc=doc,
                                   created_at=utcnow()))  # fmt: skip
        except IntegrityError:
            return False
        return True
