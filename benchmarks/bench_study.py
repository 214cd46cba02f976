"""Study benchmark of issue 19: a 10,000-case LTI design study, three ways.

    python benchmarks/bench_study.py                # ~1 min on the 2-core machine
    python benchmarks/bench_study.py --cases 2500   # a 50 x 50 grid
    python benchmarks/bench_study.py --smoke        # seconds: a 6 x 6 grid, 2 modes
    python benchmarks/bench_study.py --label x      # names the section written to RESULTS.md
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
"""

from __future__ import annotations

import argparse
import os
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

from pipeflow.model import build_model  # noqa: E402
from pipeflow.paper import PAPER_PIPE  # noqa: E402
from pipeflow.schema.registry import COMPUTATIONS  # noqa: E402
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
    ap.add_argument("--cpu", action="store_true", help="print the shipped path's CPU only")
    args = ap.parse_args(argv)
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
