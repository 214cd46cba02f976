"""Service benchmark of issue 12: the HTTP service against its own probes and the library.

    python benchmarks/bench_service.py                  # ~3 min on the 2-core machine
    python benchmarks/bench_service.py --smoke          # seconds: every row, tiny counts (CI)
    python benchmarks/bench_service.py --label after    # names the section written to RESULTS.md

Starts the server the README's way (``uvicorn service.main:app --port P`` from the repo
root, data in a fresh temporary directory, the default settings otherwise) and measures,
each row against a reference measured in the same run:

- cache hit, one client (sequential, keep-alive), p50 vs ``GET /healthz`` p50 on the same
  server (interleaved, so drift hits both);
- cache hits under ``wrk`` (32 connections, 2 threads; a Lua script posts the body), vs
  ``wrk`` on ``/healthz``;
- cold LTI request (v = 0.4 m/s, w0 = 100 rad/s, 10 modes, 2001 samples, default method;
  each request a distinct key by a 1e-9 relative change of u0), vs ``scipy.signal.lsim`` of
  the same state matrix and initial state called locally, and vs the library call
  ``simulate()`` of the same spec (what the worker runs: solve, error estimate, frozen
  spectrum; the difference is the service's own cost), called after the requests;
- cold paper example (v = 0.4 t m/s) vs ``pipeflow.simulation.simulate`` of the same spec
  (the target), and vs ``documents.simulation(simulate())``, the same document the
  service sends;
- each worker's first cold request after start (told by the worker pid of the
  computation's log line) vs the later ones;
- mixed load of 32 Python clients (90% hits, 10% misses): errors and the RSS of the server
  and its workers at 10% and at 100% of the run (also split: server process, workers).

The cold rows also give the computation's own time in the worker (``duration_ms`` of its
``computation finished`` log line): the rest is the service's (HTTP, store, Dask dispatch).

Prints the table and writes it, with the machine and the settings, as a section of
``benchmarks/RESULTS.md`` (``--out``), replacing a section of the same label.
"""

from __future__ import annotations

import argparse
import asyncio
import importlib.util
import json
import os
import platform
import random
import re
import shutil
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import httpx
import numpy as np
from scipy import signal

from pipeflow.computations import documents
from pipeflow.loading import Loading
from pipeflow.model import build_model
from pipeflow.schema.simulation import PAPER_EXAMPLE, SimulationSpec
from pipeflow.simulation import simulate
from service.launch import serve

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "benchmarks" / "RESULTS.md"

#: the issue's LTI case: constant v = 0.4 m/s, default method (no "method" key)
LTI: dict[str, Any] = {k: v for k, v in PAPER_EXAMPLE.items() if k not in ("method", "flow")} | {
    "flow": {"velocity": {"kind": "constant", "value": 0.4}}
}
PAPER: dict[str, Any] = {k: v for k, v in PAPER_EXAMPLE.items() if k != "method"}

#: the issue's "today" column (issue 12, measured on main before it)
TODAY = {
    "hit1": "2.7 ms",
    "wrk": "865 req/s, p50 34 ms",
    "lti": "64 ms",
    "paper": "410-460 ms",
    "first": "420-470 ms",
    "mixed": "0 errors",
}


@dataclass
class Plan:
    hits: int
    wrk_s: int
    cold: int
    paper: int
    mixed_s: float
    clients: int


FULL = Plan(hits=1000, wrk_s=20, cold=30, paper=6, mixed_s=60.0, clients=32)
SMOKE = Plan(hits=50, wrk_s=2, cold=3, paper=1, mixed_s=3.0, clients=8)


def variant(spec: dict[str, Any], i: int) -> dict[str, Any]:
    """``spec`` with u0 changed by i * 1e-9 relative: a new key, the same cost."""
    init = dict(spec["initial"], u0=spec["initial"]["u0"] * (1 + 1e-9 * i))
    return dict(spec, initial=init)


def pct(values: list[float], q: float) -> float:
    return float(np.percentile(np.asarray(values), q)) if values else float("nan")


def ms(seconds: float) -> str:
    return f"{seconds * 1e3:.2f} ms"


# -- the server ------------------------------------------------------------------------------


