"""The fast lane: small computations in threads of the API process instead of a Dask task.

Below ~50 ms the cross-process round trip of a Dask task (client -> scheduler -> worker ->
scheduler -> client, 10-25 ms on the 2-core machine) costs as much as the computation;
beyond, the worker's isolation (its own core and GIL, killed if it overruns) is worth it.
A lane run is :func:`service.engine.task.run_job` with this replica's store: the record,
its lease and the result as a worker writes them (a restart finds the lease stale and
recovers the job); the event loop only awaits.

The lane is on when ``fast_lane_threads`` and ``fast_lane_max_s`` are > 0; off, it takes
nothing (:meth:`FastLane.takes`) and every computation goes to a worker.  It knows nothing
of the runner: it is handed the store, the settings, this replica's id and how to build a
task's configuration.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
from collections.abc import Awaitable, Callable
from concurrent.futures import ThreadPoolExecutor
from typing import Any

from pipeflow.parallel import metered
from service import observability
from service.engine import flight as flights
from service.engine.flight import Flight
from service.engine.lifecycle import ClaimOutcome
from service.engine.outcome import Outcome, result_of
from service.engine.task import HANDED_OFF, Accept, TaskConfig, run_job
from service.keys import Keyed
from service.settings import Settings
from service.store import Claim, Job, StorageError, Store

log = logging.getLogger("service.engine")


def handed_off(job: Job) -> bool:
    """Whether the fast lane handed ``job`` off to a worker (its attempt was given back,
    so ``job.attempts`` does not show it)."""
    return (job.last_retry_reason or "").startswith(HANDED_OFF)


def run_in_lane(allowance_s: float | None, *args: Any) -> Outcome:
    """:func:`run_job` (``args``) in a thread of the fast lane; with ``allowance_s`` [s]
    its metered work is charged against it (:func:`pipeflow.parallel.metered`, a context
    variable of this thread's run only), and the work that would pass it is not started:
    the run ends ``handoff`` (:mod:`service.engine.task`)."""
    if allowance_s is None:
        return run_job(*args)
    with metered(allowance_s):
        return run_job(*args)


class _ClaimChannel:
    """How the lane's thread hands the record it wrote (its :class:`Claim`, or the
    :class:`StorageError` that refused it) to the event loop: at once through ``future``,
    or, ``quiet`` (a look-up flight), kept in ``quiet`` until the run has ended."""

    def __init__(self, loop: asyncio.AbstractEventLoop, quiet: bool) -> None:
        self.loop = loop
        self.future: asyncio.Future[Claim] = loop.create_future()
        self.quiet: list[Claim | StorageError] | None = [] if quiet else None

    def settle(self, result: Claim | StorageError) -> None:
        """In the loop: the future's result (or exception), once."""
        if self.future.done():
            return
        if isinstance(result, StorageError):
            self.future.set_exception(result)
        else:
            self.future.set_result(result)

    def on_claim(self, result: Claim | StorageError) -> None:
        """In the lane's thread (:class:`Accept`'s callback)."""
        if self.quiet is not None:
            self.quiet.append(result)
            return
        with contextlib.suppress(RuntimeError):  # the loop is closed: nobody waits
            self.loop.call_soon_threadsafe(self.settle, result)


