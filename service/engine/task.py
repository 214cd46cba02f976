"""The Dask task of one computation: self-contained and idempotent, on any worker.

:func:`run_job` takes the job's lease in the store, computes, stores the compressed
result and finishes the job record itself, so it does not depend on the replica that
submitted it staying alive.  While it runs, the process's heartbeat thread (one for all
its computations) renews the lease, records progress and reads the cancel flag every
``progress_interval_s``; the kind's function stops at its next progress callback
(cooperative cancel and runtime limit); a fan-out waiting for its pieces stops at the
limit too (:class:`service.engine.fanout.DaskHost`).  A function that stops reporting is
still held to the runtime limit: past it plus a grace period the heartbeat thread fails
the job with the reason (the client is answered then) and kills its own worker process
(the nanny starts a fresh one), but only once no other job's task runs in that process: a
job that seceded for its fan-out frees its thread, so another job's task may have started
there, and one job's limit must never cost another job anything (issue 22, defect 3).
Until then the overdue thread holds the process's thread, so no new task starts there.

The return value is small (the body goes to the store): an :class:`Outcome`
(:mod:`service.engine.outcome`), whose ``status`` (a :class:`TaskStatus`) is ``succeeded``
| ``failed`` | ``cancelled`` | ``done`` (someone finished it already) | ``elsewhere`` (a
live attempt holds the lease) | ``queued`` (the fast lane found an active record first:
not claimed) | ``lost`` (another attempt took the lease) | ``storage`` (the store refused
a write) | ``handoff`` (the fast lane's metered computation would pass its allowance:
stopped, its lease given up with the reason, the job left for a worker) | ``hit`` (the
fast lane looked the result up first and found it stored: nothing written, the body
answered).  Errors travel as neutral
:class:`pipeflow.errors.ErrorRecord` values (made by :func:`pipeflow.errors.classify`),
never as pickled exceptions, and the job record stores them as such: only the HTTP layer
turns a record into a problem document.  A computation that fans out
(:mod:`pipeflow.parallel`) spreads its pieces over the cluster through
:class:`service.engine.fanout.DaskHost`; the result's ``diagnostics.fan_out`` then counts
the pieces and the workers that ran them.  The request arrives
validated by the route (pickled, not validated again) and the result is encoded by
:func:`service.encoding.dumps` (non-finite numbers become null).  The log lines of a
computation (logger ``service.worker``) carry the id of the request that started it.
"""

from __future__ import annotations

import contextlib
import logging
import os
import signal
import socket
import threading
import time
import uuid
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from pipeflow import parallel
from pipeflow.errors import Cancelled, ErrorRecord, OverAllowance, StorageError, classify
from pipeflow.solvers.checkpoint import checkpointing
from service import encoding, observability
from service.engine.fanout import DaskHost, in_worker
from service.engine.lifecycle import ClaimOutcome, Counted, JobState, LeaseState, TaskStatus
from service.engine.outcome import Outcome
from service.store import Claim, Job, Store, worker_store
from service.store.checkpoints import StoreCheckpoints
from service.store.memo import StoreMemo

log = logging.getLogger("service.engine.task")
#: how the record of a job the fast lane handed off to a worker starts its retry reason
#: (the runner sends such a job to a worker, never to the lane again)
HANDED_OFF = "handed off to a worker by the fast lane"
#: the computation's own lines (started, finished), with the request id
work_log = logging.getLogger("service.worker")

if TYPE_CHECKING:
    from pipeflow.computations.registry import Computation

#: the ``outcome`` of the "computation finished" log line: ok | error as the metrics count
#: them, else the run's status (cancelled, lost, handoff)
_LOGGED = {TaskStatus.SUCCEEDED: Counted.OK, TaskStatus.FAILED: Counted.ERROR}


@dataclass(frozen=True)
class TaskConfig:
    """What a task needs to know of the service's settings (times in seconds)."""

    db_url: str
    cache_max_bytes: int
    timeout_s: float  # runtime limit of one attempt [s]
    progress_interval_s: float  # heartbeat, progress and cancel-check period [s]
    stale_after_s: float  # a lease without heartbeat for this long is dead [s]
    grace_s: float  # past timeout_s + grace_s a silent computation is killed [s]
    checkpoint_interval_s: float = 5.0  # a long solve's checkpoints, at most this often [s]
    checkpoint_max_bytes: int = 64 << 20  # larger checkpoints are skipped; 0: none [bytes]


