"""The HTTP service.

Importing it pins the BLAS and OpenMP thread pools of this process to one thread (unless
the environment already says otherwise), as the workers' are
(:mod:`service.engine.preload`): the API process computes only in its fast lane
(:mod:`service.engine.lane`), beside the workers on the same cores: with two BLAS
threads the lane's LTI computation took 8.0 and 10.9 ms (cold request 28 and 31 ms), with
one 3.6 and 3.5 ms (14.5 and 13.3 ms), alternated on the 2-core machine at a load of 3-4.
Effective only if numpy is not loaded yet (``uvicorn service.main:app`` imports this
first).
"""

from __future__ import annotations

import os

THREAD_VARIABLES = (
    "OMP_NUM_THREADS",
    "OPENBLAS_NUM_THREADS",
    "MKL_NUM_THREADS",
    "BLIS_NUM_THREADS",
    "VECLIB_MAXIMUM_THREADS",
    "NUMEXPR_NUM_THREADS",
)

for _name in THREAD_VARIABLES:
    os.environ.setdefault(_name, "1")
