"""API keys: only a SHA-256 digest of each secret is stored; a key is ``sw_<id>_<secret>``.

The secret is 32 random bytes (256 bits), so a plain digest is enough (no password stretching
is needed for a secret that cannot be guessed); it is compared with :func:`hmac.compare_digest`.
"""

from __future__ import annotations

import hashlib
import hmac
import secrets
from dataclasses import dataclass
from datetime import datetime, timedelta

from sqlalchemy import Boolean, DateTime, String, delete, select, update
from sqlalchemy.orm import Mapped, mapped_column

from service.api.storage.models import Base, utcnow

KEY_PREFIX = "sw_"


class ApiKeyRow(Base):
    __tablename__ = "api_keys"

    id: Mapped[str] = mapped_column(String(32), primary_key=True)
    owner: Mapped[str] = mapped_column(String(200), index=True)
    digest: Mapped[str] = mapped_column(String(64))
    admin: Mapped[bool] = mapped_column(Boolean, default=False)
    note: Mapped[str | None] = mapped_column(String(500))
    created_at: Mapped[datetime] = mapped_column(DateTime)
    revoked_at: Mapped[datetime | None] = mapped_column(DateTime)


class PageSessionRow(Base):
    """A page session: the SHA-256 of the login cookie's random token and who it stands for."""

    __tablename__ = "page_sessions"

    token_hash: Mapped[str] = mapped_column(String(64), primary_key=True)
    owner: Mapped[str] = mapped_column(String(200))
    admin: Mapped[bool] = mapped_column(Boolean)
    key_id: Mapped[str | None] = mapped_column(String(32), nullable=True)
    created_at: Mapped[datetime] = mapped_column(DateTime)
    expires_at: Mapped[datetime] = mapped_column(DateTime)


@dataclass(frozen=True)
class KeyInfo:
    """What is known of a key without its secret."""

    id: str
    owner: str
    admin: bool
    note: str | None
    created_at: datetime
    revoked_at: datetime | None


def digest(secret: str) -> str:
    return hashlib.sha256(secret.encode("utf-8", "surrogatepass")).hexdigest()


def split_key(token: str) -> tuple[str, str] | None:
    """``(id, secret)`` of a well-formed key, else None."""
    if not token.startswith(KEY_PREFIX):
        return None
    parts = token[len(KEY_PREFIX) :].split("_", 1)
    if len(parts) != 2 or not parts[0] or not parts[1] or len(parts[0]) > 32:
        return None
    return parts[0], parts[1]


def _info(row: ApiKeyRow) -> KeyInfo:
    return KeyInfo(row.id, row.owner, bool(row.admin), row.note, row.created_at, row.revoked_at)


class KeysMixin:
    """Key management of :class:`~service.api.storage.Store`."""

    def create_key(
        self, owner: str | None = None, *, admin: bool = False, note: str | None = None
    ) -> tuple[str, KeyInfo]:
        """Create a key; returns the full key (shown once, never stored) and its info."""
        kid = secrets.token_hex(6)
        secret = secrets.token_urlsafe(32)
        row = ApiKeyRow(
            id=kid,
            owner=owner or f"key-{kid}",
            digest=digest(secret),
            admin=bool(admin),
            note=note,
            created_at=utcnow(),
            revoked_at=None,
        )
        with self.session() as s:  # type: ignore[attr-defined]
            s.add(row)
        return f"{KEY_PREFIX}{kid}_{secret}", _info(row)

    def list_keys(self, include_revoked: bool = False) -> list[KeyInfo]:
        with self.session() as s:  # type: ignore[attr-defined]
            q = select(ApiKeyRow).order_by(ApiKeyRow.created_at, ApiKeyRow.id)
            if not include_revoked:
                q = q.where(ApiKeyRow.revoked_at.is_(None))
            return [_info(r) for r in s.execute(q).scalars().all()]

    def revoke_key(self, key_id: str) -> bool:
        with self.session() as s:  # type: ignore[attr-defined]
            res = s.execute(
                update(ApiKeyRow)
                .where(ApiKeyRow.id == key_id, ApiKeyRow.revoked_at.is_(None))
                .values(revoked_at=utcnow())
            )
            return res.rowcount == 1

    def count_keys(self) -> int:
        return len(self.list_keys())

    def verify_key(self, token: str) -> KeyInfo | None:
        """The info of the live key ``token`` is, or None (constant-time digest comparison)."""
        parts = split_key(token)
        if parts is None:
            return None
        kid, secret = parts
        with self.session() as s:  # type: ignore[attr-defined]
            row = s.get(ApiKeyRow, kid)
            info = _info(row) if row is not None else None
            stored = row.digest if row is not None else "0" * 64
        ok = hmac.compare_digest(digest(secret), stored)
        if info is None or not ok or info.revoked_at is not None:
            return None
        return info

    def create_session(self, owner: str, admin: bool, key_id: str | None, ttl_s: float) -> str:
        """A new page session for this caller: its random token (given once; only its digest
        is stored), valid ``ttl_s`` seconds or until its key is revoked."""
        token = secrets.token_urlsafe(32)
        now = utcnow()
        row = PageSessionRow(token_hash=digest(token), owner=owner, admin=bool(admin),
                             key_id=key_id, created_at=now,
                             expires_at=now + timedelta(seconds=ttl_s))  # fmt: skip
        with self.session() as s:  # type: ignore[attr-defined]
            s.add(row)
            s.execute(delete(PageSessionRow).where(PageSessionRow.expires_at < now))
        return token

    def session_caller(self, token: str) -> tuple[str, bool, str | None] | None:
        """``(owner, admin, key_id)`` of a live page session (None: unknown, expired, or its
        key revoked)."""
        with self.session() as s:  # type: ignore[attr-defined]
            row = s.get(PageSessionRow, digest(token))
            if row is None or row.expires_at < utcnow():
                return None
            if row.key_id is not None:
                key = s.get(ApiKeyRow, row.key_id)
                if key is None or key.revoked_at is not None:
                    return None
            return row.owner, bool(row.admin), row.key_id

    def end_session(self, token: str) -> None:
        """Forget a page session (logout)."""
        with self.session() as s:  # type: ignore[attr-defined]
            s.execute(delete(PageSessionRow).where(PageSessionRow.token_hash == digest(token)))