def _store(cfg: TaskConfig) -> Store:
    """One store per worker process and database (no migrations: the service ran them)."""
    return worker_store(cfg.db_url, cfg.cache_max_bytes)


def _worker() -> Any:
    """The Dask worker running this task (call from the task's thread), else None."""
    try:
        from distributed import get_worker

        return get_worker()
    except (ImportError, ValueError):
        return None


def _worker_address() -> str:
    try:
        from distributed import get_worker

        return str(get_worker().address)
    except (ImportError, ValueError):
        return f"{socket.gethostname()}:{os.getpid()}"


class _Heartbeat:
    """One computation's lease as this process's :class:`_Beats` thread renews it: renews
    the lease and records ``progress``; sets ``stop`` on cancel or a lost lease; past the
    runtime limit plus the grace period, a computation that did not stop fails its job and
    (on a worker) its process is killed."""

    def __init__(
        self,
        store: Store,
        key: str,
        owner: str,
        cfg: TaskConfig,
        *,
        inline: bool = False,
        worker: Any = None,
    ) -> None:
        self.store, self.key, self.owner, self.cfg = store, key, owner, cfg
        self.inline = inline
        self.progress: float | None = None
        self.stop: str | None = None
        self.deadline = time.monotonic() + cfg.timeout_s
        self.due = time.monotonic() + cfg.progress_interval_s  # next renewal [monotonic s]
        self.done = False
        #: the Dask worker running the task (None in the fast lane), and the task's own key
        self.worker = worker
        self.own: set[str] = set()
        if worker is not None:
            with contextlib.suppress(Exception):
                self.own.add(str(worker.get_current_task()))
        self.host: DaskHost | None = None  # the task's fan-out (its pieces are its own)
        self.overdue = False  # the watchdog failed the job; the process dies when alone

    def start(self) -> None:
        """Renewed from now on, every ``progress_interval_s``."""
        _beats().add(self)

    def finish(self) -> None:
        """Stop renewing (a renewal being written meanwhile is guarded by the owner and the
        running status, so it cannot touch the finished record)."""
        self.done = True
        _beats().remove(self)

    def beat(self) -> bool:
        """One renewal (by the :class:`_Beats` thread); False: stop renewing this lease."""
        if time.monotonic() > self.deadline + self.cfg.grace_s:
            if self.inline:
                self._abandon_overdue()
                return False
            self._kill_overdue()
            return True  # the job is failed: no lease to renew; looked at again next interval
        try:
            state = self.store.heartbeat(self.key, self.owner, self.progress)
        except StorageError:
            return True  # the store recovers by itself; the lease may go stale meanwhile
        if state != LeaseState.OK:
            self.stop = "cancelled by request" if state == LeaseState.CANCELLED else state
        return True

    def _abandon_overdue(self) -> None:
        """The fast lane's watchdog: the API process is not killed for a computation that
        overran its limit without stopping; its job fails with the reason (so the lease
        is gone and the request is answered) and its thread is left to finish (it holds
        one of the lane's fixed threads until then: new work goes to Dask meanwhile)."""
        log.error("job %s overran the runtime limit in the fast lane: thread abandoned", self.key)
        self.stop = "runtime limit"
        self.store.finish_job(
            self.key,
            JobState.FAILED,
            ErrorRecord.runtime_limit(self.cfg.timeout_s).to_dict(),
            owner=self.owner,
        )

    def others(self) -> list[str]:
        """Keys of the tasks executing in this worker process (seceded ones included) that
        are not this job's: its own task and its pieces may die with the process."""
        if self.worker is None:
            return []
        state = self.worker.state
        running = state.executing | state.long_running  # set union: atomic under the GIL
        mine = self.own | (self.host.keys if self.host is not None else set())
        return sorted(str(ts.key) for ts in running if str(ts.key) not in mine)

    def _kill_overdue(self) -> None:
        """Fail the job (once), stop it where it is cooperative, then kill this process if
        no other job's task runs in it; else wait (called again every interval)."""
        if self.done:
            return  # the computation returned meanwhile
        if not self.overdue:
            self.overdue = True
            self.stop = "runtime limit"
            with contextlib.suppress(StorageError):  # the lease goes stale: still failed
                self.store.finish_job(
                    self.key,
                    JobState.FAILED,
                    ErrorRecord.runtime_limit(self.cfg.timeout_s, killed=True).to_dict(),
                    owner=self.owner,
                )
        others = self.others()
        if others:
            log.warning(
                "job %s overran the runtime limit without stopping: its worker is killed once "
                "the other tasks in it end (%s)",
                self.key,
                ", ".join(others),
            )
            return
        log.error("job %s overran the runtime limit without stopping: killing worker", self.key)
        os.kill(os.getpid(), signal.SIGKILL)


