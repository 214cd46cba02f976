"""Study benchmark of issue 19: a 10,000-case LTI design study, three ways.

    python benchmarks/bench_study.py                # ~1 min on the 2-core machine
    python benchmarks/bench_study.py --cases 2500   # a 50 x 50 grid
    python benchmarks/bench_study.py --smoke        # seconds: a 6 x 6 grid, 2 modes
    python benchmarks/bench_study.py --label x      # names the section written to RESULTS.md
    python benchmarks/bench_study.py --time-variant # the 100-case v = a t study (library)

    python benchmarks/bench_study.py --cpu          # print only: CPU of the shipped path
    PIPEFLOW_TREE=/work/main python benchmarks/bench_study.py --cpu   # of another checkout

The study: the paper's pipe, a grid of constant flow v in [0, 20] m/s by constant spin w0 in
[0, 200] rad/s (sqrt(cases) values each), 10 modes, 1 s, 201 samples, method ``auto``
(= cma), each case summarised in one row (peak tip displacement, the fundamental's final
sigma and omega, method_used, result_status).  Measured in the same run:

- the floor: a batched numpy computation written here, on one core (OMP/OpenBLAS threads
  = 1): the state matrices of every case stacked from the model's pieces, one
  ``np.linalg.eig`` per chunk of 256, the tip history by broadcasting
  V exp(Lambda t) V^-1 z0, the peak and the lowest-frequency eigenvalue per case;
- the library study runner (``COMPUTATIONS["study"].execute``, serial, this process);
- over HTTP: ``POST /v1/studies`` on a server started with :func:`service.launch.serve`
  (the README's ``uvicorn service.main:app``; a fresh data directory, default workers),
  then ``GET /v1/jobs/{key}`` every 20 ms until it succeeded and ``GET /v1/results/{key}``:
  the time from the POST to the result's last byte, and the POST's own answer time.  Each
  repetition moves one grid value by 1e-9 relative: a new study, whose other cases the
  store's memo then serves, so the first (cold) repetition is the one that computes
  everything; later ones are reported apart (warm).  The machine is shared, so the floor
  is measured again before each job and after the last (interleaved), each job's ratio
  taken against the mean of the floors on either side of it, and the CPU time of the
  server and its workers during each job is set against the floor's own CPU time (a
  ratio the other engineers' load blurs less than wall times);
- the resident memory of the server and its workers (:func:`rss_bytes` of the process
  tree, sampled every 20 ms) idle before the first study and at its peak.

``--cpu`` prints, instead, the CPU time of the study on a host of width 2 that ships its
pieces through pickle and runs them in this process (the service's path on the workers,
with the store's memo on a fresh SQLite file), cold (every case computed) and warm (the
memo serving all but one grid value), against the floor's CPU time: a measure the other
engineers' load hardly changes, comparable between checkouts (``PIPEFLOW_TREE`` names the
tree whose packages are measured: e.g. main, for a before/after in alternation).

Prints the ratios against the floor with the targets (HTTP within 2.5x of the floor, peak
RSS within 1.5x of idle) and writes a section to benchmarks/RESULTS.md.

``--time-variant`` measures the issue's other study instead, in the library (serial, one
core): v = a t with a in [0.1, 2] m/s^2 by constant w0 in [0, 200] rad/s (10 x 10), the
paper's pipe, 10 modes, 1 s, 2001 samples, ``auto`` (= magnus at tolerance 1e-8).  Measured
in the same run, interleaved round by round (:func:`time_variant`):

- the floor: batched Magnus-4 written here in plain numpy (:func:`magnus_floor`): every
  case at the uniform step the library's accepted run ends with (so at the library's
  accuracy, told the step it would otherwise have to find), the step exponentials of all
  cases with that step formed together (by the library's own batched exponential,
  :func:`pipeflow.linalg.expm_stack`, so that the floor and the library pay the same per
  exponential and the ratio measures what the library adds: its step control, spectra and
  summaries), one batched product per output interval, the peak tip and the lowest
  eigenvalue of S(t_end); no error control, no branch tracking;
- the library's study runner (``COMPUTATIONS["study"].execute``): the stacked magnus of
  :mod:`pipeflow.solvers.magnus.stack` through :func:`pipeflow.batch.summaries`;
- the per-case path the runner took before (each case ``execute`` + ``summarize``: the
  full result and its document), the same runner with the base's ``summarize_many`` off.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import os
import re
import sys
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

for _name in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_name, "1")  # the floor and the library on one core

import numpy as np  # noqa: E402

ROOT = Path(os.environ.get("PIPEFLOW_TREE") or Path(__file__).resolve().parents[1])
# this tree's packages first (a checkout or worktree measures its own code), then this
# directory (bench_service)
sys.path[:0] = [str(ROOT), str(ROOT / "benchmarks")]

import bench_service as BENCH  # noqa: E402  (the server start-up, timers, section writer)

from pipeflow.computations.registry import COMPUTATIONS  # noqa: E402
from pipeflow.linalg import expm_stack  # noqa: E402
from pipeflow.model import build_model  # noqa: E402
from pipeflow.paper import PAPER_PIPE  # noqa: E402
from pipeflow.schema.simulation import PAPER_EXAMPLE  # noqa: E402
from pipeflow.schema.study import StudySpec  # noqa: E402

RESULTS = ROOT / "benchmarks" / "RESULTS.md"
HTTP_TARGET = 2.5
RSS_TARGET = 1.5
POLL_S = 0.02
CHUNK = 256


def study_body(side: int, modes: int, shift: float = 0.0) -> dict[str, Any]:
    """The issue's grid: ``side`` x ``side`` cases; ``shift`` moves v's top value (a
    distinct study)."""
    v = np.linspace(0.0, 20.0, side)
    v[-1] *= 1.0 + shift
    base = {
        "pipe": PAPER_EXAMPLE["pipe"],
        "modes": modes,
        "time": {"t_end": 1.0, "samples": 201},
    }
    return {
        "base": {"kind": "simulation", "spec": base},
        "grid": {
            "flow.velocity.value": [float(x) for x in v],
            "rotation.omega0.value": [float(x) for x in np.linspace(0.0, 200.0, side)],
        },
    }


def floor(side: int, modes: int) -> tuple[float, np.ndarray]:
    """The batched numpy computation of every row's numbers [s] (and the peaks)."""
    model = build_model(PAPER_PIPE, modes)
    started = time.perf_counter()
    vv, ww = np.meshgrid(np.linspace(0.0, 20.0, side), np.linspace(0.0, 200.0, side))
    v, w2 = vv.T.ravel(), (ww.T.ravel()) ** 2
    n = modes
    weights = np.stack([np.ones_like(v), v, np.zeros_like(v), v * v, w2], axis=1)
    pieces = model.state_pieces.reshape(5, -1)
    d0, v0 = model.initial_state(0.001, 0.0)
    z0 = model.to_balanced(d0, v0).astype(complex)
    t = np.linspace(0.0, 1.0, 201)
    peaks, fund = [], []
    for s in range(0, v.size, CHUNK):
        S = (weights[s : s + CHUNK] @ pieces).reshape(-1, 2 * n, 2 * n)
        lam, V = np.linalg.eig(S)
        c = np.linalg.solve(V, np.broadcast_to(z0, lam.shape)[..., None])[..., 0]
        amp = (model.tip @ V[:, n:, :]) * c
        tip = np.einsum("btk,bk->bt", np.exp(lam[:, None, :] * t[None, :, None]), amp).real
        peaks.append(np.abs(tip).max(axis=1))
        upper = np.where(lam.imag > 0, lam.imag, np.inf)
        fund.append(np.take_along_axis(lam, upper.argmin(axis=1)[:, None], axis=1)[:, 0])
    out = np.concatenate(peaks)
    return time.perf_counter() - started, out


