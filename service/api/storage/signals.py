"""The signals aggregate: recorded or simulated samples with their metadata."""

from __future__ import annotations

import hashlib
from dataclasses import dataclass
from typing import Any

import numpy as np
from sqlalchemy import delete, func, select
from sqlalchemy.orm import defer

from service.api.storage import idempotency
from service.api.storage.models import (
    DEFAULT_OWNER,
    SignalRow,
    decode_f64,
    encode_f64,
    new_id,
    sanitize,
    utcnow,
)


@dataclass
class StoredSignal:
    row: SignalRow
    t: np.ndarray | None
    w: np.ndarray


def _scoped(q: Any, scope: str | None) -> Any:
    return q if scope is None else q.where(SignalRow.owner == scope)


_NO_SAMPLES = (defer(SignalRow.w, raiseload=True), defer(SignalRow.t, raiseload=True))


def signal_row(
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
    owner: str = DEFAULT_OWNER,
) -> SignalRow:
    """A new signal's row (samples encoded, hashed), to be added in some transaction."""
    wb = encode_f64(w)
    return SignalRow(
        id=new_id(),
        owner=owner,
        name=sanitize(name),
        n=int(w.size),
        dt=float(dt),
        t0=float(t0),
        unit=sanitize(unit),
        value_unit=sanitize(value_unit),
        control_name=sanitize((control or {}).get("name")),
        control_value=(control or {}).get("value"),
        control_unit=sanitize((control or {}).get("unit")),
        meta=sanitize(metadata or {}),
        source=source,
        w=wb,
        t=encode_f64(t) if t is not None else None,
        has_t=t is not None,
        sha256=hashlib.sha256(wb).hexdigest(),
        created_at=utcnow(),
    )


class SignalsMixin:
    """Signal access of :class:`~service.api.storage.Store`.

    ``scope`` is the owner a read is restricted to (None: every owner, for admins and jobs).
    """

    def add_signal(self, **fields: Any) -> SignalRow:
        """Store a signal (the fields of :func:`signal_row`); returns its row."""
        row = signal_row(**fields)
        with self.session() as s:  # type: ignore[attr-defined]
            s.add(row)
            idempotency.bind(s, f"/v1/signals/{row.id}", 201)
        return row

    def get_signal_meta(self, signal_id: str, scope: str | None = None) -> SignalRow | None:
        """The row without its samples (they are not read from the database)."""
        with self.session() as s:  # type: ignore[attr-defined]
            q = select(SignalRow).where(SignalRow.id == signal_id).options(*_NO_SAMPLES)
            return s.execute(_scoped(q, scope)).scalar_one_or_none()

    def get_signal(self, signal_id: str, scope: str | None = None) -> StoredSignal | None:
        with self.session() as s:  # type: ignore[attr-defined]
            q = select(SignalRow).where(SignalRow.id == signal_id)
            row = s.execute(_scoped(q, scope)).scalar_one_or_none()
        if row is None:
            return None
        t = decode_f64(row.t) if row.t is not None else None
        return StoredSignal(row=row, t=t, w=decode_f64(row.w))

    def delete_signal(self, signal_id: str, scope: str | None = None) -> bool:
        """Delete one signal; True for exactly one of concurrent deletes of the same id."""
        with self.session() as s:  # type: ignore[attr-defined]
            q = delete(SignalRow).where(SignalRow.id == signal_id)
            if scope is not None:
                q = q.where(SignalRow.owner == scope)
            return s.execute(q).rowcount == 1

    def list_signals(
        self, limit: int, offset: int, scope: str | None = None
    ) -> tuple[list[SignalRow], int]:
        """A page of signals (newest first, samples not read) and the total count."""
        with self.session() as s:  # type: ignore[attr-defined]
            q = select(SignalRow).options(*_NO_SAMPLES)
            rows = (
                s.execute(
                    _scoped(q, scope)
                    .order_by(SignalRow.created_at.desc(), SignalRow.id)
                    .limit(limit)
                    .offset(offset)
                )
                .scalars()
                .all()
            )
            total = s.execute(
                _scoped(select(func.count()).select_from(SignalRow), scope)
            ).scalar_one()
        return list(rows), int(total)

    def count_signals(self, scope: str | None = None) -> int:
        with self.session() as s:  # type: ignore[attr-defined]
            q = _scoped(select(func.count()).select_from(SignalRow), scope)
            return int(s.execute(q).scalar_one())
