"""The paper example's cold path: the options for its dispatch, measured in one process
and one run (interleaved), against the library call that makes the same document.

    python benchmarks/bench_cold_paper.py --rounds 12

The app runs in this process (``httpx.ASGITransport``, its lifespan: one Dask worker
process, the fast lane on).  Each round, in a rotating order:

- ``dask``: a cold paper-example request as the service runs it today (time-variant: no
  estimate, so a Dask worker computes it);
- ``lane``: the same request with the simulation's run-time estimate replaced by 10 ms
  for the round (what a time-variant estimate under ``fast_lane_max_s`` would do: a
  thread of this process computes it);
- ``simulate().to_dict()`` here (``bench_service.simulate_timer(PAPER, True)``);
- a no-op Dask task (submit to result), unpinned and pinned to the worker
  (``workers=[address]``: what a "warm pinned worker connection" can be in Dask, whose
  tasks always pass through the scheduler), and a hop to a thread of this process.

During each request an asyncio task sleeps 1 ms in a loop; the largest lag past 1 ms is
the event loop's worst wait in that request (a computation in the lane shares the GIL
with the event loop; numpy's kernels release it).  Medians over the rounds.
"""

from __future__ import annotations

import argparse
import asyncio
import os
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

for _name in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_name, "1")  # as the service pins them (before numpy loads)

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT), str(ROOT / "benchmarks")]

import bench_service as BENCH  # noqa: E402
import httpx  # noqa: E402

from pipeflow.schema.registry import COMPUTATIONS  # noqa: E402
from service.main import create_app  # noqa: E402
from service.settings import Settings  # noqa: E402


def _noop() -> int:
    return 0


async def _lagged(run: Any) -> tuple[float, float, Any]:
    """(seconds of ``await run``, largest event-loop lag past a 1 ms sleep meanwhile, result)."""
    lags: list[float] = [0.0]
    done = False

    async def probe() -> None:
        while not done:
            t0 = time.perf_counter()
            await asyncio.sleep(0.001)
            lags.append(time.perf_counter() - t0 - 0.001)

    task = asyncio.create_task(probe())
    t0 = time.perf_counter()
    result = await run
    seconds = time.perf_counter() - t0
    done = True
    await task
    return seconds, max(lags), result


async def measure(rounds: int) -> dict[str, list[float]]:
    sim = COMPUTATIONS["simulation"]
    real_estimate = sim.run_time
    lane = {"on": False}

    def estimate(spec: Any) -> float | None:
        return 0.01 if lane["on"] else (real_estimate(spec) if real_estimate else None)

    object.__setattr__(sim, "run_time", estimate)  # a frozen dataclass: this run only
    doc_ref = BENCH.simulate_timer(BENCH.PAPER, True)
    out: dict[str, list[float]] = {
        k: [] for k in ("dask", "lane", "ref", "lag dask", "lag lane", "noop", "pinned", "hop")
    }
    with tempfile.TemporaryDirectory(prefix="pipeflow-paper-") as tmp:
        app = create_app(
            Settings(data_dir=tmp, workers=1, log_level="WARNING", fast_lane_max_s=0.5)
        )
        async with app.router.lifespan_context(app):
            runner = app.state.runner
            while not runner.ready:
                await asyncio.sleep(0.05)
            identity = await runner.client.scheduler.identity()
            address = next(iter(identity["workers"]))
            transport = httpx.ASGITransport(app=app)
            async with httpx.AsyncClient(transport=transport, base_url="http://t") as c:

                async def post(side: str, i: int) -> None:
                    lane["on"] = side == "lane"
                    before = runner.lane_runs
                    seconds, lag, r = await _lagged(
                        c.post("/v1/simulations", json=BENCH.variant(BENCH.PAPER, i))
                    )
                    if r.status_code != 200 or r.headers["x-cache"] != "MISS":
                        raise RuntimeError(f"{r.status_code} {r.text[:300]}")
                    if (runner.lane_runs > before) != (side == "lane"):
                        raise RuntimeError(f"the {side} request went the other way")
                    if i > 0:
                        out[side].append(seconds)
                        out[f"lag {side}"].append(lag)

                for w in range(2):  # warm-up of both sides: not counted
                    await post("lane", -(2 * w + 1))
                    await post("dask", -(2 * w + 2))
                for r in range(rounds):
                    sides = ["dask", "lane", "ref"]
                    for side in sides[r % 3 :] + sides[: r % 3]:
                        if side == "ref":
                            out["ref"].append(doc_ref())
                        else:
                            await post(side, 1 + 2 * r + (side == "lane"))
                    for _ in range(5):
                        t0 = time.perf_counter()
                        await runner.client.submit(_noop, pure=False)
                        out["noop"].append(time.perf_counter() - t0)
                        t0 = time.perf_counter()
                        await runner.client.submit(
                            _noop, pure=False, workers=[address], allow_other_workers=False
                        )
                        out["pinned"].append(time.perf_counter() - t0)
                        t0 = time.perf_counter()
                        await asyncio.to_thread(_noop)
                        out["hop"].append(time.perf_counter() - t0)
    object.__setattr__(sim, "run_time", real_estimate)
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rounds", type=int, default=12)
    args = ap.parse_args(argv)
    print(BENCH.machine(), flush=True)
    out = asyncio.run(measure(args.rounds))
    load = " ".join(f"{x:.1f}" for x in os.getloadavg())
    p50 = {k: BENCH.pct(v, 50) for k, v in out.items()}
    ref = p50["ref"]
    print(f"load average at the end {load}; {args.rounds} rounds")
    print("| paper example, cold | p50 | / simulate().to_dict() | event-loop lag p50 (max) |")
    print("|---|---|---|---|")
    print(f"| simulate().to_dict() here | {ref * 1e3:.1f} ms | 1.00x | |")
    for side in ("dask", "lane"):
        lag = out[f"lag {side}"]
        print(
            f"| {side} | {p50[side] * 1e3:.1f} ms | {p50[side] / ref:.2f}x | "
            f"{p50[f'lag {side}'] * 1e3:.2f} ms ({max(lag) * 1e3:.2f} ms) |"
        )
    print(
        f"no-op Dask task p50 {p50['noop'] * 1e3:.2f} ms, pinned to the worker "
        f"{p50['pinned'] * 1e3:.2f} ms, a thread hop {p50['hop'] * 1e3:.3f} ms"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
