"""Where a cold request's time goes in the server: a breakdown by span of py-spy's samples.

    python benchmarks/profile_cold_path.py --case lti --requests 300
    python benchmarks/profile_cold_path.py --case paper --requests 60

Starts ``uvicorn service.main:app`` from this tree (the default settings: the fast lane runs
the computation in the API process, as ``benchmarks/bench_cold_paper.py``'s ``lane``
server), warms it, then samples it with ``py-spy record --nonblocking`` (every thread, 1
kHz, the server not paused per sample; samples of waiting threads, told by their innermost
frame (:data:`IDLE`), left out) while ``--requests`` cold requests of the case go one after
the other (a fresh key each: u0 changed by 1e-9 relative). Each sample's stack is put in the
first span of :data:`WHOLE` / :data:`INNERMOST` (see there). Printed: the client's median
request time and the span table (span, busy samples of all the server's threads, share of
them), with ``--top`` the heaviest leaf frames of the ``other`` span (to name a new span).
Shares only: on this container py-spy falls far behind its rate under load (15-250 ticks
per second measured) and its ticks are not evenly spread over the threads, so samples are
not converted to milliseconds; the span times in ms come from ``perf_counter_ns`` marks
(benchmarks/RESULTS.md says how)."""

from __future__ import annotations

import argparse
import os
import re
import signal
import subprocess
import sys
import tempfile
import time
from collections import Counter
from contextlib import ExitStack
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT), str(ROOT / "benchmarks")]

import bench_cold_ab as AB  # noqa: E402  (the server start)
import bench_service as BENCH  # noqa: E402  (cases, percentiles)
import httpx  # noqa: E402

#: (span, regular expression on one frame ``function (file:line)``).  The spans of
#: :data:`WHOLE` take a sample if any of its frames matches (the store's operations with the
#: SQLAlchemy and SQLite calls under them, the numerics, in this order); otherwise the
#: innermost frame that matches one of :data:`INNERMOST` names the span (the middleware
#: layers wrap every request: only their own code counts for them)
WHOLE: list[tuple[str, str]] = [
    ("store: enqueue_and_claim (record + lease)", r"^JobStore\.enqueue_and_claim "),
    ("compression of the result (zlib)", r"^compress \(.*service/store/results"),
    ("store: finish_with_result (result + finish)", r"^Store\.finish_with_result "),
    ("store: cache lookup (get_result)", r"^ResultStore\.get_result "),
    ("store: dispatcher (claim_waiting)", r"^JobStore\.claim_waiting "),
    ("store: other (monitor, heartbeats)", r"service/store/"),
    ("JSON encode (orjson)", r"service/encoding\.py"),
    ("document (pipeflow.computations.documents)", r"pipeflow/computations/documents\.py"),
    ("simulate (numerics)", r"pipeflow/(?!schema/keys)"),
    ("Dask scheduler/client in the API process", r"distributed/|tornado/|psutil/"),
]
INNERMOST: list[tuple[str, str]] = [
    ("lane thread hop (call_soon_threadsafe)", r"^Runner\._(in_lane|lane_first)\.<locals>"),
    ("task wrapper (service/engine/task.py)", r"service/engine/task\.py"),
    ("canonical key", r"service/keys\.py|pipeflow/schema/keys|rfc8785"),
    ("access log / metrics", r"service/observability\.py|prometheus_client|/logging/"),
    ("middleware: request context, security, auth, hit path, body limit", r"service/http/"),
    ("orchestration / runner (event loop)", r"service/(orchestration|engine/runner)\.py"),
    ("body parse + validation (FastAPI, pydantic)", r"fastapi/|pydantic"),
    ("HTTP server (uvicorn, httptools)", r"uvicorn/|h11/|httptools"),
    ("starlette routing / responses", r"starlette/|anyio/"),
    ("asyncio machinery / threads", r"asyncio/|concurrent/futures|threading\.py"),
]
#: a sample whose innermost frame is one of these is a thread waiting (py-spy's own idle
#: detection does not work in this container): left out
IDLE = re.compile(
    r"^(_worker \(concurrent/futures/thread\.py|Condition\.wait |Popen\.poll |Event\.wait |"
    r"Runner\.run \(asyncio/runners\.py|select |poll \(selectors|Queue\.get )"
)