class _Beats(threading.Thread):
    """The one heartbeat thread of a process: renews every lease the process's
    computations hold, each at its own ``progress_interval_s``.  Starting a thread per
    computation cost the fast lane ~0.3-1 ms per cold request on the 2-core machine; a
    lease is now registered without waking this thread (it sleeps until the next renewal
    due, :data:`IDLE_WAKE_S` when it holds none, and is woken only for a lease whose first
    renewal would otherwise be more than one interval late)."""

    def __init__(self) -> None:
        super().__init__(name="heartbeats", daemon=True)
        self._leases: set[_Heartbeat] = set()
        self._cond = threading.Condition()
        self._wake_at = 0.0  # when the thread's wait ends [monotonic s]

    def add(self, lease: _Heartbeat) -> None:
        with self._cond:
            self._leases.add(lease)
            # its first renewal may come up to one interval late rather than wake the
            # thread (a context switch per cold request); only a short interval wakes it
            if lease.due + lease.cfg.progress_interval_s < self._wake_at:
                self._cond.notify()

    def remove(self, lease: _Heartbeat) -> None:
        with self._cond:
            self._leases.discard(lease)

    def run(self) -> None:
        while True:
            with self._cond:
                now = time.monotonic()
                due = [lease for lease in self._leases if lease.due <= now]
                for lease in due:
                    lease.due = now + lease.cfg.progress_interval_s
                nxt = min((lease.due for lease in self._leases), default=now + IDLE_WAKE_S)
                if not due:
                    self._wake_at = nxt
                    self._cond.wait(max(nxt - now, 0.0))
                    self._wake_at = 0.0
                    continue
            for lease in due:  # outside the lock: a slow store delays renewals, not starts
                try:
                    keep = lease.beat()
                except Exception:
                    log.exception("heartbeat of job %s", lease.key)
                    keep = True
                if not keep:
                    self.remove(lease)


#: how long the heartbeat thread sleeps when no lease is held [s] (it then wakes to look)
IDLE_WAKE_S = 0.5
_BEATS: list[_Beats] = []
_BEATS_LOCK = threading.Lock()


def _beats() -> _Beats:
    """This process's heartbeat thread, started on first use (again in a forked child)."""
    with _BEATS_LOCK:
        if not _BEATS or not _BEATS[0].is_alive():
            _BEATS[:] = [_Beats()]
            _BEATS[0].start()
        return _BEATS[0]


@dataclass(frozen=True)
class Accept:
    """A new job that the attempt itself accepts (the fast lane's first attempt): the
    record is written already leased to the attempt, in one transaction
    (:meth:`Store.enqueue_and_claim`), and ``claimed`` is called right after it (in the
    attempt's thread) with the :class:`~service.store.Claim`, or with the
    :class:`StorageError` that refused the write."""

    spec: dict[str, Any]  # the request's canonical JSON (the record's spec)
    refresh: bool  # recompute even if a result is stored
    claimed: Callable[[Claim | StorageError], None]
    principal: str | None = None  # who asked (service.http.identity)
    cost: float = 0.0  # the estimate the quotas count [s]
    dispatcher: str | None = None  # the replica that drives the job
    #: look the result up first (the request's cache lookup, in the same thread hop): a
    #: stored result is answered as it is (``claimed`` gets a ``"hit"`` claim, the outcome
    #: is ``hit`` with the body) and nothing is written; only a miss writes the record
    look_up: bool = False


