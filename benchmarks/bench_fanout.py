"""Fan-out benchmark of issue 11: a spin map job on 1 worker against 2 workers.

    python benchmarks/bench_fanout.py              # ~2 min on the 2-core machine
    python benchmarks/bench_fanout.py --smoke      # seconds: a tiny map, one repetition
    python benchmarks/bench_fanout.py --label x    # names the section written to RESULTS.md

The user's path: two servers started the README's way (``uvicorn service.main:app --port
P`` from the repo root, a fresh data directory each), one with ``PIPEFLOW_WORKERS=1`` and
one with ``PIPEFLOW_WORKERS=2``, both up for the whole run.  Each repetition submits the
issue's map (the paper's pipe, 100 x 100 (v, w0) points on [0, 60] m/s x [0, 2000]
rad/s, 10 modes) to ``POST /v1/sweeps``, waits with long polls (``GET
/v1/jobs/{key}?wait=60``, answered when the job has ended) until it succeeded and fetches
``GET /v1/results/{key}``: the time from the POST to the result's
last byte.  Every repetition is a distinct key (the spin range's upper end moved by
1e-9 relative), so the cache never answers; the two servers take turns (1, 2, 1, 2, ...)
so that a change of the machine's load hits both.  One unmeasured job per server first
(the workers' first spin map pays lazy imports).  The plain library call (the registry's
``execute`` of the same request, serial, one BLAS thread, in this process) is timed in the
same run, and so is the machine's own parallelism at the moment: the same call in two
processes at once against one alone (2 x alone / both, at most 2).  Reports medians, the
2-vs-1 ratio against the 1.6x target of the issue, the workers' own compute time (the job
record's started..finished), the result's ``diagnostics.fan_out`` (pieces and the
distinct workers that ran them) and the API server process's CPU during a job (its
requests, the polls included, and the embedded Dask scheduler: with 2 workers it shares
their 2 cores).  ``--poll S`` polls every S seconds instead (the old way; 0.02 s was its
default).

``--study`` measures the same way the 10,000-case LTI design study of issue 19 instead
of the map (``POST /v1/studies``, the grid of ``benchmarks/bench_study.py``: v in [0, 20]
m/s x w0 in [0, 200] rad/s, 10 modes, 1 s, 201 samples; ``--smoke``: 6 x 6, 2 modes), each
repetition a distinct study (v's top value moved by 1e-9 relative: the store's memo serves
nothing, every case is computed), the library call being the serial study runner.

``--timeline`` (with ``--study``) instead traces where one study job's time goes, on a
2-worker cluster as the service's (``LocalCluster``, one thread a worker, the service's
preload) and a fresh SQLite store: a task on a worker runs the job's path (the
``DaskHost`` fan-out with the store's memo around the registry's ``execute``, then the
result's encoding and its store write, as :func:`service.engine.task._compute` and
:func:`~service.engine.task.run_job` do) and records the job's phases, when each piece
started and ended on which worker (with its own phases: validation and keys, memo look-up,
compute, memo write, from the piece's ``timing``), when the job received it, and the gaps
the job waited with a worker idle.  Printed (and written to RESULTS.md) as a table.

``--ab-poll`` adds, in every round and on each server, a job waited for by polling every
20 ms (the way before long polls), in alternating order with the long-polled one: the
two ways' medians, 2-vs-1 ratios and API-process CPU side by side (the main table stays
the long-polled jobs').

``--direct`` (with ``--study``) times that job path alone on a 1-worker and a 2-worker
cluster, taking turns, ``--repeats`` times each: the fan-out's own 2-vs-1 ratio, which
the HTTP measurement adds the API process to (its polls and scheduler share the 2 cores
with 2 workers, not with 1).

``--sweeps`` adds the measurement behind leaving argand/campbell sweeps serial: the batched
frozen spectra of a sweep (``pipeflow.spectra.decompose``: eigenvalues and left/right
eigenvectors at every point) computed here against 8 pieces on a 2-worker LocalCluster
(eigenvectors shipped back), beside the whole sweep's time.
"""