def library(side: int, modes: int) -> tuple[float, dict[str, Any]]:
    spec = StudySpec.model_validate(study_body(side, modes, shift=-1e-9))
    started = time.perf_counter()
    result = COMPUTATIONS["study"].execute(spec)
    return time.perf_counter() - started, result


class Sampler(threading.Thread):
    """The peak RSS of a process tree, sampled every 20 ms until stopped."""

    def __init__(self, pid: int) -> None:
        super().__init__(daemon=True)
        self.pid, self.peak, self._done = pid, 0, threading.Event()

    def run(self) -> None:
        while not self._done.is_set():
            self.peak = max(self.peak, BENCH.rss_bytes(self.pid))
            time.sleep(0.02)

    def stop(self) -> int:
        self._done.set()
        self.join()
        return self.peak


def cpu_seconds(pid: int) -> float:
    """CPU time (user + system) of ``pid`` and all its descendants so far [s] (/proc)."""
    total = 0
    for p in BENCH._tree_rss(pid):
        try:
            fields = Path(f"/proc/{p}/stat").read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        total += int(fields[11]) + int(fields[12])  # utime, stime [clock ticks]
    return total / os.sysconf("SC_CLK_TCK")


def timed_floor(side: int, modes: int) -> tuple[float, float]:
    """The floor's wall and CPU time [s]."""
    cpu = time.process_time()
    wall = floor(side, modes)[0]
    return wall, time.process_time() - cpu