@contextmanager
def server(data_dir: Path, log: Path, env: dict[str, str]) -> Iterator[tuple[str, int]]:
    """The README's ``uvicorn service.main:app --port P`` (:func:`service.launch.serve`);
    yields (url, pid) once ready."""
    with serve(log, env={"PIPEFLOW_DATA_DIR": str(data_dir), **env}) as s:
        yield s.url, s.pid


def rss_bytes(pid: int) -> int:
    """Resident memory of ``pid`` and all its descendants [bytes] (from /proc)."""
    return sum(_tree_rss(pid).values())


def _tree_rss(pid: int) -> dict[int, int]:
    """pid -> resident memory [bytes] of ``pid`` and all its descendants (from /proc)."""
    children: dict[int, list[int]] = {}
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            stat = (entry / "stat").read_text()
        except OSError:
            continue
        ppid = int(stat.rsplit(")", 1)[1].split()[1])
        children.setdefault(ppid, []).append(int(entry.name))
    out, todo = {}, [pid]
    while todo:
        p = todo.pop()
        todo.extend(children.get(p, []))
        try:
            status = Path(f"/proc/{p}/status").read_text()
        except OSError:
            continue
        m = re.search(r"VmRSS:\s+(\d+) kB", status)
        if m:
            out[p] = int(m.group(1)) * 1024
    return out


# -- measurements ----------------------------------------------------------------------------


def timed_post(
    client: httpx.Client, url: str, spec: dict[str, Any]
) -> tuple[float, httpx.Response]:
    t0 = time.perf_counter()
    r = client.post(url, json=spec)
    dt = time.perf_counter() - t0
    if r.status_code != 200:
        raise RuntimeError(f"POST {url}: {r.status_code} {r.text[:300]}")
    return dt, r


def cold_requests(
    client: httpx.Client, url: str, spec: dict[str, Any], n: int, offset: int
) -> tuple[list[float], list[str]]:
    """``n`` cold requests one after the other: their times [s] and keys."""
    times, keys = [], []
    for i in range(n):
        dt, r = timed_post(client, url + "/v1/simulations", variant(spec, offset + i))
        if r.headers.get("X-Cache") != "MISS":
            raise RuntimeError("a cold request was answered from the cache")
        times.append(dt)
        keys.append(r.json()["key"])
    return times, keys


def log_records(log: Path) -> list[dict[str, Any]]:
    """The JSON lines of the server's log (its workers' included)."""
    out = []
    for line in log.read_text().splitlines():
        if line.startswith("{"):
            try:
                out.append(json.loads(line))
            except ValueError:
                continue
    return out


def computations(records: list[dict[str, Any]]) -> dict[str, tuple[int, float]]:
    """key -> (worker pid, duration [s]) of each computation the workers logged."""
    return {
        r["key"]: (r["pid"], r["duration_ms"] / 1e3)
        for r in records
        if r.get("message") == "computation finished" and "key" in r
    }


def process_rss(pid: int) -> dict[str, int]:
    """RSS [bytes] of the server process (``server``) and of each Dask worker process."""
    out = {"server": 0, "workers": 0}
    for p, rss in _tree_rss(pid).items():
        try:
            cmd = Path(f"/proc/{p}/cmdline").read_bytes()
        except OSError:
            continue
        if p == pid:
            out["server"] = rss
        elif b"spawn_main" in cmd:
            out["workers"] += rss
    return out


def lsim_timer(spec: dict[str, Any]) -> Callable[[], float]:
    """One timed ``scipy.signal.lsim`` of the spec's (constant) state equation [s]."""
    sim = SimulationSpec.model_validate(spec).to_simulation()
    model = build_model(sim.pipe, sim.modes, sim.quadrature_order)
    S = model.state_matrix(Loading(sim.flow, sim.spin).coefficients(np.zeros(1)))[0]
    d0, v0 = model.initial_state(sim.u0, sim.du0, sim.initial_shape)
    z0 = model.to_balanced(d0, v0)
    t = np.linspace(0.0, sim.t_end, sim.samples)
    n = S.shape[0]
    system = signal.StateSpace(S, np.zeros((n, 1)), np.eye(n), np.zeros((n, 1)))

    def once() -> float:
        t0 = time.perf_counter()
        signal.lsim(system, np.zeros(t.size), t, X0=z0)
        return time.perf_counter() - t0

    return once