def run_job(
    computation: Computation,
    request: Any,
    key: str,
    cfg: TaskConfig,
    request_id: str | None = None,
    store: Store | None = None,
    accept: Accept | None = None,
) -> Outcome:
    """Compute the job ``key`` (``computation.execute(request, progress)``) once.

    ``request_id`` (of the request that started the computation) is set for the log
    lines written meanwhile (:data:`service.observability.REQUEST_ID`).  ``store``: run
    in the API process (the fast lane, :mod:`service.engine.lane`) with its store: the
    same lease, record and result, but a computation that overruns its limit without
    stopping fails its job and is abandoned, not killed with the process, and the
    answer carries the result's body.  ``accept``: the job's record is written by this
    call, with its lease (see :class:`Accept`); otherwise it exists and is claimed."""
    token = observability.REQUEST_ID.set(request_id)
    try:
        return _run_job(computation, request, key, cfg, store, accept)
    finally:
        observability.REQUEST_ID.reset(token)


def _run_job(
    computation: Computation,
    request: Any,
    key: str,
    cfg: TaskConfig,
    inline: Store | None,
    accept: Accept | None,
) -> Outcome:
    store = inline if inline is not None else _store(cfg)
    owner = uuid.uuid4().hex
    try:
        if accept is None:
            claim = store.claim(key, owner, _worker_address(), cfg.stale_after_s)
        elif accept.look_up and (stored := store.get_result(key)) is not None:
            accept.claimed(Claim(ClaimOutcome.HIT, None))
            return Outcome(TaskStatus.HIT, body=stored)
        else:
            claim = store.enqueue_and_claim(
                key,
                computation.name,
                accept.spec,
                owner,
                _worker_address(),
                refresh=accept.refresh,
                principal=accept.principal,
                cost=accept.cost,
                dispatcher=accept.dispatcher,
            )
    except StorageError as exc:
        if accept is not None:
            accept.claimed(exc)
        return Outcome(TaskStatus.STORAGE, classify(exc))
    if accept is not None:
        accept.claimed(claim)
    match claim.outcome:
        case ClaimOutcome.STORED:  # computed by an earlier attempt; the claim finished it
            return Outcome(TaskStatus.SUCCEEDED)
        case ClaimOutcome.DONE | ClaimOutcome.ELSEWHERE | ClaimOutcome.QUEUED:  # not ours
            note = claim.job.status if claim.job else None
            return Outcome(TaskStatus(claim.outcome), note=note)
    assert claim.job is not None
    try:
        beat = _Heartbeat(store, key, owner, cfg, inline=inline is not None, worker=_worker())
        beat.start()
        started = time.perf_counter()
        work_log.info("computation started", extra={"key": key, "computation": computation.name})
        try:
            status, payload, error = _compute(computation, request, beat, cfg, claim.job)
        finally:
            beat.finish()
        seconds = time.perf_counter() - started
        work_log.info(
            "computation finished",
            extra={
                "key": key,
                "outcome": _LOGGED.get(status, status),
                "duration_ms": round(seconds * 1e3, 3),
                "lane": "api" if inline is not None else "worker",
            },
        )
        if status == TaskStatus.LOST:
            return Outcome(TaskStatus.LOST, note=str(payload))
        if status == TaskStatus.SUCCEEDED:
            assert isinstance(payload, bytes)
            # one transaction; the API process's own store keeps the body out of its memory
            # front (its hits are answered from the hit cache)
            done = store.finish_with_result(
                key, owner, computation.name, payload, remember=inline is None
            )
            body = payload if done and inline is not None else None
            return Outcome(TaskStatus.SUCCEEDED, seconds=seconds, finished=done, body=body)
        if status == TaskStatus.HANDOFF:
            # the lane's allowance stopped it before the work that would pass it: the record
            # stays active, unowned, with the reason, and the attempt is given back (a
            # hand-off must not use up one of the starts a dying worker may take); the
            # replica submits it to a worker
            why = str(payload)
            store.release(key, owner, f"{HANDED_OFF}: {why}", refund=True)
            return Outcome(TaskStatus.HANDOFF, seconds=seconds, note=why)
        if status == TaskStatus.CANCELLED:
            store.release(key, owner)  # the record already says cancelled (by the request)
            return Outcome(TaskStatus.CANCELLED, seconds=seconds, note=str(payload))
        assert error is not None
        store.finish_job(key, JobState.FAILED, error.to_dict(), owner=owner)
        return Outcome(TaskStatus.FAILED, error, seconds)
    except StorageError as exc:
        return Outcome(TaskStatus.STORAGE, classify(exc))


