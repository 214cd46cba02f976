"""Dense output of ``magnus``: cost against the number of output samples (issue 23).

    OMP_NUM_THREADS=1 python benchmarks/bench_dense.py [--rounds 5] [--samples 2001 20001 100001]
    python benchmarks/bench_dense.py --smoke

The paper's example (v = 0.4 t m/s, w0 = 100 rad/s, 10 modes, 1 s, default method ``auto``,
which runs ``magnus`` at tolerance 1e-8) at 2,001, 20,001 and 100,001 samples.  Each round
times, for every sample count in rotating order (so the load of the shared machine hits
every count alike): ``simulate()`` alone, and ``simulate()`` followed by its document
(``documents.simulation``, what the service stores: the ``to_dict`` of the result).  Wall
and CPU (``time.process_time``) times; the table gives best and median wall, median CPU and
the ratios of each to the first sample count's, measured in the same run, plus what the
solver reports: steps, exponentials, estimated error and how the samples were produced
(``diagnostics.dense_output``).  The issue's target: 100,001 samples within 3x of 2,001
for ``simulate()``, accuracy at every sample within the tolerance
(tests/pipeflow/solvers/test_magnus_dense.py).

``--smoke``: one round at 2,001 and 8,001 samples (a few seconds).
"""

from __future__ import annotations

import argparse
import os
import statistics
import time
from typing import Any

from pipeflow.computations import documents
from pipeflow.paper import PAPER_FLOW, PAPER_PIPE, PAPER_SPIN
from pipeflow.simulation import Simulation, simulate


def timed(fn: Any) -> tuple[float, float, Any]:
    """Wall and CPU seconds of one call of ``fn``, and its result."""
    t0, c0 = time.perf_counter(), time.process_time()
    out = fn()
    return time.perf_counter() - t0, time.process_time() - c0, out


def run(samples: list[int], rounds: int) -> dict[str, Any]:
    """Interleaved rounds; per (what, samples) the wall and CPU times and the last result."""
    sims = {n: Simulation(PAPER_PIPE, flow=PAPER_FLOW, spin=PAPER_SPIN, samples=n) for n in samples}
    wall: dict[tuple[str, int], list[float]] = {}
    cpu: dict[tuple[str, int], list[float]] = {}
    last: dict[int, Any] = {}
    for n in samples:  # warm-up (imports, caches of the model and quadrature)
        documents.simulation(simulate(sims[n]))
    for r in range(rounds):
        order = samples[r % len(samples) :] + samples[: r % len(samples)]
        for n in order:
            for what in ("simulate", "simulate + document"):
                if what == "simulate":
                    w, c, res = timed(lambda n=n: simulate(sims[n]))
                    last[n] = res
                else:
                    w, c, _ = timed(lambda n=n: documents.simulation(simulate(sims[n])))
                wall.setdefault((what, n), []).append(w)
                cpu.setdefault((what, n), []).append(c)
    return {"wall": wall, "cpu": cpu, "last": last}


def report(samples: list[int], rounds: int, data: dict[str, Any]) -> None:
    wall, cpu, last = data["wall"], data["cpu"], data["last"]
    print(
        f"paper example, default method; load average {os.getloadavg()[0]:.2f} (1 min), "
        f"{rounds} interleaved rounds"
    )
    print()
    print("| samples | steps | exponentials | estimate | samples filled by |")
    print("|---:|---:|---:|---:|---|")
    for n in samples:
        d = last[n].diagnostics
        dense = d.get("dense_output")
        how = (
            f"{dense['samples_filled']:,} filled ({dense['method']}, fill error "
            f"{dense['fill_estimated_relative_error']:.2g})"
            if dense
            else "every sample a step end"
        )
        print(
            f"| {n:,} | {d['steps']:,} | {d['matrix_exponentials']:,} | "
            f"{d['estimated_relative_error']:.3g} | {how} |"
        )
    print()
    print(
        "| what | samples | best [ms] | median [ms] | CPU median [ms] | best / first | "
        "median / first | CPU / first |"
    )
    print("|---|---:|---:|---:|---:|---:|---:|---:|")
    for what in ("simulate", "simulate + document"):
        # per sample count: best wall, median wall, median CPU [s]
        stats = {
            n: (
                min(wall[(what, n)]),
                statistics.median(wall[(what, n)]),
                statistics.median(cpu[(what, n)]),
            )
            for n in samples
        }
        first = stats[samples[0]]
        for n, row in stats.items():
            ms = " | ".join(f"{v * 1e3:.1f}" for v in row)
            ratios = " | ".join(f"{v / f:.2f}" for v, f in zip(row, first, strict=True))
            print(f"| {what} | {n:,} | {ms} | {ratios} |")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--samples", type=int, nargs="+", default=[2001, 20001, 100001])
    parser.add_argument("--smoke", action="store_true", help="one round, 2,001 and 8,001")
    args = parser.parse_args()
    samples, rounds = ([2001, 8001], 1) if args.smoke else (args.samples, args.rounds)
    report(samples, rounds, run(samples, rounds))


if __name__ == "__main__":
    main()
