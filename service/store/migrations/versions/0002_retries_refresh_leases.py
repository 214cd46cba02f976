"""Compressed results, job retries, the persisted refresh flag, leases, the storage probe.

- ``results.codec``: how ``body`` is encoded; rows written before are ``identity``.
- ``jobs.attempts`` / ``last_retry_reason``: how often the computation started, and why
  it was started again.
- ``jobs.refresh``: the request asked to recompute (a resubmission on any replica sees it).
- ``jobs.generation``: bumped each time a finished job is accepted again (the Dask key).
- ``jobs.owner`` / ``worker`` / ``heartbeat``: the lease of the running attempt.

Revision ID: 0002
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision = "0002"
down_revision = "0001"
branch_labels = None
depends_on = None


def upgrade() -> None:
    op.add_column(
        "results", sa.Column("codec", sa.String(16), nullable=False, server_default="identity")
    )
    op.add_column("jobs", sa.Column("attempts", sa.Integer, nullable=False, server_default="0"))
    op.add_column("jobs", sa.Column("last_retry_reason", sa.Text))
    op.add_column(
        "jobs", sa.Column("refresh", sa.Boolean, nullable=False, server_default=sa.false())
    )
    op.add_column("jobs", sa.Column("generation", sa.Integer, nullable=False, server_default="1"))
    op.add_column("jobs", sa.Column("owner", sa.String(64)))
    op.add_column("jobs", sa.Column("worker", sa.String(256)))
    op.add_column("jobs", sa.Column("heartbeat", sa.Float))
    op.create_table(
        "probe",
        sa.Column("id", sa.Integer, primary_key=True),
        sa.Column("body", sa.LargeBinary, nullable=False),
        sa.Column("written", sa.Float, nullable=False),
    )


def downgrade() -> None:
    op.drop_table("probe")
    for column in ("heartbeat", "worker", "owner", "generation", "refresh"):
        op.drop_column("jobs", column)
    op.drop_column("jobs", "last_retry_reason")
    op.drop_column("jobs", "attempts")
    op.drop_column("results", "codec")
