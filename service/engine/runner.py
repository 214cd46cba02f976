"""The replica's side of the engine: computations as Dask tasks, driven to a terminal job record.

Embedded mode (default): the app's lifespan starts a ``distributed.LocalCluster`` of
``PIPEFLOW_WORKERS`` worker processes (one thread and one BLAS thread each).  Distributed
mode: ``PIPEFLOW_SCHEDULER_ADDRESS=tcp://host:8786`` makes the service a client of an
existing cluster (``dask scheduler`` + ``dask worker --nthreads 1 --preload-nanny
service.engine.preload``), ``tls://`` with Dask's TLS configuration (:mod:`service.tls`).

Start-up runs in the background (:meth:`Runner.start` returns at once, so liveness answers
while the cluster starts); :attr:`Runner.ready` turns true once the workers are warm, and
readiness also follows the workers the scheduler has (:attr:`Runner.no_worker`): Dask's own
worker events (``remove-worker``) update it at once, and end the lease of the jobs that
worker ran, so they are taken over without waiting for ``stale_after_s``.

One computation is one Dask task (:func:`service.engine.task.run_job`) keyed by the
parameter hash (plus the job's generation and attempt): identical requests from any
replica share it.  The task owns the job record while it runs (a lease in the store), so
the replica that submitted it may die.  Here, per replica:

- :meth:`Runner.submit` writes the job record, then returns the one in-flight
  :class:`asyncio.Task` per key that drives it to a terminal state (single flight);
- a monitor loop wakes flights whose job finished or was cancelled, keeps the heartbeat
  of queued jobs this replica waits for, probes a failed store until it is writable
  again, and resubmits any job whose heartbeat went stale (its worker, its replica or the
  scheduler died): nothing accepted is lost.

- :meth:`Runner.enqueue` accepts an asynchronous job into the store's durable queue (a
  record nobody drives yet) and wakes the dispatcher, a loop that takes the next waiting
  jobs (:meth:`Store.claim_waiting`: in order, fairly between clients, never one job by
  two replicas) whenever this replica has fewer computations in flight than workers, and
  drives them as :meth:`submit` does.  A queued job survives any restart: it is a row.

Limits: at most ``workers + queue_size`` distinct computations are in flight per replica
(:class:`QueueFull` beyond, answered with 503 to a synchronous request); at most
``max_queued_jobs`` jobs wait in the durable queue over all replicas (:class:`QueueFull`
beyond); with no worker connected a synchronous request is answered 503 too
(:class:`NoWorker`), not left waiting; a job whose computation started
:data:`MAX_ATTEMPTS` times without finishing is failed with the reason.
"""

from __future__ import annotations

import asyncio
import contextlib
import functools
import logging
import time
import uuid
from collections.abc import Awaitable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from typing import Any

from pydantic import BaseModel, ValidationError

from pipeflow.computations.registry import COMPUTATIONS
from pipeflow.errors import ErrorRecord, StorageError
from pipeflow.parallel import metered
from service import observability
from service.engine.preload import MODULE as PRELOAD
from service.engine.task import HANDED_OFF, Accept, Outcome, TaskConfig, run_job
from service.keys import Keyed
from service.settings import Settings
from service.store import Claim, Job, Store

log = logging.getLogger("service.engine")

#: extra time past the runtime limit before a silent computation's worker is killed [s]
WATCHDOG_GRACE_S = 5.0
#: starts of one computation (worker deaths under it) before its job is failed
MAX_ATTEMPTS = 3
#: bound on the warm-up tasks of the workers at start [s]
WARM_UP_TIMEOUT_S = 60.0
#: how often the warm-up looks whether each worker is warm or busy [s]
WARM_UP_POLL_S = 0.1
#: how often the workers the scheduler has are read again (besides its events) [s]
WORKERS_RESYNC_S = 2.0
#: a synchronous request waits at most this long for a worker to join the scheduler [s]
NO_WORKER_GRACE_S = 5.0
#: the same for the embedded cluster, whose nannies restart a dead worker (the watchdog's
#: kill, a crash): such a restart took 38 s at load average 15 on the 2-core machine [s]
EMBEDDED_NO_WORKER_GRACE_S = 60.0


class NoWorker(Exception):
    """No worker can take a computation now (the engine is starting, or the scheduler has
    none); answered 503 with Retry-After to a synchronous request."""


class QueueFull(Exception):
    """No room for another computation."""


class ComputationFailed(Exception):
    """The computation ended in a failure; ``error`` is what its job record says (an
    :class:`~pipeflow.errors.ErrorRecord` as JSON, see :meth:`ErrorRecord.to_dict`)."""

    def __init__(self, error: dict[str, Any]) -> None:
        record = ErrorRecord.from_dict(error)
        super().__init__(record.message if record is not None else error.get("detail", "failed"))
        self.error = error


class ComputationCancelled(Exception):
    """The computation was cancelled (DELETE on its job)."""


@dataclass
class Flight:
    job: Keyed
    task: asyncio.Task[bytes] | None = None
    accepted: asyncio.Event = field(default_factory=asyncio.Event)
    changed: asyncio.Event = field(default_factory=asyncio.Event)
    resubmits: int = 0
    #: a DELETE asked this run to stop: a resubmission waits for it and starts a new run
    cancelled: bool = False
    #: how long the last finished attempt computed [s] (for the computation metrics)
    seconds: float | None = None
    #: who asked, and the estimated cost: written on the record this flight creates
    principal: str | None = None
    cost: float = 0.0
    #: the request's cache lookup is this flight's first step (:meth:`Runner.look_up_or_run`)
    look_up: bool = False
    #: ... and it found the result stored: the body is a hit, no record was written
    hit: bool = False
    #: another request joined this flight (its record may have been written by it)
    joined: bool = False

    @property
    def key(self) -> str:
        return self.job.key


@dataclass
class _Watch:
    """The long polls waiting for one job's end: set once, by :meth:`Runner.job_changed`."""

    ended: asyncio.Event = field(default_factory=asyncio.Event)
    waiters: int = 0