def simulate_timer(spec: dict[str, Any], document: bool = False) -> Callable[[], float]:
    """One timed library call ``simulate()`` of the spec [s]; with ``document``,
    ``documents.simulation(simulate())``: the same result document the service sends
    (simulate() defers the CMA exponents to their first use, which the document is)."""
    sim = SimulationSpec.model_validate(spec).to_simulation()

    def once() -> float:
        t0 = time.perf_counter()
        result = simulate(sim)
        if document:
            documents.simulation(result)
        return time.perf_counter() - t0

    return once


def median_time(once: Callable[[], float], repeats: int) -> float:
    """Median of ``repeats`` calls of a timer [s]."""
    return pct([once() for _ in range(repeats)], 50)


def one_client_hits(client: httpx.Client, url: str, spec: dict[str, Any], n: int) -> dict[str, Any]:
    """p50 of a cache hit and of GET /healthz, interleaved, one keep-alive client."""
    timed_post(client, url + "/v1/simulations", spec)  # stored
    hits, health = [], []
    for _ in range(n):
        t0 = time.perf_counter()
        r = client.get(url + "/healthz")
        health.append(time.perf_counter() - t0)
        assert r.status_code == 200
        dt, r = timed_post(client, url + "/v1/simulations", spec)
        assert r.headers["X-Cache"] == "HIT"
        hits.append(dt)
    return {"hit_p50": pct(hits, 50), "health_p50": pct(health, 50), "bytes": len(r.content)}


_UNITS = {"us": 1e-6, "ms": 1e-3, "s": 1.0, "m": 60.0}


def _seconds(text: str) -> float:
    m = re.fullmatch(r"([\d.]+)(us|ms|s|m)", text)
    if m is None:
        raise ValueError(f"wrk latency {text!r}")
    return float(m.group(1)) * _UNITS[m.group(2)]


def wrk(
    url: str,
    body: Path | None,
    seconds: int,
    connections: int,
    work: Path,
    headers: dict[str, str] | None = None,
) -> dict[str, Any]:
    """``wrk -t2 -c<connections> --latency``; POSTs ``body`` (a Lua script) when given."""
    exe = shutil.which("wrk")
    if exe is None:
        raise RuntimeError("wrk is not installed (apt-get install -y wrk)")
    cmd = [exe, "-t2", f"-c{connections}", f"-d{seconds}s", "--latency", "--timeout", "10s"]
    for name, value in (headers or {}).items():
        cmd += ["-H", f"{name}: {value}"]
    if body is not None:
        script = work / "post.lua"
        script.write_text(
            'wrk.method = "POST"\n'
            'wrk.headers["Content-Type"] = "application/json"\n'
            f"wrk.body = io.open({json.dumps(str(body))}, 'rb'):read('*a')\n"
        )
        cmd += ["-s", str(script)]
    out = subprocess.run([*cmd, url], capture_output=True, text=True, check=True).stdout
    rps = float(re.search(r"Requests/sec:\s+([\d.]+)", out).group(1))  # type: ignore[union-attr]
    lat = dict(re.findall(r"^\s+(50|99)%\s+(\S+)", out, re.M))
    non2xx = re.search(r"Non-2xx or 3xx responses:\s+(\d+)", out)
    sock = re.search(r"Socket errors:.*", out)
    return {
        "rps": rps,
        "p50": _seconds(lat["50"]),
        "p99": _seconds(lat["99"]),
        "errors": int(non2xx.group(1)) if non2xx else 0,
        "socket": sock.group(0) if sock else "",
        "raw": out,
    }