def over_http(side: int, modes: int, repeats: int) -> dict[str, Any]:
    import httpx

    tmp = Path(tempfile.mkdtemp(prefix="pipeflow-bench-study-"))
    runs: list[dict[str, Any]] = []
    floors: list[tuple[float, float]] = []
    with (
        BENCH.server(tmp / "data", tmp / "server.log", {"PIPEFLOW_LOG_LEVEL": "WARNING"}) as (
            url,
            pid,
        ),
        httpx.Client(timeout=600) as client,
    ):
        # first use of the workers (imports), unmeasured: a tiny study of another shape
        warm = study_body(2, modes + 1)  # no case in common with the measured ones
        one_job(client, url, warm)
        time.sleep(1.0)
        idle = BENCH.rss_bytes(pid)
        sampler = Sampler(pid)
        sampler.start()
        for i in range(repeats):
            floors.append(timed_floor(side, modes))  # interleaved: before each job
            cpu = cpu_seconds(pid)
            run = one_job(client, url, study_body(side, modes, shift=1e-9 * (i + 1)))
            runs.append(run | {"cpu": cpu_seconds(pid) - cpu})
        floors.append(timed_floor(side, modes))  # and after the last
        peak = sampler.stop()
    for i, run in enumerate(runs):  # each job against the floors on either side of it
        run["floor"] = (floors[i][0] + floors[i + 1][0]) / 2
        run["floor_cpu"] = (floors[i][1] + floors[i + 1][1]) / 2
    return {"runs": runs, "idle": idle, "peak": peak, "floors": floors}


def one_job(client: Any, url: str, body: dict[str, Any]) -> dict[str, Any]:
    started = time.perf_counter()
    r = client.post(f"{url}/v1/studies", json=body)
    posted = time.perf_counter() - started
    r.raise_for_status()
    key = r.json()["key"]
    while True:
        job = client.get(f"{url}/v1/jobs/{key}").json()
        if job["status"] == "succeeded":
            break
        if job["status"] in ("failed", "cancelled"):
            raise RuntimeError(f"job {key} {job['status']}: {job.get('error')}")
        time.sleep(POLL_S)
    doc = client.get(f"{url}/v1/results/{key}").json()
    return {"wall": time.perf_counter() - started, "post": posted, "counts": doc["counts"]}


