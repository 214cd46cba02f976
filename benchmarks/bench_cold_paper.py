"""Cold requests over HTTP against the library call that makes the same document, in one
run, interleaved: the paper example (issue 23's target: at most 1.15x
``simulate().to_dict()``) and the LTI case (at most 5x ``simulate()``).

    python benchmarks/bench_cold_paper.py --rounds 30

Two real servers (``uvicorn service.main:app`` from this tree, one Dask worker each, the
fast lane on, started as ``benchmarks/bench_cold_ab.py`` does):

- ``lane``: the default settings: the paper example runs in the fast lane under the
  allowance of metered work (``fast_lane_max_metered_s``), the LTI case in the lane by
  its estimate;
- ``worker``: ``fast_lane_max_metered_s=0``: the paper example on the Dask worker, as
  before the metered lane (the LTI case still in the lane).

Each round, in a rotating order: a cold paper request to each server, a cold LTI request to
the ``lane`` server, a cold request of the paper example at the tolerance 1e-10 to each server
(``refined``: its step control plans an 8,000-step refinement past the lane's allowance, so
the ``lane`` server hands it off to its worker: what a hand-off costs over going to the
worker at once), ``documents.simulation(simulate())`` of the paper example and
``simulate()`` of the LTI case in this process (``bench_service.simulate_timer``).  Each
request is a new key (u0 changed by 1e-9 relative).  Printed: the medians, their ratios,
and the median of the per-round ratios (each request over the reference timed in the same
round: steadier when the machine's load drifts).  Where each computation ran is read from
the servers' logs (``computation finished``: ``lane`` api | worker, ``outcome``).
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
from contextlib import ExitStack
from pathlib import Path
from typing import Any

for _name in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_name, "1")  # as the service pins its workers (before numpy loads)

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT), str(ROOT / "benchmarks")]

import bench_cold_ab as AB  # noqa: E402  (the server start)
import bench_service as BENCH  # noqa: E402  (cases, timers, percentiles, log reading)
import httpx  # noqa: E402

#: the servers: name -> settings other than the defaults (log lines say where it ran)
SERVERS: dict[str, dict[str, str]] = {
    "lane": {"log_level": "INFO"},
    "worker": {"log_level": "INFO", "fast_lane_max_metered_s": "0"},
}


#: the paper example at the tolerance 1e-10: 3,500 steps of pilot, check and rate (53 ms
#: estimated), then a refinement of 8,000 steps (122 ms) past the default allowance (0.1 s).
#: (At 501 samples, the case before, the refinement is capped at 8x since 5 Dec 2026:
#: 4,000 steps, which the lane now computes itself.)
REFINED: dict[str, Any] = {**BENCH.PAPER, "options": {"tolerance": 1e-10}}


def where(log: Path) -> dict[str, int]:
    """``lane/outcome`` -> count of the ``computation finished`` lines in a server's log."""
    counts: dict[str, int] = {}
    for r in BENCH.log_records(log):
        if r.get("message") == "computation finished":
            name = f"{r.get('lane')}/{r.get('outcome')}"
            counts[name] = counts.get(name, 0) + 1
    return counts


def measure(rounds: int) -> tuple[dict[str, list[float]], dict[str, dict[str, int]]]:
    paper_ref = BENCH.simulate_timer(BENCH.PAPER, True)
    lti_ref = BENCH.simulate_timer(BENCH.LTI)
    out: dict[str, list[float]] = {
        k: []
        for k in (
            "paper lane",
            "paper worker",
            "paper ref",
            "lti lane",
            "lti ref",
            "refined lane",
            "refined worker",
        )
    }
    with tempfile.TemporaryDirectory(prefix="pipeflow-paper-") as tmp, ExitStack() as stack:
        urls = {}
        for name, settings in SERVERS.items():
            (Path(tmp) / name).mkdir()
            urls[name] = AB.start(ROOT, settings, Path(tmp) / name, stack)
        client = stack.enter_context(httpx.Client(timeout=120))
        for url in urls.values():  # each server's first requests: not counted
            BENCH.cold_requests(client, url, BENCH.PAPER, 2, 10**6)
            BENCH.cold_requests(client, url, BENCH.LTI, 2, 10**6)
            BENCH.cold_requests(client, url, REFINED, 1, 10**6)
        for _ in range(2):
            paper_ref(), lti_ref()

        def post(url: str, spec: dict[str, Any], i: int) -> float:
            dt, r = BENCH.timed_post(client, url + "/v1/simulations", BENCH.variant(spec, i))
            if r.headers.get("X-Cache") != "MISS":
                raise RuntimeError("a cold request was answered from the cache")
            return dt

        steps = {
            "paper lane": lambda i: post(urls["lane"], BENCH.PAPER, i),
            "paper worker": lambda i: post(urls["worker"], BENCH.PAPER, i),
            "paper ref": lambda i: paper_ref(),
            "lti lane": lambda i: post(urls["lane"], BENCH.LTI, i),
            "lti ref": lambda i: lti_ref(),
            "refined lane": lambda i: post(urls["lane"], REFINED, i),
            "refined worker": lambda i: post(urls["worker"], REFINED, i),
        }
        names = list(steps)
        for r in range(rounds):
            for name in names[r % len(names) :] + names[: r % len(names)]:
                out[name].append(steps[name](r + 1))
        logs = {name: where(Path(tmp) / name / "server.log") for name in SERVERS}
    return out, logs


def paired(out: dict[str, list[float]], side: str, ref: str) -> float:
    """Median over the rounds of ``side`` / ``ref`` measured in the same round."""
    return BENCH.pct([a / b for a, b in zip(out[side], out[ref], strict=True)], 50)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rounds", type=int, default=30)
    args = ap.parse_args(argv)
    print(BENCH.machine(), flush=True)
    out, logs = measure(args.rounds)
    load = " ".join(f"{x:.1f}" for x in os.getloadavg())
    p50 = {k: BENCH.pct(v, 50) for k, v in out.items()}
    print(f"load average at the end {load}; {args.rounds} rounds")
    print("| cold request | p50 | reference p50 | ratio of p50s | median per-round ratio |")
    print("|---|---|---|---|---|")
    rows = (
        ("paper example, fast lane (metered)", "paper lane", "paper ref", "to_dict()"),
        ("paper example, Dask worker", "paper worker", "paper ref", "to_dict()"),
        ("LTI, fast lane", "lti lane", "lti ref", "simulate()"),
    )
    for label, side, ref, what in rows:
        print(
            f"| {label} | {p50[side] * 1e3:.1f} ms | {what} {p50[ref] * 1e3:.1f} ms | "
            f"{p50[side] / p50[ref]:.2f}x | {paired(out, side, ref):.2f}x |"
        )
    print(
        "paper example, fast lane / Dask worker: ratio of p50s "
        f"{p50['paper lane'] / p50['paper worker']:.2f}x, median per-round ratio "
        f"{paired(out, 'paper lane', 'paper worker'):.2f}x"
    )
    print(
        f"paper example at tolerance 1e-10 (handed off by the lane server): lane server "
        f"{p50['refined lane'] * 1e3:.1f} ms, worker server {p50['refined worker'] * 1e3:.1f} "
        f"ms p50, ratio {p50['refined lane'] / p50['refined worker']:.2f}x, median per-round "
        f"{paired(out, 'refined lane', 'refined worker'):.2f}x"
    )
    for name, counts in logs.items():
        print(f"server {name}: computations by lane/outcome {counts}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
