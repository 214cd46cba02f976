"""HTTP hardening of issue 22: tables kept encoded, 304s, and the cost of API keys.

    python benchmarks/bench_http.py              # ~1-2 min on the 2-core machine
    python benchmarks/bench_http.py --smoke      # a few rounds (seconds after start-up)

Starts two servers the README's way (``uvicorn service.main:app``, one worker each, data in
fresh temporary directories): A with the defaults, B with ``PIPEFLOW_TABLE_CACHE_BYTES=0``
(every table written again, as before issue 22) and ``PIPEFLOW_AUTH_REQUIRED=true``.  Both
store the same simulation (the paper's example, 10 modes, 2001 samples, 4 stations, 10
traced eigenvalues), then the rows below run interleaved, one request of each per round
(so load drift on the shared cores hits every row alike), on one keep-alive client per
server; the table gives each row's median and its ratio to ``GET /healthz`` on the same
server in the same rounds.

Rows: CSV and Parquet of the history table (A: from memory; B: read, parsed and written
again), the same with ``If-None-Match`` (A: 304), and the JSON cache hit with a key on B
against A without one (the cost of authentication on the hottest path).
"""

from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import httpx

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from pipeflow.schema.simulation import PAPER_EXAMPLE  # noqa: E402
from service.http.auth import new_key  # noqa: E402
from service.launch import serve  # noqa: E402

SPEC = {**PAPER_EXAMPLE, "output": {"positions": [0.005, 0.01, 0.015, 0.02], "eigen_modes": 10}}


def _timed(call: Callable[[], httpx.Response], expect: int) -> float:
    start = time.perf_counter()
    r = call()
    seconds = time.perf_counter() - start
    assert r.status_code == expect, (r.status_code, r.text[:300])
    return seconds


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--smoke", action="store_true", help="a few rounds only")
    ap.add_argument("--rounds", type=int, default=200)
    args = ap.parse_args()
    rounds = 5 if args.smoke else args.rounds
    key, entry = new_key("bench")
    with tempfile.TemporaryDirectory() as tmp_a, tempfile.TemporaryDirectory() as tmp_b:
        env_a = {"PIPEFLOW_DATA_DIR": tmp_a, "PIPEFLOW_WORKERS": "1"}
        env_b = {
            "PIPEFLOW_DATA_DIR": tmp_b,
            "PIPEFLOW_WORKERS": "1",
            "PIPEFLOW_TABLE_CACHE_BYTES": "0",
            "PIPEFLOW_AUTH_REQUIRED": "true",
            "PIPEFLOW_API_KEYS": entry,
        }
        log_a, log_b = Path(tmp_a) / "server.log", Path(tmp_b) / "server.log"
        with serve(log_a, env=env_a) as a, serve(log_b, env=env_b) as b:
            auth = {"Authorization": f"Bearer {key}"}
            ca = httpx.Client(base_url=a.url, timeout=120)
            cb = httpx.Client(base_url=b.url, timeout=120, headers=auth)
            stored = ca.post("/v1/simulations", json=SPEC).json()["key"]
            assert cb.post("/v1/simulations", json=SPEC).json()["key"] == stored
            url = f"/v1/results/{stored}"
            csv_tag = ca.get(url, params={"format": "csv"}).headers["etag"]
            pq_tag = ca.get(url, params={"format": "parquet"}).headers["etag"]
            size = {
                "csv": len(ca.get(url, params={"format": "csv"}).content),
                "parquet": len(ca.get(url, params={"format": "parquet"}).content),
                "json": len(ca.get(url).content),
            }
            csv, pq = {"format": "csv"}, {"format": "parquet"}
            rows: dict[str, tuple[Callable[[], httpx.Response], int, str]] = {
                "A: GET /healthz": (lambda: ca.get("/healthz"), 200, "A"),
                "B: GET /healthz": (lambda: cb.get("/healthz"), 200, "B"),
                "A: CSV, kept encoded": (lambda: ca.get(url, params=csv), 200, "A"),
                "B: CSV, written again": (lambda: cb.get(url, params=csv), 200, "B"),
                "A: CSV, If-None-Match (304)": (
                    lambda: ca.get(url, params=csv, headers={"If-None-Match": csv_tag}),
                    304,
                    "A",
                ),
                "A: Parquet, kept encoded": (lambda: ca.get(url, params=pq), 200, "A"),
                "B: Parquet, written again": (lambda: cb.get(url, params=pq), 200, "B"),
                "A: Parquet, If-None-Match (304)": (
                    lambda: ca.get(url, params=pq, headers={"If-None-Match": pq_tag}),
                    304,
                    "A",
                ),
                "A: POST hit, no auth": (lambda: ca.post("/v1/simulations", json=SPEC), 200, "A"),
                "B: POST hit, bearer key": (
                    lambda: cb.post("/v1/simulations", json=SPEC),
                    200,
                    "B",
                ),
            }
            for call, expect, _ in rows.values():  # warm both (caches, connections)
                _timed(call, expect)
            times: dict[str, list[float]] = {name: [] for name in rows}
            for _ in range(rounds):
                for name, (call, expect, _) in rows.items():
                    times[name].append(_timed(call, expect))
            ca.close()
            cb.close()
    med = {name: statistics.median(t) * 1e3 for name, t in times.items()}
    print(
        f"stored result: JSON {size['json']:,} B, history CSV {size['csv']:,} B, "
        f"Parquet {size['parquet']:,} B; {rounds} interleaved rounds"
    )
    print("| row | median [ms] | / GET /healthz (same server) |")
    print("|---|---:|---:|")
    for name, (_, _, server_name) in rows.items():
        base = med[f"{server_name}: GET /healthz"]
        print(f"| {name} | {med[name]:.2f} | {med[name] / base:.1f}x |")
    ratio = {
        "CSV written again / kept": ("B: CSV, written again", "A: CSV, kept encoded"),
        "Parquet written again / kept": ("B: Parquet, written again", "A: Parquet, kept encoded"),
        "hit with key / without": ("B: POST hit, bearer key", "A: POST hit, no auth"),
    }
    print("; ".join(f"{k}: {med[a] / med[b]:.2f}x" for k, (a, b) in ratio.items()))
    return 0


if __name__ == "__main__":
    sys.exit(main())
