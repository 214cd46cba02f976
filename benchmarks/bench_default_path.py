"""The whole default path of ``simulate()``, not only the solver (issue 9, section 3).

    python benchmarks/bench_default_path.py [--repeats 7]
    python benchmarks/bench_default_path.py --ab main=/work/main branch=. [--rounds 15]
    python benchmarks/bench_default_path.py --parts [--rounds 15]

On the paper's example (10 modes, 1 s, 2001 samples, w0 = 100 rad/s, default method
``auto``) for v = 0.4 m/s (constant: ``auto`` runs ``cma``) and v = 0.4 t m/s (``auto``
runs ``magnus``) it prints, best of ``--repeats`` runs: the wall time of ``simulate()``,
the solver's own time (``diagnostics.solve_seconds``), the error check
(``diagnostics.error_estimate_seconds``), the frozen-spectrum and CMA-exponent traces
(timed separately with the same functions), and the ratio simulate / solver of the same
run (median over the runs).  Target of the issue for the constant case: simulate <= 3x the solver.

``--ab NAME=TREE ...``: an A/B of source trees (e.g. main's checkout against this one), the
issue-23 target "the paper example's ``simulate().to_dict()`` at most 0.6x of main's".  One
child process per tree (its ``PYTHONPATH`` the tree) times ``documents.simulation(simulate())``
of the paper example (the service's request example: v = 0.4 t, w0 = 100 rad/s, 10 modes,
1 s, 2001 samples, default method), one call per round, the trees in rotating order within
each round, so that the load of the shared machine hits every side alike; it prints each
tree's best and median and the ratios to the first tree's.

``--parts``: where the paper example's document time goes, in this tree (one process,
CPU time, the parts in rotating order within each of ``--rounds`` rounds, medians): the
whole ``documents.simulation(simulate())``; the magnus solve's matrix exponentials
(``expm_stack`` on the very stacks the solve passed it, recorded once); their batched
20 x 20 products alone (the same blocks, 5 + s products each, s the block's squarings:
the floor of the scaling-and-squaring Taylor scheme); the two eigenvalue stacks (the
frozen spectrum and the CMA exponents, ``numpy.linalg.eigvals`` on the recorded stacks);
and the rest (the whole minus exponentials and eigenvalues).
"""

from __future__ import annotations

import argparse
import math
import os
import statistics
import subprocess
import sys
import time
from collections.abc import Callable
from typing import Any

import numpy as np

from pipeflow.loading import Loading
from pipeflow.model import build_model
from pipeflow.paper import PAPER_FLOWS, PAPER_PIPE, PAPER_SPIN
from pipeflow.profiles import Profile
from pipeflow.simulation import Simulation, cma_exponents, frozen_spectrum, simulate

CASES: dict[str, Profile] = {"v=0.4 (LTI)": PAPER_FLOWS["v=0.4"], "v=0.4t": PAPER_FLOWS["v=0.4t"]}


def best(fn: Callable[[], Any], repeats: int) -> tuple[float, Any]:
    """Fastest wall time [s] of ``repeats`` calls of ``fn``, and its last result."""
    out, fastest = None, float("inf")
    for _ in range(repeats):
        t0 = time.perf_counter()
        out = fn()
        fastest = min(fastest, time.perf_counter() - t0)
    return fastest, out


#: the child of one tree in --ab: times one paper-example document per line read
_CHILD = """
import sys, time
from pipeflow.computations import documents
from pipeflow.schema.simulation import PAPER_EXAMPLE, SimulationSpec
from pipeflow.simulation import simulate
spec = {k: v for k, v in PAPER_EXAMPLE.items() if k != "method"}
sim = SimulationSpec.model_validate(spec).to_simulation()
documents.simulation(simulate(sim))  # warm-up
from pipeflow.model import build_model
from pipeflow.loading import Loading
from pipeflow.solvers import SOLVERS, Problem
import numpy as np
model = build_model(sim.pipe, sim.modes)
d0, v0 = model.initial_state(sim.u0, sim.du0, sim.initial_shape)
problem = Problem(
    model, Loading(sim.flow, sim.spin), model.to_balanced(d0, v0),
    np.linspace(0.0, sim.t_end, sim.samples), sim.options,
)
from pipeflow.profiles import Harmonic
pulsating = Problem(
    model, Loading(Harmonic(2.0, 1.0, 50.0), sim.spin), problem.z0, problem.t, sim.options
)
print("ready", flush=True)
for line in sys.stdin:
    t0, c0 = time.perf_counter(), time.process_time()
    if line.strip() == "document":
        diagnostics = documents.simulation(simulate(sim))["diagnostics"]
    elif line.strip() == "pulsating":  # the solver on v = 2 + sin 50 t instead
        diagnostics = SOLVERS["magnus"].solve(pulsating).diagnostics
    else:  # the solver alone (magnus, what "auto" runs here)
        diagnostics = SOLVERS["magnus"].solve(problem).diagnostics
    dt, dc = time.perf_counter() - t0, time.process_time() - c0
    print(dt, dc, diagnostics["estimated_relative_error"], flush=True)
"""


