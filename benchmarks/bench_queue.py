"""What the durable job queue costs the store (issue 22, defect 4).

    python benchmarks/bench_queue.py [--depths 0 1000 5000] [--rounds 200] [--url URL]

On a fresh SQLite file (or ``--url``, e.g. a PostgreSQL database), with ``depth`` jobs
already waiting from 20 clients, it times per round, interleaved: ``enqueue_job`` of a new
key (the synchronous path's record write, the peer), ``queue_job`` of a new key (a job
accepted into the queue: the bound's count + the insert) and ``claim_waiting`` of one job
(the dispatcher: fairness over the waiting clients + the conditional update).  Each round
queues one job and takes one, so the depth stays put.  Prints the median [ms] of each and
its ratio to ``enqueue_job`` of the same run.
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
import time
from pathlib import Path

from service.store import Store


def _fill(store: Store, depth: int) -> None:
    for i in range(depth):
        store.queue_job(f"fill-{i}", "simulation", {"i": i}, bound=10**9, principal=f"c{i % 20}")


def run(url: str, depth: int, rounds: int) -> dict[str, float]:
    store = Store(url, cache_max_bytes=1 << 30, memory_cache_bytes=0)
    _fill(store, depth)
    times: dict[str, list[float]] = {"enqueue_job": [], "queue_job": [], "claim_waiting": []}
    for r in range(rounds):
        t0 = time.perf_counter()
        store.enqueue_job(f"sync-{depth}-{r}", "simulation", {"r": r}, dispatcher="bench")
        t1 = time.perf_counter()
        store.queue_job(
            f"job-{depth}-{r}", "simulation", {"r": r}, bound=10**9, principal=f"c{r % 20}"
        )
        t2 = time.perf_counter()
        taken = store.claim_waiting("bench", 1)
        t3 = time.perf_counter()
        assert len(taken) == 1
        times["enqueue_job"].append(t1 - t0)
        times["queue_job"].append(t2 - t1)
        times["claim_waiting"].append(t3 - t2)
    store.close()
    return {k: statistics.median(v) * 1e3 for k, v in times.items()}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--depths", type=int, nargs="+", default=[0, 1000, 5000])
    parser.add_argument("--rounds", type=int, default=200)
    parser.add_argument("--url", default=None, help="a database URL (default: a temp SQLite)")
    args = parser.parse_args()
    print("| waiting jobs | enqueue_job [ms] | queue_job [ms] | claim_waiting [ms] | ratios |")
    print("|---:|---:|---:|---:|---|")
    for depth in args.depths:
        with tempfile.TemporaryDirectory() as tmp:
            url = args.url or f"sqlite:///{Path(tmp) / 'bench.sqlite3'}"
            m = run(url, depth, args.rounds)
        base = m["enqueue_job"]
        print(
            f"| {depth:,} | {base:.3f} | {m['queue_job']:.3f} | {m['claim_waiting']:.3f} | "
            f"queue {m['queue_job'] / base:.2f}x, claim {m['claim_waiting'] / base:.2f}x |"
        )


if __name__ == "__main__":
    main()
