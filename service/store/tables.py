"""The tables of the store (SQLAlchemy Core): the shape after the newest migration.

Migrations in ``service/store/migrations/versions`` are how the database gets here; this
module is what the code reads and writes.  Times are Unix seconds (UTC).
"""

from __future__ import annotations

from sqlalchemy import (
    BigInteger,
    Boolean,
    Column,
    Float,
    Index,
    Integer,
    LargeBinary,
    MetaData,
    String,
    Table,
    Text,
    false,
)

metadata = MetaData()

results = Table(
    "results",
    metadata,
    Column("key", String(128), primary_key=True),
    Column("kind", String(64), nullable=False),
    Column("body", LargeBinary, nullable=False),  # the result JSON, compressed by `codec`
    Column("size", Integer, nullable=False),  # stored bytes (what the disk bound counts)
    Column("created", Float, nullable=False),
    Column("accessed", Float, nullable=False),
    Column("codec", String(16), nullable=False, server_default="identity"),
)
Index("results_accessed", results.c.accessed)

#: migration 0003: running totals over ``results``, one row (``id`` = 1), updated in the
#: transaction of every write that changes them (the disk bound reads it, no table scan)
store_stats = Table(
    "store_stats",
    metadata,
    Column("id", Integer, primary_key=True),
    Column("result_bytes", BigInteger, nullable=False),  # SUM(results.size)
    Column("result_rows", BigInteger, nullable=False),  # COUNT(*) of results
)

jobs = Table(
    "jobs",
    metadata,
    Column("key", String(128), primary_key=True),
    Column("kind", String(64), nullable=False),
    Column("spec", Text, nullable=False),
    Column("status", String(16), nullable=False),
    Column("progress", Float, nullable=False, server_default="0"),
    Column("error", Text),
    Column("created", Float, nullable=False),
    Column("started", Float),
    Column("finished", Float),
    Column("updated", Float, nullable=False),
    Column("cancel", Integer, nullable=False, server_default="0"),
    # migration 0002: retries, the persisted refresh flag, the lease of the running attempt
    Column("attempts", Integer, nullable=False, server_default="0"),
    Column("last_retry_reason", Text),
    Column("refresh", Boolean, nullable=False, server_default=false()),
    Column("generation", Integer, nullable=False, server_default="1"),
    Column("owner", String(64)),  # id of the attempt holding the lease, NULL when none
    Column("worker", String(256)),  # where that attempt runs (Dask worker address)
    Column("heartbeat", Float),  # last sign of life of the job's owner or submitter
    # migration 0004: the client that asked (quotas, fairness), the replica driving the job
    # (NULL: waiting in the durable queue), the estimated cost [fraction of its kind's bound]
    Column("principal", String(256)),
    Column("dispatcher", String(64)),
    Column("dispatched", Float),  # when a replica took it from the queue
    Column("cost", Float, nullable=False, server_default="0"),
)
Index("jobs_status", jobs.c.status)
Index("jobs_principal", jobs.c.principal, jobs.c.created)
Index("jobs_queue", jobs.c.status, jobs.c.dispatcher, jobs.c.principal, jobs.c.created)
Index("jobs_served", jobs.c.principal, jobs.c.dispatched)

#: migration 0005: the latest checkpoint of a running job's computation (an opaque blob of
#: :mod:`pipeflow.solvers.checkpoint`), by job key and generation; deleted when it finishes
checkpoints = Table(
    "checkpoints",
    metadata,
    Column("key", String(128), primary_key=True),
    Column("generation", Integer, primary_key=True),
    Column("body", LargeBinary, nullable=False),
    Column("size", Integer, nullable=False),  # [bytes]
    Column("written", Float, nullable=False),
)

#: migration 0006: a client that joined another client's run of a job (submitted the same
#: computation), and the record's generation then: it may follow that run too
#: (:mod:`service.store.grants`)
job_grants = Table(
    "job_grants",
    metadata,
    Column("key", String(128), primary_key=True),
    Column("principal", String(256), primary_key=True),
    Column("generation", Integer, nullable=False),
)

#: a scratch row written by the storage probe (is there room for a write again?)
probe = Table(
    "probe",
    metadata,
    Column("id", Integer, primary_key=True),
    Column("body", LargeBinary, nullable=False),
    Column("written", Float, nullable=False),
)
