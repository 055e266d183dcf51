"""Live sweeps: the open sweep's options and version, its records and their updates.

Revision ID: 0003_live
Revises: 0002
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision = "0003_live"
down_revision = "0002"
branch_labels = None
depends_on = None


def upgrade() -> None:
    op.create_table(
        "live_sweeps",
        sa.Column("id", sa.String(32), primary_key=True),
        sa.Column("owner", sa.String(200), nullable=False, server_default=sa.text("'local'")),
        sa.Column("control_name", sa.String(200), nullable=False),
        sa.Column("control_unit", sa.String(100)),
        sa.Column("options", sa.JSON, nullable=False),
        sa.Column("status", sa.String(20), nullable=False),
        sa.Column("version", sa.Integer, nullable=False),
        sa.Column("created_at", sa.DateTime, nullable=False),
        sa.Column("closed_at", sa.DateTime),
    )
    op.create_index("ix_live_sweeps_owner", "live_sweeps", ["owner"])
    op.create_table(
        "live_records",
        sa.Column("id", sa.Integer, primary_key=True, autoincrement=True),
        sa.Column("sweep_id", sa.String(32), nullable=False),
        sa.Column("seq", sa.Integer, nullable=False),
        sa.Column("signal_id", sa.String(32)),
        sa.Column("control", sa.Double, nullable=False),
        sa.Column("record", sa.JSON, nullable=False),
        sa.Column("doc", sa.JSON, nullable=False),
        sa.Column("created_at", sa.DateTime, nullable=False),
        sa.UniqueConstraint("sweep_id", "seq", name="uq_live_records_sweep_seq"),
    )
    op.create_index("ix_live_records_sweep_id", "live_records", ["sweep_id"])


def downgrade() -> None:
    op.drop_index("ix_live_records_sweep_id", "live_records")
    op.drop_table("live_records")
    op.drop_index("ix_live_sweeps_owner", "live_sweeps")
    op.drop_table("live_sweeps")
