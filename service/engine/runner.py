"""The replica's side of the engine: computations as Dask tasks, driven to a terminal job record.

:class:`Runner` is a small coordinator: it owns the engine's parts, each in a module of
its own, and wires them with callbacks (Dask's scheduler plugins and event hooks are the
model): no part imports another, and only this module imports them all.

- :mod:`~service.engine.cluster`: the Dask connection, the workers the scheduler has
  (its events, a periodic resync), the warm-up and the admission of synchronous requests;
- :mod:`~service.engine.lane`: the fast lane, small computations in threads of this
  process (off with ``fast_lane_threads=0``);
- :mod:`~service.engine.drive`: one flight's job driven to a terminal record;
- :mod:`~service.engine.dispatcher`: the durable queue, taken as workers free up;
- :mod:`~service.engine.watches`: the long polls;
- :mod:`~service.engine.monitor`: changes, heartbeats of queued jobs, the store's probe,
  stale leases recovered;

over the floor of :mod:`~service.engine.flight` (single flight: one in-flight task per
key, shared by every request for it), :mod:`~service.engine.outcome` and
:mod:`~service.engine.lifecycle` (the job and task states).

Start-up runs in the background (:meth:`Runner.start` returns at once, so liveness answers
while the cluster starts); :attr:`Runner.ready` turns true once the workers are warm, and
readiness also follows the workers the scheduler has (:attr:`Runner.no_worker`).

One computation is one Dask task (:func:`service.engine.task.run_job`) keyed by the
parameter hash (plus the job's generation and attempt): identical requests from any
replica share it.  The task owns the job record while it runs (a lease in the store), so
the replica that submitted it may die.  :meth:`Runner.submit` writes the job record, then
returns the one in-flight :class:`asyncio.Task` per key that drives it;
:meth:`Runner.enqueue` accepts an asynchronous job into the store's durable queue.

Limits: at most ``workers + queue_size`` distinct computations are in flight per replica
(:class:`QueueFull` beyond, answered with 503 to a synchronous request); at most
``max_queued_jobs`` jobs wait in the durable queue over all replicas (:class:`QueueFull`
beyond); with no worker connected a synchronous request is answered 503 too
(:class:`NoWorker`), not left waiting; a job whose computation started
:data:`MAX_ATTEMPTS` times without finishing is failed with the reason.
"""

from __future__ import annotations

import asyncio
import functools
import logging
import time
import uuid
from collections.abc import Awaitable
from typing import Any

from pydantic import BaseModel, ValidationError

from pipeflow.computations.registry import COMPUTATIONS
from service.engine import flight as flights
from service.engine.cluster import Cluster
from service.engine.dispatcher import Dispatcher
from service.engine.drive import MAX_ATTEMPTS, Driver
from service.engine.flight import Flight, Flights
from service.engine.lane import FastLane, run_in_lane
from service.engine.lifecycle import JobState
from service.engine.monitor import Monitor
from service.engine.outcome import (
    ComputationCancelled,
    ComputationFailed,
    NoWorker,
    Outcome,
    QueueFull,
    internal,
)
from service.engine.task import TaskConfig
from service.engine.watches import Watches
from service.keys import Keyed
from service.settings import Settings
from service.store import Job, StorageError, Store

log = logging.getLogger("service.engine")

#: extra time past the runtime limit before a silent computation's worker is killed [s]
WATCHDOG_GRACE_S = 5.0
#: the fast lane's run of a computation (the name its tests import from here)
_run_in_lane = run_in_lane

__all__ = [
    "MAX_ATTEMPTS",
    "WATCHDOG_GRACE_S",
    "ComputationCancelled",
    "ComputationFailed",
    "Flight",
    "NoWorker",
    "QueueFull",
    "Runner",
]


def _view(part: str, name: str, doc: str | None = None) -> Any:
    """A read-only property of the runner showing the attribute ``name`` of its ``part``."""
    return property(lambda self: getattr(getattr(self, part), name), doc=doc)


