"""What every computing endpoint does, for any computation: cache, single flight, jobs.

Routes stay thin: they validate the body once (FastAPI + the computation's request model),
key it once (:func:`service.keys.keyed`) and call :func:`run_sync` (answer with the
result) or :func:`accept_job` (answer 202 with a job).  The answers themselves are built by
:mod:`service.http.responses`; an engine outcome that is an error becomes a problem
document there too (:func:`service.http.problems.stored_problem`).

A job is a promise to run later: :func:`submit_job` accepts it into the store's durable
queue (:meth:`Runner.enqueue`), up to ``max_queued_jobs`` over all replicas (503 with
Retry-After beyond), and the replicas' dispatchers run it as workers free up.  A
synchronous request runs at once or, past ``workers + queue_size`` in flight, is a 503.
Both check the client's quotas first (:func:`check_quotas`, 429 with Retry-After), by the
identity of :func:`service.http.identity.principal`.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import math
import time
from collections.abc import Iterator
from typing import Annotated

from fastapi import Query, Response
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse
from pydantic import ValidationError

from service.engine import ComputationCancelled, ComputationFailed, NoWorker, QueueFull, Runner
from service.http.identity import ANONYMOUS
from service.http.problems import ProblemError, stored_problem
from service.http.responses import Hit, hit_response, job_response, result_response
from service.keys import Keyed
from service.store import COST_WINDOW_S, Job, Store

log = logging.getLogger("service")

Refresh = Annotated[
    bool, Query(description="Recompute even if the result is cached (and replace it).")
]


def _unavailable(runner: Runner, detail: str, slug: str) -> ProblemError:
    """503 with Retry-After [s]: nothing was computed, retry later."""
    headers = {"Retry-After": str(runner.settings.retry_after_s)}
    return ProblemError(503, detail, slug=slug, headers=headers)


def _saturated(runner: Runner, exc: QueueFull, what: str | None = None) -> ProblemError:
    """503 with Retry-After: ``what`` is full (default: the computation slots)."""
    what = what or f"all {runner.capacity} computation slots are taken"
    return _unavailable(runner, f"{what} ({exc}); retry later", "saturated")


def _no_worker(runner: Runner, exc: NoWorker) -> ProblemError:
    detail = f"no compute worker is available ({exc}); the request is not computed now, retry later"
    return _unavailable(runner, detail, "no-worker")


def job_cost(job: Keyed) -> float:
    """The estimated cost of ``job`` in units of its kind's cost bound, in [0, 1]
    (:attr:`~pipeflow.computations.registry.Computation.estimate`: units / bound), what the
    cost-per-minute quota counts; 1 where the kind has no estimate (an unknown cost is
    taken at its bound)."""
    estimate = job.computation.estimate
    if estimate is None:
        return 1.0
    try:
        cost = estimate(job.request)
    except Exception:  # an estimate is advice: never fail a request over it
        log.exception("estimate of %s", job.computation.name)
        return 1.0
    if cost is None or cost.bound <= 0:
        return 1.0
    return min(1.0, max(0.0, cost.units / cost.bound))


def _over_quota(detail: str, retry_after_s: float) -> ProblemError:
    return ProblemError(
        429,
        detail,
        slug="quota",
        headers={"Retry-After": str(max(1, math.ceil(retry_after_s)))},
    )


async def check_quotas(
    runner: Runner, store: Store, principal: str, cost: float, *, queued: bool
) -> None:
    """Refuse a new computation of ``principal`` over one of its quotas (settings
    ``quota_*``, all off by default) with a 429 problem and Retry-After [s].

    ``queued``: a job for the durable queue (counts the queued-jobs quota; the
    concurrent-jobs quota holds it back in the queue instead); else a synchronous
    computation (counts the concurrent-jobs quota).  The cost-per-minute quota counts
    both; a client with nothing in the last minute is always let through once (a single
    request costlier than the quota would never pass).  Counts are read once, not
    locked: replicas accepting at the same instant may each let one more through."""
    s = runner.settings
    concurrent = None if queued else s.quota_concurrent_jobs
    waiting = s.quota_queued_jobs if queued else None
    per_minute = s.quota_cost_per_minute
    if concurrent is None and waiting is None and per_minute is None:
        return
    usage = await asyncio.to_thread(store.usage, principal)
    if concurrent is not None and usage.active >= concurrent:
        raise _over_quota(
            f"client {principal!r} has {usage.active} computations running; its quota of "
            f"concurrent jobs is {concurrent} (quota_concurrent_jobs)",
            s.retry_after_s,
        )
    if waiting is not None and usage.waiting >= waiting:
        raise _over_quota(
            f"client {principal!r} has {usage.waiting} jobs queued; its quota of queued jobs "
            f"is {waiting} (quota_queued_jobs)",
            s.retry_after_s,
        )
    if per_minute is not None and usage.cost > 0 and usage.cost + cost > per_minute:
        oldest = usage.oldest if usage.oldest is not None else time.time()
        raise _over_quota(
            f"client {principal!r} started computations costing {usage.cost:.3g} in the last "
            f"{COST_WINDOW_S:g} s and this one costs {cost:.3g} (units of each kind's cost "
            f"bound); its quota is {per_minute:g} per minute (quota_cost_per_minute)",
            oldest + COST_WINDOW_S - time.time(),
        )


async def check_request(job: Keyed) -> None:
    """The computation's validation too costly for the event loop
    (:attr:`~pipeflow.computations.registry.Computation.check`, e.g. every case of a study), in a
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


