"""Who else may follow a job (issue 34, safety item 3).

- table ``job_grants``: a client (an API key's id, ``principal``) that submitted the
  computation of job ``key`` while another client's run of it was the record's (it joined
  that run: an active record is shared, a stored result finishes the record at once), with
  the record's ``generation`` then.  With API keys required, the job routes show a record
  to its own ``jobs.principal``, to an admin key, and to a client granted its current
  generation; a reset record (a new generation: another client's new run) is not shown to
  the clients of the old one.  Rows whose job is gone are pruned with the job records.

Revision ID: 0006
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision = "0006"
down_revision = "0005"
branch_labels = None
depends_on = None


def upgrade() -> None:
    op.create_table(
        "job_grants",
        sa.Column("key", sa.String(128), primary_key=True),
        sa.Column("principal", sa.String(256), primary_key=True),
        sa.Column("generation", sa.Integer, nullable=False),
    )


def downgrade() -> None:
    op.drop_table("job_grants")