from __future__ import annotations

import argparse
import multiprocessing
import os
import statistics
import sys
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor
from contextlib import ExitStack
from datetime import datetime
from pathlib import Path
from typing import Any

import httpx

for _name in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_name, "1")  # the library call on one core, like one worker

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

import bench_service as BENCH  # noqa: E402  (the server start-up, timers, section writer)

from pipeflow.computations.registry import COMPUTATIONS  # noqa: E402

RESULTS = ROOT / "benchmarks" / "RESULTS.md"
TARGET = 1.6
#: the benchmark's job polling period [s] (``--poll``); None: long polls of LONG_POLL_S
POLL_S: float | None = None
#: how long one long poll (``GET /v1/jobs/{key}?wait=``) may be held [s]
LONG_POLL_S = 60.0
#: ``--ab-poll``: each round also waits for a job per server by polling every AB_POLL_S [s]
AB_POLL = False
AB_POLL_S = 0.02

#: the issue's map (the registry's example): the paper's pipe, 100 x 100 points, 10 modes
MAP: dict[str, Any] = COMPUTATIONS["spin_map"].examples["spin_map"]["value"]
SMOKE_MAP = MAP | {"modes": 4, "velocity_points": 20, "spin_points": 12}


def variant(spec: dict[str, Any], i: int) -> dict[str, Any]:
    """A distinct key: the spin range's upper end moved by ``i`` x 1e-9 relative; a study:
    every velocity moved by ``i`` x 1e-9 m/s (every case new: the memo serves none)."""
    if "grid" in spec:
        v = [x + 1e-9 * i for x in spec["grid"]["flow.velocity.value"]]
        return spec | {"grid": spec["grid"] | {"flow.velocity.value": v}}
    lo, hi = spec["spin_range"]
    return spec | {"spin_range": [lo, hi * (1.0 + 1e-9 * i)]}


def study(smoke: bool) -> dict[str, Any]:
    """The study of issue 19 (``benchmarks/bench_study.py``'s grid), with ``kind`` for
    :func:`library_call` (the study request has no such field: dropped before the POST)."""
    import bench_study

    side, modes = (6, 2) if smoke else (100, 10)
    return {"kind": "study", **bench_study.study_body(side, modes)}


def job_over_http(
    client: httpx.Client, url: str, spec: dict[str, Any], poll: float | None = None
) -> dict[str, Any]:
    """POST, wait for success (long polls; ``poll`` [s]: polling at that period), GET the
    result: wall time [s], compute time [s], fan_out."""
    path, body = "sweeps", spec
    if spec.get("kind") == "study":
        path, body = "studies", {k: v for k, v in spec.items() if k != "kind"}
    started = time.perf_counter()
    r = client.post(f"{url}/v1/{path}", json=body)
    r.raise_for_status()
    key = r.json()["key"]
    # a long poll (the service answers once the job ended), or ``--poll``'s polling
    params = {"wait": f"{LONG_POLL_S:g}"} if poll is None else None
    while True:
        job = client.get(f"{url}/v1/jobs/{key}", params=params).json()
        if job["status"] == "succeeded":
            break
        if job["status"] in ("failed", "cancelled"):
            raise RuntimeError(f"job {key} {job['status']}: {job.get('error')}")
        if poll is not None:
            time.sleep(poll)
    doc = client.get(f"{url}/v1/results/{key}").json()
    wall = time.perf_counter() - started
    t0, t1 = (datetime.fromisoformat(job[k]).timestamp() for k in ("started", "finished"))
    fan_out = (doc.get("diagnostics") or {}).get("fan_out")
    if spec.get("kind") == "study":
        fan_out = doc["counts"]  # a study has no diagnostics: its counts say what ran
    return {"wall": wall, "compute": t1 - t0, "fan_out": fan_out}


