"""Atlases: the atlas (its spec) and one row per finished cell, unique per (atlas, key).

Revision ID: 0004_atlases
Revises: 0003_live
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision = "0004_atlases"
down_revision = "0003_live"
branch_labels = None
depends_on = None


def upgrade() -> None:
    op.create_table(
        "atlases",
        sa.Column("id", sa.String(32), primary_key=True),
        sa.Column("owner", sa.String(200), nullable=False, server_default=sa.text("'local'")),
        sa.Column("name", sa.String(500)),
        sa.Column("kind", sa.String(20), nullable=False),
        sa.Column("spec", sa.JSON, nullable=False),
        sa.Column("cells_total", sa.Integer, nullable=False),
        sa.Column("created_at", sa.DateTime, nullable=False),
    )
    op.create_index("ix_atlases_owner", "atlases", ["owner"])
    op.create_table(
        "atlas_cells",
        sa.Column("id", sa.Integer, primary_key=True, autoincrement=True),
        sa.Column("atlas_id", sa.String(32), nullable=False),
        sa.Column("key", sa.String(64), nullable=False),
        sa.Column("idx", sa.Integer, nullable=False),
        sa.Column("status", sa.String(20), nullable=False),
        sa.Column("seconds", sa.Double, nullable=False),
        sa.Column("doc", sa.JSON, nullable=False),
        sa.Column("created_at", sa.DateTime, nullable=False),
        sa.UniqueConstraint("atlas_id", "key", name="uq_atlas_cells_atlas_key"),
    )
    op.create_index("ix_atlas_cells_atlas_id", "atlas_cells", ["atlas_id"])


def downgrade() -> None:
    op.drop_index("ix_atlas_cells_atlas_id", "atlas_cells")
    op.drop_table("atlas_cells")
    op.drop_index("ix_atlases_owner", "atlases")
    op.drop_table("atlases")