async def mixed_load(
    url: str, pid: int, seconds: float, clients: int, start: int
) -> dict[str, Any]:
    """``clients`` concurrent clients for ``seconds``: 90% hits on 20 stored specs, 10% misses."""
    stored = [variant(LTI, start + i) for i in range(20)]
    counter = [start + 1000]
    stats = {"ok": 0, "errors": 0, "hit": [], "miss": []}
    rss: dict[str, int] = {}
    reasons: dict[str, int] = {}
    async with httpx.AsyncClient(
        base_url=url, timeout=60, limits=httpx.Limits(max_connections=clients)
    ) as client:
        for spec in stored:
            await client.post("/v1/simulations", json=spec)
        rss["start"] = rss_bytes(pid)
        parts: dict[str, dict[str, int]] = {"start": process_rss(pid)}
        rng = random.Random(12)
        end = time.monotonic() + seconds

        async def one() -> None:
            while time.monotonic() < end:
                miss = rng.random() < 0.1
                if miss:
                    counter[0] += 1
                    spec = variant(LTI, counter[0])
                else:
                    spec = rng.choice(stored)
                t0 = time.perf_counter()
                try:
                    r = await client.post("/v1/simulations", json=spec)
                    good = r.status_code == 200
                    why = str(r.status_code)
                except httpx.HTTPError as exc:
                    good, why = False, type(exc).__name__
                dt = time.perf_counter() - t0
                if good:
                    stats["ok"] += 1  # type: ignore[operator]
                    stats["miss" if miss else "hit"].append(dt)  # type: ignore[attr-defined]
                else:
                    stats["errors"] += 1  # type: ignore[operator]
                    reasons[why] = reasons.get(why, 0) + 1

        async def sample_rss() -> None:
            await asyncio.sleep(0.1 * seconds)
            rss["at_10pct"] = rss_bytes(pid)
            parts["at_10pct"] = process_rss(pid)

        await asyncio.gather(sample_rss(), *(one() for _ in range(clients)))
        rss["end"] = rss_bytes(pid)
        parts["end"] = process_rss(pid)
    return stats | {"rss": rss, "rss_by_process": parts, "error_reasons": reasons}


# -- the run ---------------------------------------------------------------------------------


def machine() -> str:
    cpu = "?"
    try:
        cpu = next(
            line.split(":", 1)[1].strip()
            for line in Path("/proc/cpuinfo").read_text().splitlines()
            if line.startswith("model name")
        )
    except (OSError, StopIteration):
        pass
    load = " ".join(f"{x:.1f}" for x in os.getloadavg())
    return (
        f"{platform.platform()}, {os.cpu_count()} CPUs ({cpu}), Python "
        f"{platform.python_version()}, load average {load} at the start"
    )


def verdict(ok: bool) -> str:
    return "met" if ok else "MISSED"