def process_cpu(pid: int) -> float:
    """CPU seconds (user + system) of process ``pid`` so far, its own threads only (the
    API server: its requests and the embedded Dask scheduler, not its workers)."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def library_call(spec: dict[str, Any]) -> float:
    computation = COMPUTATIONS[spec["kind"]]
    body = {k: v for k, v in spec.items() if k != "kind"} if spec["kind"] == "study" else spec
    request = computation.request.model_validate(body)
    started = time.perf_counter()
    computation.execute(request)
    return time.perf_counter() - started


def run(spec: dict[str, Any], repeats: int) -> dict[str, Any]:
    tmp = Path(tempfile.mkdtemp(prefix="pipeflow-bench-fanout-"))
    env = {"PIPEFLOW_LOG_LEVEL": "WARNING"}
    runs: dict[int, list[dict[str, Any]]] = {1: [], 2: []}
    library: list[float] = []
    pairs: list[float] = []
    with ExitStack() as stack:
        pool = stack.enter_context(
            ProcessPoolExecutor(2, mp_context=multiprocessing.get_context("spawn"))
        )
        list(pool.map(library_call, [spec, spec]))  # start-up and first use, unmeasured
        servers = {
            n: stack.enter_context(
                BENCH.server(
                    tmp / f"data{n}", tmp / f"server{n}.log", env | {"PIPEFLOW_WORKERS": str(n)}
                )
            )
            for n in (1, 2)
        }
        urls = {n: url for n, (url, _) in servers.items()}
        client = stack.enter_context(httpx.Client(timeout=120))
        library_call(spec)  # first use in this process, unmeasured
        for n in (1, 2):
            job_over_http(client, urls[n], variant(spec, 10_000 + n))  # warm-up, unmeasured
        # --ab-poll: every round also a job waited for by polling every 20 ms (the old way)
        polled: dict[int, list[dict[str, Any]]] = {1: [], 2: []}
        for i in range(repeats):
            library.append(library_call(spec))
            started = time.perf_counter()
            list(pool.map(library_call, [spec, spec]))
            pairs.append(time.perf_counter() - started)
            ways = [(runs, POLL_S), (polled, AB_POLL_S)] if AB_POLL else [(runs, POLL_S)]
            if AB_POLL and i % 2:
                ways.reverse()
            for n in (1, 2):
                for out, poll in ways:
                    cpu = process_cpu(servers[n][1])
                    k = 4 * i + 2 * n + (out is polled)
                    out[n].append(job_over_http(client, urls[n], variant(spec, k), poll))
                    out[n][-1]["server_cpu"] = process_cpu(servers[n][1]) - cpu
    raw = {"library": library, "pairs": pairs, "runs": runs, "load_after": os.getloadavg()}
    if AB_POLL:
        raw["polled"] = polled
    return raw


def _sweep_piece(args: tuple[int, Any]) -> Any:
    from pipeflow.model import build_model
    from pipeflow.paper import PAPER_PIPE
    from pipeflow.spectra import decompose
    from pipeflow.stability.core import state_matrices

    modes, p = args
    return decompose(state_matrices(build_model(PAPER_PIPE, modes), p, 100.0))


def sweep_probe() -> str:
    """Frozen spectra of velocity sweeps (w0 = 100 rad/s, v in [0, 60] m/s): here vs 8
    pieces on 2 workers, and the whole ``sweep`` here (best of 3 each)."""
    import numpy as np
    from distributed import Client, LocalCluster

    from pipeflow.paper import PAPER_PIPE
    from pipeflow.stability.sweeps import sweep

    def best(fn: Any, *args: Any) -> float:
        times = []
        for _ in range(3):
            t = time.perf_counter()
            fn(*args)
            times.append(time.perf_counter() - t)
        return min(times)

    rows = []
    env = {name: "1" for name in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")}
    with (
        LocalCluster(
            n_workers=2, threads_per_worker=1, dashboard_address=None, env=env, processes=True
        ) as cluster,
        Client(cluster) as client,
    ):
        client.gather(client.map(_sweep_piece, [(2, np.linspace(0, 1, 3))] * 4, pure=False))
        for modes, points in ((10, 201), (10, 2001), (20, 2001), (40, 2001)):
            p = np.linspace(0.0, 60.0, points)
            parts = [(modes, q) for q in np.array_split(p, 8)]
            here = best(_sweep_piece, (modes, p))
            fanned = best(lambda ps: client.gather(client.map(_sweep_piece, ps, pure=False)), parts)
            whole = best(sweep, PAPER_PIPE, "velocity", (0.0, 60.0), 100.0, modes, 4, points)
            rows.append(
                f"| {modes} | {points} | {whole * 1e3:.0f} | {here * 1e3:.0f} | "
                f"{fanned * 1e3:.0f} | {(here - fanned) / whole:+.0%} |"
            )
    return "\n".join(
        [
            "Argand sweeps (w0 = 100 rad/s, v in [0, 60] m/s, 4 tracked modes), best of 3 [ms]: "
            "the frozen spectra here vs in 8 pieces on a 2-worker LocalCluster.",
            "",
            "| modes | points | whole sweep | spectra here | spectra, 8 pieces on 2 workers "
            "| gain on the sweep |",
            "|---:|---:|---:|---:|---:|---:|",
            *rows,
        ]
    )


def _traced_job(request: Any, db_url: str) -> dict[str, Any]:
    """The study job's path on a worker (see the module docstring, ``--timeline``): the
    job's phases [s since the epoch] and, per piece, its timing and arrival."""
    from pipeflow import parallel
    from pipeflow.computations import study_runner
    from service import encoding
    from service.engine.fanout import DaskHost
    from service.store import worker_store
    from service.store.memo import StoreMemo

    marks: dict[str, float] = {"start": time.time()}
    cpu0 = time.thread_time()
    arrivals: list[dict[str, Any]] = []

    class Recording:
        """The DaskHost, with each piece's arrival in the job noted."""

        def __init__(self, host: DaskHost) -> None:
            self.host = host

        @property
        def width(self) -> int:
            return self.host.width

        def map(self, fn: Any, items: Any) -> Any:
            marks["submit"] = time.time()
            for i, rows in self.host.map(fn, items):
                arrivals.append({"i": i, "arrived": time.time(), **rows.timing})
                yield i, rows

    table = study_runner._table

    def timed_table(*args: Any, **kwargs: Any) -> Any:
        marks["merged"] = time.time()
        try:
            return table(*args, **kwargs)
        finally:
            marks["table"] = time.time()

    store = worker_store(db_url, 1 << 32)
    study_runner._table = timed_table  # type: ignore[assignment]
    try:
        with parallel.hosting(host=Recording(DaskHost()), memo=StoreMemo(store)):
            result = COMPUTATIONS["study"].execute(request, lambda f: None)
    finally:
        study_runner._table = table  # type: ignore[assignment]
    marks["executed"] = time.time()
    body = encoding.dumps(result)
    marks["encoded"] = time.time()
    store.put_result(f"timeline-{marks['start']}", "study", body)
    marks["stored"] = time.time()
    return {
        "marks": marks,
        "pieces": arrivals,
        "bytes": len(body),
        "job_cpu": time.thread_time() - cpu0,
        "job_pid": os.getpid(),
    }


