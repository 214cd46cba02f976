"""What every computing endpoint does, for any computation: cache, single flight, jobs.

Routes stay thin: they validate the body once (FastAPI + the computation's request model),
key it once (:func:`service.keys.keyed`) and call :func:`run_sync` (answer with the
result) or :func:`accept_job` (answer 202 with a job).  The answers themselves are built by
:mod:`service.http.responses`; an engine outcome that is an error becomes a problem
document there too (:func:`service.http.problems.stored_problem`).
"""

from __future__ import annotations

import asyncio
from typing import Annotated

from fastapi import Query, Response
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse
from pydantic import ValidationError

from service.engine import ComputationCancelled, ComputationFailed, NoWorker, QueueFull, Runner
from service.http.problems import ProblemError, stored_problem
from service.http.responses import Hit, hit_response, job_response, result_response
from service.keys import Keyed
from service.store import Job, Store

Refresh = Annotated[
    bool, Query(description="Recompute even if the result is cached (and replace it).")
]


def _unavailable(runner: Runner, detail: str, slug: str) -> ProblemError:
    """503 with Retry-After [s]: nothing was computed, retry later."""
    headers = {"Retry-After": str(runner.settings.retry_after_s)}
    return ProblemError(503, detail, slug=slug, headers=headers)


def _saturated(runner: Runner, exc: QueueFull) -> ProblemError:
    detail = f"all {runner.capacity} computation slots are taken ({exc}); retry later"
    return _unavailable(runner, detail, "saturated")


def _no_worker(runner: Runner, exc: NoWorker) -> ProblemError:
    detail = f"no compute worker is available ({exc}); the request is not computed now, retry later"
    return _unavailable(runner, detail, "no-worker")


async def check_request(job: Keyed) -> None:
    """The computation's validation too costly for the event loop
    (:attr:`~pipeflow.schema.registry.Computation.check`, e.g. every case of a study), in a
    thread; a failure is answered as the body's own validation errors are (422 naming the
    field)."""
    check = job.computation.check
    if check is None:
        return
    try:
        await asyncio.to_thread(check, job.request)
    except ValidationError as exc:
        errors = [{**e, "loc": ("body", *e["loc"])} for e in exc.errors()]
        body = job.request.model_dump(mode="json", exclude_unset=True)
        raise RequestValidationError(errors, body=body) from None


async def run_sync(
    runner: Runner, store: Store, job: Keyed, refresh: bool, hit: Hit | None = None
) -> Response:
    """Serve the result of ``job``: from the cache, or computed now (once per key).

    With ``hit`` (the app's hit cache, see :class:`Hit`), a hit is answered from memory as
    its pre-encoded bytes, gzip when the client accepts it."""
    key = job.key
    cache = hit.cache if hit is not None else None
    if not refresh:
        encoded = cache.get(key) if cache is not None else None
        if encoded is not None:
            return result_response(key, True, encoded, hit is not None and hit.gzip)
        body = await asyncio.to_thread(store.get_result, key)
        if body is not None:
            return await hit_response(key, body, hit)
    if cache is not None:
        cache.pop(key)  # a recomputation replaces the stored result
    if not runner.is_active(key):
        await check_request(job)
    try:
        await runner.admit()
        task = await runner.submit(job, force=refresh)
        body = await runner.result(task)
    except NoWorker as exc:
        raise _no_worker(runner, exc) from None
    except QueueFull as exc:
        raise _saturated(runner, exc) from None
    except ComputationFailed as exc:
        raise ProblemError.from_document(stored_problem(exc.error)) from None
    except ComputationCancelled as exc:
        raise ProblemError(409, f"the computation was cancelled: {exc}", slug="cancelled") from None
    return result_response(key, False, body)


async def submit_job(runner: Runner, store: Store, job: Keyed, refresh: bool) -> Job:
    """Accept ``job`` (idempotent: the id is the parameter hash) and return its record."""
    key = job.key
    if not refresh and not runner.is_active(key) and await asyncio.to_thread(store.has_result, key):
        await asyncio.to_thread(store.mark_succeeded, key, job.computation.name, job.canonical)
    else:
        if not runner.is_active(key):
            await check_request(job)
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