def report(side: int, modes: int, raw: dict[str, Any], started: float, smoke: bool) -> str:
    cases = side * side
    fl, lib = raw["floor"], raw["library"]
    runs = raw["http"]["runs"]
    cold = runs[0]
    warm = runs[1:]
    idle, peak = raw["http"]["idle"], raw["http"]["peak"]
    http_ratio = cold["wall"] / cold["floor"]
    rss_ratio = peak / idle
    verdict = "met" if http_ratio <= HTTP_TARGET else "**missed**"
    rss_verdict = "met" if rss_ratio <= RSS_TARGET else "**missed**"
    post_verdict = "met" if cold["post"] <= 0.1 else "**missed**"
    rows = [
        ["batched numpy floor (written here, one core)", fl, cases / fl, 1.0],
        ["library study runner (`execute`, serial)", lib, cases / lib, lib / fl],
        ["POST to result over HTTP, cold (every case computed; / the floors either side)",
         cold["wall"], cases / cold["wall"], http_ratio],
    ]  # fmt: skip
    if warm:
        w = min(warm, key=lambda r: r["wall"] / r["floor"])
        rows.append(
            ["POST to result over HTTP, warm (memo: one new grid value; / the floors either side)",
             w["wall"], cases / w["wall"], w["wall"] / w["floor"]]
        )  # fmt: skip
    load = " ".join(f"{x:.1f}" for x in raw["load_after"])
    lines = [
        f"`python benchmarks/bench_study.py{' --smoke' if smoke else f' --cases {cases}'}` "
        f"({time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}, "
        f"{time.monotonic() - started:.0f} s): {raw['machine']}; load average {load} at the "
        f"end. Grid {side} x {side} (v in [0, 20] m/s x w0 in [0, 200] rad/s), {modes} modes, "
        "1 s, 201 samples, auto (= cma).",
        "",
        "| what | wall [s] | cases/s | / floor |",
        "|---|---:|---:|---:|",
        *(f"| {r[0]} | {r[1]:.3f} | {r[2]:,.0f} | {r[3]:.2f}x |" for r in rows),
        "",
        "| target | measured | verdict |",
        "|---|---:|---|",
        f"| HTTP POST to result within {HTTP_TARGET}x of the floor | {http_ratio:.2f}x | "
        f"{verdict} |",
        f"| POST answered in < 100 ms | {cold['post'] * 1e3:.0f} ms | {post_verdict} |",
        f"| peak RSS of server + workers within {RSS_TARGET}x of idle | "
        f"{peak / 2**20:.0f} / {idle / 2**20:.0f} MiB = {rss_ratio:.2f}x | {rss_verdict} |",
        "",
        f"counts of the cold job: {cold['counts']}; POST answer times [ms]: "
        + ", ".join(f"{r['post'] * 1e3:.0f}" for r in runs),
        "",
        "CPU time of the server and its workers per job against the floor's (the mean of "
        "the floors either side): "
        + ", ".join(
            f"{r['cpu']:.2f} s / {r['floor_cpu']:.2f} s = {r['cpu'] / r['floor_cpu']:.2f}x"
            for r in runs
        )
        + " (cold first); floors interleaved with the jobs, wall [s]: "
        + ", ".join(f"{f[0]:.3f}" for f in raw["http"]["floors"]),
    ]
    return "\n".join(lines)


# -- the time-variant study (library) -----------------------------------------------------

TV_TARGET = 1.5


def tv_body(side: int, modes: int, samples: int) -> dict[str, Any]:
    """v = a t for ``side`` values of a in [0.1, 2] m/s^2 by ``side`` spins in [0, 200]."""
    base = {
        "pipe": PAPER_EXAMPLE["pipe"],
        "modes": modes,
        "time": {"t_end": 1.0, "samples": samples},
        "flow": {"velocity": {"kind": "polynomial", "coefficients": [0.0, 0.4]}},
    }
    return {
        "base": {"kind": "simulation", "spec": base},
        "grid": {
            "flow.velocity.coefficients.1": [float(x) for x in np.linspace(0.1, 2.0, side)],
            "rotation.omega0.value": [float(x) for x in np.linspace(0.0, 200.0, side)],
        },
    }


