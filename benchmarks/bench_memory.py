"""Idle memory of the embedded set-up (issue 22, defect 9): ``uvicorn service.main:app`` with
2 workers, ready and idle, every process of its group measured from /proc.

    python benchmarks/bench_memory.py before=/path/to/other/checkout after=. \
        nolane=.:fast_lane_threads=0 --rounds 3

Each ``NAME=TREE[:setting=value,...]`` starts the server from that source tree (as
``bench_cold_ab.py`` does: its own data directory, the default settings but those given,
``PIPEFLOW_WORKERS=2``), waits for ``/readyz`` and ``--settle`` seconds, then sums over the
server, its workers and multiprocessing's resource tracker: RSS (``VmRSS``: shared pages
counted in each process, what ``ps`` and ``docker stats`` show) and PSS (``Pss`` of
``smaps_rollup``: shared pages split between the processes sharing them).  The sides are
started one after another, in a rotating order each round; the medians over the rounds
are printed, with each side's ratio to the first.

    python benchmarks/bench_memory.py --distributed

measures the processes of docker-compose.yml's roles instead, run here without containers
or TLS: ``dask scheduler``, 2 ``dask worker --nthreads 1 --preload-nanny
service.engine.preload`` (each a nanny and its worker process) and one API replica
(``uvicorn service.main:app`` with ``PIPEFLOW_SCHEDULER_ADDRESS``; SQLite in place of
PostgreSQL, whose server is not ours), idle for ``--settle`` seconds once ``/readyz``
answers; RSS and PSS per role.
"""

from __future__ import annotations

import statistics
import sys
import tempfile
import time
from contextlib import ExitStack
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT), str(ROOT / "benchmarks")]

from bench_cold_ab import parse_sides, sides_parser, start  # noqa: E402  (a source tree's server, ready)

from tests.service.processes import live_group_members  # noqa: E402


def _kb(path: Path, field: str) -> int:
    for line in path.read_text().splitlines():
        if line.startswith(field + ":"):
            return int(line.split()[1])
    return 0


def group_memory(pgid: int) -> list[tuple[int, str, int, int]]:
    """``(pid, command, rss_kb, pss_kb)`` of each live process of group ``pgid``."""
    rows = []
    for pid in sorted(live_group_members(pgid)):
        proc = Path("/proc") / str(pid)
        try:
            cmd = (proc / "cmdline").read_bytes().replace(b"\0", b" ").decode()[:60]
            rows.append(
                (pid, cmd, _kb(proc / "status", "VmRSS"), _kb(proc / "smaps_rollup", "Pss"))
            )
        except OSError:
            continue
    return rows


def measure(tree: Path, settings: dict[str, str], settle_s: float) -> dict[str, float]:
    with ExitStack() as stack:
        work = Path(stack.enter_context(tempfile.TemporaryDirectory(prefix="pipeflow-mem-")))
        _, proc = start_server(tree, {"workers": "2", **settings}, work, stack)
        time.sleep(settle_s)
        rows = group_memory(proc)
        for pid, cmd, rss, pss in rows:
            print(f"    {pid:>7} {rss / 1024:7.1f} MB RSS {pss / 1024:7.1f} MB PSS  {cmd}")
        return {
            "rss": sum(r[2] for r in rows) / 1024,
            "pss": sum(r[3] for r in rows) / 1024,
            "processes": len(rows),
        }


def start_server(
    tree: Path, settings: dict[str, str], work: Path, stack: ExitStack
) -> tuple[str, int]:
    """:func:`bench_cold_ab.start`, and the server's pid (the leader of its process group:
    the uvicorn process whose command line has the URL's port)."""
    url = start(tree, settings, work, stack)
    port = url.rsplit(":", 1)[1]
    for entry in Path("/proc").iterdir():
        try:
            args = (entry / "cmdline").read_bytes().split(b"\0")
        except OSError:
            continue
        if b"service.main:app" in args and port.encode() in args:
            return url, int(entry.name)
    raise RuntimeError(f"no server process for {url}")