def _process_cpu() -> tuple[int, float]:
    """(pid, CPU seconds so far) of the worker process running this."""
    times = os.times()
    return os.getpid(), times.user + times.system


def _study_store() -> str:
    """The URL of a fresh SQLite store, migrated once (as the service does)."""
    from service.store import Store

    tmp = Path(tempfile.mkdtemp(prefix="pipeflow-bench-study-job-"))
    db_url = f"sqlite:///{tmp / 'store.sqlite3'}"
    Store(db_url, 1 << 32, 0).close()
    return db_url


def _study_cluster(stack: ExitStack, workers: int) -> Any:
    """A client of a ``workers``-worker LocalCluster as the service's (one thread a worker,
    its preload), closed with ``stack``."""
    from distributed import Client, LocalCluster

    from service.engine.preload import MODULE as PRELOAD

    cluster = stack.enter_context(
        LocalCluster(
            n_workers=workers,
            threads_per_worker=1,
            processes=True,
            dashboard_address=None,
            preload_nanny=[PRELOAD],
        )
    )
    return stack.enter_context(Client(cluster))


def timeline(spec: dict[str, Any], workers: int = 2) -> str:
    """One traced study job (after an untraced one) on a ``workers``-worker cluster: the
    Markdown timeline (see the module docstring, ``--timeline``)."""
    from pipeflow.schema.study import StudySpec

    db_url = _study_store()
    body = {k: v for k, v in spec.items() if k != "kind"}
    with ExitStack() as stack:
        client = _study_cluster(stack, workers)
        warm = StudySpec.model_validate(variant(body, 20_000))
        client.submit(_traced_job, warm, db_url, pure=False).result()  # untraced
        request = StudySpec.model_validate(variant(body, 20_001))
        before = dict(client.run(_process_cpu).values())
        trace = client.submit(_traced_job, request, db_url, pure=False).result()
        after = dict(client.run(_process_cpu).values())
    trace["process_cpu"] = {pid: after[pid] - before[pid] for pid in after}
    return timeline_table(trace)