def _internal(message: str) -> dict[str, Any]:
    """A job record's error: the engine failed (not the computation)."""
    return ErrorRecord.internal(message).to_dict()


def _handed_off(job: Job) -> bool:
    """Whether the fast lane handed ``job`` off to a worker (its attempt was given back,
    so ``job.attempts`` does not show it)."""
    return (job.last_retry_reason or "").startswith(HANDED_OFF)


def _run_in_lane(allowance_s: float | None, *args: Any) -> Outcome:
    """:func:`run_job` (``args``) in a thread of the fast lane; with ``allowance_s`` [s]
    its metered work is charged against it (:func:`pipeflow.parallel.metered`, a context
    variable of this thread's run only), and the work that would pass it is not started:
    the run ends ``handoff`` (:mod:`service.engine.task`)."""
    if allowance_s is None:
        return run_job(*args)
    with metered(allowance_s):
        return run_job(*args)


class Runner:
    """The replica's side of the engine (the name is the routes' seam: ``RunnerDep``)."""

    def __init__(self, settings: Settings, store: Store) -> None:
        self.settings = settings
        self.store = store
        self._db_url = settings.db_url  # resolved once (a path resolution per task config)
        self.capacity = settings.workers + settings.queue_size
        self.computations = 0  # Dask tasks this replica submitted (tests check single flight)
        self.ready = False
        self.watchdog_grace_s = WATCHDOG_GRACE_S
        self.embedded_no_worker_grace_s = EMBEDDED_NO_WORKER_GRACE_S
        self.nannies_restored = 0  # embedded nannies Dask closed and this runner replaced
        self._restoring: asyncio.Future[Any] | None = None  # their start, while it runs
        self.client: Any = None
        self._cluster: Any = None
        self._connected = asyncio.Event()
        # the scheduler's workers (addresses), followed once connected (_track_workers)
        self._worker_set: set[str] = set()
        self._tracking = False
        self._flights: dict[str, Flight] = {}
        self._background: set[asyncio.Task[Any]] = set()
        # jobs to fail with their storage error once the store takes writes again
        self._pending_failures: dict[str, dict[str, Any]] = {}
        self.poll_s = min(settings.progress_interval_s, 0.5)
        # the fast lane: small computations in threads of this process (see _lane_takes)
        self._lane: ThreadPoolExecutor | None = None
        if settings.fast_lane_threads > 0 and settings.fast_lane_max_s > 0:
            self._lane = ThreadPoolExecutor(
                settings.fast_lane_threads, thread_name_prefix="fast-lane"
            )
        self._lane_busy = 0
        self.lane_runs = 0  # computations the fast lane ran (tests, diagnostics)
        self.lane_handoffs = 0  # of those, stopped by their allowance and sent to a worker
        #: this replica's id in the job records it drives (``dispatcher``)
        self.replica = uuid.uuid4().hex
        self._kick = asyncio.Event()  # wakes the dispatcher (a job queued, a flight ended)
        #: the dispatcher's last look found no job it could take waiting (it had slots to
        #: spare): a flight that ends does not wake it (see :meth:`_done`)
        self._drained = False
        self._dispatching = asyncio.Lock()
        self.dispatched = 0  # jobs this replica took from the durable queue (tests)
        # long polls (GET /v1/jobs/{key}?wait=): per watched key, the event its end sets
        self._watches: dict[str, _Watch] = {}
        self.waiting = 0  # long polls held open now (bounded by max_job_waiters)

    # -- lifecycle -----------------------------------------------------------------------

    async def start(self) -> None:
        """Start the engine in the background and return at once (liveness answers during
        start-up): the cluster (started, or connected to), then the recovery of jobs left
        active, the monitor, the warm-up (:attr:`ready`) and the worker tracking."""
        self._spawn(self._start())

    async def _start(self) -> None:
        while True:
            try:
                await self._connect()
                break
            except asyncio.CancelledError:
                raise
            except Exception as exc:
                log.error(
                    "could not start the engine (%s: %s); again in %d s",
                    type(exc).__name__,
                    exc,
                    self.settings.retry_after_s,
                )
                await self._close_cluster()
                await asyncio.sleep(self.settings.retry_after_s)
        self.client.subscribe_topic("all", self._on_cluster_event)
        await self._read_workers()
        self._tracking = True
        self._spawn(self._track_workers())
        self._connected.set()
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
            if job.status == "running":
                await self._recover(job)
        self._spawn(self._monitor())
        self._spawn(self._dispatch())

    async def _connect(self) -> None:
        """Start the embedded cluster, or connect to the scheduler; then the client."""
        from distributed import Client, LocalCluster

        address = self.settings.scheduler_address
        if address:
            # Dask's configuration gives the TLS files of a tls:// address (service.tls)
            self.client = await Client(address, asynchronous=True, timeout="60s")
            return
        self._cluster = LocalCluster(
            n_workers=self.settings.workers,
            threads_per_worker=1,
            processes=True,
            # the scheduler always serves HTTP (health, metrics); no dashboard, and a free
            # localhost port instead of 8787, which a second server on the host would hold
            dashboard_address="127.0.0.1:0",
            scheduler_kwargs={"dashboard": False},
            asynchronous=True,
            env={
                "PIPEFLOW_LOG_LEVEL": self.settings.log_level,
                "PIPEFLOW_LOG_FORMAT": self.settings.log_format,
            },
            # the one preload of every worker (its nanny sets the worker's environment)
            preload_nanny=[PRELOAD],
            silence_logs=logging.WARNING,
        )
        await self._cluster
        self.client = await Client(self._cluster, asynchronous=True)

    async def _close_cluster(self) -> None:
        for closing in (self.client, self._cluster):
            if closing is not None:
                with contextlib.suppress(Exception):
                    await asyncio.wait_for(closing.close(), 10)
        self.client = self._cluster = None

    async def stop(self) -> None:
        for task in list(self._background):
            task.cancel()
        for flight in list(self._flights.values()):
            if flight.task is not None:
                flight.task.cancel()  # records stay active: a live replica recovers them
        self.ready = False
        if self._lane is not None:
            # a running lane computation is left to its thread (a daemon's fate at exit):
            # its record stays active with its lease, which goes stale, and is recovered
            self._lane.shutdown(wait=False, cancel_futures=True)
        await self._close_cluster()

    def _spawn(self, coro: Any) -> None:
        task = asyncio.create_task(coro)
        self._background.add(task)
        task.add_done_callback(self._background.discard)

    async def _warm_up(self) -> None:
        """Ready once a worker is connected (the embedded cluster: all of them) and each
        connected worker ran :func:`service.engine.preload.warm_task` or is busy with a
        computation (a recovered job: readiness does not wait for it).  A failure there is
        logged: the first job then pays for it."""
        wanted = 1 if self.settings.scheduler_address else self.settings.workers
        await self.client.wait_for_workers(wanted)
        try:
            await asyncio.wait_for(self._warm_workers(), WARM_UP_TIMEOUT_S)
        except Exception as exc:
            log.warning("worker warm-up task failed: %s: %s", type(exc).__name__, exc)
        if self._lane is not None:
            # the lane's first computation must not pay the numerical stack's first use
            from service.engine.preload import warm_up

            await asyncio.get_running_loop().run_in_executor(self._lane, warm_up)
        self.ready = True

    async def _warm_workers(self) -> None:
        """Send each worker its warm-up task (ahead of queued computations: high
        priority) and wait until each worker ran it or is computing something else."""
        from service.engine.preload import warm_task

        cfg = self._config()
        identity = await self.client.scheduler.identity(n_workers=-1)
        self._worker_set |= set(identity.get("workers", {}))
        warm: dict[str, Any] = {
            address: self.client.submit(
                warm_task,
                cfg,
                workers=[address],
                allow_other_workers=False,
                pure=False,
                priority=1_000_000,
                key=f"warm-up-{uuid.uuid4().hex}",
            )
            for address in identity.get("workers", {})
        }
        while True:
            pending = {a: f for a, f in warm.items() if not f.done()}
            for future in warm.values():
                if future.status == "error":
                    await future  # raises the worker's error
            if not pending:
                return
            processing = await self.client.processing(workers=list(pending))
            busy = {
                address
                for address, keys in processing.items()
                if any(not str(key).startswith("warm-up-") for key in keys)
            }
            if all(address in busy or address not in self._worker_set for address in pending):
                log.info("warm-up left to %d busy worker(s)", len(pending))
                return
            await asyncio.sleep(WARM_UP_POLL_S)

    # -- the workers the scheduler has ------------------------------------------------------

    @property
    def workers(self) -> int:
        """Workers connected to the scheduler now (0 before the cluster is connected)."""
        return len(self._worker_set)

    @property
    def no_worker(self) -> bool:
        """The engine is connected to an external scheduler that has no worker.  Never for
        the embedded cluster: its nannies restart a worker that died (a crash, the
        watchdog's kill), which under load takes tens of seconds without any worker."""
        return self._tracking and self._cluster is None and not self._worker_set

    async def _track_workers(self) -> None:
        """Follow the scheduler's workers: its ``add-worker`` / ``remove-worker`` events at
        once, and a full read every :data:`WORKERS_RESYNC_S` (events missed across a
        scheduler restart; an unreachable scheduler counts as no worker); the embedded
        cluster's lost nannies are replaced at the same pace (:meth:`_restore_nannies`)."""
        while True:
            await asyncio.sleep(WORKERS_RESYNC_S)
            await self._read_workers()
            try:
                self._restore_nannies()
            except Exception:
                log.exception("restoring the embedded cluster's workers")

    def _restore_nannies(self) -> None:
        """Give the embedded cluster back the nannies Dask closed: a nanny restarts its
        worker when the process dies (the watchdog's kill), but the cluster closes the
        nanny itself when no worker of that name has registered again within
        ``distributed.deploy.lost-worker-timeout`` (15 s): under load (a restart took 38 s
        at load average 15) the cluster was left with no worker and no nanny for good,
        and every computation after it waited forever (the queued Dask task, its record
        queued and heartbeated by this replica).  A nanny missing from the cluster's
        workers, or closed, is started again from its spec."""
        from distributed.core import Status

        cluster = self._cluster
        if cluster is None or cluster.status != Status.running:
            return
        gone = (Status.closing, Status.closed, Status.failed)
        lost = [
            name
            for name in cluster.worker_spec
            if name not in cluster.workers or cluster.workers[name].status in gone
        ]
        if not lost or (self._restoring is not None and not self._restoring.done()):
            return  # a start in progress is not in ``cluster.workers`` until it is up
        log.warning("the embedded cluster closed the nanny of worker(s) %s: started again", lost)
        for name in lost:
            cluster.workers.pop(name, None)
        self.nannies_restored += len(lost)
        # what SpecCluster.scale runs (the spec is unchanged), but with the task to wait on
        self._restoring = asyncio.ensure_future(cluster._correct_state())
        self._restoring.add_done_callback(lambda f: f.cancelled() or f.exception())

    async def _read_workers(self) -> None:
        try:
            identity = await asyncio.wait_for(self.client.scheduler.identity(n_workers=-1), 10)
            self._worker_set = set(identity.get("workers", {}))
        except asyncio.CancelledError:
            raise
        except Exception:
            self._worker_set = set()

    def _on_cluster_event(self, event: tuple[float, Any]) -> None:
        msg = event[1]
        if not isinstance(msg, dict) or "worker" not in msg:
            return
        address = str(msg["worker"])
        if msg.get("action") == "add-worker":
            self._worker_set.add(address)
        elif msg.get("action") == "remove-worker":
            self._worker_set.discard(address)
            self._spawn(self._worker_lost(address))

    async def _worker_lost(self, address: str) -> None:
        """Dask's worker-loss signal: the leases of the jobs that worker was running end
        now (their computation is taken over at once, by Dask's rescheduled task or a
        replica's recovery) instead of after ``stale_after_s`` without heartbeat."""
        try:
            keys = await asyncio.to_thread(
                self.store.expire_leases, address, time.time() - self.settings.stale_after_s
            )
        except StorageError:
            return  # the stale timeout recovers them
        if keys:
            log.warning("worker %s left: %d job lease(s) ended", address, len(keys))
            for key in keys:
                flight = self._flights.get(key)
                if flight is not None:
                    flight.changed.set()

    async def admit(self) -> None:
        """Raise :class:`NoWorker` unless a worker can take a synchronous computation: the
        engine's start is waited for (the embedded cluster's up to
        :data:`WARM_UP_TIMEOUT_S`; a scheduler that cannot be reached yet, up to
        :data:`NO_WORKER_GRACE_S`), then the scheduler must have a worker."""
        if not self._connected.is_set():
            embedded = not self.settings.scheduler_address
            limit = WARM_UP_TIMEOUT_S if embedded else NO_WORKER_GRACE_S
            with contextlib.suppress(TimeoutError):
                await asyncio.wait_for(self._connected.wait(), limit)
            if not self._connected.is_set():
                raise NoWorker("the engine is starting")
        if self.no_worker:
            raise NoWorker("the scheduler has no worker")

    async def result(self, task: asyncio.Task[bytes]) -> bytes:
        """The body ``task`` ends with, for a synchronous request: :class:`NoWorker` once
        the scheduler has had no worker for :data:`NO_WORKER_GRACE_S` (the embedded
        cluster: ``embedded_no_worker_grace_s``, its nannies restart a dead worker; the
        job stays accepted and runs when a worker joins; the task is never cancelled
        here)."""
        shielded = asyncio.shield(task)
        since: float | None = None
        grace = NO_WORKER_GRACE_S if self._cluster is None else self.embedded_no_worker_grace_s
        while True:
            done, _ = await asyncio.wait({shielded}, timeout=0.25)
            if done:
                return shielded.result()
            if not self._tracking or self._worker_set:
                since = None
            elif since is None:
                since = time.monotonic()
            elif time.monotonic() - since >= grace:
                # the flight goes on; its outcome is read by whoever waits for it next
                shielded.add_done_callback(lambda f: f.cancelled() or f.exception())
                raise NoWorker("the scheduler lost its workers during the computation")

    async def call(self, fn: Any, *args: Any) -> Any:
        """Run a picklable function on a worker (tests and diagnostics)."""
        return await self.client.submit(fn, *args, pure=False)

    # -- state ---------------------------------------------------------------------------

    @property
    def in_flight(self) -> int:
        return len(self._flights)

    @property
    def saturated(self) -> bool:
        return len(self._flights) >= self.capacity

    def is_active(self, key: str) -> bool:
        return key in self._flights

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
        while (old := self._flights.get(key)) is not None and old.cancelled:
            assert old.task is not None
            with contextlib.suppress(Exception, asyncio.CancelledError):
                await asyncio.shield(old.task)
            if self._flights.get(key) is old:  # its done-callback has not run yet
                del self._flights[key]
        flight = self._flights.get(key)
        if flight is None and not recover and self.saturated:
            await self._release_finished()
            flight = self._flights.get(key)
        if flight is None:
            if not recover and self.saturated:
                raise QueueFull(f"{self.in_flight} computations in flight")
            flight = Flight(job, principal=principal, cost=cost, look_up=look_up)
            self._flights[key] = flight
            flight.task = asyncio.create_task(self._drive(flight, force, recover))
            flight.task.add_done_callback(functools.partial(self._done, flight))
        elif not recover and not flight.hit:
            # (a flight that found its result stored answers from it: nothing to write)
            # joining: a finished record is accepted again (a new generation), but for a
            # run that has just stored its result (a request that missed the store a moment
            # before it was written: the flight answers it; resetting would compute twice)
            flight.joined = True
            name = job.computation.name
            await asyncio.to_thread(
                functools.partial(
                    self.store.enqueue_job,
                    key,
                    name,
                    job.canonical,
                    refresh=force,
                    keep_stored=not force,
                    principal=principal,
                    cost=cost,
                    dispatcher=self.replica,
                )
            )
            flight.changed.set()
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
        new record of it now (:meth:`_lane_takes`).  Any of these false, the lookup is
        its own thread hop as before (a hit must be answered whatever the engine's state,
        and a miss goes the ordinary way)."""
        return (
            self._connected.is_set()
            and not self.no_worker
            and self.store.healthy
            and not self.saturated
            and job.key not in self._flights
            and self._lane_takes(job, None)[0]
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

    async def _release_finished(self, wait_s: float = 1.0) -> None:
        """Free the slots of flights whose job record has already ended (e.g. failed by a
        worker's watchdog) without waiting for the monitor's next tick: wake them and give
        them up to ``wait_s`` [s] to leave.  A store that cannot be read frees nothing."""
        keys = list(self._flights)
        try:
            records = await asyncio.to_thread(self.store.jobs_by_key, keys)
        except StorageError:
            return
        ended = []
        for key in keys:
            job, flight = records.get(key), self._flights.get(key)
            if (
                flight is not None
                and flight.task is not None
                and job is not None
                and not job.active
            ):
                flight.changed.set()
                ended.append(flight.task)
        if ended:
            await asyncio.wait(ended, timeout=wait_s)

    def cancel(self, key: str) -> None:
        """Mark the run of ``key`` (if any) as asked to stop; see :meth:`submit`.  The job
        record's cancel flag, which the task reads, is set by the caller."""
        flight = self._flights.get(key)
        if flight is not None:
            flight.cancelled = True
            flight.changed.set()

    def _done(self, flight: Flight, task: asyncio.Task[bytes]) -> None:
        if self._flights.get(flight.key) is flight:
            del self._flights[flight.key]
            if not self._drained:  # a slot is free: the dispatcher may take a waiting job
                self._kick.set()
        self.job_changed(flight.key)
        if not task.cancelled():
            task.exception()  # retrieved here so an unobserved job failure is not logged twice

    # -- long polls: waiting for a job's end ------------------------------------------------

    def job_changed(self, key: str) -> None:
        """Wake the long polls of job ``key`` (its record may have ended): a flight of this
        replica ended or saw its task finish, a DELETE cancelled it, or the monitor read it
        ended (another replica's run, or a job nobody here drives)."""
        watch = self._watches.pop(key, None)
        if watch is not None:
            watch.ended.set()

    async def wait_job(self, job: Job, wait_s: float) -> Job:
        """``job``'s record once it is no longer active (succeeded, failed, cancelled), or as
        it is after ``wait_s`` [s] (cut to the ``max_job_wait_s`` setting):
        ``GET /v1/jobs/{key}?wait=``.  No busy loop and no thread held: the wait is an event
        set by :meth:`job_changed`, after which the record is read again (a spurious wake-up
        waits on for the rest of ``wait_s``).  At most ``max_job_waiters`` such waits at
        once; past it ``job`` is returned as it is.  A vanished record (pruned) returns the
        last one read."""
        wait_s = min(wait_s, self.settings.max_job_wait_s)
        if not job.active or wait_s <= 0 or self.waiting >= self.settings.max_job_waiters:
            return job
        loop = asyncio.get_running_loop()
        deadline = loop.time() + wait_s
        key = job.key
        self.waiting += 1
        try:
            while True:
                watch = self._watches.get(key)
                if watch is None:
                    watch = self._watches[key] = _Watch()
                watch.waiters += 1
                try:
                    with contextlib.suppress(TimeoutError):
                        await asyncio.wait_for(watch.ended.wait(), deadline - loop.time())
                finally:
                    watch.waiters -= 1
                    if watch.waiters == 0 and self._watches.get(key) is watch:
                        del self._watches[key]
                read = await asyncio.to_thread(self.store.get_job, key)
                if read is None:
                    return job
                job = read
                if not job.active or loop.time() >= deadline:
                    return job
        finally:
            self.waiting -= 1

    # -- the durable queue ---------------------------------------------------------------

    async def enqueue(
        self, job: Keyed, *, force: bool = False, principal: str | None = None, cost: float = 0.0
    ) -> Job:
        """Accept ``job`` into the store's durable queue (or join its active record) and
        wake the dispatcher; its record.  Raises :class:`QueueFull` when
        ``max_queued_jobs`` jobs wait already, :class:`StorageError` when the store fails."""
        if not self.store.healthy:
            raise self.store.unavailable()
        bound = self.settings.max_queued_jobs
        record, accepted = await asyncio.to_thread(
            functools.partial(
                self.store.queue_job,
                job.key,
                job.computation.name,
                job.canonical,
                bound=bound,
                refresh=force,
                principal=principal,
                cost=cost,
            )
        )
        if not accepted or record is None:
            raise QueueFull(f"{bound} jobs wait in the queue")
        # a free worker takes the next job before the 202 is answered (not at the
        # dispatcher's next wake-up): a request right after it finds the slot taken; the
        # job is accepted whatever happens here (the dispatcher tries again)
        try:
            await self._dispatch_once()
        except StorageError:
            self._kick.set()
        return record

    @property
    def free_slots(self) -> int:
        """Computations the dispatcher may start now: a worker each, less those in flight
        (synchronous requests' included; they may use ``queue_size`` more)."""
        return max(self.workers, 1) - len(self._flights)

    async def _dispatch(self) -> None:
        """Take waiting jobs from the durable queue as workers free up (woken by
        :meth:`enqueue` and by a flight that ends; every poll interval otherwise, for jobs
        queued by other replicas)."""
        await self._connected.wait()
        while True:
            with contextlib.suppress(TimeoutError):
                await asyncio.wait_for(self._kick.wait(), self.poll_s)
            self._kick.clear()
            try:
                await self._dispatch_once()
            except StorageError:
                continue
            except Exception:
                log.exception("engine dispatcher")

    async def _dispatch_once(self) -> None:
        """Take as many waiting jobs as there are free slots and drive them (one round at
        a time: two rounds would both count the same free slots)."""
        async with self._dispatching:
            free = self.free_slots
            self._drained = False  # unknown until the read below says otherwise
            if free <= 0 or not self.store.healthy or not self._connected.is_set():
                return
            per_principal = self.settings.quota_concurrent_jobs
            taken = await asyncio.to_thread(
                self.store.claim_waiting, self.replica, free, per_principal
            )
            # fewer than it could take, and no client's quota held one back: nothing
            # waited beyond these.  A flight that ends then leaves the dispatcher asleep
            # (its read after every computation, each cold request's, was a thread hop
            # and a query); a job queued later wakes it (enqueue), or, from another
            # replica, its next poll (poll_s) takes it
            self._drained = len(taken) < free and per_principal is None
            for job in taken:
                self.dispatched += 1
                await self._recover(job, "dispatching")
        if len(taken) == free:
            self._kick.set()  # there may be more, and room once these end

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
            await asyncio.to_thread(self.store.finish_job, job.key, "failed", _internal(str(exc)))
            return
        log.info("%s %s job %s (%s)", why, job.kind, job.key, job.status)
        await self.submit(Keyed(computation, request, job.spec, job.key), recover=True)

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

    def _submit_task(self, flight: Flight, job: Job) -> Awaitable[Outcome]:
        """Start the task of ``job`` (:func:`service.engine.task.run_job`) and count it;
        the seam tests replace to run it elsewhere."""
        self.computations += 1
        return self._execute(flight, job)

    def _lane_takes(
        self, request: Keyed, job: Job | None, resubmits: int = 0
    ) -> tuple[bool, float | None]:
        """Whether the fast lane runs this attempt, and the allowance [s] of its metered
        work (None: not metered).  The lane must be on and have a free thread, and it must
        be the job's first attempt here (a recovered, retried or handed-off job goes to a
        worker; ``job`` None: a new record, see :meth:`_lane_first`; ``resubmits``: the
        flight's resubmissions of an abnormally ended task).  Then either

        - the computation estimates its whole run time (:attr:`Computation.run_time`) at
          most ``fast_lane_max_s``: below ~50 ms the cross-process round trip of a Dask
          task (client -> scheduler -> worker -> scheduler -> client, 10-25 ms on the
          2-core machine) costs as much as the computation; beyond, the worker's
          isolation (its own core and GIL, killed if it overruns) is worth it; or
        - its work of unknown cost is metered (:attr:`Computation.metered_run_time`: a
          time-variant magnus simulation, whose steps are known only as its step control
          plans them), the rest is estimated at most ``fast_lane_max_s``, and
          ``fast_lane_max_metered_s`` > 0: it runs under that allowance
          (:func:`_run_in_lane`), charged each propagation's estimate before it is
          computed, and the first that would pass it stops the computation there; its
          job then goes to a worker (:meth:`_drive_once`: the lease given up with the
          reason, the record still active, submitted again).  An overrun is therefore
          bounded by the allowance plus the estimated rest, not only advised."""
        computation = request.computation
        if (
            self._lane is None
            or self._lane_busy >= self.settings.fast_lane_threads
            or (job is not None and (job.attempts > 0 or _handed_off(job)))
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

    async def _lane_first(
        self, flight: Flight, force: bool
    ) -> tuple[Job | None, asyncio.Future[Outcome] | None]:
        """A new job the fast lane takes (:meth:`_lane_takes`): its record is written by
        the lane's thread already leased to the computation that starts there at once
        (:meth:`Store.enqueue_and_claim`: one transaction, one thread hop, instead of the
        record, then the lease).  Answers once the record is written, as
        :meth:`Store.enqueue_job` would: ``(None, the computation's outcome)`` when the
        lane claimed it; ``(the record, None)`` when it did not (an active record was
        there first, or the result was stored: the ordinary path goes on from it);
        ``(None, None)`` when the lane does not take it or did not start.  Raises the
        :class:`StorageError` that refused the write."""
        taken, allowance = self._lane_takes(flight.job, None)
        loop = asyncio.get_running_loop()
        if not taken:  # (a look-up flight: the lane was taken meanwhile)
            return None, await self._look_up(flight)
        claimed: asyncio.Future[Claim] = loop.create_future()

        def settle(result: Claim | StorageError) -> None:
            if claimed.done():
                return
            if isinstance(result, StorageError):
                claimed.set_exception(result)
            else:
                claimed.set_result(result)

        # a look-up flight's request waits for the answer only (look_up_or_run): its
        # claim is read once the run has ended, not sent to the loop mid-run (a wake-up of
        # the event loop, contending for the GIL with the computation)
        quiet: list[Claim | StorageError] | None = [] if flight.look_up else None

        def on_claim(result: Claim | StorageError) -> None:  # in the lane's thread
            if quiet is not None:
                quiet.append(result)
                return
            with contextlib.suppress(RuntimeError):  # the loop is closed: nobody waits
                loop.call_soon_threadsafe(settle, result)

        accept = Accept(
            flight.job.canonical,
            force,
            on_claim,
            principal=flight.principal,
            cost=flight.cost,
            dispatcher=self.replica,
            look_up=flight.look_up,
        )
        try:
            run = self._in_lane(flight, flight.key, accept, allowance)
            waiter = asyncio.ensure_future(self._result_of(run))
        except RuntimeError:  # the lane is shut down (the replica is stopping)
            return None, await self._look_up(flight)
        if quiet is None:
            pending: set[asyncio.Future[Any]] = {claimed, waiter}
            await asyncio.wait(pending, return_when=asyncio.FIRST_COMPLETED)
        else:
            # until the run ends, or the monitor flags its record once written (the lane's
            # watchdog failed an overrun: answered now, its thread abandoned)
            while not waiter.done() and not quiet:
                await self._wait(flight, waiter)
            if not waiter.done():
                flight.changed.set()  # the flag is the driving loop's to act on
        if quiet:
            settle(quiet[0])
        if not claimed.done():  # the lane's run ended before writing anything
            claimed.cancel()
            return None, await self._look_up(flight)
        claim = claimed.result()  # raises the StorageError
        if claim.outcome == "hit":  # found stored: nothing written, nothing computed
            self.lane_runs -= 1
            return None, waiter
        if claim.outcome != "claimed":
            # it computed nothing: its thread is released before the ordinary path asks
            # for the lane again (a request joining this flight may have written the
            # record first, queued: the lane then claims it as a worker would)
            self.lane_runs -= 1
            await waiter
            return claim.job, None
        self.computations += 1
        return None, waiter

    async def _look_up(self, flight: Flight) -> asyncio.Future[Outcome] | None:
        """A look-up flight (:meth:`look_up_or_run`) the lane did not take: its lookup in a
        thread hop of its own, a ``hit`` outcome if found (None: not a look-up flight, or
        not stored: the ordinary path writes the record)."""
        if not flight.look_up:
            return None
        body = await asyncio.to_thread(self.store.get_result, flight.key)
        if body is None:
            return None
        found: asyncio.Future[Outcome] = asyncio.get_running_loop().create_future()
        found.set_result(Outcome("hit", body=body))
        return found

    def _in_lane(
        self,
        flight: Flight,
        key: str,
        accept: Accept | None = None,
        allowance: float | None = None,
    ) -> Awaitable[Outcome]:
        """:func:`run_job` in a thread of the fast lane, with this replica's store: the
        record, its lease and the result as a worker writes them (a restart finds the
        lease stale and recovers the job); the event loop only awaits.  The lane's thread
        counts as busy until its computation returns, even one abandoned past its limit.
        ``accept``: the lane writes the job's record too (:meth:`_lane_first`);
        ``allowance`` [s]: the computation's metered work is bounded by it
        (:func:`_run_in_lane`)."""
        assert self._lane is not None
        loop = asyncio.get_running_loop()
        self._lane_busy += 1
        self.lane_runs += 1
        try:
            fut = self._lane.submit(
                _run_in_lane,
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
            self._lane_busy -= 1
            self.lane_runs -= 1
            raise

        def release(_: Any) -> None:
            with contextlib.suppress(RuntimeError):  # the loop is closed: nothing to count
                loop.call_soon_threadsafe(self._release_lane)

        fut.add_done_callback(release)
        return asyncio.wrap_future(fut)

    def _release_lane(self) -> None:
        self._lane_busy -= 1

    def _execute(self, flight: Flight, job: Job) -> Awaitable[Outcome]:
        from distributed import fire_and_forget

        taken, allowance = self._lane_takes(flight.job, job, flight.resubmits)
        if taken:
            return self._in_lane(flight, job.key, allowance=allowance)

        dask_key = f"{job.kind}-{job.key}-g{job.generation}-a{job.attempts}"
        if flight.resubmits:
            dask_key += f"-r{flight.resubmits}"
        fut = self.client.submit(
            run_job,
            flight.job.computation,
            flight.job.request,
            job.key,
            self._config(),
            observability.request_id(),
            key=dask_key,
            pure=False,
        )
        fire_and_forget(fut)  # runs to the end even if this replica goes away
        # its long polls wake when the scheduler says the task ended (its record is final
        # by then), not once its Outcome has been fetched from the worker
        loop = asyncio.get_running_loop()

        def ended(_: Any) -> None:  # in Dask's callback thread
            with contextlib.suppress(RuntimeError):  # the loop is closed: nobody waits
                loop.call_soon_threadsafe(self.job_changed, job.key)

        fut.add_done_callback(ended)
        awaitable: Awaitable[Outcome] = fut
        return awaitable

    async def _wait(self, flight: Flight, waiter: asyncio.Future[Any] | None) -> None:
        """Until ``waiter`` is done, the monitor flags a change, or one poll interval."""
        changed = asyncio.ensure_future(flight.changed.wait())
        pending = {changed} | ({waiter} if waiter is not None else set())
        timeout = None if waiter is not None else self.settings.stale_after_s / 4
        try:
            await asyncio.wait(pending, timeout=timeout, return_when=asyncio.FIRST_COMPLETED)
        finally:
            changed.cancel()
        flight.changed.clear()

    async def _drive(self, flight: Flight, force: bool, recover: bool) -> bytes:
        started = time.perf_counter()
        try:
            body = await self._drive_once(flight, force, recover)
        except ComputationCancelled:
            self._record(flight, "cancelled", started, None)
            raise
        except ComputationFailed:
            self._record(flight, "error", started, None)
            raise
        self._record(flight, "ok", started, body)
        return body

    def _record(self, flight: Flight, outcome: str, started: float, body: bytes | None) -> None:
        """Count a computation this flight saw finish (not a result found stored)."""
        if flight.seconds is None and outcome != "cancelled":
            return
        seconds = flight.seconds if flight.seconds is not None else time.perf_counter() - started
        observability.record_computation(flight.job.computation.name, outcome, seconds, body)

    async def _stopped(self, flight: Flight, waiter: asyncio.Future[Any] | None) -> None:
        """A DELETE asked this run to stop: wait until its task has stopped (or never
        took the lease), reading the record through the monitor's query only."""
        while waiter is not None and not waiter.done():
            records = await asyncio.to_thread(self.store.jobs_by_key, [flight.key])
            record = records.get(flight.key)
            if record is None or record.owner is None:
                break  # not computing: the task finds the record cancelled when it starts
            await self._wait(flight, waiter)
        raise ComputationCancelled("cancelled by request")

    async def _enqueue(self, flight: Flight, **how: bool) -> Job:
        """The flight's job record written (``Store.enqueue_job``, off the event loop):
        queued, or answered from a stored result; ``how``: ``refresh`` / ``keep_stored``."""
        job_in = flight.job
        return await asyncio.to_thread(
            functools.partial(
                self.store.enqueue_job,
                flight.key,
                job_in.computation.name,
                job_in.canonical,
                principal=flight.principal,
                cost=flight.cost,
                dispatcher=self.replica,
                **how,
            )
        )

    async def _drive_once(self, flight: Flight, force: bool, recover: bool) -> bytes:
        key = flight.key
        known: Job | None = None  # the record as enqueue_job left it: not read again
        waiter: asyncio.Future[Any] | None = None
        try:
            if not recover:
                known, waiter = await self._lane_first(flight, force)
                if known is None and waiter is None:
                    known = await self._enqueue(flight, refresh=force)
        finally:
            flight.accepted.set()
        if waiter is not None:  # computing in the lane already: its end is the next news
            await self._wait(flight, waiter)
        await self._connected.wait()
        tag: tuple[int, int] | None = None
        while True:
            if flight.cancelled:
                await self._stopped(flight, waiter)
            if waiter is not None and waiter.done() and waiter.result().status == "hit":
                # the lookup found the result stored and wrote nothing; a request that
                # joined meanwhile writes a record (its own lookup missed: an eviction in
                # between), which the ordinary path below finishes from the stored result
                # (written here too, as the joiner does: either write may come first)
                outcome, waiter = waiter.result(), None
                assert outcome.body is not None
                if not flight.joined:
                    flight.hit = True
                    return outcome.body
                known = await self._enqueue(flight, keep_stored=True)
                continue
            if waiter is not None and waiter.done() and waiter.result().finished:
                # our task stored the result and finished the record with it: no re-read
                # of the record; the fast lane's answer even carries the body
                outcome = waiter.result()
                flight.seconds = outcome.seconds
                self.job_changed(key)  # the record is final: long polls answer now
                return outcome.body if outcome.body is not None else await self._body(key)
            try:
                job = (
                    known if known is not None else await asyncio.to_thread(self.store.get_job, key)
                )
                known = None
            except StorageError:
                await asyncio.sleep(self.settings.retry_after_s)
                continue
            if job is None:
                raise ComputationFailed(_internal(f"the record of job {key} disappeared"))
            if not job.active:
                if waiter is not None and job.started is not None and job.finished is not None:
                    # our task finished it (its own answer may still be on the way)
                    flight.seconds = job.finished - job.started
                return await self._outcome(job)
            if waiter is not None and not waiter.done():
                await self._wait(flight, waiter)
                continue
            if waiter is not None:
                outcome = waiter.result()
                waiter = None
                if outcome.seconds is not None:
                    flight.seconds = outcome.seconds
                if outcome.status == "handoff":
                    # the lane's allowance stopped it: the record is unowned and says why,
                    # and the submission below goes to a worker (no first attempt now)
                    self.lane_handoffs += 1
                    log.info("job %s handed off from the fast lane: %s", key, outcome.note)
                if outcome.status == "storage":
                    assert outcome.error is not None
                    await self._storage_failure(key, outcome.error)
                if outcome.status == "exception":
                    log.warning("task of job %s ended abnormally: %s", key, outcome.note)
                    flight.resubmits += 1  # a fresh Dask key: the old one may be erred
                    tag = None
                    await asyncio.sleep(self.poll_s)
                    continue
            stale = (
                job.heartbeat is None or time.time() - job.heartbeat >= self.settings.stale_after_s
            )
            if job.owner is not None and not stale:
                await self._wait(flight, None)  # a live attempt holds the lease
                continue
            if job.owner is not None and job.attempts >= MAX_ATTEMPTS:
                await asyncio.to_thread(
                    self.store.finish_job,
                    key,
                    "failed",
                    _internal(
                        f"the computation started {job.attempts} times and its worker died each "
                        f"time (last: attempt {job.attempts} on {job.worker} stopped "
                        "heartbeating)"
                    ),
                )
                continue
            if tag == (job.generation, job.attempts) and job.owner is None and not stale:
                await self._wait(flight, None)  # our task ran and left it queued: wait
                continue
            tag = (job.generation, job.attempts)
            waiter = asyncio.ensure_future(self._result_of(self._submit_task(flight, job)))
            # the record is read again once the task ends or the monitor flags a change,
            # not right away (that read only competed with the task starting)
            await self._wait(flight, waiter)

    @staticmethod
    async def _result_of(fut: Awaitable[Outcome]) -> Outcome:
        try:
            return await fut
        except asyncio.CancelledError:
            return Outcome("exception", note="cancelled by the scheduler (restarted or lost)")
        except Exception as exc:
            return Outcome("exception", note=f"{type(exc).__name__}: {exc}")

    async def _storage_failure(self, key: str, failure: ErrorRecord) -> None:
        """The task could not store its result: fail the job with the reason (if the store
        takes that write) and answer the waiting request with the storage error."""
        message, full = failure.message, bool(failure.data.get("full"))
        doc = ErrorRecord(
            "storage",
            "storage",
            f"the result could not be stored: {message}",
            data={"full": full},
        ).to_dict()
        self.store.mark_failed(message, full=full)  # not ready until a probe write succeeds
        try:
            await asyncio.to_thread(self.store.finish_job, key, "failed", doc)
        except StorageError:
            self._pending_failures[key] = doc  # written by the monitor once writes work
        raise StorageError(message, full=full)

    async def _body(self, key: str) -> bytes:
        """The stored result of a succeeded job, sent once to the requests waiting for it,
        not kept in the store's memory front: a 60 s mixed load filled that to its 64 MB
        bound with fresh results."""
        body = await asyncio.to_thread(
            functools.partial(self.store.get_result, key, remember=False)
        )
        if body is None:
            raise ComputationFailed(_internal(f"the result of job {key} was evicted"))
        return body

    async def _outcome(self, job: Job) -> bytes:
        if job.status == "succeeded":
            return await self._body(job.key)
        if job.status == "cancelled":
            raise ComputationCancelled(str((job.error or {}).get("detail", "cancelled")))
        raise ComputationFailed(job.error or _internal("failed"))

    # -- the monitor -----------------------------------------------------------------------

    async def _monitor(self) -> None:
        """Wake flights on changes, heartbeat queued jobs, probe the store, recover stale jobs."""
        stale_after = self.settings.stale_after_s
        last_touch = last_recovery = 0.0
        while True:
            await asyncio.sleep(self.poll_s)
            try:
                if not self.store.healthy:
                    await asyncio.to_thread(self.store.probe)
                    continue
                while self._pending_failures:
                    key, doc = next(iter(self._pending_failures.items()))
                    await asyncio.to_thread(self.store.finish_job, key, "failed", doc)
                    del self._pending_failures[key]
                now = time.time()
                keys = list(self._flights)
                # jobs long-polled here that no flight of this replica drives (queued, or
                # run by another replica): their end is seen in the same read
                watched = [k for k in self._watches if k not in self._flights]
                records = await asyncio.to_thread(self.store.jobs_by_key, keys + watched)
                for key in watched:
                    job = records.pop(key, None)
                    if job is None or not job.active:
                        self.job_changed(key)
                for key in keys:
                    job = records.get(key)
                    flight = self._flights.get(key)
                    if flight is None:
                        continue
                    lease_dead = (
                        job is not None
                        and job.owner is not None
                        and (job.heartbeat is None or now - job.heartbeat >= stale_after)
                    )
                    if job is None or not job.active or lease_dead:
                        flight.changed.set()
                if now - last_touch >= stale_after / 3:
                    last_touch = now
                    queued = [k for k, j in records.items() if j.status == "queued"]
                    await asyncio.to_thread(self.store.touch, queued)
                if now - last_recovery >= stale_after / 2:
                    last_recovery = now
                    if await asyncio.to_thread(self.store.requeue_stale, stale_after):
                        self._kick.set()  # back in the queue: taken as slots free up
                    for job in await asyncio.to_thread(self.store.stale_jobs, stale_after):
                        if job.key not in self._flights:
                            await self._recover(job)
            except StorageError:
                continue
            except Exception:
                log.exception("engine monitor")
