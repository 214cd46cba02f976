"""Service configuration: one settings class, read from ``PIPEFLOW_*`` environment variables."""

from __future__ import annotations

import os
import tempfile
from functools import lru_cache
from pathlib import Path
from typing import Literal

import platformdirs
from pydantic import Field
from pydantic_settings import BaseSettings, SettingsConfigDict


def default_data_dir() -> Path:
    """The per-user data directory: ``$XDG_DATA_HOME/pipeflow``, by default
    ``~/.local/share/pipeflow`` on Linux (``platformdirs.user_data_dir``; the platform's
    equivalent elsewhere), so the store does not depend on where the server was started."""
    return Path(platformdirs.user_data_dir("pipeflow", appauthor=False))


class Settings(BaseSettings):
    """Every knob of the service: ``PIPEFLOW_<NAME>`` sets ``<name>`` (``PIPEFLOW_WORKERS=4``)."""

    model_config = SettingsConfigDict(env_prefix="PIPEFLOW_", extra="ignore")

    data_dir: Path = Field(
        default_factory=default_data_dir,
        description="Directory of the SQLite store (results cache and jobs); one server "
        "process per directory. Default: the per-user data directory (default_data_dir).",
    )
    database_url: str | None = Field(
        None,
        description="SQLAlchemy URL of the store, e.g. postgresql+psycopg://user@host/db "
        "(several replicas); default: sqlite:/// file pipeflow.sqlite3 in data_dir.",
    )
    scheduler_address: str | None = Field(
        None,
        description="Dask scheduler to use, e.g. tcp://host:8786; default: an embedded "
        "LocalCluster of `workers` processes.",
    )
    workers: int = Field(
        default_factory=lambda: max(1, min(2, os.cpu_count() or 1)),
        ge=1,
        le=64,
        description="Worker processes running simulations (one BLAS thread each).",
    )
    queue_size: int = Field(
        16,
        ge=0,
        le=10_000,
        description="Computations that may wait for a worker; beyond workers + queue_size: 503.",
    )
    max_queued_jobs: int = Field(
        5000,
        ge=0,
        le=1_000_000,
        description="Jobs (POST .../jobs) that may wait in the store's durable queue for a "
        "worker, over all replicas sharing the store; beyond: 503 with Retry-After.",
    )
    quota_concurrent_jobs: int | None = Field(
        None,
        ge=1,
        description="Per client (service.http.identity.principal): jobs computing at once; a "
        "synchronous request beyond is answered 429 with Retry-After, a queued job waits "
        "for its turn. None (default): no quota.",
    )
    quota_queued_jobs: int | None = Field(
        None,
        ge=1,
        description="Per client: jobs waiting in the durable queue; beyond: 429 with "
        "Retry-After. None (default): no quota.",
    )
    quota_cost_per_minute: float | None = Field(
        None,
        gt=0,
        description="Per client: summed estimated cost of the computations started in the "
        "last 60 s, in units of each kind's cost bound (a request at its kind's bound costs "
        "1; a kind without an estimate costs 1); beyond: 429 with Retry-After [s] until "
        "enough of it leaves the window. None (default): no quota.",
    )
    fast_lane_threads: int = Field(
        1,
        ge=0,
        le=8,
        description="Threads of the API process that run small computations in place of a "
        "Dask worker (the fast lane: no scheduler and worker round trip); 0 turns the lane "
        "off, every computation then goes to Dask.",
    )
    fast_lane_max_s: float = Field(
        0.05,
        ge=0,
        le=1.0,
        description="Largest estimated run time of a computation the fast lane takes [s] "
        "(the computation's own estimate, for one core; kinds without an estimate never "
        "take it); larger ones go to a Dask worker.",
    )
    fast_lane_max_metered_s: float = Field(
        0.1,
        ge=0,
        le=10.0,
        description="Allowance of metered work of a computation in the fast lane [s, "
        "estimated on one core before each part runs]: a time-variant magnus simulation "
        "(whose step count is known only as its step control plans it) takes the lane when "
        "the rest of its work is estimated under fast_lane_max_s, and is charged each "
        "propagation's estimate (steps x the cost of a step of its size) before it is "
        "computed; the first one that would pass this allowance stops it there and its job "
        "goes to a Dask worker (the record re-queued, computed once). 0: such runs always "
        "go to a worker.",
    )
    max_job_waiters: int = Field(
        1000,
        ge=0,
        le=100_000,
        description="Long polls (GET /v1/jobs/{key}?wait=) held open at once per replica; "
        "past it such a request is answered at once with the job's current status, as "
        "without wait (0: never hold one).",
    )
    max_job_wait_s: float = Field(
        60.0,
        ge=0.0,
        le=60.0,
        description="Longest a long poll (GET /v1/jobs/{key}?wait=) is held [s]: a larger "
        "wait is cut to it and answered then with the job's current status (below a "
        "reverse proxy's read timeout, e.g. nginx's 60 s default, set it lower).",
    )
    max_body_bytes: int = Field(
        2_000_000, ge=1024, description="Largest accepted request body [bytes]; larger: 413."
    )
    read_timeout_s: float = Field(
        30.0,
        gt=0,
        le=3600,
        description="Longest a client may take to send a request, its headers and body [s], "
        "counted from the connection's opening (its first request) or the request's first "
        "byte; past it the server answers 408 and closes the connection, so a half-sent "
        "request does not hold one. Needs the service's HTTP protocol: python -m service "
        "and pipeflow serve use it, uvicorn is given --http "
        "service.http.deadline:HTTPProtocol.",
    )
    job_timeout_s: float = Field(
        600.0, gt=0, description="Runtime limit of one computation [s]; past it the job fails."
    )
    cache_max_bytes: int = Field(
        1 << 30, ge=0, description="Bound on stored result bodies on disk [bytes], LRU eviction."
    )
    memory_cache_bytes: int = Field(
        64 << 20, ge=0, description="Bound on the in-memory front of the result cache [bytes]."
    )
    hit_cache_bytes: int = Field(
        64 << 20,
        ge=0,
        description="Bound on the pre-encoded (and gzipped) cache-hit answers in memory [bytes].",
    )
    table_cache_bytes: int = Field(
        32 << 20,
        ge=0,
        description="Bound on the encoded CSV/Parquet tables of results kept in memory "
        "[bytes] (a repeated download is not rebuilt).",
    )
    retry_after_s: int = Field(5, ge=1, description="Retry-After sent with 503 responses [s].")
    job_retention_s: float = Field(
        7 * 86400.0, gt=0, description="Finished job records older than this are pruned [s]."
    )
    progress_interval_s: float = Field(
        0.25,
        gt=0,
        le=60,
        description="How often a running computation heartbeats, records progress and "
        "checks for cancel [s].",
    )
    stale_after_s: float = Field(
        10.0,
        gt=0,
        description="A job whose heartbeat is older than this is taken to be dead (its "
        "worker, replica or the scheduler died) and is submitted again [s].",
    )
    checkpoint_interval_s: float = Field(
        5.0,
        gt=0,
        description="A long simulation (magnus, rk4) saves a checkpoint in the store at most "
        "this often, the first after this long, so a computation killed with its worker or "
        "server resumes from it instead of from zero; shorter runs never write one [s].",
    )
    checkpoint_max_bytes: int = Field(
        64 << 20,
        ge=0,
        description="Largest checkpoint kept in the store [bytes]; a computation whose "
        "checkpoint would be larger is not checkpointed (0: never checkpoint).",
    )

    auth_required: bool = Field(
        False,
        description="Require an API key (Authorization: Bearer <key> or X-API-Key) on the "
        "API (/v1/...) and /metrics: 401 without a known one. Off by default (the embedded "
        "single-user set-up); the probes, pages and documentation stay open.",
    )
    api_keys: str = Field(
        "",
        description="The keys the server accepts, as entries <id>:sha256:<hex of the key's "
        "SHA-256> separated by commas or new lines (python -m service.http.auth new <id> "
        "makes a key and its entry); never the keys themselves.",
    )
    api_keys_file: Path | None = Field(
        None, description="A file of more key entries, one per line (# comments)."
    )
    metrics_auth: bool = Field(
        True,
        description="With auth_required: whether /metrics needs a key too (false: open, "
        "for a scraper on a private network).",
    )
    metrics_key_ids: str = Field(
        "",
        description="Comma-separated key ids that may read /metrics (others: 403); empty: "
        "any known key.",
    )
    admin_key_ids: str = Field(
        "",
        description="With auth_required: comma-separated key ids (of the key ring) that may "
        "read and cancel any client's job; every other key sees and cancels only the jobs "
        "it started (and follows those it joined). Empty: no admin key.",
    )

    log_level: Literal["DEBUG", "INFO", "WARNING", "ERROR", "CRITICAL"] = Field(
        "INFO", description="Lowest level of log records written to stdout."
    )
    log_format: Literal["json", "text"] = Field(
        "json", description="One JSON object per log line, or plain text for a terminal."
    )

    @property
    def db_path(self) -> Path:
        return self.data_dir / "pipeflow.sqlite3"

    @property
    def db_url(self) -> str:
        """The store's SQLAlchemy URL (``database_url``, else the SQLite file in data_dir)."""
        return self.database_url or f"sqlite:///{self.db_path.resolve()}"

    def ensure_data_dir(self) -> Path:
        """Create :attr:`data_dir` if needed and check this process may write there; raises
        :class:`DataDirError` saying how to fix it (a root-owned bind mount, typically)."""
        path = self.data_dir
        try:
            path.mkdir(parents=True, exist_ok=True)
            with tempfile.TemporaryFile(dir=path):
                pass
        except OSError as exc:
            uid = os.getuid() if hasattr(os, "getuid") else "this user"
            raise DataDirError(
                f"PIPEFLOW_DATA_DIR={path} is not a writable directory for uid {uid} "
                f"({exc.strerror}): give that user the directory (chown {uid} {path}), run "
                'as its owner (docker run --user "$(id -u):$(id -g)"), or set '
                "PIPEFLOW_DATA_DIR to a writable directory"
            ) from exc
        return path


class DataDirError(RuntimeError):
    """The data directory cannot be written: the server refuses to start."""


@lru_cache(maxsize=1)
def get_settings() -> Settings:
    """The process-wide settings, read once from the environment."""
    return Settings()
