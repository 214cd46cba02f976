"""Running totals of the results table: ``store_stats`` (one row, ``id`` = 1).

``result_bytes`` = SUM(results.size) and ``result_rows`` = COUNT(*) of results, kept by
every write to ``results`` in its own transaction (:class:`service.store.results.ResultStore`),
so the disk bound costs O(1) per write instead of a full-table ``SUM(size)``.  Filled here
from the rows already stored.

Revision ID: 0003
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision = "0003"
down_revision = "0002"
branch_labels = None
depends_on = None


def upgrade() -> None:
    op.create_table(
        "store_stats",
        sa.Column("id", sa.Integer, primary_key=True),
        sa.Column("result_bytes", sa.BigInteger, nullable=False),
        sa.Column("result_rows", sa.BigInteger, nullable=False),
    )
    op.execute(
        "INSERT INTO store_stats (id, result_bytes, result_rows) "
        "SELECT 1, COALESCE(SUM(size), 0), COUNT(*) FROM results"
    )


def downgrade() -> None:
    op.drop_table("store_stats")