class Runner:
    """The replica's side of the engine (the name is the routes' seam: ``RunnerDep``).

    Owns: ``cluster``, ``lane``, ``flights``, ``driver``, ``dispatcher``, ``watches``,
    ``monitor`` (see the module docstring).  The seams tests use: :meth:`_execute` (one
    attempt of a job, overridden to run it elsewhere), :meth:`_config`,
    :meth:`_restore_nannies`."""

    def __init__(self, settings: Settings, store: Store) -> None:
        self.settings = settings
        self.store = store
        self._db_url = settings.db_url  # resolved once (a path resolution per task config)
        self.ready = False
        self.watchdog_grace_s = WATCHDOG_GRACE_S
        self._tasks = 0  # attempts this replica submitted (the lane's first runs apart)
        self._background: set[asyncio.Task[Any]] = set()
        #: this replica's id in the job records it drives (``dispatcher``)
        self.replica = uuid.uuid4().hex
        poll_s = min(settings.progress_interval_s, 0.5)
        self.cluster = Cluster(
            settings,
            spawn=self._spawn,
            on_worker_lost=lambda address: self.monitor.worker_lost(address),
            resynced=lambda: self._restore_nannies(),  # looked up at each call: a seam
        )
        self.lane = FastLane(settings, store, self.replica, self._config)
        self.flights = Flights(settings.workers + settings.queue_size, self._flight_ended)
        self.watches = Watches(settings, store)
        self.driver = Driver(
            settings,
            store,
            self.replica,
            connected=self.cluster.connected,
            first=self._first,
            submit=self._submit_task,
            ended=self.watches.changed,
            handed_off=self.lane.handed_off,
            fail_later=lambda key, doc: self.monitor.fail_later(key, doc),
            poll_s=poll_s,
        )
        self.dispatcher = Dispatcher(
            settings,
            store,
            self.replica,
            connected=self.cluster.connected,
            free_slots=lambda: self.free_slots,
            drive=functools.partial(self._recover, why="dispatching"),
            poll_s=poll_s,
        )
        self.monitor = Monitor(
            settings,
            store,
            self.flights,
            watched=self.watches.keys,
            ended=self.watches.changed,
            requeued=self.dispatcher.kick,
            recover=self._recover,
            poll_s=poll_s,
        )

    # -- lifecycle -----------------------------------------------------------------------

    async def start(self) -> None:
        """Start the engine in the background and return at once (liveness answers during
        start-up): the cluster (started, or connected to), then the recovery of jobs left
        active, the monitor, the warm-up (:attr:`ready`) and the worker tracking."""
        self._spawn(self._start())

    async def _start(self) -> None:
        await self.cluster.start()
        self._spawn(self._warm_up())
        pruned = await asyncio.to_thread(
            self.store.prune_jobs, time.time() - self.settings.job_retention_s
        )
        if pruned:
            log.info("pruned %d old job records", pruned)
        # the disk bound's running total, recounted once (drift of writers of an older version)
        await asyncio.to_thread(self.store.recount_results)
        for job in await asyncio.to_thread(self.store.active_jobs):
            # a job no attempt started (waiting, or taken by a replica that has not started
            # it) is the dispatcher's, in its turn (the monitor puts the latter back in the
            # queue once its replica is stale): not driven here beyond this replica's slots
            if job.status == JobState.RUNNING:
                await self._recover(job)
        self._spawn(self.monitor.run())
        self._spawn(self.dispatcher.run())

    async def _warm_up(self) -> None:
        """Ready once the workers (:meth:`Cluster.warm_up`) and the fast lane are warm."""
        await self.cluster.warm_up(self._config())
        await self.lane.warm_up()
        self.ready = True

    async def stop(self) -> None:
        for task in list(self._background):
            task.cancel()
        self.flights.stop()  # records stay active: a live replica recovers them
        self.ready = False
        self.lane.shutdown()
        await self.cluster.close()

    def _spawn(self, coro: Any) -> None:
        task = asyncio.create_task(coro)
        self._background.add(task)
        task.add_done_callback(self._background.discard)

    def _restore_nannies(self) -> None:
        """After each resync of the workers: the embedded cluster's closed nannies are
        started again (:meth:`Cluster.restore_nannies`)."""
        self.cluster.restore_nannies()

    def _config(self) -> TaskConfig:
        s = self.settings
        return TaskConfig(
            db_url=self._db_url,
            cache_max_bytes=s.cache_max_bytes,
            timeout_s=s.job_timeout_s,
            progress_interval_s=s.progress_interval_s,
            stale_after_s=s.stale_after_s,
            grace_s=max(self.watchdog_grace_s, 0.1 * s.job_timeout_s),
            checkpoint_interval_s=s.checkpoint_interval_s,
            checkpoint_max_bytes=s.checkpoint_max_bytes,
        )

    # -- admission and state (the cluster's, the flights') ---------------------------------

    async def admit(self) -> None:
        """Raise :class:`NoWorker` unless a worker can take a synchronous computation."""
        await self.cluster.admit()

    async def result(self, task: asyncio.Task[bytes]) -> bytes:
        """The body ``task`` ends with, for a synchronous request (:meth:`Cluster.result`:
        :class:`NoWorker` once the scheduler has had no worker for a grace period)."""
        return await self.cluster.result(task)

    async def call(self, fn: Any, *args: Any) -> Any:
        """Run a picklable function on a worker (tests and diagnostics)."""
        return await self.cluster.call(fn, *args)

    @property
    def workers(self) -> int:
        """Workers connected to the scheduler now (0 before the cluster is connected)."""
        return self.cluster.workers

    @property
    def no_worker(self) -> bool:
        """Connected to an external scheduler that has no worker (:attr:`Cluster.no_worker`)."""
        return self.cluster.no_worker

    @property
    def capacity(self) -> int:
        return self.flights.capacity

    @property
    def in_flight(self) -> int:
        return len(self.flights)

    @property
    def saturated(self) -> bool:
        return self.flights.saturated

    def is_active(self, key: str) -> bool:
        return key in self.flights

    @property
    def free_slots(self) -> int:
        """Computations the dispatcher may start now: a worker each, less those in flight
        (synchronous requests' included; they may use ``queue_size`` more)."""
        return max(self.workers, 1) - len(self.flights)

    # -- submission ----------------------------------------------------------------------

    async def submit(
        self,
        job: Keyed,
        *,
        force: bool = False,
        recover: bool = False,
        principal: str | None = None,
        cost: float = 0.0,
    ) -> asyncio.Task[bytes]:
        """The in-flight task for ``job.key``, started if needed, once its record is written.

        ``force`` recomputes even if a result is stored; ``recover`` drives a record that
        is already active and bypasses the bound; ``principal`` and ``cost`` (in units of
        the kind's cost bound) go on a record this call writes.  A run that a DELETE asked to stop
        (:meth:`cancel`) is never shared: the resubmission waits until it has stopped (its
        task checks the flag at its next heartbeat), then starts a new run.
        Raises :class:`QueueFull`, or :class:`StorageError` when the store is failing.
        """
        flight = await self._flight(job, force, recover, principal, cost)
        assert flight.task is not None
        return flight.task

    async def _flight(
        self,
        job: Keyed,
        force: bool,
        recover: bool,
        principal: str | None,
        cost: float,
        look_up: bool = False,
    ) -> Flight:
        """:meth:`submit`: the flight of ``job.key`` (``look_up``: a new one looks the
        result up first, see :meth:`look_up_or_run`)."""
        key = job.key
        if not recover and not self.store.healthy:
            raise self.store.unavailable()  # its result could not be stored either
        await self.flights.cancelled_gone(key)
        flight = self.flights.get(key)
        if flight is None and not recover and self.flights.saturated:
            await self.monitor.release_finished()
            flight = self.flights.get(key)
        if flight is None:
            if not recover and self.flights.saturated:
                raise QueueFull(f"{self.in_flight} computations in flight")
            new = Flight(job, principal=principal, cost=cost, look_up=look_up)
            flight = self.flights.start(
                new, lambda f: self.driver.drive(f, force=force, recover=recover)
            )
        elif not recover and not flight.hit:
            # joining (a flight that found its result stored answers from it: no write)
            await self.driver.join(flight, job, force, principal, cost)
        await flight.accepted.wait()
        assert flight.task is not None
        if flight.task.done() and not flight.task.cancelled():
            exc = flight.task.exception()
            if isinstance(exc, StorageError):
                raise exc
        return flight

    def looks_up_in_lane(self, job: Keyed) -> bool:
        """Whether a synchronous request's cache lookup of ``job`` can be the first step of
        its fast-lane run (:meth:`look_up_or_run`): the engine is up with a worker, the
        store healthy, a slot free, no flight of the key here, and the lane would take a
        new record of it now (:meth:`FastLane.takes`).  Any of these false, the lookup is
        its own thread hop as before (a hit must be answered whatever the engine's state,
        and a miss goes the ordinary way)."""
        return (
            self.cluster.connected.is_set()
            and not self.no_worker
            and self.store.healthy
            and not self.saturated
            and job.key not in self.flights
            and self.lane.takes(job, None)[0]
        )

    async def look_up_or_run(
        self, job: Keyed, *, principal: str | None = None, cost: float = 0.0
    ) -> tuple[bytes, bool]:
        """The body of ``job`` and whether it was stored already (a hit): the store's
        lookup and, on a miss, the record and the computation, in one thread hop of the
        fast lane (:class:`service.engine.task.Accept` ``look_up``) instead of a hop for
        the lookup, then one for the lane.  A hit writes nothing (no record), as the
        route's own lookup.  Call only when :meth:`looks_up_in_lane` (the lane may still
        be taken meanwhile: the lookup then runs in its own hop first)."""
        flight = await self._flight(job, False, False, principal, cost, look_up=True)
        assert flight.task is not None
        body = await self.result(flight.task)
        return body, flight.hit

    def cancel(self, key: str) -> None:
        """Mark the run of ``key`` (if any) as asked to stop; see :meth:`submit`.  The job
        record's cancel flag, which the task reads, is set by the caller."""
        self.flights.cancel(key)

    def _flight_ended(self, flight: Flight, freed: bool) -> None:
        if freed:  # a slot is free: the dispatcher may take a waiting job
            self.dispatcher.slot_freed()
        self.job_changed(flight.key)

    async def _first(
        self, flight: Flight, force: bool
    ) -> tuple[Job | None, asyncio.Future[Outcome] | None]:
        """A new job's first step (the driver's ``first``): the fast lane's, if it is on;
        else a look-up flight's lookup (:func:`service.engine.flight.look_up`)."""
        if self.lane.on:
            return await self.lane.first(flight, force)
        return None, await flights.look_up(self.store, flight)

    def _submit_task(self, flight: Flight, job: Job) -> Awaitable[Outcome]:
        """Start the task of ``job`` (the driver's ``submit``) and count it."""
        self._tasks += 1
        return self._execute(flight, job)

    def _execute(self, flight: Flight, job: Job) -> Awaitable[Outcome]:
        """One attempt of ``job``: in the fast lane if it takes it, else a Dask task (the
        seam tests replace to run it elsewhere)."""
        taken, allowance = self.lane.takes(flight.job, job, flight.resubmits)
        if taken:
            return self.lane.run(flight, job.key, allowance=allowance)
        dask_key = f"{job.kind}-{job.key}-g{job.generation}-a{job.attempts}"
        if flight.resubmits:
            dask_key += f"-r{flight.resubmits}"
        return self.cluster.submit(flight.job, job.key, dask_key, self._config(), self.job_changed)

    async def _recover(self, job: Job, why: str = "recovering") -> None:
        """Drive the active record ``job`` (found at start, stale, or taken from the
        queue): its request is validated again from the stored spec."""
        computation = COMPUTATIONS.get(job.kind)
        try:
            if computation is None:
                raise LookupError(f"unknown job kind {job.kind!r} after restart")
            # a stored request is validated like a new one (once, for this run)
            request: BaseModel = computation.request.model_validate(job.spec)
        except (LookupError, ValidationError) as exc:
            await asyncio.to_thread(
                self.store.finish_job, job.key, JobState.FAILED, internal(str(exc))
            )
            return
        log.info("%s %s job %s (%s)", why, job.kind, job.key, job.status)
        await self.submit(Keyed(computation, request, job.spec, job.key), recover=True)

    # -- the durable queue and the long polls --------------------------------------------

    async def enqueue(
        self, job: Keyed, *, force: bool = False, principal: str | None = None, cost: float = 0.0
    ) -> Job:
        """Accept ``job`` into the store's durable queue (:meth:`Dispatcher.enqueue`)."""
        return await self.dispatcher.enqueue(job, force=force, principal=principal, cost=cost)

    def job_changed(self, key: str) -> None:
        """Wake the long polls of job ``key`` (its record may have ended): a flight of this
        replica ended or saw its task finish, a DELETE cancelled it, or the monitor read it
        ended (another replica's run, or a job nobody here drives)."""
        self.watches.changed(key)

    async def wait_job(self, job: Job, wait_s: float) -> Job:
        """``GET /v1/jobs/{key}?wait=``: ``job``'s record once it is no longer active, or as
        it is after ``wait_s`` [s] (:meth:`Watches.wait`)."""
        return await self.watches.wait(job, wait_s)

    # -- what tests and diagnostics read (the parts' own state) ---------------------------

    @property
    def poll_s(self) -> float:
        """How often the dispatcher and the monitor look [s]."""
        return self.dispatcher.poll_s

    @poll_s.setter
    def poll_s(self, value: float) -> None:
        self.dispatcher.poll_s = self.monitor.poll_s = self.driver.poll_s = value

    @property
    def embedded_no_worker_grace_s(self) -> float:
        return self.cluster.embedded_no_worker_grace_s

    @embedded_no_worker_grace_s.setter
    def embedded_no_worker_grace_s(self, value: float) -> None:
        self.cluster.embedded_no_worker_grace_s = value

    @property
    def computations(self) -> int:
        """Computations this replica started (Dask tasks and lane runs; single flight)."""
        return self._tasks + self.lane.claimed

    # read-only views of the parts' state, under the names tests and diagnostics use
    client = _view("cluster", "client")
    nannies_restored = _view("cluster", "nannies_restored")
    lane_runs = _view("lane", "runs")
    lane_handoffs = _view("lane", "handoffs")
    dispatched = _view("dispatcher", "dispatched")
    waiting = _view("watches", "waiting", "long polls held open now")
    _connected = _view("cluster", "connected")
    _cluster = _view("cluster", "cluster")
    _flights = _view("flights", "table")
    _lane_busy = _view("lane", "busy")
    _watches = _view("watches", "by_key")
    _drained = _view("dispatcher", "drained")
