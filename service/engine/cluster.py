"""The cluster: the connection to Dask and the workers it has.

Embedded mode (default): a ``distributed.LocalCluster`` of ``PIPEFLOW_WORKERS`` worker
processes (one thread and one BLAS thread each).  Distributed mode:
``PIPEFLOW_SCHEDULER_ADDRESS=tcp://host:8786`` makes the service a client of an existing
cluster (``dask scheduler`` + ``dask worker --nthreads 1 --preload-nanny
service.engine.preload``), ``tls://`` with Dask's TLS configuration (:mod:`service.tls`).

:class:`Cluster` follows the scheduler's workers (its ``add-worker`` / ``remove-worker``
events at once, a full read every :data:`WORKERS_RESYNC_S`), warms them, admits a
synchronous request only when a worker can take it, and submits a job's task.  It is told
nothing of jobs: what a lost worker means for them is the ``on_worker_lost`` callback it
is handed, and what runs after each resync is ``resynced`` (Dask's plugins and event hooks
are the model).
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import time
import uuid
from collections.abc import Awaitable, Callable
from typing import Any

from service import observability
from service.engine.outcome import NoWorker, Outcome
from service.engine.preload import MODULE as PRELOAD
from service.engine.task import TaskConfig, run_job
from service.settings import Settings

log = logging.getLogger("service.engine")

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


class Cluster:
    """The Dask client (and the embedded cluster) and the scheduler's workers.

    Callbacks: ``spawn(coro)`` runs a background task of the engine; ``on_worker_lost
    (address)`` is called (as a spawned task) when the scheduler says a worker left;
    ``resynced()`` after each periodic read of the workers."""

    def __init__(
        self,
        settings: Settings,
        *,
        spawn: Callable[[Awaitable[Any]], None],
        on_worker_lost: Callable[[str], Awaitable[None]],
        resynced: Callable[[], None],
    ) -> None:
        self.settings = settings
        self._spawn = spawn
        self._on_worker_lost = on_worker_lost
        self._resynced = resynced
        self.client: Any = None
        self.cluster: Any = None  # the embedded LocalCluster (None: an external scheduler)
        self.connected = asyncio.Event()
        self.embedded_no_worker_grace_s = EMBEDDED_NO_WORKER_GRACE_S
        self.nannies_restored = 0  # embedded nannies Dask closed and this engine replaced
        self._restoring: asyncio.Future[Any] | None = None  # their start, while it runs
        # the scheduler's workers (addresses), followed once connected (_track)
        self.worker_set: set[str] = set()
        self.tracking = False

    # -- connection ------------------------------------------------------------------------

    async def start(self) -> None:
        """Connect (again every ``retry_after_s`` until it works), then follow the
        scheduler's workers; :attr:`connected` is set at the end."""
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
                await self.close()
                await asyncio.sleep(self.settings.retry_after_s)
        self.client.subscribe_topic("all", self._on_event)
        await self._read_workers()
        self.tracking = True
        self._spawn(self._track())
        self.connected.set()

    async def _connect(self) -> None:
        """Start the embedded cluster, or connect to the scheduler; then the client."""
        from distributed import Client, LocalCluster

        address = self.settings.scheduler_address
        if address:
            # Dask's configuration gives the TLS files of a tls:// address (service.tls)
            self.client = await Client(address, asynchronous=True, timeout="60s")
            return
        self.cluster = LocalCluster(
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
        await self.cluster
        self.client = await Client(self.cluster, asynchronous=True)

    async def close(self) -> None:
        for closing in (self.client, self.cluster):
            if closing is not None:
                with contextlib.suppress(Exception):
                    await asyncio.wait_for(closing.close(), 10)
        self.client = self.cluster = None

    # -- warm-up ---------------------------------------------------------------------------

    async def warm_up(self, cfg: TaskConfig) -> None:
        """Once a worker is connected (the embedded cluster: all of them), until each
        connected worker ran :func:`service.engine.preload.warm_task` or is busy with a
        computation (a recovered job: readiness does not wait for it).  A failure there is
        logged: the first job then pays for it."""
        wanted = 1 if self.settings.scheduler_address else self.settings.workers
        await self.client.wait_for_workers(wanted)
        try:
            await asyncio.wait_for(self._warm_workers(cfg), WARM_UP_TIMEOUT_S)
        except Exception as exc:
            log.warning("worker warm-up task failed: %s: %s", type(exc).__name__, exc)

    async def _warm_workers(self, cfg: TaskConfig) -> None:
        """Send each worker its warm-up task (ahead of queued computations: high
        priority) and wait until each worker ran it or is computing something else."""
        from service.engine.preload import warm_task

        identity = await self.client.scheduler.identity(n_workers=-1)
        self.worker_set |= set(identity.get("workers", {}))
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
                if future.status == "error":  # (Dask's future status)
                    await future  # raises the worker's error
            if not pending:
                return
            processing = await self.client.processing(workers=list(pending))
            busy = {
                address
                for address, keys in processing.items()
                if any(not str(key).startswith("warm-up-") for key in keys)
            }
            if all(address in busy or address not in self.worker_set for address in pending):
                log.info("warm-up left to %d busy worker(s)", len(pending))
                return
            await asyncio.sleep(WARM_UP_POLL_S)

    # -- the workers the scheduler has ------------------------------------------------------

    @property
    def workers(self) -> int:
        """Workers connected to the scheduler now (0 before the cluster is connected)."""
        return len(self.worker_set)

    @property
    def no_worker(self) -> bool:
        """Connected to an external scheduler that has no worker.  Never for the embedded
        cluster: its nannies restart a worker that died (a crash, the watchdog's kill),
        which under load takes tens of seconds without any worker."""
        return self.tracking and self.cluster is None and not self.worker_set

    async def _track(self) -> None:
        """Follow the scheduler's workers: its events at once (:meth:`_on_event`), and a
        full read every :data:`WORKERS_RESYNC_S` (events missed across a scheduler
        restart; an unreachable scheduler counts as no worker), then ``resynced()`` (the
        runner restores the embedded cluster's lost nannies there)."""
        while True:
            await asyncio.sleep(WORKERS_RESYNC_S)
            await self._read_workers()
            try:
                self._resynced()
            except Exception:
                log.exception("restoring the embedded cluster's workers")

    def restore_nannies(self) -> None:
        """Give the embedded cluster back the nannies Dask closed: a nanny restarts its
        worker when the process dies (the watchdog's kill), but the cluster closes the
        nanny itself when no worker of that name has registered again within
        ``distributed.deploy.lost-worker-timeout`` (15 s): under load (a restart took 38 s
        at load average 15) the cluster was left with no worker and no nanny for good,
        and every computation after it waited forever (the queued Dask task, its record
        queued and heartbeated by this replica).  A nanny missing from the cluster's
        workers, or closed, is started again from its spec."""
        from distributed.core import Status

        cluster = self.cluster
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
            self.worker_set = set(identity.get("workers", {}))
        except asyncio.CancelledError:
            raise
        except Exception:
            self.worker_set = set()

    def _on_event(self, event: tuple[float, Any]) -> None:
        msg = event[1]
        if not isinstance(msg, dict) or "worker" not in msg:
            return
        address = str(msg["worker"])
        if msg.get("action") == "add-worker":
            self.worker_set.add(address)
        elif msg.get("action") == "remove-worker":
            self.worker_set.discard(address)
            self._spawn(self._on_worker_lost(address))

    # -- admission -------------------------------------------------------------------------

    async def admit(self) -> None:
        """Raise :class:`NoWorker` unless a worker can take a synchronous computation: the
        start is waited for (the embedded cluster's up to :data:`WARM_UP_TIMEOUT_S`; a
        scheduler that cannot be reached yet, up to :data:`NO_WORKER_GRACE_S`), then the
        scheduler must have a worker."""
        if not self.connected.is_set():
            embedded = not self.settings.scheduler_address
            limit = WARM_UP_TIMEOUT_S if embedded else NO_WORKER_GRACE_S
            with contextlib.suppress(TimeoutError):
                await asyncio.wait_for(self.connected.wait(), limit)
            if not self.connected.is_set():
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
        grace = NO_WORKER_GRACE_S if self.cluster is None else self.embedded_no_worker_grace_s
        while True:
            done, _ = await asyncio.wait({shielded}, timeout=0.25)
            if done:
                return shielded.result()
            if not self.tracking or self.worker_set:
                since = None
            elif since is None:
                since = time.monotonic()
            elif time.monotonic() - since >= grace:
                # the flight goes on; its outcome is read by whoever waits for it next
                shielded.add_done_callback(lambda f: f.cancelled() or f.exception())
                raise NoWorker("the scheduler lost its workers during the computation")

    # -- tasks -----------------------------------------------------------------------------

    def submit(
        self,
        job: Any,
        key: str,
        dask_key: str,
        cfg: TaskConfig,
        ended: Callable[[str], None],
    ) -> Awaitable[Outcome]:
        """Submit the task of the job ``key`` (``job``: its :class:`~service.keys.Keyed`)
        under ``dask_key``; ``ended(key)`` is called in the event loop when the scheduler
        says the task ended (its record is final by then), not once its :class:`Outcome`
        has been fetched from the worker."""
        from distributed import fire_and_forget

        fut = self.client.submit(
            run_job,
            job.computation,
            job.request,
            key,
            cfg,
            observability.request_id(),
            key=dask_key,
            pure=False,
        )
        fire_and_forget(fut)  # runs to the end even if this replica goes away
        loop = asyncio.get_running_loop()

        def on_end(_: Any) -> None:  # in Dask's callback thread
            with contextlib.suppress(RuntimeError):  # the loop is closed: nobody waits
                loop.call_soon_threadsafe(ended, key)

        fut.add_done_callback(on_end)
        awaitable: Awaitable[Outcome] = fut
        return awaitable

    async def call(self, fn: Any, *args: Any) -> Any:
        """Run a picklable function on a worker (tests and diagnostics)."""
        return await self.client.submit(fn, *args, pure=False)