def magnus_floor(
    a: np.ndarray, w0: np.ndarray, steps: np.ndarray, modes: int, samples: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Peak |u(L, t)| [m], the lowest eigenvalue of S(t_end) [1/s] and the final balanced
    state of each case (flow a t, spin w0), by Magnus-4 with ``steps[c]`` equal steps per
    output interval."""
    model = build_model(PAPER_PIPE, modes)
    pieces = model.state_pieces.reshape(5, -1)
    d0, v0 = model.initial_state(0.001, 0.0)
    z0 = model.to_balanced(d0, v0)
    tipw = model.from_balanced(np.eye(2 * modes))[0] @ model.tip  # tip of each state entry
    t = np.linspace(0.0, 1.0, samples)
    dt = t[1] - t[0]
    n = 2 * modes
    g = np.array([0.5 - math.sqrt(3) / 6, 0.5 + math.sqrt(3) / 6])
    peaks = np.empty(a.size)
    final = np.empty((a.size, 2 * modes))
    block = 32  # output intervals whose exponentials are formed at once
    for m in np.unique(steps):
        cases = np.flatnonzero(steps == m)
        G, h = cases.size, dt / m
        z = np.repeat(z0[None], G, axis=0)
        peak = np.abs(z @ tipw)
        for k0 in range(0, samples - 1, block):
            k1 = min(samples - 1, k0 + block)
            starts = (t[k0:k1, None] + h * np.arange(m)[None, :]).ravel()  # (nb m,)
            nodes = starts[None, :] + g[:, None] * h  # (2, nb m)
            v = a[cases, None, None] * nodes[None]  # (G, 2, nb m)
            wts = np.stack(
                [np.ones_like(v), v, np.broadcast_to(a[cases, None, None], v.shape), v * v,
                 np.broadcast_to((w0[cases] ** 2)[:, None, None], v.shape)], axis=-1,
            )  # fmt: skip
            A = (wts @ pieces).reshape(G, 2, -1, n, n)
            A1, A2 = A[:, 0], A[:, 1]
            Om = 0.5 * h * (A1 + A2) + (math.sqrt(3) / 12 * h * h) * (A2 @ A1 - A1 @ A2)
            E = expm_stack(Om.reshape(-1, n, n)).reshape(G, k1 - k0, m, n, n)
            for j in range(k1 - k0):
                for i in range(m):
                    z = np.einsum("gij,gj->gi", E[:, j, i], z)
                peak = np.maximum(peak, np.abs(z @ tipw))
        peaks[cases] = peak
        final[cases] = z
    weights = np.stack([np.ones_like(a), a, a, a * a, w0 * w0], axis=1)  # v(1) = a
    lam = np.linalg.eigvals((weights @ pieces).reshape(-1, n, n))
    upper = np.where(lam.imag > 0, lam.imag, np.inf)
    lowest = np.take_along_axis(lam, upper.argmin(axis=1)[:, None], axis=1)[:, 0]
    return peaks, lowest, final


def _per_case_base() -> Any:
    """The simulation computation without its stacked summaries: each case through
    ``execute`` and ``summarize`` (the study runner's path before the stacked magnus)."""
    return dataclasses.replace(COMPUTATIONS["simulation"], summarize_many=None, batchable=None)


def time_variant(side: int, modes: int, samples: int, rounds: int) -> dict[str, Any]:
    """Interleaved rounds of the floor, the library and the per-case path [s]."""
    from pipeflow.batch import time_variant_summaries
    from pipeflow.computations.study_runner import run_study
    from pipeflow.solvers.magnus.stack import solve_many

    spec = StudySpec.model_validate(tv_body(side, modes, samples))
    sims = [r.to_simulation() for r in (spec.validate_case(o)[0] for o in spec.overrides())]
    a = np.array([s.flow.coefficients[1] for s in sims])  # type: ignore[attr-defined]
    w0 = np.array([s.spin.value(0.0) for s in sims], dtype=float)
    # the library's accepted step per case (and its work), unmeasured
    problems = [batch_problem(s) for s in sims]
    outs = solve_many(problems)
    steps = np.array([o.diagnostics["steps"] // (samples - 1) for o in outs])  # type: ignore[union-attr]
    exps = sum(o.diagnostics["matrix_exponentials"] for o in outs)  # type: ignore[union-attr]
    order6 = sum(o.diagnostics["steps_order_6"] for o in outs)  # type: ignore[union-attr]
    rows = time_variant_summaries(sims)
    peaks, lowest, final = magnus_floor(a, w0, steps, modes, samples)
    # the floor's accuracy: its final states against the library's accepted runs (the same
    # steps, both order 4 here: rounding apart, the same states and so the same error)
    final_diff = max(
        float(np.linalg.norm(f - o.z[-1]) / np.max(np.linalg.norm(o.z, axis=1)))  # type: ignore[union-attr]
        for f, o in zip(final, outs, strict=True)
    )
    lib_peaks = np.array([r.peak_tip_displacement for r in rows])  # type: ignore[union-attr]
    study = COMPUTATIONS["study"]
    per_case = _per_case_base()
    times: dict[str, list[float]] = {"floor": [], "library": [], "per_case": []}
    cpu: dict[str, list[float]] = {"floor": [], "library": [], "per_case": []}

    def timed(name: str, call: Any) -> Any:
        wall, used = time.perf_counter(), time.process_time()
        out = call()
        times[name].append(time.perf_counter() - wall)
        cpu[name].append(time.process_time() - used)
        return out

    for _ in range(rounds):
        timed("floor", lambda: magnus_floor(a, w0, steps, modes, samples))
        result = timed("library", lambda: study.execute(spec))
        before = timed("per_case", lambda: run_study(spec, per_case))
    assert result["counts"]["ok"] == side * side, result["counts"]
    same = [r[4:] == b[4:] for r, b in zip(result["rows"], before["rows"], strict=True)]
    return {
        "times": times,
        "cpu": cpu,
        "steps": steps,
        "exps": exps,
        "order6": order6,
        "floor_steps": int(steps.sum()) * (samples - 1),
        "peak_diff": float(np.max(np.abs(peaks - lib_peaks) / lib_peaks)),
        "final_diff": final_diff,
        "estimates": [o.diagnostics["estimated_relative_error"] for o in outs],  # type: ignore[union-attr]
        "lowest": lowest,
        "rows_equal": sum(same),
    }


def batch_problem(sim: Any) -> Any:
    """The solver problem of a simulation, as :func:`pipeflow.simulation.simulate` forms it."""
    from pipeflow.loading import Loading
    from pipeflow.solvers import Problem

    model = build_model(sim.pipe, sim.modes)
    d0, v0 = model.initial_state(sim.u0, sim.du0, sim.initial_shape)
    t = np.linspace(0.0, sim.t_end, sim.samples)
    return Problem(model, Loading(sim.flow, sim.spin), model.to_balanced(d0, v0), t, sim.options)


def tv_report(side: int, modes: int, samples: int, raw: dict[str, Any], started: float) -> str:
    cases = side * side
    t, c = raw["times"], raw["cpu"]
    fl, lib, old = min(t["floor"]), min(t["library"]), min(t["per_case"])
    cfl, clib, cold = min(c["floor"]), min(c["library"]), min(c["per_case"])
    ratio = lib / fl
    verdict = "met" if ratio <= TV_TARGET else "**missed**"
    counts = ", ".join(f"{int((raw['steps'] == m).sum())} x {m}" for m in np.unique(raw["steps"]))
    load = " ".join(f"{x:.1f}" for x in raw["load_after"])
    fmt = lambda xs: ", ".join(f"{x:.2f}" for x in xs)  # noqa: E731
    lines = [
        f"`python benchmarks/bench_study.py --time-variant{' --smoke' if side < 10 else ''}` "
        f"({time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}, "
        f"{time.monotonic() - started:.0f} s): {raw['machine']}; load average {load} at the "
        f"end. v = a t, a in [0.1, 2] m/s^2 x w0 in [0, 200] rad/s ({side} x {side}), "
        f"{modes} modes, 1 s, {samples} samples, auto (= magnus, tolerance 1e-8); "
        f"{len(t['floor'])} interleaved rounds, best of each.",
        "",
        "| what | wall [s] (rounds) | cases/s | / floor | CPU [s] (rounds) | CPU / floor |",
        "|---|---:|---:|---:|---:|---:|",
        f"| batched Magnus-4 floor (written here, the accepted steps given) | {fmt(t['floor'])} "
        f"| {cases / fl:.1f} | 1.00x | {fmt(c['floor'])} | 1.00x |",
        f"| library study runner, stacked magnus (after) | {fmt(t['library'])} | "
        f"{cases / lib:.1f} | {lib / fl:.2f}x | {fmt(c['library'])} | {clib / cfl:.2f}x |",
        f"| library study runner, per case (before: execute + summarize) | "
        f"{fmt(t['per_case'])} | {cases / old:.1f} | {old / fl:.2f}x | {fmt(c['per_case'])} "
        f"| {cold / cfl:.2f}x |",
        "",
        "| target | measured | verdict |",
        "|---|---:|---|",
        f"| library within {TV_TARGET}x of the floor (wall, best of the rounds) | {ratio:.2f}x "
        f"| {verdict} |",
        f"| the same in CPU time of this process (less sensitive to the machine's load) | "
        f"{clib / cfl:.2f}x | {'met' if clib / cfl <= TV_TARGET else '**missed**'} |",
        "",
        f"Work: the floor takes the accepted steps only ({raw['floor_steps']:,} exponentials; "
        f"steps per output interval: {counts}); the library's step control forms "
        f"{raw['exps']:,} ({raw['exps'] / raw['floor_steps']:.2f}x: the first attempt, its "
        "check with twice the step, and where refined the run with four times the step and "
        f"the refined attempt; {raw['order6']} steps of order 6). The floor against the "
        f"library's accepted runs: peak tip max relative difference {raw['peak_diff']:.1e}, "
        f"final state {raw['final_diff']:.1e} of the state's largest norm (the library's "
        f"estimated errors {min(raw['estimates']):.1e} to {max(raw['estimates']):.1e}: the "
        "floor is at the library's accuracy). Rows of the stacked "
        f"and the per-case runner identical (every summary column, == on floats): "
        f"{raw['rows_equal']} of {cases}. Speed-up of the stacked runner over the per-case "
        f"one: {old / lib:.2f}x (CPU {cold / clib:.2f}x).",
    ]
    return "\n".join(lines)


def write_top(path: Path, title: str, text: str) -> None:
    """Put the section ``## <title>`` first in ``path`` (after its heading), replacing an
    older one of that title."""
    old = path.read_text() if path.exists() else "# Benchmark results\n"
    head, _, rest = old.partition("\n")
    pattern = re.compile(rf"^## {re.escape(title)}\n.*?(?=^## |\Z)", re.S | re.M)
    rest = pattern.sub("", rest)
    path.write_text(f"{head}\n\n## {title}\n\n{text.rstrip()}\n\n{rest.lstrip()}")


def main_time_variant(args: argparse.Namespace) -> int:
    side, modes, samples, rounds = (3, 3, 201, 1) if args.smoke else (10, 10, 2001, args.rounds)
    started = time.monotonic()
    raw = time_variant(side, modes, samples, rounds)
    raw["machine"] = BENCH.machine()
    raw["load_after"] = os.getloadavg()
    text = tv_report(side, modes, samples, raw, started)
    print(text, flush=True)
    if not args.no_write:
        write_top(args.out, f"Study benchmark, time-variant (issue 19): {args.label}", text)
        print(f"\nwritten to {args.out}")
    return 0


def shipped_cpu(side: int, modes: int) -> dict[str, float]:
    """CPU seconds of the floor and of the study on a width-2 host shipping its pieces
    through pickle (run here), cold then warm, with the store's memo on SQLite."""
    import pickle

    from pipeflow import parallel
    from service import encoding
    from service.store import Store
    from service.store.memo import StoreMemo

    class Shipping:
        width = 2

        def map(self, fn: Any, items: Any) -> Any:
            for i, item in enumerate(items):
                yield i, pickle.loads(pickle.dumps(fn(pickle.loads(pickle.dumps(item)))))

    store = Store(Path(tempfile.mkdtemp(prefix="pipeflow-bench-cpu-")) / "s.sqlite3", 1 << 30, 0)
    floor(2, modes)  # first use, unmeasured
    out = {"floor": timed_floor(side, modes)[1]}
    for name, shift in (("cold", 1e-3), ("warm", 2e-3)):
        spec = StudySpec.model_validate(study_body(side, modes, shift))
        cpu = time.process_time()
        with parallel.hosting(host=Shipping(), memo=StoreMemo(store)):
            result = COMPUTATIONS["study"].execute(spec)
        store.put_result(f"study-{shift}", "study", encoding.dumps(result))
        out[name] = time.process_time() - cpu
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", type=int, default=10_000, help="grid size (a square)")
    ap.add_argument("--smoke", action="store_true", help="a 6 x 6 grid, 2 modes")
    ap.add_argument("--repeats", type=int, default=2, help="HTTP jobs (the first cold)")
    ap.add_argument("--label", default="latest", help="section name in RESULTS.md")
    ap.add_argument("--out", type=Path, default=RESULTS, help="Markdown file to write into")
    ap.add_argument("--no-write", action="store_true", help="print only")
    ap.add_argument("--time-variant", action="store_true", help="the v = a t study (library)")
    ap.add_argument("--rounds", type=int, default=3, help="--time-variant: interleaved rounds")
    ap.add_argument("--cpu", action="store_true", help="print the shipped path's CPU only")
    args = ap.parse_args(argv)
    if args.time_variant:
        return main_time_variant(args)
    side = 6 if args.smoke else max(2, round(args.cases**0.5))
    modes = 2 if args.smoke else 10
    if args.cpu:
        c = shipped_cpu(side, modes)
        print(
            f"{ROOT}: CPU [s] floor {c['floor']:.2f}; study on a shipping host: cold "
            f"{c['cold']:.2f} ({c['cold'] / c['floor']:.2f}x the floor), warm {c['warm']:.2f} "
            f"({c['warm'] / c['floor']:.2f}x)",
            flush=True,
        )
        return 0
    started = time.monotonic()
    raw: dict[str, Any] = {"machine": BENCH.machine()}
    floor(2, modes)  # first use, unmeasured
    raw["floor"] = min(floor(side, modes)[0] for _ in range(3))
    library(2, modes)
    raw["library"] = library(side, modes)[0]
    raw["http"] = over_http(side, modes, 1 if args.smoke else args.repeats)
    raw["load_after"] = os.getloadavg()
    text = report(side, modes, raw, started, args.smoke)
    print(text, flush=True)
    if not args.no_write:
        BENCH.write_section(args.out, args.label, text, prefix="Study benchmark (issue 19)")
        print(f"\nwritten to {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
