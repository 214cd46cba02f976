"""A supported pipe costs what the cantilever costs (issue 31, "Speed").

    python benchmarks/bench_supports.py [--rounds 5]

The same requests on the paper's pipe as a cantilever (clamped-free, the default) and as a
pinned-pinned span with a midspan spring and tension (the same pipe otherwise), in this one
process, the two in alternating order within each round (so the shared machine's load hits
both alike), median CPU-independent wall time per request and the ratio supported /
cantilever.  Target: every ratio <= 1.2.

- simulate: 10 modes, 1 s, 2001 samples, w0 = 100 rad/s, v = 0.4 t m/s (``auto`` -> magnus)
  and v = 0.4 m/s (``auto`` -> cma);
- FRF: 20 modes, 400 frequencies, point force at 0.6 L, two stations;
- stability map: spin_map, 10 modes, 40 velocities x 10 spins.

Each support set's basis is computed once per process (cached like the cantilever's); the
first round includes it and the median does not hide it: ``--cold`` times one first call each.
"""

from __future__ import annotations

import argparse
import dataclasses
import statistics
import time
from collections.abc import Callable

import numpy as np

from pipeflow import profiles
from pipeflow.frequency import PointForce, frequency_response
from pipeflow.paper import PAPER_PIPE
from pipeflow.simulation import Simulation, simulate
from pipeflow.stability.maps import spin_map
from pipeflow.supports import PointSupport, Support, Supports

CANTILEVER = PAPER_PIPE
SUPPORTED = dataclasses.replace(
    PAPER_PIPE,
    supports=Supports(Support("pinned"), Support("pinned")),
    intermediate_supports=(PointSupport(0.5 * PAPER_PIPE.L, translational=10.0),),
    tension=1e-3,
)
L = PAPER_PIPE.L


def cases(pipe: object) -> dict[str, Callable[[], object]]:
    def sim(flow: profiles.Profile) -> Callable[[], object]:
        return lambda: simulate(
            Simulation(
                pipe=pipe,
                flow=flow,
                spin=profiles.Constant(100.0),
                u0=1e-4,
                du0=0.0,
                modes=10,
                t_end=1.0,
                samples=2001,
            )
        )

    W = np.linspace(100.0, 4e4, 400)
    return {
        "simulate magnus (v = 0.4 t)": sim(profiles.polynomial(0.0, 0.4)),
        "simulate cma (v = 0.4)": sim(profiles.Constant(0.4)),
        "FRF (20 modes, 400 W)": lambda: frequency_response(
            pipe,
            5.0,
            100.0,
            load=PointForce(0.6 * L),
            positions=[0.25 * L, 0.5 * L],  # type: ignore[arg-type]
            frequencies=W,
            modes=20,
        ),
        "spin_map (40 x 10)": lambda: spin_map(
            pipe,
            (0.0, 40.0),
            (0.0, 1000.0),
            modes=10,
            velocity_points=40,
            spin_points=10,  # type: ignore[arg-type]
        ),
    }


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--rounds", type=int, default=5)
    args = ap.parse_args()
    a, b = cases(CANTILEVER), cases(SUPPORTED)
    times: dict[str, dict[str, list[float]]] = {k: {"cantilever": [], "supported": []} for k in a}
    for r in range(args.rounds):
        for name in a:
            order = [("cantilever", a[name]), ("supported", b[name])]
            for label, fn in order if r % 2 == 0 else order[::-1]:
                t0 = time.perf_counter()
                fn()
                times[name][label].append(time.perf_counter() - t0)
    print(f"{'request':32s} {'cantilever [s]':>15s} {'supported [s]':>14s} {'ratio':>7s}")
    for name, t in times.items():
        ca, su = statistics.median(t["cantilever"]), statistics.median(t["supported"])
        print(f"{name:32s} {ca:15.4f} {su:14.4f} {su / ca:7.3f}")


if __name__ == "__main__":
    main()
