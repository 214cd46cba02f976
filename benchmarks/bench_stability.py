"""Benchmarks of the stability analyses (wall time; not run by CI).

    python benchmarks/bench_stability.py

Target from issue 5: a 100 x 100 (v, w0) stability map of the paper's pipe with 10 modes in
about a second on this 2-core machine.  Also times one critical-velocity analysis, an Argand
sweep, the u_cr(beta) map and a parametric-resonance chart, and prints u_cr(beta).
"""

from __future__ import annotations

import math
import os
import time
from collections.abc import Callable
from typing import Any

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

from pipeflow.computations import documents
from pipeflow.model import build_model
from pipeflow.paper import PAPER_PIPE
from pipeflow.stability import critical_velocities
from pipeflow.stability.core import eigenvalues, nondimensional_pipe
from pipeflow.stability.floquet import resonance_chart
from pipeflow.stability.maps import beta_map, spin_map
from pipeflow.stability.sweeps import sweep


def timed(label: str, fn: Callable[[], Any], repeat: int = 3) -> Any:
    best = math.inf
    out = None
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t0)
    print(f"{label:58s} {best:8.3f} s")
    return out


def main() -> None:
    timed(
        "spin_map 100 x 100 (v, w0), paper pipe, 10 modes",
        lambda: spin_map(PAPER_PIPE, (0.0, 60.0), (0.0, 2000.0), 10, 100, 100),
    )
    timed(
        "critical_velocities, paper pipe, w0 = 100, 10 modes",
        lambda: critical_velocities(PAPER_PIPE, 100.0, (0.0, 60.0), 10),
    )
    timed(
        "argand sweep 201 points, 10 modes, refinement",
        lambda: sweep(PAPER_PIPE, "velocity", (0.0, 60.0), 100.0, 10, 4, 201),
    )
    bm = timed(
        "beta_map 100 betas x 201 u, 10 modes",
        lambda: beta_map((0.05, 0.95), (0.0, 20.0), 0.0, 10, 100, 201),
        repeat=1,
    )
    window = documents.beta_map(bm)["multiple_crossings"]
    print(f"  betas with several crossings: {window}")
    pipe = nondimensional_pipe(0.2)
    v0 = 4.0 / math.sqrt(0.2)
    w = eigenvalues(build_model(pipe, 4), v0, 0.0)[0]
    om2 = sorted(w.imag[w.imag > 0])[1]
    ch = timed(
        "resonance_chart 21 x 41, 4 modes (beta 0.2, u 4)",
        lambda: resonance_chart(pipe, v0, (0, 0.8 * v0), (1.5 * om2, 2.5 * om2), 0.0, 4, 21, 41),
        repeat=1,
    )
    for r in documents.resonance_regions(ch)[:2]:
        print("  region", r)
    print("u_cr(beta), 10 modes:")
    for beta in (0.1, 0.2, 0.3, 0.5, 0.8):
        p = nondimensional_pipe(beta)
        res = critical_velocities(p, 0.0, (0.0, 20.0 / math.sqrt(beta)), 10)
        first = next(c for c in res.crossings if c.boundary)
        print(f"  beta {beta}: u_cr = {res.u_cr:.5f} (mode {first.mode})")


if __name__ == "__main__":
    main()
