"""The engine: computations as Dask tasks, driven to a terminal job record.

The replica's side is :class:`Runner` (:mod:`service.engine.runner`); the Dask task of one
computation is :func:`service.engine.task.run_job`; what a worker process loads at start
is :mod:`service.engine.preload` (``dask worker --preload service.engine.preload``); a
computation's fan-out over the cluster is :mod:`service.engine.fanout`.

The engine speaks no HTTP: a failed computation is a neutral
:class:`pipeflow.errors.ErrorRecord`, which only the HTTP layer (:mod:`service.http`)
turns into a problem document.
"""

from __future__ import annotations

from service.engine.runner import (
    MAX_ATTEMPTS,
    WATCHDOG_GRACE_S,
    ComputationCancelled,
    ComputationFailed,
    Flight,
    QueueFull,
    Runner,
)

__all__ = [
    "MAX_ATTEMPTS",
    "WATCHDOG_GRACE_S",
    "ComputationCancelled",
    "ComputationFailed",
    "Flight",
    "QueueFull",
    "Runner",
]