def direct(spec: dict[str, Any], repeats: int) -> str:
    """The study job's path (as ``--timeline`` traces it) on a 1-worker and a 2-worker
    cluster, both up, taking turns (1, 2, 1, 2, ...): the 2-vs-1 ratio of the job alone,
    without HTTP, polling or the API process (see the module docstring, ``--direct``)."""
    from pipeflow.schema.study import StudySpec

    db_url = _study_store()
    body = {k: v for k, v in spec.items() if k != "kind"}
    totals: dict[int, list[float]] = {1: [], 2: []}
    with ExitStack() as stack:
        clients = {n: _study_cluster(stack, n) for n in (1, 2)}
        for n, client in clients.items():  # first use, unmeasured
            warm = StudySpec.model_validate(variant(body, 30_000 + n))
            client.submit(_traced_job, warm, db_url, pure=False).result()
        for i in range(repeats):
            for n, client in clients.items():
                request = StudySpec.model_validate(variant(body, 31_000 + 2 * i + n))
                m = client.submit(_traced_job, request, db_url, pure=False).result()["marks"]
                totals[n].append(m["stored"] - m["start"])
    one, two = median(totals[1]), median(totals[2])
    return (
        f"The study job alone (its task's path on a 1- and a 2-worker cluster, no HTTP), "
        f"{repeats} repetitions each, medians: 1 worker {one * 1e3:.0f} ms, 2 workers "
        f"{two * 1e3:.0f} ms: **{one / two:.2f}x**.\n\n1 worker [ms]: "
        + ", ".join(f"{x * 1e3:.0f}" for x in totals[1])
        + "\n\n2 workers [ms]: "
        + ", ".join(f"{x * 1e3:.0f}" for x in totals[2])
    )