def ab(trees: list[str], rounds: int, what: str = "document") -> None:
    """Interleaved A/B of ``simulate().to_dict()`` on the paper example across trees."""
    children: dict[str, subprocess.Popen[str]] = {}
    for item in trees:
        name, _, path = item.partition("=")
        env = dict(os.environ, PYTHONPATH=os.path.abspath(path))
        children[name] = subprocess.Popen(
            [sys.executable, "-c", _CHILD],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            text=True,
            env=env,
            cwd=os.path.abspath(path),
        )
    names = list(children)
    times: dict[str, list[float]] = {n: [] for n in names}
    cpu: dict[str, list[float]] = {n: [] for n in names}
    estimate: dict[str, str] = {}
    try:
        for child in children.values():
            assert child.stdout is not None and child.stdout.readline().strip() == "ready"
        for r in range(rounds):
            for name in names[r % len(names) :] + names[: r % len(names)]:
                child = children[name]
                assert child.stdin is not None and child.stdout is not None
                child.stdin.write(what + "\n")
                child.stdin.flush()
                dt, dc, est = child.stdout.readline().split()
                times[name].append(float(dt))
                cpu[name].append(float(dc))
                estimate[name] = est
    finally:
        for child in children.values():
            if child.stdin is not None:
                child.stdin.close()
            child.wait(timeout=60)
    print(f"{what}: load average {os.getloadavg()[0]:.2f} (1 min), {rounds} interleaved rounds")
    print(
        "| tree | best [ms] | median [ms] | best / first | median / first | "
        "CPU median [ms] | CPU / first | estimate |"
    )
    print("|---|---:|---:|---:|---:|---:|---:|---|")
    b0, m0 = min(times[names[0]]), statistics.median(times[names[0]])
    c0 = statistics.median(cpu[names[0]])
    for n in names:
        b, m, c = min(times[n]), statistics.median(times[n]), statistics.median(cpu[n])
        print(
            f"| {n} | {b * 1e3:.1f} | {m * 1e3:.1f} | {b / b0:.2f} | {m / m0:.2f} | "
            f"{c * 1e3:.1f} | {c / c0:.2f} | {estimate[n]} |"
        )