def distributed(settle_s: float) -> int:
    """The compose roles' idle memory (see the module docstring)."""
    import subprocess

    from service.launch import answers, child_environment, free_port, stop_group

    def rows_of(proc: subprocess.Popen[bytes]) -> list[tuple[int, str, int, int]]:
        return group_memory(proc.pid)

    with ExitStack() as stack:
        work = Path(stack.enter_context(tempfile.TemporaryDirectory(prefix="pipeflow-mem-")))
        env = child_environment(PIPEFLOW_LOG_LEVEL="WARNING", PIPEFLOW_DATA_DIR=str(work))
        env.pop("DASK_CONFIG", None)

        def spawn(name: str, args: list[str], **extra: str) -> subprocess.Popen[bytes]:
            log = stack.enter_context(open(work / f"{name}.log", "ab"))
            proc = subprocess.Popen(
                args,
                cwd=ROOT,
                env={**env, **extra},
                stdout=log,
                stderr=subprocess.STDOUT,
                start_new_session=True,
            )
            stack.callback(stop_group, proc, 15, 20.0)
            return proc

        port, dashboard, http = free_port(), free_port(), free_port()
        address = f"tcp://127.0.0.1:{port}"
        roles = {
            "scheduler": spawn(
                "scheduler",
                [
                    sys.executable,
                    "-m",
                    "distributed.cli.dask_scheduler",
                    "--host",
                    "127.0.0.1",
                    "--port",
                    str(port),
                    "--dashboard-address",
                    f"127.0.0.1:{dashboard}",
                ],
            )
        }
        for i in (1, 2):
            roles[f"worker {i}"] = spawn(
                f"worker{i}",
                [
                    sys.executable,
                    "-m",
                    "distributed.cli.dask_worker",
                    address,
                    "--nthreads",
                    "1",
                    "--preload-nanny",
                    "service.engine.preload",
                    "--no-dashboard",
                ],
                OMP_NUM_THREADS="1",
                OPENBLAS_NUM_THREADS="1",
                MKL_NUM_THREADS="1",
            )
        roles["api replica"] = spawn(
            "api",
            [sys.executable, "-m", "uvicorn", "service.main:app", "--port", str(http)],
            PIPEFLOW_SCHEDULER_ADDRESS=address,
        )
        deadline = time.monotonic() + 180
        while not answers(f"http://127.0.0.1:{http}/readyz"):
            if time.monotonic() > deadline:
                raise RuntimeError((work / "api.log").read_text(errors="replace")[-3000:])
            time.sleep(0.2)
        time.sleep(settle_s)
        print("| role | processes | RSS [MB] | PSS [MB] |")
        print("|---|---:|---:|---:|")
        total_rss = total_pss = 0.0
        for name, proc in roles.items():
            rows = rows_of(proc)
            rss = sum(r[2] for r in rows) / 1024
            pss = sum(r[3] for r in rows) / 1024
            total_rss, total_pss = total_rss + rss, total_pss + pss
            detail = ", ".join(f"{r[2] / 1024:.0f}" for r in rows)
            print(f"| {name} | {len(rows)} ({detail} MB RSS) | {rss:.0f} | {pss:.0f} |")
        print(f"| all | | {total_rss:.0f} | {total_pss:.0f} |")
    return 0


def main(argv: list[str] | None = None) -> int:
    ap = sides_parser(__doc__, 3)
    ap.add_argument("--settle", type=float, default=3.0, help="idle time before measuring [s]")
    ap.add_argument(
        "--distributed", action="store_true", help="the compose roles instead (see above)"
    )
    for action in ap._actions:  # the sides are not needed with --distributed
        if action.dest == "servers":
            action.nargs = "*"
    args = ap.parse_args(argv)
    if args.distributed:
        return distributed(args.settle)
    if not args.servers:
        ap.error("give at least one NAME=TREE side (or --distributed)")
    sides = parse_sides(args.servers)
    results: dict[str, list[dict[str, float]]] = {name: [] for name, _, _ in sides}
    for r in range(args.rounds):
        order = sides[r % len(sides) :] + sides[: r % len(sides)]
        for name, tree, settings in order:
            print(f"round {r + 1}: {name} ({tree}, {settings or 'defaults'})")
            results[name].append(measure(tree, settings, args.settle))
    first = sides[0][0]
    base = {k: statistics.median(m[k] for m in results[first]) for k in ("rss", "pss")}
    print(f"\n| side | processes | RSS sum [MB] | PSS sum [MB] | RSS / {first} |")
    print("|---|---:|---:|---:|---:|")
    for name, _, _ in sides:
        rss = statistics.median(m["rss"] for m in results[name])
        pss = statistics.median(m["pss"] for m in results[name])
        n = int(statistics.median(m["processes"] for m in results[name]))
        print(f"| {name} | {n} | {rss:.0f} | {pss:.0f} | {rss / base['rss']:.2f} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
