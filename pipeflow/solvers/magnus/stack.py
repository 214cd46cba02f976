"""The Magnus solver over a stack of problems: a design study's time-variant cases at once.

:func:`solve_many` runs :class:`~pipeflow.solvers.magnus.Magnus` on many problems of one
state size and output grid and gives each problem the output the single run gives it: the
same step plans, order choices, error estimates, refinements and diagnostics (the control
of :meth:`Magnus._solve_impl`, step for step), with the propagations of all problems that
are at the same stage done together.

How.  Each problem's step control is :func:`~pipeflow.solvers.magnus.step_control`, the
generator ``Magnus._solve_impl`` itself drives with the single run's
:func:`~pipeflow.solvers.magnus.propagate` (one definition of the control).
Where the single run propagates, the generator yields the run it needs (its generator,
output times and plan) and is sent the states back.  The driver collects
the pending runs of every problem, groups those on the same output times and state size,
and propagates each group by :func:`propagate_stack`: per window of output intervals, the
step exponentials of all the group's runs with the same sub-step count and order in one
:func:`~pipeflow.linalg.expm_stack` (the Magnus generators of each run from its own
:class:`~pipeflow.solvers.magnus.MagnusGenerator`), multiplied per interval
(:func:`~pipeflow.linalg.product_of_steps`), then applied to the stacked states by one
batched matrix-vector product per output interval instead of one per interval and run.
Each step exponential is the single run's (the same generator, the same per-matrix
scaling and squaring), so the states agree with the single run's to rounding.

Problems with external loads (the Jordan-bordered exponential-integrator step) or constant
coefficients (one exact exponential) are not taken (:func:`stackable`): their single runs
are already one batched exponential or differ in shape.
"""

from __future__ import annotations

import time
from collections import defaultdict
from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from pipeflow._types import FloatArray
from pipeflow.linalg import expm_stack, product_of_steps
from pipeflow.solvers.base import (
    Problem,
    SolverOutput,
    SolverStats,
)
from pipeflow.solvers.magnus.control import MagnusRun, StepControl, step_control
from pipeflow.solvers.magnus.generator import augmented_initial_state

#: most runs propagated together (bounds the window's propagators: 16 runs x 256
#: intervals x 21^2 entries = 14 MB at the paper's 10 modes) [-]
MAX_RUNS = 16
#: matrix entries of one window's propagators over all the group's runs [-]
WINDOW_ENTRIES = 2_000_000
#: most output intervals in one window (as the single run's window) [-]
MAX_WINDOW = 256
#: matrix entries of the step exponentials formed by one expm_stack call (measured on 13
#: runs of the paper's pipe, 10 modes, 2001 samples, v = a t for a in 0.1-2 m/s^2 and
#: w0 in 0-200 rad/s and a spin-up, three interleaved rounds on the loaded 2-core machine:
#: 12k, 50k, 200k and 1M entries took 3.7-4.4, 2.9-4.8, 2.9-4.2 and 3.9-6.4 s) [-]
EXPM_ENTRIES = 200_000


def stackable(problem: Problem) -> bool:
    """Whether :func:`solve_many` takes ``problem``: coefficients varying in time, no
    external loads."""
    return problem.loads is None and not problem.loading.is_time_invariant


