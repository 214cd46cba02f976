"""What every computing endpoint does, for any computation: cache, single flight, jobs.

Routes stay thin: they validate the body once (FastAPI + the computation's request model),
key it once (:func:`service.keys.keyed`) and call :func:`run_sync` (answer with the
result) or :func:`accept_job` (answer 202 with a job); the OpenAPI pieces they share
(:data:`Refresh`, :data:`CACHE_HEADERS`, :data:`JOB_ACCEPTED`) are here too.
"""

from __future__ import annotations

import asyncio
from datetime import UTC, datetime
from typing import Annotated, Any

from fastapi import Query, Response
from fastapi.responses import JSONResponse

from service.keys import Keyed
from service.problems import ProblemError
from service.runner import ComputationCancelled, ComputationFailed, QueueFull, Runner
from service.schemas import JobStatus
from service.store import Job, Store

Refresh = Annotated[
    bool, Query(description="Recompute even if the result is cached (and replace it).")
]

#: OpenAPI headers of a result answered by :func:`result_response`
CACHE_HEADERS: dict[str, Any] = {
    "X-Cache": {
        "description": "HIT when served from the cache, MISS when computed for this request.",
        "schema": {"type": "string", "enum": ["HIT", "MISS"]},
    },
    "ETag": {"description": "Strong validator: the key in quotes.", "schema": {"type": "string"}},
}

#: OpenAPI entry of the 202 answered by :func:`accept_job`
JOB_ACCEPTED: dict[int | str, dict[str, Any]] = {
    202: {"headers": {"Location": {"description": "/v1/jobs/{key}", "schema": {"type": "string"}}}}
}


def envelope(key: str, cached: bool, body: bytes) -> bytes:
    """``{"key": ..., "cached": ..., **result}`` without re-encoding the stored result."""
    head = b'{"key":"%s","cached":%s' % (key.encode(), b"true" if cached else b"false")
    rest = body.strip()[1:]  # the stored body is a JSON object: drop its '{'
    return head + (b"," + rest if rest.strip() != b"}" else b"}")


def result_response(key: str, cached: bool, body: bytes) -> Response:
    return Response(
        envelope(key, cached, body),
        media_type="application/json",
        headers={
            "X-Cache": "HIT" if cached else "MISS",
            "ETag": f'"{key}"',
            "Content-Location": f"/v1/results/{key}",
        },
    )


def _saturated(runner: Runner, exc: QueueFull) -> ProblemError:
    return ProblemError(
        503,
        f"all {runner.capacity} computation slots are taken ({exc}); retry later",
        slug="saturated",
        headers={"Retry-After": str(runner.settings.retry_after_s)},
    )


async def run_sync(runner: Runner, store: Store, job: Keyed, refresh: bool) -> Response:
    """Serve the result of ``job``: from the cache, or computed now (once per key)."""
    key = job.key
    if not refresh:
        body = await asyncio.to_thread(store.get_result, key)
        if body is not None:
            return result_response(key, True, body)
    try:
        task = await runner.submit(job, force=refresh)
        body = await asyncio.shield(task)
    except QueueFull as exc:
        raise _saturated(runner, exc) from None
    except ComputationFailed as exc:
        raise ProblemError.from_document(exc.problem) from None
    except ComputationCancelled as exc:
        raise ProblemError(409, f"the computation was cancelled: {exc}", slug="cancelled") from None
    return result_response(key, False, body)


async def submit_job(runner: Runner, store: Store, job: Keyed, refresh: bool) -> Job:
    """Accept ``job`` (idempotent: the id is the parameter hash) and return its record."""
    key = job.key
    if not refresh and not runner.is_active(key) and await asyncio.to_thread(store.has_result, key):
        await asyncio.to_thread(store.mark_succeeded, key, job.computation.name, job.canonical)
    else:
        try:
            await runner.submit(job, force=refresh)
        except QueueFull as exc:
            raise _saturated(runner, exc) from None
    record = await asyncio.to_thread(store.get_job, key)
    assert record is not None
    return record


async def accept_job(runner: Runner, store: Store, job: Keyed, refresh: bool) -> JSONResponse:
    """:func:`submit_job`, answered 202 with the job and ``Location: /v1/jobs/{key}``."""
    return job_response(await submit_job(runner, store, job, refresh), 202)


def job_response(job: Job, status: int = 200) -> JSONResponse:
    """The job as :class:`service.schemas.JobStatus` JSON; a 202 carries its ``Location``."""
    body = JobStatus.model_validate(job_document(job)).model_dump(mode="json")
    headers = {"Location": f"/v1/jobs/{job.key}"} if status == 202 else None
    return JSONResponse(body, status, headers)


def _time(t: float | None) -> datetime | None:
    return None if t is None else datetime.fromtimestamp(t, tz=UTC)


def job_document(job: Job) -> dict[str, Any]:
    """The JSON of a job record (see :class:`service.schemas.JobStatus`)."""
    return {
        "key": job.key,
        "kind": job.kind,
        "status": job.status,
        "progress": job.progress,
        "created": _time(job.created),
        "started": _time(job.started),
        "finished": _time(job.finished),
        "updated": _time(job.updated),
        "error": job.error,
        "result": f"/v1/results/{job.key}" if job.status == "succeeded" else None,
    }
