"""Code that runs inside the worker processes.

Imported by freshly spawned workers, so it must not import numpy (or pipeflow) at module
level: :func:`init` pins the BLAS thread pools to one thread first, then imports the
numerical stack, and warms up (:func:`warm_up`).  Results travel back as JSON bytes
(serialised here by :func:`service.encoding.dumps`: non-finite numbers become null) and
errors as problem dicts, never as pickled exceptions.
"""

from __future__ import annotations

import logging
import os
import time
from typing import TYPE_CHECKING, Any

from service import encoding, observability, store

log = logging.getLogger("service.worker")

if TYPE_CHECKING:  # the worker imports numpy only after init() has pinned the threads
    from pipeflow.schema.registry import Computation

THREAD_VARIABLES = (
    "OMP_NUM_THREADS",
    "OPENBLAS_NUM_THREADS",
    "MKL_NUM_THREADS",
    "BLIS_NUM_THREADS",
    "VECLIB_MAXIMUM_THREADS",
    "NUMEXPR_NUM_THREADS",
)

# Outcome of one run: ("ok", json bytes) | ("error", problem dict) | ("cancelled", reason)
Outcome = tuple[str, Any]


def init(log_level: str = "INFO", log_format: str = "json") -> None:
    """Process-pool initializer: one BLAS thread per worker, the server's log settings,
    then warm the imports."""
    for name in THREAD_VARIABLES:
        os.environ[name] = "1"
    observability.configure_logging(log_level, log_format)
    import pipeflow.simulation  # noqa: F401  (imports numpy/scipy with the pinned env)

    warm_up()


#: the warm-up case: the paper's pipe, 2 modes, 11 samples (milliseconds per method)
_WARM_UP_METHODS = ("cma", "magnus", "rk4")
_warmed_up = [False]


def warm_up() -> None:
    """Import everything a computation needs (every job kind's module) and run a tiny
    simulation per solver through the job function and the encoder, so the first-use
    costs (lazy imports inside scipy and pipeflow, pydantic's validators, matplotlib for
    the plot names) are paid before the worker takes its first job.  A failure here is
    logged, never fatal: the job would then pay (and report) it."""
    started = time.perf_counter()
    try:
        from numpy.linalg import LinAlgError  # noqa: F401  (what run() imports, all of it)

        from pipeflow.errors import Cancelled, PipeflowError  # noqa: F401
        from pipeflow.schema.registry import COMPUTATIONS
        from pipeflow.schema.simulation import PAPER_EXAMPLE
        from service.problems import pipeflow_problem, problem  # noqa: F401  (FastAPI: ~1 s)

        small = dict(PAPER_EXAMPLE, modes=2, time={"t_end": 0.01, "samples": 11})
        for method in _WARM_UP_METHODS:
            simulation = COMPUTATIONS["simulation"]
            spec = simulation.request.model_validate(dict(small, method=method))
            encoding.dumps(simulation.execute(spec, lambda fraction: None))
    except Exception:
        log.exception("worker warm-up failed")
        return
    _warmed_up[0] = True
    log.info(
        "worker warmed up",
        extra={"duration_ms": round((time.perf_counter() - started) * 1e3, 3)},
    )


def ping() -> dict[str, Any]:
    """What a worker looks like from inside (used by readiness warm-up and tests)."""
    import sys

    return {
        "pid": os.getpid(),
        "threads": {name: os.environ.get(name) for name in THREAD_VARIABLES},
        "numpy_loaded": "numpy" in sys.modules,
        "registry_loaded": "pipeflow.schema.registry" in sys.modules,
        "warmed_up": _warmed_up[0],
        "modules": sorted(sys.modules),
    }


def run(
    computation: Computation,
    request: Any,
    key: str,
    db_path: str,
    timeout_s: float,
    interval_s: float,
    request_id: str | None = None,
) -> Outcome:
    """Run ``computation.execute(request, progress)`` on the request validated by the route
    (pickled, not validated again), return its JSON bytes.

    ``request_id`` (of the request that started the computation) is set for the log lines
    written meanwhile (:data:`service.observability.REQUEST_ID`).  Progress is written to
    the job record at most every ``interval_s`` seconds, and each
    write checks the cancel flag and the runtime limit ``timeout_s`` [s]; the solver stops
    by the :class:`pipeflow.errors.Cancelled` raised from its progress callback.
    """
    token = observability.REQUEST_ID.set(request_id)
    started = time.perf_counter()
    log.info("computation started", extra={"key": key, "computation": computation.name})
    try:
        outcome = _run(computation, request, key, db_path, timeout_s, interval_s)
        log.info(
            "computation finished",
            extra={
                "key": key,
                "outcome": outcome[0],
                "duration_ms": round((time.perf_counter() - started) * 1e3, 3),
            },
        )
    finally:
        observability.REQUEST_ID.reset(token)
    return outcome


def _run(
    computation: Computation,
    request: Any,
    key: str,
    db_path: str,
    timeout_s: float,
    interval_s: float,
) -> Outcome:
    from numpy.linalg import LinAlgError

    from pipeflow.errors import Cancelled, PipeflowError
    from service.problems import pipeflow_problem, problem

    conn = store.connect(db_path)
    try:
        if not store.mark_started(conn, key):
            return ("cancelled", "cancelled before it started")
        deadline = time.monotonic() + timeout_s
        last = [0.0]

        def progress(fraction: float) -> None:
            now = time.monotonic()
            if now > deadline:
                raise Cancelled("runtime limit")  # caught below as a runtime failure
            if now - last[0] < interval_s:
                return
            last[0] = now
            if store.report_progress(conn, key, fraction):
                raise Cancelled("cancelled by request")

        try:
            result = computation.execute(request, progress)
        except Cancelled as exc:
            if time.monotonic() > deadline:
                return ("error", runtime_problem(timeout_s))
            return ("cancelled", str(exc) or "cancelled")
        except PipeflowError as exc:
            return ("error", pipeflow_problem(exc))
        except (ArithmeticError, LinAlgError) as exc:
            return ("error", out_of_range_problem(f"{type(exc).__name__}: {exc}"))
        except Exception as exc:
            return (
                "error",
                problem(500, f"internal error: {type(exc).__name__}: {exc}", slug="internal"),
            )
        try:
            body = encoding.dumps(result)  # non-finite numbers -> null (the one rule)
        except Exception as exc:
            return (
                "error",
                problem(500, f"internal error: {type(exc).__name__}: {exc}", slug="internal"),
            )
        return ("ok", body)
    finally:
        conn.close()


def runtime_problem(timeout_s: float) -> dict[str, Any]:
    from service.problems import problem

    return problem(
        422,
        f"the computation exceeded the runtime limit of {timeout_s:g} s; ask for fewer modes, "
        "samples or a shorter t_end",
        slug="runtime-limit",
        title="Runtime limit exceeded",
    )


def out_of_range_problem(cause: str) -> dict[str, Any]:
    """422 for inputs whose magnitudes take the numerics out of double precision.

    Valid in type and sign but extreme (e.g. ``pipe.L`` = 1e308 m, ``omega0`` = 1e308
    rad/s): the model overflows or divides by zero.  No single field can be blamed, so
    the problem names the inputs whose magnitudes set the scales.
    """
    from service.problems import problem

    return problem(
        422,
        f"the inputs take the computation out of the range of double precision ({cause}); "
        "check the magnitudes of pipe (E, I, L, M1, M2, damping, tip_mass, tip_inertia), "
        "rotation.omega0, rotation.hub_radius and flow.velocity",
        slug="numerical-range",
        title="Inputs out of numerical range",
    )
