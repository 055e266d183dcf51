"""Idempotency keys: a POST that creates, retried with the same ``Idempotency-Key``, gets the
first answer again instead of creating a duplicate."""

from __future__ import annotations

from typing import Any

from sqlalchemy import delete, select, update
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

    def complete_idempotent(
        self, owner: str, key: str, fingerprint: str, status: int, body: Any
    ) -> None:
        """Store the answer of the request that claimed ``key``."""
        with self.session() as s:  # type: ignore[attr-defined]
            s.execute(
                update(IdempotencyRow)
                .where(IdempotencyRow.owner == owner, IdempotencyRow.key == key)
                .values(fingerprint=fingerprint, status=int(status), body=sanitize(body))
            )

    def release_idempotent(self, owner: str, key: str) -> None:
        """Forget a claimed key whose request failed (a retry runs it again)."""
        with self.session() as s:  # type: ignore[attr-defined]
            s.execute(
                delete(IdempotencyRow).where(
                    IdempotencyRow.owner == owner,
                    IdempotencyRow.key == key,
                    IdempotencyRow.status == 0,
                )
            )

    def claim_idempotent(self, owner: str, key: str) -> bool:
        """Claim ``key`` for a first request (a pending record); False if already there."""
        row = IdempotencyRow(
            owner=owner, key=key, fingerprint="", status=0, body=None, created_at=utcnow()
        )
        try:
            with self.session() as s:  # type: ignore[attr-defined]
                s.add(row)
        except IntegrityError:
            return False
        return True
