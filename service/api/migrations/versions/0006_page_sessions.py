"""Page sessions: the login cookie holds a random token, stored here as its SHA-256 (never the
API key), with the caller it stands for and its expiry.

Revision ID: 0006_page_sessions
Revises: 0005_idempotency_lease
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision = "0006_page_sessions"
down_revision = "0005_idempotency_lease"
branch_labels = None
depends_on = None


def upgrade() -> None:
    op.create_table(
        "page_sessions",
        sa.Column("token_hash", sa.String(64), primary_key=True),
        sa.Column("owner", sa.String(200), nullable=False),
        sa.Column("admin", sa.Boolean, nullable=False),
        sa.Column("key_id", sa.String(32)),
        sa.Column("created_at", sa.DateTime, nullable=False),
        sa.Column("expires_at", sa.DateTime, nullable=False),
    )


def downgrade() -> None:
    op.drop_table("page_sessions")
