"""The durable job queue and the client of each job (issue 22: queueing, quotas).

- ``jobs.principal``: who asked for the job (:func:`service.http.identity.principal`): an
  API key's id, else ``anonymous``; fairness between clients and the per-client quotas
  count by it.  NULL for rows written before.
- ``jobs.dispatcher``: the replica driving the job (its in-flight computation), NULL while
  an accepted job waits in the durable queue for a free worker (``status = 'queued'``).
  Rows active before this migration were all being driven: they get ``'before-0004'``.
- ``jobs.dispatched``: when a replica took the job from the queue [Unix s] (fairness:
  the client served longest ago goes next).
- ``jobs.cost``: the request's estimated cost in units of its kind's cost bound [0, 1],
  for the cost-per-minute quota.
- index ``jobs_principal (principal, created)``: the quota's look-up of one client's recent
  jobs; ``jobs_queue (status, dispatcher, principal, created)``: the queue's count, its
  clients and their oldest jobs read from the index alone (benchmarks/bench_queue.py);
  ``jobs_served (principal, dispatched)``: when each client was last served.

Revision ID: 0004
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision = "0004"
down_revision = "0003"
branch_labels = None
depends_on = None


def upgrade() -> None:
    with op.batch_alter_table("jobs") as batch:
        batch.add_column(sa.Column("principal", sa.String(256)))
        batch.add_column(sa.Column("dispatcher", sa.String(64)))
        batch.add_column(sa.Column("dispatched", sa.Float))
        batch.add_column(sa.Column("cost", sa.Float, nullable=False, server_default="0"))
    op.create_index("jobs_principal", "jobs", ["principal", "created"])
    op.create_index("jobs_queue", "jobs", ["status", "dispatcher", "principal", "created"])
    op.create_index("jobs_served", "jobs", ["principal", "dispatched"])
    op.execute("UPDATE jobs SET dispatcher = 'before-0004' WHERE status IN ('queued', 'running')")


def downgrade() -> None:
    op.drop_index("jobs_served", table_name="jobs")
    op.drop_index("jobs_queue", table_name="jobs")
    op.drop_index("jobs_principal", table_name="jobs")
    with op.batch_alter_table("jobs") as batch:
        batch.drop_column("cost")
        batch.drop_column("dispatched")
        batch.drop_column("dispatcher")
        batch.drop_column("principal")