def timeline_table(trace: dict[str, Any]) -> str:
    m, pieces = trace["marks"], sorted(trace["pieces"], key=lambda p: p["start"])
    t0 = m["start"]
    pids = {pid: n for n, pid in enumerate(sorted({p["pid"] for p in pieces}), start=1)}
    busy = {pid: sum(p["end"] - p["start"] for p in pieces if p["pid"] == pid) for pid in pids}
    last = max(p["arrived"] for p in pieces)
    rows = []
    for p in pieces:
        rows.append(
            f"| {p['i']} | w{pids[p['pid']]} | {(p['start'] - t0) * 1e3:.0f} | "
            f"{(p['end'] - t0) * 1e3:.0f} | {(p['arrived'] - t0) * 1e3:.0f} | "
            f"{p['validate'] * 1e3:.0f} | {p['memo_get'] * 1e3:.0f} | {p['compute'] * 1e3:.0f} | "
            f"{p['memo_put'] * 1e3:.0f} | {p['memo_put_cpu'] * 1e3:.0f} | "
            f"{p['cpu'] / (p['end'] - p['start']):.0%} |"
        )
    first_start = min(p["start"] for p in pieces)
    span = max(p["end"] for p in pieces) - first_start
    phases = [
        ("job start to pieces submitted (expand, split)", m["submit"] - t0),
        ("pieces submitted to the first piece started", first_start - m["submit"]),
        ("pieces running (first start to last end)", span),
        ("last piece ended to the job has it", last - max(p["end"] for p in pieces)),
        ("last arrival to merge done (rows merged)", m["merged"] - last),
        ("`_table` (rows, statistics, document)", m["table"] - m["merged"]),
        ("to execute's return", m["executed"] - m["table"]),
        ("result encoded (`encoding.dumps`)", m["encoded"] - m["executed"]),
        ("result stored (compress, write)", m["stored"] - m["encoded"]),
        ("**job total**", m["stored"] - t0),
    ]
    sums = {
        k: sum(p[k] for p in pieces)
        for k in ("validate", "memo_get", "compute", "memo_put", "cpu", "memo_put_cpu")
    }
    walls = sum(p["end"] - p["start"] for p in pieces)
    own = {pid: sum(p["cpu"] for p in pieces if p["pid"] == pid) for pid in pids}
    processes = "; ".join(
        f"w{pids.get(float(pid), '?')}{' (runs the job)' if pid == trace['job_pid'] else ''}: "
        f"{cpu * 1e3:.0f} ms, its pieces {own.get(float(pid), 0.0) * 1e3:.0f}"
        for pid, cpu in sorted(trace["process_cpu"].items())
    )
    return "\n".join(
        [
            f"Timeline of one study job ({len(pieces)} pieces on {len(pids)} workers, result "
            f"{trace['bytes'] / 1e6:.1f} MB of JSON); times in ms from the job's start.",
            "",
            f"CPU of each worker process during the job (all its threads): {processes}; the "
            f"job's own thread: {trace['job_cpu'] * 1e3:.0f} ms.",
            "",
            "| job phase | ms |",
            "|---|---:|",
            *(f"| {name} | {dt * 1e3:.0f} |" for name, dt in phases),
            "",
            "Busy time per worker (sum of its pieces) [ms]: "
            + ", ".join(f"w{n} {busy[pid] * 1e3:.0f}" for pid, n in pids.items())
            + f"; over all pieces [ms]: validation and keys {sums['validate'] * 1e3:.0f}, "
            f"memo look-up {sums['memo_get'] * 1e3:.0f}, compute {sums['compute'] * 1e3:.0f}, "
            f"memo write {sums['memo_put'] * 1e3:.0f} (CPU {sums['memo_put_cpu'] * 1e3:.0f}); the "
            f"pieces' CPU {sums['cpu'] * 1e3:.0f} of {walls * 1e3:.0f} wall (the rest waited: "
            "a lock, the GIL, another process on the core).",
            "",
            "| piece | worker | start | end | job has it | validate+keys | memo get | compute "
            "| memo put | its CPU | piece CPU / wall |",
            "|---:|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|",
            *rows,
        ]
    )


def median(values: list[float]) -> float:
    return float(statistics.median(values))