def propagate_stack(
    runs: Sequence[MagnusRun], z0s: Sequence[FloatArray]
) -> tuple[FloatArray, list[int]]:
    """The states of every run (same output times and state size) from its initial state
    in ``z0s`` at its output times, shape (runs, times, size), and the exponentials each
    used."""
    t = runs[0].t
    n = runs[0].gen.size
    B = len(runs)
    dt = np.diff(t)
    K = dt.size
    Z = np.empty((B, t.size, n))
    z = np.stack(list(z0s))
    Z[:, 0] = z
    exps = [0] * B
    window = max(1, min(MAX_WINDOW, WINDOW_ENTRIES // (B * n * n)))
    for k in range(0, K, window):
        stop = min(K, k + window)
        E_win = np.empty((B, stop - k, n, n))
        # (run, intervals) per sub-step count and order, over the whole group
        groups: dict[int, list[tuple[int, NDArray[np.intp]]]] = defaultdict(list)
        for b, run in enumerate(runs):
            keys = run.plan.substeps[k:stop] * 16 + run.plan.order[k:stop]
            for key in np.unique(keys):
                groups[int(key)].append((b, k + np.flatnonzero(keys == key)))
        for key, parts in groups.items():
            m, q = key // 16, key % 16
            limit = max(1, EXPM_ENTRIES // (n * n * m))  # intervals per expm_stack call
            pieces = [
                (b, idx[s : s + limit]) for b, idx in parts for s in range(0, idx.size, limit)
            ]
            while pieces:
                batch, count = [], 0
                while pieces and count + pieces[0][1].size <= limit:
                    batch.append(pieces.pop(0))
                    count += batch[-1][1].size
                omegas = []
                for b, idx in batch:
                    h = dt[idx] / m
                    starts = (t[idx][:, None] + h[:, None] * np.arange(m)[None, :]).ravel()
                    omegas.append(runs[b].gen.omega(starts, np.repeat(h, m), q))
                    exps[b] += idx.size * m
                E = expm_stack(np.concatenate(omegas))
                P = product_of_steps(E.reshape(count, m, n, n))
                at = 0
                for b, idx in batch:
                    E_win[b, idx - k] = P[at : at + idx.size]
                    at += idx.size
        for j in range(stop - k):
            z = np.matmul(E_win[:, j], z[:, :, None])[:, :, 0]
            Z[:, k + j + 1] = z
    return Z, exps


def solve_many(problems: Sequence[Problem]) -> list[SolverOutput | Exception]:
    """:meth:`Magnus.solve` of every problem (each :func:`stackable`), or the exception its
    single run raises (a budget exceeded, an invalid option).  The diagnostics are the
    single run's; ``solve_seconds`` is the stack's wall time shared evenly."""
    started = time.perf_counter()
    out: list[SolverOutput | Exception | None] = [None] * len(problems)
    stats = [SolverStats() for _ in problems]
    controls: dict[int, StepControl] = {}
    pending: dict[int, MagnusRun] = {}

    def advance(i: int, sent: tuple[FloatArray, int] | None) -> None:
        try:
            run = controls[i].send(sent) if sent is not None else next(controls[i])
        except StopIteration as stop:
            out[i] = stop.value
            pending.pop(i, None)
        except Exception as exc:  # the single run raises it: the caller reports it
            out[i] = exc
            pending.pop(i, None)
        else:
            pending[i] = run

    for i, problem in enumerate(problems):
        if not stackable(problem):
            raise ValueError(f"problem {i} has loads or constant coefficients")
        controls[i] = step_control(problem, stats[i])
        advance(i, None)
    while pending:
        groups: dict[tuple[bytes, int], list[int]] = defaultdict(list)
        for i, run in pending.items():
            groups[(run.t.tobytes(), run.gen.size)].append(i)
        for members in groups.values():
            for s in range(0, len(members), MAX_RUNS):
                part = members[s : s + MAX_RUNS]
                Z, used = propagate_stack(
                    [pending[i] for i in part],
                    [augmented_initial_state(problems[i], pending[i].gen) for i in part],
                )
                for b, i in enumerate(part):
                    advance(i, (Z[b], used[b]))
    return _finish(list(zip(out, stats, strict=True)), started)


def _finish(
    results: Sequence[tuple[SolverOutput | Exception | None, SolverStats]], started: float
) -> list[SolverOutput | Exception]:
    """The outputs as ``Solver.solve`` completes them (counters in the diagnostics, the
    method); ``solve_seconds`` is the wall time since ``started`` shared evenly."""
    share = (time.perf_counter() - started) / max(1, len(results))
    done: list[SolverOutput | Exception] = []
    for result, stats in results:
        assert result is not None
        if isinstance(result, SolverOutput):
            stats.solve_seconds = share
            result.stats = stats
            result.method = "magnus"
            result.diagnostics.update(stats.as_dict())
        done.append(result)
    return done
