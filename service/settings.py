"""Service configuration: one settings class, read from ``PIPEFLOW_*`` environment variables."""

from __future__ import annotations

import os
from functools import lru_cache
from pathlib import Path
from typing import Literal

from pydantic import Field
from pydantic_settings import BaseSettings, SettingsConfigDict


class Settings(BaseSettings):
    """Every knob of the service: ``PIPEFLOW_<NAME>`` sets ``<name>`` (``PIPEFLOW_WORKERS=4``)."""

    model_config = SettingsConfigDict(env_prefix="PIPEFLOW_", extra="ignore")

    data_dir: Path = Field(
        Path("./var"), description="Directory of the SQLite store (results cache and jobs)."
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
    max_body_bytes: int = Field(
        2_000_000, ge=1024, description="Largest accepted request body [bytes]; larger: 413."
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
    retry_after_s: int = Field(5, ge=1, description="Retry-After sent with 503 responses [s].")
    job_retention_s: float = Field(
        7 * 86400.0, gt=0, description="Finished job records older than this are pruned [s]."
    )
    progress_interval_s: float = Field(
        0.25, gt=0, description="How often a worker records progress and checks for cancel [s]."
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


@lru_cache(maxsize=1)
def get_settings() -> Settings:
    """The process-wide settings, read once from the environment."""
    return Settings()
