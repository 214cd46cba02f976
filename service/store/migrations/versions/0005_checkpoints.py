"""Checkpoints of long computations (issue 22, defect 8).

- table ``checkpoints``: the latest checkpoint of a running job's computation
  (:mod:`pipeflow.solvers.checkpoint`: an opaque blob the solver reads back), keyed by the
  job's key and generation (a job reset to a new generation never resumes from an older
  one); ``size`` [bytes] of the blob, ``written`` [Unix s].  Rows are deleted when the job
  finishes (any terminal status), in the transaction that finishes it.

Revision ID: 0005
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision = "0005"
down_revision = "0004"
branch_labels = None
depends_on = None


def upgrade() -> None:
    op.create_table(
        "checkpoints",
        sa.Column("key", sa.String(128), primary_key=True),
        sa.Column("generation", sa.Integer, primary_key=True),
        sa.Column("body", sa.LargeBinary, nullable=False),
        sa.Column("size", sa.Integer, nullable=False),
        sa.Column("written", sa.Float, nullable=False),
    )


def downgrade() -> None:
    op.drop_table("checkpoints")
