"""What checkpoints cost a long solve, and what a resume saves (issue 22, defect 8).

One process, interleaved rounds (the machine is shared: each round runs every variant
once, in turn, and the table reports medians of wall and CPU time and their ratios to the
plain run of the same round):

- ``plain``: ``simulate()`` with no checkpoints installed (main's path);
- ``idle``: checkpoints installed, interval 1 h (never due): the seam's own cost, which is
  what every run shorter than ``PIPEFLOW_CHECKPOINT_INTERVAL_S`` pays;
- ``memory``: a checkpoint after *every* window of 256 output intervals, into memory (the
  worst case of the library's side: the blob is built every window);
- ``sqlite``: the same into the service's store (a real SQLite file, the job's lease held,
  :class:`service.store.checkpoints.StoreCheckpoints`): the library's and the store's cost.

Then a resume from a checkpoint taken half-way (by exponentials) against the run from
zero, the blob's size, and why the blob is not compressed (zlib level 1 on it).

    OMP_NUM_THREADS=1 python benchmarks/bench_checkpoint.py            # ~40 s
    python benchmarks/bench_checkpoint.py --smoke                      # seconds

The service's default interval is 5 s, so a long run writes one checkpoint per 5 s: its
overhead is the ``sqlite`` row's cost per checkpoint divided by 5 s.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
import time
import zlib
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from pipeflow.paper import PAPER_PIPE
from pipeflow.profiles import Constant, Harmonic
from pipeflow.simulation import Simulation, simulate
from pipeflow.solvers import Options
from pipeflow.solvers.checkpoint import checkpointing, decode


class Memory:
    """Checkpoints kept in memory; ``stop_after`` saves, then the solve is interrupted."""

    def __init__(self, interval_s: float, stop_after: int | None = None) -> None:
        self.interval_s = interval_s
        self.max_bytes = 1 << 40
        self.blob: bytes | None = None
        self.saves = 0
        self.stop_after = stop_after
        self.keep: list[bytes] | None = None  # every blob written (None: not kept)

    def load(self) -> bytes | None:
        return self.blob

    def save(self, data: bytes) -> None:
        self.blob = data
        self.saves += 1
        if self.keep is not None:
            self.keep.append(data)
        if self.stop_after is not None and self.saves >= self.stop_after:
            raise _Stop


class _Stop(Exception):
    pass


def carried_by(blob: bytes) -> int:
    """Exponentials a resume from ``blob`` carries over (magnus's header)."""
    snap = decode(blob)
    assert snap is not None
    head = snap.header
    return int(sum(head["exponentials"]) + head["partial"]["exponentials"])


def case(smoke: bool) -> Simulation:
    """Pulsating flow v = 2 + sin 50 t m/s, w0 = 100 rad/s, magnus at 1e-8 (its default)."""
    modes, samples = (4, 501) if smoke else (10, 2001)
    return Simulation(
        PAPER_PIPE,
        flow=Harmonic(2.0, 1.0, 50.0),
        spin=Constant(100.0),
        modes=modes,
        t_end=1.0,
        samples=samples,
        method="magnus",
        options=Options(tolerance=1e-8),
    )


def timed(fn: Any) -> tuple[float, float, Any]:
    w0, c0 = time.perf_counter(), time.process_time()
    out = fn()
    return time.perf_counter() - w0, time.process_time() - c0, out


def store_checkpoints(tmp: Path, n: int) -> Any:
    """A real store with a job leased to an attempt, and that attempt's checkpoints."""
    from service.store import Store
    from service.store.checkpoints import StoreCheckpoints

    store = Store(tmp / f"db{n}.sqlite3", cache_max_bytes=1 << 30, memory_cache_bytes=0)
    key = f"{n:064x}"
    store.enqueue_job(key, "simulation", {})
    store.claim(key, "attempt", "bench", 60.0)
    return StoreCheckpoints(store, key, 1, "attempt", interval_s=0.0, max_bytes=1 << 30)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--rounds", type=int, default=7)
    ap.add_argument("--smoke", action="store_true", help="a tiny case, 2 rounds")
    args = ap.parse_args(argv)
    rounds = 2 if args.smoke else args.rounds
    sim = case(args.smoke)
    simulate(sim)  # warm-up (imports, caches)
    rows: dict[str, list[tuple[float, float]]] = {
        k: [] for k in ("plain", "idle", "memory", "sqlite")
    }
    saves: dict[str, int] = {}
    with tempfile.TemporaryDirectory() as d:
        tmp = Path(d)
        for r in range(rounds):
            for name in rows:
                cp: Any = None
                if name == "idle":
                    cp = Memory(3600.0)
                elif name == "memory":
                    cp = Memory(0.0)
                elif name == "sqlite":
                    cp = store_checkpoints(tmp, r)
                with checkpointing(cp):
                    wall, cpu, _ = timed(lambda: simulate(sim))
                rows[name].append((wall, cpu))
                if cp is not None:
                    saves[name] = getattr(cp, "saves", getattr(cp, "saved", 0))
                if name == "sqlite":
                    cp.store.close()

        # a resume from the checkpoint nearest half the exponentials, against from zero
        full = Memory(0.0)
        full.keep = []
        with checkpointing(full):
            whole = simulate(sim)
        total = whole.diagnostics["matrix_exponentials"]
        blob = min(full.keep, key=lambda b: abs(carried_by(b) - total / 2))
        zero_w, zero_c, _ = timed(lambda: simulate(sim))
        resume = Memory(3600.0)
        resume.blob = blob
        with checkpointing(resume):
            res_w, res_c, resumed = timed(lambda: simulate(sim))
        assert (resumed.d == whole.d).all(), "resumed states differ from the whole run"
        z0 = time.perf_counter()
        packed = zlib.compress(blob, 1)
        z_ms = (time.perf_counter() - z0) * 1e3

    med = {
        k: (statistics.median(w for w, _ in v), statistics.median(c for _, c in v))
        for k, v in rows.items()
    }
    base_w, base_c = med["plain"]
    diag = whole.diagnostics
    print(
        f"## checkpoints of a long solve ({time.strftime('%d %b %Y, %H:%M UTC', time.gmtime())})\n"
    )
    print(
        f"Case: {sim.modes} modes, {sim.samples} samples, v = 2 + sin 50 t, magnus at 1e-8: "
        f"{diag['steps']} steps, {diag['attempts']} attempts, {diag['matrix_exponentials']} "
        f"exponentials; {rounds} interleaved rounds, medians.\n"
    )
    print("| variant | wall [s] | CPU [s] | wall / plain | CPU / plain | checkpoints written |")
    print("|---|---|---|---|---|---|")
    for name, (w, c) in med.items():
        print(
            f"| {name} | {w:.3f} | {c:.3f} | {w / base_w:.3f} | {c / base_c:.3f} | "
            f"{saves.get(name, 0)} |"
        )
    per_save = (med["sqlite"][0] - base_w) / max(saves.get("sqlite", 1), 1)
    print(
        f"\nPer checkpoint (sqlite, wall): {per_save * 1e3:.1f} ms, i.e. "
        f"{per_save / 5.0 * 100:.2f} % of a run at the default interval of 5 s.\n"
    )
    carried = resumed.diagnostics["resumed_exponentials"]
    print("| resume | wall [s] | CPU [s] | CPU of the run from zero | exponentials carried |")
    print("|---|---|---|---|---|")
    print(f"| from zero | {zero_w:.3f} | {zero_c:.3f} | 1.000 | 0 |")
    print(
        f"| from the checkpoint nearest half-way | {res_w:.3f} | {res_c:.3f} | "
        f"{res_c / zero_c:.3f} | {carried} of {diag['matrix_exponentials']} |"
    )
    print(
        f"\nBlob: {len(blob) / 1e6:.2f} MB half-way; zlib level 1: {len(packed) / len(blob):.2f} "
        f"of it in {z_ms:.0f} ms ({z_ms / (len(blob) / 1e6):.0f} ms per MB)."
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
