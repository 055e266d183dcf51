"""The live-sweep aggregate: an open sweep, its records in arrival order, and their updates.

A live sweep is an ordinary sweep row plus its job row (same id, kind ``"sweep-live"``, status
``"open"`` while records arrive: the job runner neither claims nor recovers it), and a
``live_sweeps`` row with the sweep's options and a ``version`` (its number of records). A record
is appended by optimistic concurrency: ``UPDATE live_sweeps SET version = v + 1 WHERE id = ?
AND version = v AND status = 'open'`` and the insert of record ``seq = v + 1`` commit together,
so concurrent writers are serialised on every database (SQLite and PostgreSQL alike) and none
is lost; the loser recomputes its update on the new state and retries. The unique
``(sweep_id, seq)`` guards the same invariant a second time.

Every update is stored with its record, so a stream of server-sent events (in any process)
reads them back in order: there is no in-memory bus.
"""

from __future__ import annotations

from dataclasses import dataclass
from datetime import datetime
from typing import Any

from sqlalchemy import (
    JSON,
    DateTime,
    Double,
    Integer,
    String,
    UniqueConstraint,
    select,
    update,
)
from sqlalchemy.orm import Mapped, mapped_column

from service.api.storage import idempotency
from service.api.storage.models import (
    DEFAULT_OWNER,
    Base,
    JobRow,
    SweepRow,
    new_id,
    sanitize,
    utcnow,
)

LIVE_KIND = "sweep-live"
OPEN = "open"


class LiveSweepRow(Base):
    __tablename__ = "live_sweeps"

    id: Mapped[str] = mapped_column(String(32), primary_key=True)  # = the sweep's id
    owner: Mapped[str] = mapped_column(String(200), index=True, default=DEFAULT_OWNER)
    control_name: Mapped[str] = mapped_column(String(200))
    control_unit: Mapped[str | None] = mapped_column(String(100))
    options: Mapped[dict] = mapped_column(JSON, default=dict)
    status: Mapped[str] = mapped_column(String(20))  # open | closed | finished
    version: Mapped[int] = mapped_column(Integer, default=0)  # = number of records
    created_at: Mapped[datetime] = mapped_column(DateTime)
    closed_at: Mapped[datetime | None] = mapped_column(DateTime)


class LiveRecordRow(Base):
    __tablename__ = "live_records"
    __table_args__ = (UniqueConstraint("sweep_id", "seq", name="uq_live_records_sweep_seq"),)

    id: Mapped[int] = mapped_column(Integer, primary_key=True, autoincrement=True)
    sweep_id: Mapped[str] = mapped_column(String(32), index=True)
    seq: Mapped[int] = mapped_column(Integer)
    signal_id: Mapped[str | None] = mapped_column(String(32))
    control: Mapped[float] = mapped_column(Double)
    record: Mapped[dict] = mapped_column(JSON)  # what the next update needs (LiveRecord)
    doc: Mapped[dict] = mapped_column(JSON)  # the update as answered (the wire document)
    created_at: Mapped[datetime] = mapped_column(DateTime)


@dataclass(frozen=True)
class LiveState:
    """A consistent read of a live sweep: its row (with ``version``) and its records."""

    sweep: LiveSweepRow
    records: list[dict[str, Any]]  # the stored ``record`` documents, seq order


def create_live_sweep(
    store: Any,
    *,
    name: str | None,
    request: dict[str, Any],
    control_name: str,
    control_unit: str | None,
    options: dict[str, Any],
    owner: str = DEFAULT_OWNER,
) -> tuple[SweepRow, JobRow, LiveSweepRow]:
    """Create an open live sweep: the sweep row, its job (status ``open``) and the live row."""
    sid = new_id()
    now = utcnow()
    sweep = SweepRow(
        id=sid, owner=owner, name=sanitize(name), request=sanitize(request), created_at=now
    )
    job = JobRow(
        id=sid,
        kind=LIVE_KIND,
        status=OPEN,
        params={},
        fraction=0.0,
        message="open: 0 records",
        attempts=0,
        owner=owner,
        run_s=0.0,
        created_at=now,
        started_at=now,
    )
    live = LiveSweepRow(
        id=sid,
        owner=owner,
        control_name=control_name,
        control_unit=control_unit,
        options=sanitize(options),
        status=OPEN,
        version=0,
        created_at=now,
    )
    with store.session() as s:
        s.add(job)
        s.add(sweep)
        s.add(live)
        idempotency.bind(s, f"/v1/sweeps/{sid}", 201)
    return sweep, job, live


def get_live(store: Any, sweep_id: str, scope: str | None = None) -> LiveSweepRow | None:
    """The live row of ``sweep_id`` (None if it is not a live sweep of ``scope``)."""
    with store.session() as s:
        row = s.get(LiveSweepRow, sweep_id)
        if row is None or (scope is not None and row.owner != scope):
            return None
        return row