def _looks_up_in_lane(runner: Runner, job: Keyed) -> bool:
    """Whether the cache lookup of a synchronous request can go with its fast-lane run in one
    thread hop (:meth:`Runner.look_up_or_run`): nothing must run between the lookup and
    the computation (no :func:`check_request` of the kind, no quota of a synchronous
    computation, see :func:`check_quotas`) and the runner must take it
    (:meth:`Runner.looks_up_in_lane`)."""
    s = runner.settings
    return (
        job.computation.check is None
        and s.quota_concurrent_jobs is None
        and s.quota_cost_per_minute is None
        and runner.looks_up_in_lane(job)
    )


@contextlib.contextmanager
def _engine_errors(runner: Runner) -> Iterator[None]:
    """The engine's refusals and a computation's failure as problem documents."""
    try:
        yield
    except NoWorker as exc:
        raise _no_worker(runner, exc) from None
    except QueueFull as exc:
        raise _saturated(runner, exc) from None
    except ComputationFailed as exc:
        raise ProblemError.from_document(stored_problem(exc.error)) from None
    except ComputationCancelled as exc:
        raise ProblemError(409, f"the computation was cancelled: {exc}", slug="cancelled") from None


async def run_sync(
    runner: Runner,
    store: Store,
    job: Keyed,
    refresh: bool,
    hit: Hit | None = None,
    principal: str = ANONYMOUS,
) -> Response:
    """Serve the result of ``job``: from the cache, or computed now (once per key) for
    ``principal`` (:func:`check_quotas` first).

    With ``hit`` (the app's hit cache, see :class:`Hit`), a hit is answered from memory as
    its pre-encoded bytes, gzip when the client accepts it.  A request the fast lane will
    run looks the store up in the lane's thread hop (:func:`_looks_up_in_lane`)."""
    key = job.key
    cache = hit.cache if hit is not None else None
    if not refresh:
        encoded = cache.get(key) if cache is not None else None
        if encoded is not None:
            return result_response(key, True, encoded, hit is not None and hit.gzip)
        if _looks_up_in_lane(runner, job):
            with _engine_errors(runner):
                answer, found = await runner.look_up_or_run(
                    job, principal=principal, cost=job_cost(job)
                )
            if found:
                return await hit_response(key, answer, hit)
            return result_response(key, False, answer)
        body = await asyncio.to_thread(store.get_result, key)
        if body is not None:
            return await hit_response(key, body, hit)
    if cache is not None:
        cache.pop(key)  # a recomputation replaces the stored result
    cost = 0.0
    if not runner.is_active(key):
        await check_request(job)
        cost = job_cost(job)
        await check_quotas(runner, store, principal, cost, queued=False)
    with _engine_errors(runner):
        await runner.admit()
        task = await runner.submit(job, force=refresh, principal=principal, cost=cost)
        body = await runner.result(task)
    return result_response(key, False, body)


async def submit_job(
    runner: Runner, store: Store, job: Keyed, refresh: bool, principal: str = ANONYMOUS
) -> Job:
    """Accept ``job`` for ``principal`` (idempotent: the id is the parameter hash) and
    return its record: a stored result finishes it at once, a computation in flight here
    is joined, anything else goes to the durable queue (:func:`check_quotas` first).  With
    API keys required, a client whose request joined another's run (the record's
    principal is not it) is granted that run (:mod:`service.http.access`)."""
    record = await _submit(runner, store, job, refresh, principal)
    if runner.settings.auth_required and record.principal != principal:
        await asyncio.to_thread(store.grant, record.key, principal, record.generation)
    return record


async def _submit(runner: Runner, store: Store, job: Keyed, refresh: bool, principal: str) -> Job:
    """:func:`submit_job` without the grant."""
    key = job.key
    if not refresh and not runner.is_active(key) and await asyncio.to_thread(store.has_result, key):
        await asyncio.to_thread(store.mark_succeeded, key, job.computation.name, job.canonical)
    elif runner.is_active(key):
        try:
            await runner.submit(job, force=refresh, principal=principal)
        except QueueFull as exc:
            raise _saturated(runner, exc) from None
    else:
        await check_request(job)
        cost = job_cost(job)
        await check_quotas(runner, store, principal, cost, queued=True)
        try:
            return await runner.enqueue(job, force=refresh, principal=principal, cost=cost)
        except QueueFull as exc:
            raise _saturated(runner, exc, "the job queue is full") from None
    record = await asyncio.to_thread(store.get_job, key)
    assert record is not None
    return record


async def accept_job(
    runner: Runner, store: Store, job: Keyed, refresh: bool, principal: str = ANONYMOUS
) -> JSONResponse:
    """:func:`submit_job`, answered 202 with the job and ``Location: /v1/jobs/{key}``."""
    return job_response(await submit_job(runner, store, job, refresh, principal), 202)