class FastLane:
    """The lane's threads and what it counts: ``runs`` (computations it ran, tests and
    diagnostics), ``handoffs`` (of those, stopped by their allowance and sent to a
    worker), ``claimed`` (new jobs whose first attempt it claimed and computed),
    ``busy`` (threads computing now, even one abandoned past its limit)."""

    def __init__(
        self,
        settings: Settings,
        store: Store,
        replica: str,
        config: Callable[[], TaskConfig],
    ) -> None:
        self.settings = settings
        self.store = store
        self.replica = replica
        self._config = config
        self._pool: ThreadPoolExecutor | None = None
        if settings.fast_lane_threads > 0 and settings.fast_lane_max_s > 0:
            self._pool = ThreadPoolExecutor(
                settings.fast_lane_threads, thread_name_prefix="fast-lane"
            )
        self.busy = 0
        self.runs = 0
        self.handoffs = 0
        self.claimed = 0

    @property
    def on(self) -> bool:
        return self._pool is not None

    async def warm_up(self) -> None:
        """The lane's first computation must not pay the numerical stack's first use."""
        if self._pool is not None:
            from service.engine.preload import warm_up

            await asyncio.get_running_loop().run_in_executor(self._pool, warm_up)

    def shutdown(self) -> None:
        """A running lane computation is left to its thread (a daemon's fate at exit): its
        record stays active with its lease, which goes stale, and is recovered."""
        if self._pool is not None:
            self._pool.shutdown(wait=False, cancel_futures=True)

    def handed_off(self, key: str, note: str | None) -> None:
        """The driving loop saw the lane's allowance stop the run of ``key``."""
        self.handoffs += 1
        log.info("job %s handed off from the fast lane: %s", key, note)

    def takes(
        self, request: Keyed, job: Job | None, resubmits: int = 0
    ) -> tuple[bool, float | None]:
        """Whether the fast lane runs this attempt, and the allowance [s] of its metered
        work (None: not metered).  The lane must be on and have a free thread, and it must
        be the job's first attempt here (a recovered, retried or handed-off job goes to a
        worker; ``job`` None: a new record, see :meth:`first`; ``resubmits``: the
        flight's resubmissions of an abnormally ended task).  Then either

        - the computation estimates its whole run time (:attr:`Computation.run_time`) at
          most ``fast_lane_max_s``; or
        - its work of unknown cost is metered (:attr:`Computation.metered_run_time`: a
          time-variant magnus simulation, whose steps are known only as its step control
          plans them), the rest is estimated at most ``fast_lane_max_s``, and
          ``fast_lane_max_metered_s`` > 0: it runs under that allowance
          (:func:`run_in_lane`), charged each propagation's estimate before it is
          computed, and the first that would pass it stops the computation there; its
          job then goes to a worker (the driving loop: the lease given up with the
          reason, the record still active, submitted again).  An overrun is therefore
          bounded by the allowance plus the estimated rest, not only advised."""
        computation = request.computation
        if (
            self._pool is None
            or self.busy >= self.settings.fast_lane_threads
            or (job is not None and (job.attempts > 0 or handed_off(job)))
            or resubmits > 0
        ):
            return False, None
        limit = self.settings.fast_lane_max_s
        try:  # an estimate is advice: never fail a request over it
            whole = computation.run_time(request.request) if computation.run_time else None
            if whole is not None and whole <= limit:
                return True, None
            allowance = self.settings.fast_lane_max_metered_s
            if computation.metered_run_time is None or allowance <= 0:
                return False, None
            rest = computation.metered_run_time(request.request)
        except Exception:
            log.exception("estimate of %s", computation.name)
            return False, None
        return (True, allowance) if rest is not None and rest <= limit else (False, None)

    async def first(
        self, flight: Flight, force: bool
    ) -> tuple[Job | None, asyncio.Future[Outcome] | None]:
        """A new job the fast lane takes (:meth:`takes`): its record is written by the
        lane's thread already leased to the computation that starts there at once
        (:meth:`Store.enqueue_and_claim`: one transaction, one thread hop, instead of the
        record, then the lease).  Answers once the record is written, as
        :meth:`Store.enqueue_job` would: ``(None, the computation's outcome)`` when the
        lane claimed it; ``(the record, None)`` when it did not (an active record was
        there first, or the result was stored: the ordinary path goes on from it);
        ``(None, None)`` when the lane does not take it or did not start.  Raises the
        :class:`StorageError` that refused the write."""
        taken, allowance = self.takes(flight.job, None)
        if not taken:  # (a look-up flight: the lane was taken meanwhile)
            return None, await flights.look_up(self.store, flight)
        claim = _ClaimChannel(asyncio.get_running_loop(), quiet=flight.look_up)
        accept = Accept(
            flight.job.canonical,
            force,
            claim.on_claim,
            principal=flight.principal,
            cost=flight.cost,
            dispatcher=self.replica,
            look_up=flight.look_up,
        )
        try:
            run = self.run(flight, flight.key, accept, allowance)
            waiter = asyncio.ensure_future(result_of(run))
        except RuntimeError:  # the lane is shut down (the replica is stopping)
            return None, await flights.look_up(self.store, flight)
        await self._until_claimed(flight, claim, waiter)
        if not claim.future.done():  # the lane's run ended before writing anything
            claim.future.cancel()
            return None, await flights.look_up(self.store, flight)
        return await self._answer(claim.future.result(), waiter)  # (raises the StorageError)

    async def _until_claimed(
        self, flight: Flight, claim: _ClaimChannel, waiter: asyncio.Future[Outcome]
    ) -> None:
        """Until the record is written (the claim sent to the loop) or the run ends; a
        look-up flight's request waits for the run only: its claim is read once the run
        has ended, not sent mid-run (a wake-up of the event loop, contending for the GIL
        with the computation), or once the monitor flags its record (the lane's watchdog
        failed an overrun: answered now, its thread abandoned)."""
        if claim.quiet is None:
            pending: set[asyncio.Future[Any]] = {claim.future, waiter}
            await asyncio.wait(pending, return_when=asyncio.FIRST_COMPLETED)
            return
        while not waiter.done() and not claim.quiet:
            await flights.wait(flight, waiter, self.settings.stale_after_s / 4)
        if not waiter.done():
            flight.changed.set()  # the flag is the driving loop's to act on
        if claim.quiet:
            claim.settle(claim.quiet[0])

    async def _answer(
        self, claim: Claim, waiter: asyncio.Future[Outcome]
    ) -> tuple[Job | None, asyncio.Future[Outcome] | None]:
        """:meth:`first`'s answer from the lane's claim of the new record."""
        match claim.outcome:
            case ClaimOutcome.HIT:  # found stored: nothing written, nothing computed
                self.runs -= 1
                return None, waiter
            case ClaimOutcome.CLAIMED:
                self.claimed += 1
                return None, waiter
            case _:
                # it computed nothing: its thread is released before the ordinary path
                # asks for the lane again (a request joining this flight may have written
                # the record first, queued: the lane then claims it as a worker would)
                self.runs -= 1
                await waiter
                return claim.job, None

    def run(
        self,
        flight: Flight,
        key: str,
        accept: Accept | None = None,
        allowance: float | None = None,
    ) -> Awaitable[Outcome]:
        """:func:`run_job` in a thread of the fast lane, with this replica's store.  The
        lane's thread counts as busy until its computation returns, even one abandoned
        past its limit.  ``accept``: the lane writes the job's record too (:meth:`first`);
        ``allowance`` [s]: the computation's metered work is bounded by it
        (:func:`run_in_lane`).  Raises :class:`RuntimeError` when the lane is off or shut
        down."""
        if self._pool is None:
            raise RuntimeError("the fast lane is off")
        loop = asyncio.get_running_loop()
        self.busy += 1
        self.runs += 1
        try:
            fut = self._pool.submit(
                run_in_lane,
                allowance,
                flight.job.computation,
                flight.job.request,
                key,
                self._config(),
                observability.request_id(),
                self.store,
                accept,
            )
        except RuntimeError:  # shut down (the replica is stopping)
            self.busy -= 1
            self.runs -= 1
            raise

        def release(_: Any) -> None:
            with contextlib.suppress(RuntimeError):  # the loop is closed: nothing to count
                loop.call_soon_threadsafe(self._release)

        fut.add_done_callback(release)
        return asyncio.wrap_future(fut)

    def _release(self) -> None:
        self.busy -= 1
