"""Idempotency keys: a POST that creates, retried with the same ``Idempotency-Key``, gets the
first answer again instead of creating a duplicate.

A first request claims its key with a random token and a lease (renewed while it runs). The
work binds the resource it creates to the claim in the work's own transaction
(:func:`bind`): the work commits only while its request still holds the key, and a key whose
work committed names that resource even if the request died before storing its answer. A key
whose request died is recovered: a retry after the lease replays the resource (work committed)
or takes the key over and runs (work not committed).
"""

from __future__ import annotations

from contextvars import ContextVar
from dataclasses import dataclass
from datetime import timedelta
from typing import Any

from sqlalchemy import delete, select, update
from sqlalchemy.exc import IntegrityError

from service.api.storage.models import IdempotencyRow, sanitize, utcnow


@dataclass(frozen=True)
class Claim:
    """The key a request holds: owner, key, its token, the POST's path, and a function giving
    the request's fingerprint (its body hashed as far as read)."""

    owner: str
    key: str
    token: str
    path: str
    fingerprint: Any = None


#: The claim of the request being served (set by the idempotency middleware).
CLAIM: ContextVar[Claim | None] = ContextVar("snapwarn_idempotency_claim", default=None)


def bind(s: Any, resource: str, status: int) -> None:
    """Name ``resource`` (the path a GET reads it at) as the work of the request's key, in the
    work's session ``s``: they commit together. Only for a resource under the POST's own path
    (a signal stored by a live record is not the record). Raises when the
    request no longer holds the key (a 409: its lease ran out and a retry took it over; the
    work is rolled back)."""
    claim = CLAIM.get()
    if claim is None or not resource.startswith(claim.path.rstrip("/") + "/"):
        return
    fp = claim.fingerprint() if claim.fingerprint is not None else ""
    res = s.execute(
        update(IdempotencyRow)
        .where(
            IdempotencyRow.owner == claim.owner,
            IdempotencyRow.key == claim.key,
            IdempotencyRow.token == claim.token,
            IdempotencyRow.status == 0,
        )
        .values(resource=resource, resource_status=int(status), fingerprint=fp)
    )
    if res.rowcount != 1:
        from service.api.problems import ApiProblem

        raise ApiProblem(409, "this request's Idempotency-Key was taken over by a retry (its "
                         "lease ran out); its work is not stored", field="idempotency-key",
                         value=claim.key)  # fmt: skip


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
        self,
        owner: str,
        key: str,
        fingerprint: str,
        status: int,
        body: Any,
        token: str | None = None,
    ) -> None:
        """Store the answer of the request that claimed ``key`` (with ``token``: only while it
        still holds it; a pending key recovered from its resource: any token)."""
        q = update(IdempotencyRow).where(
            IdempotencyRow.owner == owner, IdempotencyRow.key == key, IdempotencyRow.status == 0
        )
        if token is not None:
            q = q.where(IdempotencyRow.token == token)
        with self.session() as s:  # type: ignore[attr-defined]
            s.execute(
                q.values(
                    fingerprint=fingerprint,
                    status=int(status),
                    body=sanitize(body),
                    lease_until=None,
                )  # fmt: skip
            )

    def release_idempotent(self, owner: str, key: str, token: str | None = None) -> None:
        """Forget a claimed key whose request failed before its work committed (a retry runs
        it again); a key whose work committed stays, to be replayed from its resource."""
        q = delete(IdempotencyRow).where(
            IdempotencyRow.owner == owner,
            IdempotencyRow.key == key,
            IdempotencyRow.status == 0,
            IdempotencyRow.resource.is_(None),
        )
        if token is not None:
            q = q.where(IdempotencyRow.token == token)
        with self.session() as s:  # type: ignore[attr-defined]
            s.execute(q)

    def claim_idempotent(
        self, owner: str, key: str, token: str = "", lease_s: float = 30.0
    ) -> bool:
        """Claim ``key`` for a first request (a pending record held by ``token`` for
        ``lease_s``); False if already there."""
        row = IdempotencyRow(
            owner=owner, key=key, fingerprint="", status=0, body=None, created_at=utcnow(),
            token=token or None, lease_until=utcnow() + timedelta(seconds=lease_s),
        )  # fmt: skip
        try:
            with self.session() as s:  # type: ignore[attr-defined]
                s.add(row)
        except IntegrityError:
            return False
        return True

    def renew_idempotent(self, owner: str, key: str, token: str, lease_s: float) -> bool:
        """Extend the lease of a key still held by ``token`` (False: no longer held)."""
        with self.session() as s:  # type: ignore[attr-defined]
            res = s.execute(
                update(IdempotencyRow)
                .where(
                    IdempotencyRow.owner == owner,
                    IdempotencyRow.key == key,
                    IdempotencyRow.token == token,
                    IdempotencyRow.status == 0,
                )
                .values(lease_until=utcnow() + timedelta(seconds=lease_s))
            )
            return res.rowcount == 1

    def take_over_idempotent(
        self, owner: str, key: str, old: IdempotencyRow, token: str, lease_s: float
    ) -> bool:
        """Take a pending key whose lease ran out and whose work did not commit (its request
        died); True when this caller now holds it (one of concurrent retries wins)."""
        now = utcnow()
        q = update(IdempotencyRow).where(
            IdempotencyRow.owner == owner,
            IdempotencyRow.key == key,
            IdempotencyRow.status == 0,
            IdempotencyRow.resource.is_(None),
            (IdempotencyRow.lease_until.is_(None)) | (IdempotencyRow.lease_until < now),
        )
        q = q.where(
            IdempotencyRow.token.is_(None)
            if old.token is None
            else IdempotencyRow.token == old.token
        )
        with self.session() as s:  # type: ignore[attr-defined]
            res = s.execute(
                q.values(token=token, lease_until=now + timedelta(seconds=lease_s), fingerprint="")
            )
            return res.rowcount == 1

    def recover_idempotent(self) -> int:
        """Forget pending keys whose lease ran out and whose work did not commit (their
        requests died: a retry runs again); those whose work committed stay, replayed from
        their resource. Run at start-up; returns the keys forgotten."""
        with self.session() as s:  # type: ignore[attr-defined]
            res = s.execute(
                delete(IdempotencyRow).where(
                    IdempotencyRow.status == 0,
                    IdempotencyRow.resource.is_(None),
                    (IdempotencyRow.lease_until.is_(None))
                    | (IdempotencyRow.lease_until < utcnow()),
                )
            )
            return int(res.rowcount or 0)