def _compute(
    computation: Computation, request: Any, beat: _Heartbeat, cfg: TaskConfig, job: Job
) -> tuple[TaskStatus, bytes | str | None, ErrorRecord | None]:
    """``(SUCCEEDED, json bytes, None)`` | ``(FAILED, None, record)`` | ``(CANCELLED | LOST |
    HANDOFF, why, None)`` (:class:`TaskStatus`).  A long solve checkpoints into the store
    under ``job``'s key and generation and resumes from an earlier attempt's checkpoint;
    the result's diagnostics then say which attempt of the job resumed (``resumed_attempt``)."""

    def progress(fraction: float) -> None:
        if time.monotonic() > beat.deadline:
            raise Cancelled("runtime limit")
        beat.progress = fraction
        if beat.stop is not None:
            raise Cancelled(beat.stop)

    def stop() -> str | None:
        """Why a fan-out waiting for its pieces must stop now (None: it need not)."""
        return "runtime limit" if time.monotonic() > beat.deadline else beat.stop

    # fan-outs spread over the cluster, held to the limit and the cancel flag while waiting
    host = DaskHost(stop, cfg.progress_interval_s) if in_worker() else None
    beat.host = host
    try:
        beat.deadline = time.monotonic() + cfg.timeout_s  # the limit is on the computation
        # pieces computed before (a study's cases) come from the store, new ones go there
        checkpoints = None
        if cfg.checkpoint_max_bytes > 0:
            checkpoints = StoreCheckpoints(
                beat.store,
                beat.key,
                job.generation,
                beat.owner,
                cfg.checkpoint_interval_s,
                cfg.checkpoint_max_bytes,
                # retried or handed off: an earlier attempt may have saved one
                resumable=job.attempts > 1 or job.last_retry_reason is not None,
            )
        with (
            parallel.hosting(host=host, memo=StoreMemo(beat.store)),
            checkpointing(checkpoints),
        ):
            result = computation.execute(request, progress)
    except Cancelled as exc:
        if time.monotonic() > beat.deadline:
            return (TaskStatus.FAILED, None, ErrorRecord.runtime_limit(cfg.timeout_s))
        if beat.stop == LeaseState.LOST:
            return (TaskStatus.LOST, "another attempt took over the job", None)
        return (TaskStatus.CANCELLED, str(exc) or "cancelled", None)
    except OverAllowance as exc:  # the fast lane's allowance (service.engine.lane)
        return (TaskStatus.HANDOFF, str(exc), None)
    except StorageError as exc:  # a failed store is no failure of the computation
        return (
            TaskStatus.FAILED,
            None,
            ErrorRecord.internal(f"internal error: StorageError: {exc}"),
        )
    except Exception as exc:
        return (TaskStatus.FAILED, None, classify(exc))
    fan_out = host.diagnostics() if host is not None else None
    if fan_out is not None and isinstance(result.get("diagnostics"), dict):
        result["diagnostics"] = {**result["diagnostics"], "fan_out": fan_out}
    diagnostics = result.get("diagnostics")
    if isinstance(diagnostics, dict) and "resumed_from_time" in diagnostics:
        result["diagnostics"] = {**diagnostics, "resumed_attempt": job.attempts}
    try:
        # non-finite numbers -> null (the one rule)
        return (TaskStatus.SUCCEEDED, encoding.dumps(result), None)
    except Exception as exc:
        error = ErrorRecord.internal(f"internal error: {type(exc).__name__}: {exc}")
        return (TaskStatus.FAILED, None, error)