def report(spec: dict[str, Any], raw: dict[str, Any], started: float, smoke: bool) -> str:
    one = median([r["wall"] for r in raw["runs"][1]])
    two = median([r["wall"] for r in raw["runs"][2]])
    c1 = median([r["compute"] for r in raw["runs"][1]])
    c2 = median([r["compute"] for r in raw["runs"][2]])
    lib = median(raw["library"])
    pair = median(raw["pairs"])
    ceiling = 2 * lib / pair
    ratio = one / two
    fan = raw["runs"][2][-1]["fan_out"]
    fan1 = raw["runs"][1][-1]["fan_out"]
    if spec["kind"] == "study":
        grid = spec["grid"]
        what = (
            f"Design study {len(grid['flow.velocity.value'])} x "
            f"{len(grid['rotation.omega0.value'])} (v in [0, 20] m/s x w0 in [0, 200] rad/s), "
            f"{spec['base']['spec']['modes']} modes, 1 s, 201 samples, auto (= cma), every "
            "case computed"
        )
    else:
        what = (
            f"Spin map {spec['velocity_points']} x {spec['spin_points']} x {spec['modes']} "
            "modes, the paper's pipe, v in [0, 60] m/s, w0 in [0, 2000] rad/s"
        )
    rows = [
        ["library call `execute` (serial, 1 BLAS thread)", f"{lib * 1e3:.0f} ms", "", ""],
        ["job over HTTP, `PIPEFLOW_WORKERS=1`", f"{one * 1e3:.0f} ms", f"{c1 * 1e3:.0f} ms",
         f"{fan1 or 'in place (1 thread)'}"],
        ["job over HTTP, `PIPEFLOW_WORKERS=2`", f"{two * 1e3:.0f} ms", f"{c2 * 1e3:.0f} ms",
         f"{fan}"],
    ]  # fmt: skip
    lines = [
        f"`{' '.join(['python benchmarks/bench_fanout.py', *sys.argv[1:]])}` "
        f"({time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}, "
        f"{time.monotonic() - started:.0f} s): {raw['machine']}; load average "
        + " ".join(f"{x:.1f}" for x in raw["load_after"])
        + f" at the end. {what}; {len(raw['library'])} repetitions, medians.",
        "",
        "| what | median wall time (POST to result) | median compute (job started..finished) "
        "| diagnostics.fan_out |",
        "|---|---:|---:|---|",
        *("| " + " | ".join(r) + " |" for r in rows),
        "",
        f"**2 workers vs 1: {ratio:.2f}x** (target >= {TARGET}x: "
        f"{'met' if ratio >= TARGET else 'MISSED'}); compute only: {c1 / c2:.2f}x; "
        f"1-worker job vs the library call: {one / lib:.2f}x. What the machine gave two "
        f"processes at once in this run (two library calls in 2 processes: median "
        f"{pair * 1e3:.0f} ms for both, vs {lib * 1e3:.0f} ms for one alone): "
        f"{ceiling:.2f}x, the ceiling of the 2-vs-1 ratio under the other engineers' load.",
        "",
        "CPU of the API server process during a job (its requests, "
        + ("long-polled" if POLL_S is None else f"polled every {POLL_S * 1e3:.0f} ms")
        + ", and the embedded Dask scheduler), median: 1 worker "
        f"{median([r['server_cpu'] for r in raw['runs'][1]]) * 1e3:.0f} ms, 2 workers "
        f"{median([r['server_cpu'] for r in raw['runs'][2]]) * 1e3:.0f} ms (with 2 workers "
        "it shares the 2 cores with them).",
        "",
        *(_ab_poll(raw) if "polled" in raw else []),
        "wall [ms], 1 worker: " + ", ".join(f"{r['wall'] * 1e3:.0f}" for r in raw["runs"][1]),
        "",
        "wall [ms], 2 workers: " + ", ".join(f"{r['wall'] * 1e3:.0f}" for r in raw["runs"][2]),
        "",
        "library [ms]: " + ", ".join(f"{x * 1e3:.0f}" for x in raw["library"]),
        "",
        "two library calls at once [ms]: " + ", ".join(f"{x * 1e3:.0f}" for x in raw["pairs"]),
    ]
    return "\n".join(lines)


