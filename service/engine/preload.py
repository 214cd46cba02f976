"""What a Dask worker process of the service looks like from inside: one preload for every
way of starting workers.

``dask worker ADDRESS --nthreads 1 --preload-nanny service.engine.preload`` (the README's and
docker-compose.yml's command) and the embedded cluster (:mod:`service.engine.cluster`) load
this module in the nanny, before it spawns its worker process; :func:`dask_setup` there sets
the worker's environment (:func:`nanny_setup`) and loads the module again in the worker
(:func:`worker_setup`).  The worker's environment:

- one BLAS/OpenMP thread (:data:`WORKER_ENV`, set before numpy loads): two computations on
  two cores must not fight over BLAS threads;
- glibc's default, adaptive allocator: Dask's nanny sets ``MALLOC_TRIM_THRESHOLD_=65536`` by
  default (to hand freed memory back to the OS); glibc then trims after every large free and
  the paper example's many temporaries ran 1.3-1.7x slower in a worker (pipeflow's own
  measurement), so the nanny drops it (unless the operator's own environment sets it);
- the numerical stack imported and warmed up (:func:`warm_up`: a tiny run of each solver
  through the task's compute path and the encoder), so the first request does not pay;
- the worker's log lines on stdout in the service's format (``PIPEFLOW_LOG_LEVEL``,
  ``PIPEFLOW_LOG_FORMAT``).

``--preload service.engine.preload`` alone (worker side only, e.g. ``--no-nanny``) still
pins the threads and warms up, and warns when the nanny's allocator setting is in force.
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
#: the allocator setting Dask's nanny gives its workers by default, which the service drops
ALLOCATOR_VARIABLE = "MALLOC_TRIM_THRESHOLD_"
#: this module, as the nanny passes it on to its worker
MODULE = __name__


def dask_setup(target: Any) -> None:
    """Dask preload hook, in a nanny (``--preload-nanny``: :func:`nanny_setup`) or in a
    worker (``--preload``: :func:`worker_setup`)."""
    from distributed import Nanny

    if isinstance(target, Nanny):
        nanny_setup(target)
    else:
        worker_setup(target)


def nanny_setup(nanny: Any) -> None:
    """Before the nanny spawns (and respawns) its worker: the worker's environment
    (:data:`WORKER_ENV` unless the operator's environment sets a variable; the allocator
    setting dropped unless the operator set it), and this module as the worker's preload."""
    for env in (nanny.pre_spawn_env, nanny.env):
        for name, value in WORKER_ENV.items():
            if name not in os.environ:
                env[name] = value
        if ALLOCATOR_VARIABLE not in os.environ:
            env.pop(ALLOCATOR_VARIABLE, None)
    preloads = list(nanny.preload or [])
    if MODULE not in preloads:
        nanny.preload = [*preloads, MODULE]


def worker_setup(worker: Any) -> None:
    """In the worker process: pin BLAS threads (if the launcher did not), the service's log
    settings, then warm up."""
    for name in THREAD_VARIABLES:
        os.environ.setdefault(name, "1")
    from service import observability

    observability.configure_logging(
        os.environ.get("PIPEFLOW_LOG_LEVEL", "INFO"), os.environ.get("PIPEFLOW_LOG_FORMAT", "json")
    )
    if os.environ.get(ALLOCATOR_VARIABLE) is not None:
        log.warning(
            "%s=%s is set in this worker (Dask's nanny default): computations run 1.3-1.7x "
            "slower; start workers with --preload-nanny %s",
            ALLOCATOR_VARIABLE,
            os.environ[ALLOCATOR_VARIABLE],
            MODULE,
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
        from pipeflow.computations.registry import COMPUTATIONS
        from pipeflow.errors import ErrorRecord, classify
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
    release_memory()
    log.info(
        "worker warmed up",
        extra={"duration_ms": round((time.perf_counter() - started) * 1e3, 3)},
    )


def release_memory() -> None:
    """Hand the heap the warm-up freed back to the OS (glibc's ``malloc_trim``; nothing
    elsewhere): the idle process is 15-20 MB smaller.  Once, at start: after each job it
    would cost what Dask's trim threshold cost (see the module docstring)."""
    import ctypes
    import ctypes.util
    import gc

    gc.collect()
    name = ctypes.util.find_library("c")
    try:
        libc = ctypes.CDLL(name) if name else None
        if libc is not None and hasattr(libc, "malloc_trim"):
            libc.malloc_trim(0)
    except OSError:
        pass


#: glibc's environment variable of the malloc arena bound (the operator's, if set, stands)
ARENA_VARIABLE = "MALLOC_ARENA_MAX"
#: the bound :func:`cap_malloc_arenas` sets in the API process
API_ARENAS = 1
#: ``mallopt``'s parameter number of the arena bound (glibc's malloc.h)
_M_ARENA_MAX = -8


def cap_malloc_arenas(arenas: int = API_ARENAS) -> bool:
    """Bound glibc's malloc arenas of this process to ``arenas`` (``mallopt(M_ARENA_MAX)``),
    unless the operator's environment sets ``MALLOC_ARENA_MAX`` (glibc then read it itself).

    glibc gives each thread that allocates an arena of its own, up to 8 per core, and an
    arena keeps pages it touched: the API process runs its event loop, the store's and
    FastAPI's thread pools, the fast lane and Dask's client and nannies, and held 11 arenas
    and 16 MB more idle than with one (a bound of 2 saved the same with 2 workers but not
    with 1: ``benchmarks/RESULTS.md``, issue 34).  The GIL serialises the Python
    allocations of those threads anyway; what allocates without it (SQLite, zlib) waits for
    the one arena's lock instead.  Called before the process starts its threads (arenas
    made earlier stay); returns whether the bound was set (False elsewhere than on glibc,
    or when the operator set one)."""
    import ctypes
    import ctypes.util

    if os.environ.get(ARENA_VARIABLE) is not None or not sys.platform.startswith("linux"):
        return False
    name = ctypes.util.find_library("c")
    try:
        libc = ctypes.CDLL(name) if name else None
    except OSError:
        return False
    mallopt = getattr(libc, "mallopt", None)
    if mallopt is None:
        return False
    return bool(mallopt(_M_ARENA_MAX, int(arenas)))


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
    store = sys.modules.get("service.store")
    return list(getattr(store, "_STORES", {}))


def ping() -> dict[str, Any]:
    """The worker's pid, BLAS thread settings and whether numpy is loaded (tests)."""
    return {
        "pid": os.getpid(),
        "threads": {name: os.environ.get(name) for name in THREAD_VARIABLES},
        "numpy_loaded": "numpy" in sys.modules,
        "registry_loaded": "pipeflow.computations.registry" in sys.modules,
        "warmed_up": _warmed_up[0],
        "stores": sorted(_open_stores()),
        "malloc_trim_threshold": os.environ.get(ALLOCATOR_VARIABLE),
        "modules": sorted(sys.modules),
    }
