"""Idempotency keys with a lease: the claim's token and lease, and the resource its work
committed (bound in the work's own transaction), so that a key whose request died is
recovered: replayed from the resource when the work committed, run again otherwise.

Revision ID: 0005_idempotency_lease
Revises: 0004_atlases
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision = "0005_idempotency_lease"
down_revision = "0004_atlases"
branch_labels = None
depends_on = None


def upgrade() -> None:
    op.add_column("idempotency_keys", sa.Column("token", sa.String(32)))
    op.add_column("idempotency_keys", sa.Column("lease_until", sa.DateTime))
    op.add_column("idempotency_keys", sa.Column("resource", sa.String(300)))
    op.add_column("idempotency_keys", sa.Column("resource_status", sa.Integer))


def downgrade() -> None:
    for name in ("resource_status", "resource", "lease_until", "token"):
        op.drop_column("idempotency_keys", name)
