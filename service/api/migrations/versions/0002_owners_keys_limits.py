"""Owners on every resource, hashed API keys, idempotency keys, job time limits.

``jobs.owner`` held the runner's identity: it becomes ``jobs.runner``; the new ``owner``
columns name the API key owner that created the row ("local" for the rows that exist).

Revision ID: 0002
Revises: 0001
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision = "0002"
down_revision = "0001"
branch_labels = None
depends_on = None

_LOCAL = sa.text("'local'")


def upgrade() -> None:
    with op.batch_alter_table("jobs") as b:
        b.alter_column("owner", new_column_name="runner", existing_type=sa.String(200))
    with op.batch_alter_table("jobs") as b:
        b.add_column(sa.Column("owner", sa.String(200), nullable=False, server_default=_LOCAL))
        b.add_column(sa.Column("time_limit_s", sa.Double))
        b.add_column(sa.Column("run_s", sa.Double, nullable=False, server_default="0"))
        b.add_column(sa.Column("attempt_started_at", sa.DateTime))
        b.create_index("ix_jobs_owner", ["owner"])
    for table in ("signals", "sweeps"):
        with op.batch_alter_table(table) as b:
            b.add_column(
                sa.Column("owner", sa.String(200), nullable=False, server_default=_LOCAL)
            )
            b.create_index(f"ix_{table}_owner", ["owner"])
    op.create_table(
        "api_keys",
        sa.Column("id", sa.String(32), primary_key=True),
        sa.Column("owner", sa.String(200), nullable=False),
        sa.Column("digest", sa.String(64), nullable=False),
        sa.Column("admin", sa.Boolean, nullable=False),
        sa.Column("note", sa.String(500)),
        sa.Column("created_at", sa.DateTime, nullable=False),
        sa.Column("revoked_at", sa.DateTime),
    )
    op.create_index("ix_api_keys_owner", "api_keys", ["owner"])
    op.create_table(
        "idempotency_keys",
        sa.Column("id", sa.Integer, primary_key=True, autoincrement=True),
        sa.Column("owner", sa.String(200), nullable=False),
        sa.Column("key", sa.String(200), nullable=False),
        sa.Column("fingerprint", sa.String(64), nullable=False),
        sa.Column("status", sa.Integer, nullable=False),
        sa.Column("body", sa.JSON),
        sa.Column("created_at", sa.DateTime, nullable=False),
        sa.UniqueConstraint("owner", "key", name="uq_idempotency_owner_key"),
    )


def downgrade() -> None:
    op.drop_table("idempotency_keys")
    op.drop_index("ix_api_keys_owner", "api_keys")
    op.drop_table("api_keys")
    for table in ("sweeps", "signals"):
        with op.batch_alter_table(table) as b:
            b.drop_index(f"ix_{table}_owner")
            b.drop_column("owner")
    with op.batch_alter_table("jobs") as b:
        b.drop_index("ix_jobs_owner")
        for col in ("attempt_started_at", "run_s", "time_limit_s", "owner"):
            b.drop_column(col)
    with op.batch_alter_table("jobs") as b:
        b.alter_column("runner", new_column_name="owner", existing_type=sa.String(200))