def run(plan: Plan, label: str, env: dict[str, str]) -> tuple[list[list[str]], dict[str, Any]]:
    rows: list[list[str]] = []
    raw: dict[str, Any] = {}
    with tempfile.TemporaryDirectory(prefix="pipeflow-bench-") as tmp:
        work = Path(tmp)
        with (
            server(work / "data", work / "server.log", env) as (url, pid),
            httpx.Client(timeout=120) as client,
        ):
            # first: cold requests on fresh workers (the server only answered /readyz)
            cold, keys = cold_requests(client, url, LTI, plan.cold + 2, 0)
            # each worker's first computation, told by the pid in its log line (the log
            # handlers flush every record)
            done = computations(log_records(work / "server.log"))
            seen: set[int] = set()
            first_idx = []
            for i, key in enumerate(keys):
                if key in done and done[key][0] not in seen:
                    seen.add(done[key][0])
                    first_idx.append(i)
            if not first_idx:  # no worker log lines: the first two
                first_idx = [0, 1]
            first = [cold[i] for i in first_idx]
            later = [t for i, t in enumerate(cold) if i not in first_idx]
            in_worker = [done[k][1] for i, k in enumerate(keys) if k in done and i not in first_idx]
            # the local references after the requests, not interleaved with them: the
            # benchmark's BLAS threads spin for a while after each call and slowed the
            # worker's next request (cold LTI p50 42 -> 66 ms when interleaved)
            lsim = median_time(lsim_timer(LTI), max(5, plan.cold))
            lti_lib = median_time(simulate_timer(LTI), max(3, plan.cold // 3))
            lti_p50 = pct(later, 50)
            worker_p50 = pct(in_worker, 50)
            rows.append(
                [
                    "cold LTI request (v = 0.4, 10 modes, 2001 samples), p50",
                    TODAY["lti"],
                    ms(lti_p50),
                    f"{lti_p50 / lsim:.1f}x lsim ({ms(lsim)}); {lti_p50 / lti_lib:.2f}x "
                    f"simulate() ({ms(lti_lib)}); the computation in the worker "
                    f"(execute + encode) {ms(worker_p50)}",
                    "<= 15 ms, <= 3x lsim",
                    verdict(lti_p50 <= 0.015 and lti_p50 <= 3 * lsim),
                ]
            )
            first_max = max(first)
            rows.append(
                [
                    f"first request on a fresh worker ({len(first)} workers' first, max)",
                    TODAY["first"],
                    ms(first_max),
                    f"{first_max / lti_p50:.2f}x the later cold p50",
                    "the same as later ones",
                    # "the same": within 1.5x of the later p50 (the spread of cold requests)
                    verdict(first_max <= 1.5 * lti_p50),
                ]
            )
            paper, paper_keys = cold_requests(client, url, PAPER, plan.paper, 0)
            lib = median_time(simulate_timer(PAPER), max(2, plan.paper))
            lib_doc = median_time(simulate_timer(PAPER, document=True), max(2, plan.paper))
            paper_p50 = pct(paper, 50)
            done = computations(log_records(work / "server.log"))
            paper_worker = pct([done[k][1] for k in paper_keys if k in done], 50)
            rows.append(
                [
                    "cold paper example (v = 0.4 t), p50",
                    TODAY["paper"],
                    ms(paper_p50),
                    f"{paper_p50 / lib:.2f}x simulate() ({ms(lib)}); "
                    f"{paper_p50 / lib_doc:.2f}x simulate() + document ({ms(lib_doc)}); the "
                    f"computation in the worker {ms(paper_worker)}",
                    "<= 1.3x simulate()",
                    verdict(paper_p50 <= 1.3 * lib),
                ]
            )
            one = one_client_hits(client, url, LTI, plan.hits)
            rows.append(
                [
                    f"cache hit, one client, p50 ({one['bytes'] / 1e3:.0f} kB)",
                    TODAY["hit1"],
                    ms(one["hit_p50"]),
                    f"{one['hit_p50'] / one['health_p50']:.2f}x /healthz ({ms(one['health_p50'])})",
                    "<= 2x /healthz",
                    verdict(one["hit_p50"] <= 2 * one["health_p50"]),
                ]
            )
            body = work / "hit.json"
            body.write_text(json.dumps(LTI))
            hits = wrk(url + "/v1/simulations", body, plan.wrk_s, 32, work)
            gz = {"Accept-Encoding": "gzip"}
            hits_gz = wrk(url + "/v1/simulations", body, plan.wrk_s, 32, work, gz)
            health = wrk(url + "/healthz", None, plan.wrk_s, 32, work)
            rows.append(
                [
                    "cache hits, wrk 32 connections",
                    TODAY["wrk"],
                    f"{hits['rps']:.0f} req/s, p50 {ms(hits['p50'])}, p99 {ms(hits['p99'])}"
                    + (f", {hits['errors']} non-2xx" if hits["errors"] else ""),
                    f"{hits['rps'] / health['rps']:.2f}x /healthz ({health['rps']:.0f} req/s)",
                    ">= 2000 req/s, p99 <= 50 ms",
                    verdict(hits["rps"] >= 2000 and hits["p99"] <= 0.050 and not hits["errors"]),
                ]
            )
            rows.append(
                [
                    "cache hits, wrk 32 connections, Accept-Encoding: gzip",
                    "(sent uncompressed)",
                    f"{hits_gz['rps']:.0f} req/s, p50 {ms(hits_gz['p50'])}, "
                    f"p99 {ms(hits_gz['p99'])}"
                    + (f", {hits_gz['errors']} non-2xx" if hits_gz["errors"] else ""),
                    f"{hits_gz['rps'] / health['rps']:.2f}x /healthz",
                    ">= 2000 req/s, p99 <= 50 ms",
                    verdict(
                        hits_gz["rps"] >= 2000 and hits_gz["p99"] <= 0.050 and not hits_gz["errors"]
                    ),
                ]
            )
            mixed = asyncio.run(mixed_load(url, pid, plan.mixed_s, plan.clients, 10_000))
            rss = mixed["rss"]
            growth = rss["end"] / rss["at_10pct"] - 1
            rows.append(
                [
                    f"{plan.mixed_s:.0f} s mixed load, {plan.clients} clients (90% hits)",
                    TODAY["mixed"],
                    f"{mixed['errors']} errors / {mixed['ok'] + mixed['errors']}, hit p50 "
                    f"{ms(pct(mixed['hit'], 50))} p99 {ms(pct(mixed['hit'], 99))}, "
                    f"RSS {rss['at_10pct'] / 1e6:.0f} -> {rss['end'] / 1e6:.0f} MB",
                    f"RSS {growth:+.1%}",
                    "0 errors, RSS flat within 10%",
                    verdict(mixed["errors"] == 0 and abs(growth) <= 0.10),
                ]
            )
            raw = {
                "cold": cold,
                "first": first_idx,
                "paper": paper,
                "wrk_hits": hits["raw"],
                "wrk_hits_gzip": hits_gz["raw"],
                "wrk_health": health["raw"],
                "mixed": {k: v for k, v in mixed.items() if k not in ("hit", "miss")},
            }
        # the server's own warnings and errors (its log is gone with the temporary directory)
        raw["server_problems"] = [
            line[:400]
            for line in (work / "server.log").read_text().splitlines()
            if '"level":"WARNING"' in line or '"level":"ERROR"' in line
        ]
    return rows, raw


def table(rows: list[list[str]]) -> str:
    head = ["what", "today (issue)", "measured", "ratio (same run)", "target", ""]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    lines += ["| " + " | ".join(r) + " |" for r in rows]
    return "\n".join(lines)


def write_section(path: Path, label: str, text: str, prefix: str = "Service benchmark") -> None:
    """Replace (or append) the section ``## <prefix>: <label>`` of ``path``."""
    title = f"## {prefix}: {label}"
    old = path.read_text() if path.exists() else ""
    pattern = re.compile(rf"^{re.escape(title)}\n.*?(?=^## |\Z)", re.S | re.M)
    section = f"{title}\n\n{text.rstrip()}\n\n"
    new = (
        pattern.sub(lambda _: section, old)
        if pattern.search(old)
        else old.rstrip() + "\n\n" + section
    )
    path.write_text(new)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--smoke", action="store_true", help="seconds-long run of every row")
    ap.add_argument("--label", default="latest", help="section name in RESULTS.md")
    ap.add_argument("--out", type=Path, default=RESULTS, help="Markdown file to write into")
    ap.add_argument("--no-write", action="store_true", help="print only")
    ap.add_argument(
        "--setting",
        action="append",
        default=[],
        metavar="NAME=VALUE",
        help="a server setting other than its default, e.g. fast_lane_threads=0 (repeatable)",
    )
    args = ap.parse_args(argv)
    plan = SMOKE if args.smoke else FULL
    env = {"PIPEFLOW_LOG_LEVEL": "INFO"}
    settings = dict(item.split("=", 1) for item in args.setting)
    env.update({f"PIPEFLOW_{name.upper()}": value for name, value in settings.items()})
    changed = ", ".join(f"{name}={value}" for name, value in settings.items())
    started = time.monotonic()
    desc = machine()
    rows, raw = run(plan, args.label, env)
    text = "\n".join(
        [
            f"`python benchmarks/bench_service.py{' --smoke' if args.smoke else ''}` "
            f"({time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}, "
            f"{time.monotonic() - started:.0f} s): {desc}. Server: `uvicorn service.main:app` "
            f"with the default settings{f' but {changed}' if changed else ''} (2 workers, JSON "
            "request logs at INFO; HTTP "
            f"{'httptools' if importlib.util.find_spec('httptools') else 'h11'}, loop "
            f"{'uvloop' if importlib.util.find_spec('uvloop') else 'asyncio'}).",
            "",
            table(rows),
            "",
            "cold LTI requests [ms] (* a worker's first): "
            + ", ".join(
                f"{x * 1e3:.1f}" + ("*" if i in raw["first"] else "")
                for i, x in enumerate(raw["cold"])
            ),
            "",
            "paper example requests [ms]: " + ", ".join(f"{x * 1e3:.0f}" for x in raw["paper"]),
            "",
            f"mixed load: {json.dumps(raw['mixed'])}",
            "",
            f"server warnings and errors: {len(raw['server_problems'])}"
            + "".join(f"\n    {line}" for line in raw["server_problems"][:5]),
        ]
    )
    print(text, flush=True)
    if not args.no_write:
        write_section(args.out, args.label, text)
        print(f"\nwritten to {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
