"""Response models of the service's own resources (jobs, health); the computations'
request and result models are pipeflow's (:mod:`pipeflow.schema`)."""

from __future__ import annotations

from datetime import datetime
from typing import Annotated, Any, Literal

from pydantic import AfterValidator, BaseModel, Field, WithJsonSchema

from service.engine.lifecycle import JobState
from service.http.problems import Problem
from service.routes.endpoints import served

KEY_PATTERN = r"^[0-9a-f]{64}$"
#: a job's states (:class:`JobState`, validated as one) inline in the document, as a Literal
#: of them shows (no schema of its own: the document is unchanged)
_INLINE_STATES = {"enum": [s.value for s in JobState], "title": "Status", "type": "string"}


class JobStatus(BaseModel):
    """The state of a job; its id is the parameter hash."""

    key: str = Field(description="Job id = parameter hash (SHA-256 hex).")
    kind: str = Field(
        description="What is computed (the job kind, a computation of the registry): "
        + ", ".join(f"'{c.name}'" for c in served())
        + "."
    )
    status: Annotated[str, AfterValidator(JobState), WithJsonSchema(_INLINE_STATES)]
    progress: float = Field(ge=0, le=1, description="Fraction done [-].")
    created: datetime = Field(description="When the job was (last) accepted (UTC).")
    started: datetime | None = Field(description="When its current run started (UTC).")
    finished: datetime | None = Field(description="When it reached its terminal state (UTC).")
    updated: datetime = Field(description="Last change of this record (UTC).")
    error: Problem | dict[str, Any] | None = Field(
        description="Why it failed or was cancelled (an RFC 9457 problem document)."
    )
    result: str | None = Field(description="URL path of the result once succeeded.")
    attempts: int = Field(
        0,
        ge=0,
        description="How often its computation started (1 normally; more when a worker, a "
        "replica or the scheduler died under it and it was retried).",
    )
    last_retry_reason: str | None = Field(
        None, description="Why the computation was last started again (null: never retried)."
    )


class Health(BaseModel):
    status: Literal["ok"] = "ok"
    version: str = Field(description="pipeflow version.")


class Readiness(BaseModel):
    status: Literal["ready"] = "ready"
    workers: int = Field(description="Worker processes connected to the Dask scheduler now.")
    in_flight: int = Field(description="Computations queued or running.")
    capacity: int = Field(description="Computations accepted before answering 503.")
