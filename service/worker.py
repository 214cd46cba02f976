"""Code that runs inside the worker processes.

Imported by freshly spawned workers, so it must not import numpy (or pipeflow) at module
level: :func:`init` pins the BLAS thread pools to one thread first, then imports the
numerical stack.  Results travel back as JSON bytes (serialised here, with non-finite
numbers refused) and errors as problem dicts, never as pickled exceptions.
"""

from __future__ import annotations

import json
import os
import time
from collections.abc import Callable
from typing import Any

from service import store

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


def init() -> None:
    """Process-pool initializer: one BLAS thread per worker, then warm the imports."""
    for name in THREAD_VARIABLES:
        os.environ[name] = "1"
    import pipeflow.simulation  # noqa: F401  (imports numpy/scipy with the pinned env)


def ping() -> dict[str, Any]:
    """What a worker looks like from inside (used by readiness warm-up and tests)."""
    import sys

    return {
        "pid": os.getpid(),
        "threads": {name: os.environ.get(name) for name in THREAD_VARIABLES},
        "numpy_loaded": "numpy" in sys.modules,
    }


def run(
    function: Callable[[Any, Callable[[float], None]], dict[str, Any]],
    spec_model: Any,
    spec: dict[str, Any],
    key: str,
    db_path: str,
    timeout_s: float,
    interval_s: float,
) -> Outcome:
    """Validate ``spec`` with ``spec_model``, run ``function(spec, progress)``, return bytes.

    Progress is written to the job record at most every ``interval_s`` seconds, and each
    write checks the cancel flag and the runtime limit ``timeout_s`` [s]; the solver stops
    by the :class:`pipeflow.errors.Cancelled` raised from its progress callback.
    """
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
            validated = spec_model.model_validate(spec)
            result = function(validated, progress)
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
            body = json.dumps(result, separators=(",", ":"), allow_nan=False).encode()
        except ValueError:  # Inf or NaN: JSON has neither
            return ("error", out_of_range_problem("the result holds Inf or NaN"))
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
