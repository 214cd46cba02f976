"""The engine: computations as Dask tasks, driven to a terminal job record.

The replica's side is :class:`Runner` (:mod:`service.engine.runner`), a coordinator that
owns the engine's parts and wires them with callbacks (no part imports another)::

    Runner ──owns──> Cluster     (cluster.py: Dask client, workers, warm-up, admission)
       │             FastLane    (lane.py: small computations in threads; can be off)
       │             Driver      (drive.py: one flight's job to a terminal record)
       │             Dispatcher  (dispatcher.py: the durable queue, as slots free up)
       │             Watches     (watches.py: long polls)
       │             Monitor     (monitor.py: changes, heartbeats, stale leases)
       └──owns──> Flights        (flight.py: single flight, the floor they share)
    floor: flight.py, outcome.py (Outcome, the request's errors), lifecycle.py (states)

The Dask task of one computation is :func:`service.engine.task.run_job`; what a worker
process loads at start is :mod:`service.engine.preload` (``dask worker --preload-nanny
service.engine.preload``); a computation's fan-out over the cluster is
:mod:`service.engine.fanout`.

The engine speaks no HTTP: a failed computation is a neutral
:class:`pipeflow.errors.ErrorRecord`, which only the HTTP layer (:mod:`service.http`)
turns into a problem document.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from service.engine.runner import (
        MAX_ATTEMPTS,
        WATCHDOG_GRACE_S,
        ComputationCancelled,
        ComputationFailed,
        Flight,
        NoWorker,
        QueueFull,
        Runner,
    )

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


def __getattr__(name: str) -> Any:
    """The runner's names, imported on first use: a ``dask worker``'s nanny loads
    :mod:`service.engine.preload` (a small module) without the runner and the numerical
    stack behind it (13 s of imports on a loaded machine, and their memory, in a process
    that never computes)."""
    if name in __all__:
        from service.engine import runner

        return getattr(runner, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
