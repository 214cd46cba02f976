"""What a Dask worker process of the service looks like from inside.

The service's workers run with one thread and one BLAS thread each
(:data:`THREAD_VARIABLES` set to 1 in the worker's environment before numpy loads): two
computations on two cores must not fight over BLAS threads.  ``dask worker --preload
service.engine.worker`` (and the embedded cluster) import the numerical stack at start,
so the first request does not pay for it.
"""

from __future__ import annotations

import os
import sys
from typing import Any

THREAD_VARIABLES = (
    "OMP_NUM_THREADS",
    "OPENBLAS_NUM_THREADS",
    "MKL_NUM_THREADS",
    "BLIS_NUM_THREADS",
    "VECLIB_MAXIMUM_THREADS",
    "NUMEXPR_NUM_THREADS",
)

#: the environment of a worker process: one BLAS thread
WORKER_ENV = dict.fromkeys(THREAD_VARIABLES, "1")


def dask_setup(worker: Any) -> None:
    """Dask preload hook: pin BLAS threads (if the launcher did not), warm the imports."""
    for name in THREAD_VARIABLES:
        os.environ.setdefault(name, "1")
    import pipeflow.simulation  # noqa: F401  (numpy/scipy with the pinned environment)
    import service.engine.task  # noqa: F401


def ping() -> dict[str, Any]:
    """The worker's pid, BLAS thread settings and whether numpy is loaded (tests)."""
    return {
        "pid": os.getpid(),
        "threads": {name: os.environ.get(name) for name in THREAD_VARIABLES},
        "numpy_loaded": "numpy" in sys.modules,
    }
