"""Cold requests of two or more servers at once, interleaved: an A/B of the cold path that
a loaded, shared machine cannot skew towards one side.

    python benchmarks/bench_cold_ab.py before=/path/to/other/checkout after=. \
        nolane=.:fast_lane_threads=0 --rounds 40

Each ``NAME=TREE[:setting=value,...]`` starts ``uvicorn service.main:app`` from that
source tree (its own data directory, the default settings but those given).  Each round
sends one cold LTI request (the issue's case of ``benchmarks/bench_service.py``, a fresh key by
a 1e-9 change of u0) to every server, in a rotating order, then times ``simulate()`` of
it here; every ``--paper-every`` rounds the same with the paper example and
``simulate().to_dict()``.  Drift of the machine's load hits every side and the references
alike; the ratios are of medians over the same rounds.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from contextlib import ExitStack
from pathlib import Path

import httpx

ROOT = Path(__file__).resolve().parents[1]
# this tree's packages first (a checkout or worktree measures its own code), then this
# directory (bench_service)
sys.path[:0] = [str(ROOT), str(ROOT / "benchmarks")]

import bench_service as BENCH  # noqa: E402  (the server start-up, timers, section writer)

from service.launch import answers, free_port, stop_group  # noqa: E402


def start(tree: Path, settings: dict[str, str], work: Path, stack: ExitStack) -> str:
    """``uvicorn service.main:app`` from ``tree``; its URL once ready."""
    port = free_port()
    env = {
        **os.environ,
        "PYTHONPATH": str(tree),
        "PIPEFLOW_DATA_DIR": str(work / "data"),
        "PIPEFLOW_LOG_LEVEL": "WARNING",
        **{f"PIPEFLOW_{k.upper()}": v for k, v in settings.items()},
    }
    log = stack.enter_context(open(work / "server.log", "ab"))
    proc = subprocess.Popen(
        [sys.executable, "-m", "uvicorn", "service.main:app", "--port", str(port)],
        cwd=tree,
        env=env,
        stdout=log,
        stderr=subprocess.STDOUT,
        start_new_session=True,
    )
    stack.callback(stop_group, proc, 15, 20.0)
    url = f"http://127.0.0.1:{port}"
    deadline = time.monotonic() + 180
    while not answers(url + "/readyz"):
        if proc.poll() is not None or time.monotonic() > deadline:
            raise RuntimeError((work / "server.log").read_text(errors="replace")[-3000:])
        time.sleep(0.2)
    return url


def parse_sides(items: list[str]) -> list[tuple[str, Path, dict[str, str]]]:
    """``NAME=TREE[:setting=value,...]`` arguments as ``(name, tree, settings)``."""
    sides = []
    for item in items:
        name, _, rest = item.partition("=")
        tree, _, opts = rest.partition(":")
        settings = dict(o.split("=", 1) for o in opts.split(",") if o)
        sides.append((name, Path(tree).resolve(), settings))
    return sides


def sides_parser(doc: str, rounds: int) -> argparse.ArgumentParser:
    """The command line of an A/B of source trees: the sides and ``--rounds``."""
    ap = argparse.ArgumentParser(description=doc.splitlines()[0])
    ap.add_argument("servers", nargs="+", metavar="NAME=TREE[:setting=value,...]")
    ap.add_argument("--rounds", type=int, default=rounds)
    return ap


def main(argv: list[str] | None = None) -> int:
    ap = sides_parser(__doc__, 40)
    ap.add_argument("--paper-every", type=int, default=4, help="a paper round every N rounds")
    args = ap.parse_args(argv)
    sides = parse_sides(args.servers)
    lti_ref, doc_ref = BENCH.simulate_timer(BENCH.LTI), BENCH.simulate_timer(BENCH.PAPER, True)
    times: dict[str, dict[str, list[float]]] = {n: {"lti": [], "paper": []} for n, _, _ in sides}
    refs: dict[str, list[float]] = {"lti": [], "paper": []}
    print(BENCH.machine(), flush=True)
    with tempfile.TemporaryDirectory(prefix="pipeflow-ab-") as tmp, ExitStack() as stack:
        urls = {}
        for name, tree, settings in sides:
            (Path(tmp) / name).mkdir()
            urls[name] = start(tree, settings, Path(tmp) / name, stack)
        client = stack.enter_context(httpx.Client(timeout=120))
        for url in urls.values():  # each worker's (or lane's) first requests: not counted
            BENCH.cold_requests(client, url, BENCH.LTI, 4, 10**6)
            BENCH.cold_requests(client, url, BENCH.PAPER, 1, 10**6)
        for r in range(args.rounds):
            cases = [("lti", BENCH.LTI, lti_ref)]
            if r % args.paper_every == 0:
                cases.append(("paper", BENCH.PAPER, doc_ref))
            for case, spec, ref in cases:
                order = sides[r % len(sides) :] + sides[: r % len(sides)]
                for name, _, _ in order:
                    dt, _ = BENCH.timed_post(
                        client, urls[name] + "/v1/simulations", BENCH.variant(spec, r + 1)
                    )
                    times[name][case].append(dt)
                refs[case].append(ref())
        load = " ".join(f"{x:.1f}" for x in os.getloadavg())
    lti_ref_p50, doc_ref_p50 = BENCH.pct(refs["lti"], 50), BENCH.pct(refs["paper"], 50)
    print(f"load average at the end {load}; {args.rounds} rounds")
    print(
        f"simulate() LTI p50 {lti_ref_p50 * 1e3:.2f} ms; paper to_dict() p50 "
        f"{doc_ref_p50 * 1e3:.2f} ms"
    )
    print("| server | cold LTI p50 | / simulate() | paper p50 | / simulate().to_dict() |")
    print("|---|---|---|---|---|")
    for name, _, settings in sides:
        lti, paper = BENCH.pct(times[name]["lti"], 50), BENCH.pct(times[name]["paper"], 50)
        label = name + (
            f" ({', '.join(f'{k}={v}' for k, v in settings.items())})" if settings else ""
        )
        print(
            f"| {label} | {lti * 1e3:.2f} ms | {lti / lti_ref_p50:.2f}x | {paper * 1e3:.1f} ms "
            f"| {paper / doc_ref_p50:.2f}x |"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
