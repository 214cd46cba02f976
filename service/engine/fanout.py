"""The Dask host of :mod:`pipeflow.parallel`: the pieces of one computation on every worker.

A job's task (:func:`service.engine.task.run_job`) installs a :class:`DaskHost` around the
computation.  When the library fans out (a spin map's chunks of spins, a beta map's betas,
a resonance chart's frequency columns), :meth:`DaskHost.map` enters
``distributed.worker_client()``: the parent task secedes from its worker's thread pool (so
that worker computes pieces too, the parent only merges), submits one Dask task per piece
(``client.map(..., pure=False)``) and yields results as they complete
(``as_completed(..., with_results=True)``).  The parent rejoins the pool when the fan-out
ends.

- Width: the cluster's worker threads at the first call (a cluster of one thread runs the
  pieces here, in order: no dispatch, no secession).
- Stopping: closing the iteration (the computation's progress callback raised ``Cancelled``
  between pieces, for a cancel or the runtime limit, or a piece raised) cancels the pieces
  not yet finished; a piece already running finishes its chunk and is dropped.  The
  parent does not wait for a slow piece past its job's limit: it waits ``tick_s`` at a
  time and asks ``stop`` (the task's cancel flag and runtime limit) in between, raising
  ``Cancelled`` with the reason.  So a job whose pieces overrun its limit ends at that
  limit by itself, and the watchdog never has to kill the process the parent seceded in,
  where another job's task may be running meanwhile (issue 22, defect 3).
- Ownership: :attr:`DaskHost.keys` are the Dask keys of every piece submitted, so the
  watchdog can tell this job's tasks in its process from other jobs'.
- Faults: a piece whose worker dies is rerun by the scheduler (up to its
  ``allowed-failures``); an exception from a piece (a ``PipeflowError`` keeps its
  parameter through pickling) leaves the computation like one raised in-process.
- Observation: every piece reports the worker that ran it; :meth:`DaskHost.diagnostics`
  gives the count of pieces and of distinct workers, which the task adds to the result's
  ``diagnostics.fan_out``.
"""

from __future__ import annotations

import uuid
from collections.abc import Callable, Iterator, Sequence
from functools import partial
from typing import Any

from pipeflow import parallel
from pipeflow.errors import Cancelled

#: prefix of the Dask keys of pieces (tests find them in the scheduler by it)
PIECE_PREFIX = "pipeflow-piece"


def _run_piece(fn: Callable[[Any], Any], item: Any) -> tuple[str, Any]:
    """``(address of the worker that ran it, fn(item))``."""
    from distributed import get_worker

    return str(get_worker().address), fn(item)


def in_worker() -> bool:
    """Whether this code runs inside a Dask worker's task."""
    try:
        from distributed import get_worker

        get_worker()
    except (ImportError, ValueError):
        return False
    return True


class DaskHost:
    """A :class:`pipeflow.parallel.Host` submitting pieces to the cluster of the current
    Dask worker (use it inside a task only).

    ``stop``: asked every ``tick_s`` [s] while waiting for pieces; a reason (not None)
    ends the wait with ``Cancelled(reason)`` (the pieces not finished are cancelled)."""

    def __init__(self, stop: Callable[[], str | None] | None = None, tick_s: float = 0.25) -> None:
        self._width: int | None = None
        self.pieces = 0  # pieces computed on the cluster, over all fan-outs
        self.workers: set[str] = set()
        self.keys: set[str] = set()  # Dask keys of the pieces submitted, over all fan-outs
        self.stop = stop
        self.tick_s = tick_s

    @property
    def width(self) -> int:
        """Worker threads in the cluster (asked of the scheduler once)."""
        if self._width is None:
            from distributed import get_client

            self._width = max(1, sum(get_client().nthreads().values()))
        return self._width

    def map(self, fn: Callable[[Any], Any], items: Sequence[Any]) -> Iterator[tuple[int, Any]]:
        """``(i, fn(items[i]))`` in completion order; see the module docstring."""
        items = list(items)
        if self.width == 1:
            yield from parallel.SERIAL.map(fn, items)
            return
        from distributed import wait, worker_client

        name = getattr(fn, "__name__", "piece")
        token = uuid.uuid4().hex[:12]
        keys = [f"{PIECE_PREFIX}-{name}-{token}-{i}" for i in range(len(items))]
        self.keys.update(keys)
        with worker_client() as client:  # secedes: this worker computes pieces too
            futures = client.map(partial(_run_piece, fn), items, key=keys, pure=False)
            index = {f.key: i for i, f in enumerate(futures)}
            pending = set(futures)
            try:
                while pending:
                    self._check_stop()
                    try:
                        done = wait(pending, self.tick_s, return_when="FIRST_COMPLETED").done
                    except TimeoutError:
                        continue
                    # a "lost" piece (its worker died with its result) is recomputed: not done
                    done = {f for f in done if f.status in ("finished", "error", "cancelled")}
                    pending -= done
                    ordered = sorted(done, key=lambda f: index[f.key])
                    # an erred piece raises its exception here, as in-process
                    for future, (address, result) in zip(
                        ordered, client.gather(ordered), strict=True
                    ):
                        self.pieces += 1
                        self.workers.add(address)
                        yield index[future.key], result
            finally:
                # the unfinished ones stop; the finished (or erred) ones are released now,
                # not when a traceback that refers to them is collected
                client.cancel(futures)

    def _check_stop(self) -> None:
        reason = self.stop() if self.stop is not None else None
        if reason is not None:
            raise Cancelled(reason)

    def diagnostics(self) -> dict[str, int] | None:
        """``{"pieces": n, "workers": k}`` when pieces ran on the cluster, else None."""
        if not self.pieces:
            return None
        return {"pieces": self.pieces, "workers": len(self.workers)}