def parts(rounds: int) -> None:
    """--parts: the paper example's document time by part (module docstring)."""
    import pipeflow.solvers.magnus.generator as magnus
    from pipeflow.computations import documents
    from pipeflow.linalg import TAYLOR_THETA, expm_stack
    from pipeflow.schema.simulation import PAPER_EXAMPLE, SimulationSpec

    spec = {k: v for k, v in PAPER_EXAMPLE.items() if k != "method"}
    sim = SimulationSpec.model_validate(spec).to_simulation()
    blocks: list[np.ndarray] = []
    stacks: list[np.ndarray] = []
    real_expm, real_eigvals = magnus.expm_stack, np.linalg.eigvals

    def recording_expm(X: np.ndarray) -> np.ndarray:
        blocks.append(np.array(X))
        return real_expm(X)

    def recording_eigvals(S: np.ndarray) -> np.ndarray:
        stacks.append(np.array(S))
        return real_eigvals(S)

    magnus.expm_stack = recording_expm  # type: ignore[assignment]
    np.linalg.eigvals = recording_eigvals  # type: ignore[assignment]
    try:
        documents.simulation(simulate(sim))
    finally:
        magnus.expm_stack = real_expm  # type: ignore[assignment]
        np.linalg.eigvals = real_eigvals  # type: ignore[assignment]
    # the products of each block: 5 for the polynomial (Y^2, Y^3, Y^6, A9, R) and s
    # squarings, s from its largest 1-norm as expm_stack chooses it
    squarings = [
        max(0, math.ceil(math.log2(max(np.abs(X).sum(axis=-2).max(), 1e-300) / TAYLOR_THETA)))
        for X in blocks
    ]
    work = [np.empty_like(X) for X in blocks]

    def products() -> None:
        for X, s, out in zip(blocks, squarings, work, strict=True):
            for _ in range(5 + s):
                np.matmul(X, X, out=out)

    jobs: dict[str, Callable[[], Any]] = {
        "document": lambda: documents.simulation(simulate(sim)),
        "exponentials": lambda: [expm_stack(X) for X in blocks],
        "their products alone": products,
        "eigenvalues": lambda: [np.linalg.eigvals(S) for S in stacks],
    }
    cpu: dict[str, list[float]] = {name: [] for name in jobs}
    names = list(jobs)
    for r in range(rounds):
        for name in names[r % len(names) :] + names[: r % len(names)]:
            c0 = time.process_time()
            jobs[name]()
            cpu[name].append(time.process_time() - c0)
    med = {name: statistics.median(v) for name, v in cpu.items()}
    count = sum(X.shape[0] for X in blocks)
    n_products = sum((5 + s) * X.shape[0] for X, s in zip(blocks, squarings, strict=True))
    print(
        f"paper example by part: load average {os.getloadavg()[0]:.2f} (1 min), {rounds} "
        f"rounds, CPU medians; {count} exponentials in {len(blocks)} blocks ({n_products} "
        f"20 x 20 products), eigenvalue stacks {[S.shape[0] for S in stacks]}"
    )
    print("| part | CPU median [ms] | share of the document |")
    print("|---|---:|---:|")
    whole = med["document"]
    rows = [*jobs, "rest (document - exponentials - eigenvalues)"]
    med[rows[-1]] = whole - med["exponentials"] - med["eigenvalues"]
    for name in rows:
        print(f"| {name} | {med[name] * 1e3:.1f} | {med[name] / whole:.2f} |")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--repeats", type=int, default=7)
    parser.add_argument("--ab", nargs="+", metavar="NAME=TREE", help="A/B of source trees")
    parser.add_argument("--rounds", type=int, default=15)
    parser.add_argument(
        "--what",
        choices=("document", "solve", "pulsating"),
        default="document",
        help="--ab times simulate() + the document, the magnus solver alone, or the solver "
        "on the pulsating flow v = 2 + sin 50 t m/s",
    )
    parser.add_argument(
        "--parts", action="store_true", help="the paper example's document time by part"
    )
    args = parser.parse_args()
    if args.parts:
        parts(args.rounds)
        return
    if args.ab:
        ab(args.ab, args.rounds, args.what)
        return
    model = build_model(PAPER_PIPE, 10)
    eigen_t = np.linspace(0.0, 1.0, 201)
    print("| case | method used | simulate [ms] | solver [ms] | check [ms] | traces [ms] | ratio |")
    print("|---|---|---|---|---|---|---|")
    for name, flow in CASES.items():
        sim = Simulation(PAPER_PIPE, flow=flow, spin=PAPER_SPIN)
        runs = []
        for _ in range(args.repeats):  # wall and solver time of the same run
            t0 = time.perf_counter()
            result = simulate(sim)
            runs.append((time.perf_counter() - t0, result.diagnostics["solve_seconds"], result))
        wall, solve, result = min(runs, key=lambda r: r[0])
        ratio = float(np.median([w / s for w, s, _ in runs]))
        loading = Loading(flow, PAPER_SPIN)

        def traces(loading: Loading = loading) -> None:
            frozen_spectrum(model, loading, eigen_t)
            if not loading.is_time_invariant:
                cma_exponents(model, loading, eigen_t, 3)

        tr, _ = best(traces, args.repeats)
        check = float(result.diagnostics.get("error_estimate_seconds", 0.0))
        print(
            f"| {name} | {result.method_used} | {wall * 1e3:.1f} | {solve * 1e3:.1f} | "
            f"{check * 1e3:.1f} | {tr * 1e3:.1f} | {ratio:.2f} |"
        )


if __name__ == "__main__":
    main()