def live_state(store: Any, sweep_id: str) -> LiveState | None:
    """The live row and every record document, read in one transaction."""
    with store.session() as s:
        row = s.get(LiveSweepRow, sweep_id)
        if row is None:
            return None
        recs = s.execute(
            select(LiveRecordRow.record)
            .where(LiveRecordRow.sweep_id == sweep_id, LiveRecordRow.seq <= row.version)
            .order_by(LiveRecordRow.seq)
        ).scalars()
        return LiveState(row, list(recs))


def append_record(
    store: Any,
    sweep_id: str,
    version: int,
    *,
    signal_id: str | None,
    control: float,
    record: dict[str, Any],
    doc: dict[str, Any],
    finish_result: dict[str, Any] | None = None,
    new_signal: Any = None,
) -> LiveRecordRow | None:
    """Append record ``version + 1`` if the sweep is still open at ``version``.

    Returns the stored row, or None when another record (or a close) came first: the caller
    reads the new state, recomputes and retries. With ``finish_result`` the record spends the
    budget: the sweep finishes and its job succeeds with that result, in the same transaction.
    ``new_signal``: the record's samples as a new signal's row (``signals.signal_row``), stored
    in the same transaction, or neither (no signal is left behind by a record refused, too
    busy or killed); its id is the record's ``signal_id``.
    """
    seq = version + 1
    now = utcnow()
    with store.session() as s:
        res = s.execute(
            update(LiveSweepRow)
            .where(
                LiveSweepRow.id == sweep_id,
                LiveSweepRow.version == version,
                LiveSweepRow.status == OPEN,
            )
            .values(
                version=seq,
                **({"status": "finished", "closed_at": now} if finish_result else {}),
            )
        )
        if res.rowcount != 1:
            return None
        if new_signal is not None:
            s.add(new_signal)
            signal_id = new_signal.id
            doc = {**doc, "signal_id": signal_id}
        row = LiveRecordRow(
            sweep_id=sweep_id,
            seq=seq,
            signal_id=signal_id,
            control=float(control),
            record=sanitize(record),
            doc=sanitize({**doc, "seq": seq}),
            created_at=now,
        )
        s.add(row)
        values: dict[str, Any] = {"message": f"open: {seq} records"}
        if finish_result is not None:
            values = _finished(finish_result, now, f"finished: budget of {seq} records spent")
        s.execute(update(JobRow).where(JobRow.id == sweep_id).values(**values))
        idempotency.bind(s, f"/v1/sweeps/{sweep_id}/records/{seq}", 201)
    return row


def _finished(result: dict[str, Any], now: datetime, message: str) -> dict[str, Any]:
    return {
        "status": "succeeded",
        "result": sanitize(result),
        "fraction": 1.0,
        "message": message,
        "finished_at": now,
    }


def close_live(store: Any, sweep_id: str, version: int, result: dict[str, Any]) -> bool:
    """Close an open sweep that still has ``version`` records; its job succeeds with
    ``result``. False when it is not open or a record arrived meanwhile (recompute, retry)."""
    now = utcnow()
    with store.session() as s:
        res = s.execute(
            update(LiveSweepRow)
            .where(
                LiveSweepRow.id == sweep_id,
                LiveSweepRow.version == version,
                LiveSweepRow.status == OPEN,
            )
            .values(status="closed", closed_at=now)
        )
        if res.rowcount != 1:
            return False
        s.execute(
            update(JobRow)
            .where(JobRow.id == sweep_id)
            .values(**_finished(result, now, f"closed after {version} records"))
        )
    return True


def records_after(
    store: Any, sweep_id: str, after: int, limit: int = 1000
) -> tuple[LiveSweepRow | None, list[LiveRecordRow]]:
    """The live row and the records with ``seq > after`` (at most ``limit``), seq order."""
    with store.session() as s:
        row = s.get(LiveSweepRow, sweep_id)
        if row is None:
            return None, []
        recs = (
            s.execute(
                select(LiveRecordRow)
                .where(LiveRecordRow.sweep_id == sweep_id, LiveRecordRow.seq > after)
                .order_by(LiveRecordRow.seq)
                .limit(limit)
            )
            .scalars()
            .all()
        )
        return row, list(recs)


def live_version(store: Any, sweep_id: str) -> tuple[int, str] | None:
    """``(version, status)`` of a live sweep: the cheap question a stream polls."""
    with store.session() as s:
        r = s.execute(
            select(LiveSweepRow.version, LiveSweepRow.status).where(LiveSweepRow.id == sweep_id)
        ).one_or_none()
        return None if r is None else (int(r[0]), str(r[1]))