def classify(stack: list[str]) -> str:
    """The span of one sample (``stack``: outermost frame first)."""
    for span, pattern in WHOLE:
        if any(re.search(pattern, frame) for frame in stack):
            return span
    for frame in reversed(stack):
        for span, pattern in INNERMOST:
            if re.search(pattern, frame):
                return span
    return "other"


def read_raw(path: Path) -> tuple[Counter[str], Counter[str], int]:
    """py-spy's raw (collapsed) output: samples by span, the ``other`` leaves, and the
    sampling ticks py-spy took (it falls behind its rate on a loaded machine, so they are
    counted, not assumed): the median over the threads of each one's samples, busy or
    waiting (every thread is sampled at every tick)."""
    spans: Counter[str] = Counter()
    leaves: Counter[str] = Counter()
    per_thread: Counter[str] = Counter()
    for line in path.read_text().splitlines():
        stack_text, _, count = line.rpartition(" ")
        if not stack_text:
            continue
        frames = stack_text.split(";")[1:]  # the first element is the thread
        per_thread[stack_text.split(";")[0]] += int(count)
        if not frames or IDLE.search(frames[-1]):
            continue
        span = classify(frames)
        spans[span] += int(count)
        if span == "other" and frames:
            leaves[" <- ".join(reversed(frames[-3:]))] += int(count)
    totals = sorted(per_thread.values())
    return spans, leaves, totals[len(totals) // 2] if totals else 0


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--case", choices=("lti", "paper"), default="lti")
    ap.add_argument("--requests", type=int, default=300)
    ap.add_argument("--rate", type=int, default=1000, help="samples per second")
    ap.add_argument("--top", type=int, default=0, help="print the heaviest 'other' leaves")
    ap.add_argument("--tree", type=Path, default=ROOT, help="the source tree of the server")
    ap.add_argument("--raw", type=Path, help="keep py-spy's collapsed stacks in this file")
    ap.add_argument("--setting", action="append", default=[], help="name=value of the server")
    args = ap.parse_args(argv)
    spec = BENCH.LTI if args.case == "lti" else BENCH.PAPER
    settings = dict(s.split("=", 1) for s in args.setting)
    with tempfile.TemporaryDirectory(prefix="pipeflow-prof-") as tmp, ExitStack() as stack:
        url = AB.start(args.tree.resolve(), settings, Path(tmp), stack)
        pid = int(
            subprocess.check_output(["pgrep", "-n", "-f", "--", f"--port {url.rsplit(':', 1)[1]}"])
        )
        client = stack.enter_context(httpx.Client(timeout=120))
        BENCH.cold_requests(client, url, spec, 5, 10**6)  # warm: not sampled
        raw = Path(tmp) / "profile.txt"
        sampled = time.perf_counter()
        spy = subprocess.Popen(
            [
                *("py-spy", "record", "--pid", str(pid), "--rate", str(args.rate), "--threads"),
                *("--nonblocking", "--format", "raw", "--output", str(raw)),
            ],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
        )
        time.sleep(1.0)  # py-spy attaches
        times, _ = BENCH.cold_requests(client, url, spec, args.requests, 2 * 10**6)
        spy.send_signal(signal.SIGINT)
        sampled = time.perf_counter() - sampled
        spy.wait(30)
        spans, leaves, ticks = read_raw(raw)
        if args.raw is not None:
            args.raw.write_text(raw.read_text())
    n = args.requests
    total = sum(spans.values())
    rate = ticks / sampled  # the sampling rate py-spy achieved [1/s]
    load = " ".join(f"{x:.1f}" for x in os.getloadavg())
    print(f"{args.case}: {n} cold requests, client p50 {BENCH.pct(times, 50) * 1e3:.2f} ms; ")
    print(f"{total} busy samples; load {load}; py-spy took ~{rate:.0f} ticks/s")
    print("| span | busy samples | share |")
    print("|---|---|---|")
    for span, count in spans.most_common():
        print(f"| {span} | {count} | {count / total:.1%} |")
    for leaf, count in leaves.most_common(args.top):
        print(f"  {count} samples  {leaf}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
