"""What a Dask worker process of the service looks like from inside.

The service's workers run with one thread and one BLAS thread each
(:data:`THREAD_VARIABLES` set to 1 in the worker's environment before numpy loads): two
computations on two cores must not fight over BLAS threads.  ``dask worker --preload
service.engine.preload`` (and the embedded cluster) import the numerical stack at start,
and warm up (:func:`warm_up`: a tiny run of each solver through the task's compute path
and the encoder), so the first request does not pay for them.  The worker's log lines go
to stdout in the service's format (``PIPEFLOW_LOG_LEVEL``, ``PIPEFLOW_LOG_FORMAT``).
"""

from __future__ import annotations

import logging
import os
import sys
import time
from typing import Any

from service import THREAD_VARIABLES

log = logging.getLogger("service.worker")


#: the environment of a worker process: one BLAS thread
WORKER_ENV = dict.fromkeys(THREAD_VARIABLES, "1")


def dask_setup(worker: Any) -> None:
    """Dask preload hook: pin BLAS threads (if the launcher did not), the service's log
    settings, then warm up."""
    for name in THREAD_VARIABLES:
        os.environ.setdefault(name, "1")
    from service import observability

    observability.configure_logging(
        os.environ.get("PIPEFLOW_LOG_LEVEL", "INFO"), os.environ.get("PIPEFLOW_LOG_FORMAT", "json")
    )
    import pipeflow.simulation  # noqa: F401  (numpy/scipy with the pinned environment)
    import service.engine.task  # noqa: F401

    warm_up()


#: the warm-up case: the paper's pipe, 2 modes, 11 samples (milliseconds per method), then
#: the default request's mode count with the default method
_WARM_UP_METHODS = ("cma", "magnus", "rk4")
_warmed_up = [False]


def warm_up() -> None:
    """Import everything a computation needs (every computation's module) and run a tiny
    simulation per solver through the task's compute path and the encoder, so the
    first-use costs (lazy imports inside scipy and pipeflow, pydantic's validators) are
    paid before the worker takes its first job.  A failure here is logged, never fatal:
    the job would then pay (and report) it."""
    started = time.perf_counter()
    try:
        from pipeflow.errors import ErrorRecord, classify
        from pipeflow.schema.registry import COMPUTATIONS
        from pipeflow.schema.simulation import PAPER_EXAMPLE
        from service import encoding

        ErrorRecord.runtime_limit(1.0).to_dict()
        classify(OverflowError("warm-up")).to_dict()
        small = dict(PAPER_EXAMPLE, modes=2, time={"t_end": 0.01, "samples": 11})
        simulation = COMPUTATIONS["simulation"]
        specs = [dict(small, method=method) for method in _WARM_UP_METHODS]
        # the default request's model (mode integrals cached per mode count) and solver
        # paths, time-variant and constant flow: a first such job cost 2-3x the later ones
        modes = simulation.request.model_fields["modes"].default
        default = {k: v for k, v in small.items() if k != "method"} | {"modes": modes}
        specs += [default, default | {"flow": {"velocity": {"kind": "constant", "value": 0.4}}}]
        for spec in specs:
            request = simulation.request.model_validate(spec)
            encoding.dumps(simulation.execute(request, lambda fraction: None))
    except Exception:
        log.exception("worker warm-up failed")
        return
    _warmed_up[0] = True
    log.info(
        "worker warmed up",
        extra={"duration_ms": round((time.perf_counter() - started) * 1e3, 3)},
    )


def warm_task(cfg: Any) -> int:
    """The first task of a worker (the runner sends one to each worker before it is
    ready): it opens the worker's store (engine, first connection, pragmas) for the
    service's database, and its answer opens the client's connection to the worker, so
    the first job pays for neither.  Returns the worker's pid."""
    from service.engine.task import _store

    _store(cfg).has_result("0" * 64)
    return os.getpid()


def _open_stores() -> list[str]:
    """The database URLs this worker has a store open for (none before its first task)."""
    task = sys.modules.get("service.engine.task")
    return list(getattr(task, "_STORES", {}))


def ping() -> dict[str, Any]:
    """The worker's pid, BLAS thread settings and whether numpy is loaded (tests)."""
    return {
        "pid": os.getpid(),
        "threads": {name: os.environ.get(name) for name in THREAD_VARIABLES},
        "numpy_loaded": "numpy" in sys.modules,
        "registry_loaded": "pipeflow.schema.registry" in sys.modules,
        "warmed_up": _warmed_up[0],
        "stores": sorted(_open_stores()),
        "malloc_trim_threshold": os.environ.get("MALLOC_TRIM_THRESHOLD_"),
        "modules": sorted(sys.modules),
    }