def _ab_poll(raw: dict[str, Any]) -> list[str]:
    """``--ab-poll``'s table: the same rounds' jobs, long-polled against polled."""
    rows = []
    for name, runs in (
        ("long poll (`?wait=60`)", raw["runs"]),
        (f"polled every {AB_POLL_S * 1e3:.0f} ms", raw["polled"]),
    ):
        one = median([r["wall"] for r in runs[1]])
        two = median([r["wall"] for r in runs[2]])
        cpu1 = median([r["server_cpu"] for r in runs[1]])
        cpu2 = median([r["server_cpu"] for r in runs[2]])
        rows.append(
            f"| {name} | {one * 1e3:.0f} | {two * 1e3:.0f} | {one / two:.2f}x | "
            f"{cpu1 * 1e3:.0f} | {cpu2 * 1e3:.0f} |"
        )
    return [
        "Waiting by long poll against polling, the same rounds (interleaved, the order "
        "alternating), medians:",
        "",
        "| wait | 1 worker [ms] | 2 workers [ms] | 2 vs 1 | API CPU/job, 1 w [ms] "
        "| API CPU/job, 2 w [ms] |",
        "|---|---:|---:|---:|---:|---:|",
        *rows,
        "",
    ]


def main(argv: list[str] | None = None) -> int:
    global POLL_S, AB_POLL
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--smoke", action="store_true", help="a tiny map, one repetition")
    ap.add_argument("--repeats", type=int, default=9, help="measured jobs per server")
    ap.add_argument("--label", default="latest", help="section name in RESULTS.md")
    ap.add_argument("--out", type=Path, default=RESULTS, help="Markdown file to write into")
    ap.add_argument("--no-write", action="store_true", help="print only")
    ap.add_argument("--sweeps", action="store_true", help="also the sweep-spectra probe")
    ap.add_argument("--study", action="store_true", help="the 10,000-case study, not the map")
    ap.add_argument("--timeline", action="store_true", help="--study: trace one job instead")
    ap.add_argument(
        "--poll",
        type=float,
        default=None,
        help="poll the job every POLL s (the old way; default: long polls, ?wait=)",
    )
    ap.add_argument("--workers", type=int, default=2, help="--timeline: the cluster's workers")
    ap.add_argument("--direct", action="store_true", help="--study: the job alone, 2 vs 1")
    ap.add_argument(
        "--ab-poll",
        action="store_true",
        help="each round also a job polled every 20 ms: long poll against polling, same run",
    )
    args = ap.parse_args(argv)
    POLL_S = args.poll
    AB_POLL = args.ab_poll
    spec = study(args.smoke) if args.study else SMOKE_MAP if args.smoke else MAP
    started = time.monotonic()
    if args.timeline or args.direct:
        if not args.study:
            ap.error("--timeline and --direct measure the study job: add --study")
        text = direct(spec, args.repeats) if args.direct else timeline(spec, args.workers)
        text = (
            f"`{' '.join(['python benchmarks/bench_fanout.py', *sys.argv[1:]])}` "
            f"({time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}, "
            f"{time.monotonic() - started:.0f} s, load average "
            + " ".join(f"{x:.1f}" for x in os.getloadavg())
            + f" at the end): {BENCH.machine()}.\n\n{text}"
        )
        print(text, flush=True)
        if not args.no_write:
            what = "alone, 2 vs 1 worker" if args.direct else "timeline"
            BENCH.write_section(args.out, args.label, text, prefix=f"Study job {what} (issue 19)")
            print(f"\nwritten to {args.out}")
        return 0
    desc = BENCH.machine()
    raw = run(spec, 1 if args.smoke else args.repeats)
    raw["machine"] = desc
    text = report(spec, raw, started, args.smoke)
    if args.sweeps:
        text += "\n\n" + sweep_probe()
    print(text, flush=True)
    if not args.no_write:
        prefix = "Fan-out benchmark (issue " + ("19, study)" if args.study else "11)")
        BENCH.write_section(args.out, args.label, text, prefix=prefix)
        print(f"\nwritten to {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
