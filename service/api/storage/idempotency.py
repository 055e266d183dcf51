"""Idempotency keys: a POST that creates, retried with the same ``Idempotency-Key``, gets the
first answer again instead of creating a duplicate."""

from __future__ import annotations

from typing import Any

from sqlalchemy import select
from sqlalchemy.exc import IntegrityError

from service.api.storage.models import IdempotencyRow, sanitize, utcnow


class IdempotencyMixin:
    """Idempotency records of :class:`~service.api.storage.Store`."""

    def get_idempotent(self, owner: str, key: str) -> IdempotencyRow | None:
        with self.session() as s:  # type: ignore[attr-defined]
            return s.execute(
                select(IdempotencyRow).where(
                    IdempotencyRow.owner == owner, IdempotencyRow.key == key
                )
            ).scalar_one_or_none()

    def put_idempotent(
        self, owner: str, key: str, fingerprint: str, status: int, body: Any
    ) -> IdempotencyRow:
        """Record the answer of a first request; a concurrent first wins (its row returned)."""
        row = IdempotencyRow(
            owner=owner,
            key=key,
            fingerprint=fingerprint,
            status=int(status),
            body=sanitize(body),
            created_at=utcnow(),
        )
        try:
            with self.session() as s:  # type: ignore[attr-defined]
                s.add(row)
        except IntegrityError:
            first = self.get_idempotent(owner, key)
            if first is not None:
                return first
            raise
        return row
