"""Smoke test: the benchmark script imports and runs one tiny case (no timing asserted)."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import numpy as np
import pytest

from pipeflow.model import build_model
from pipeflow.paper import PAPER_PIPE
from pipeflow.profiles import Constant, polynomial


def _load():  # type: ignore[no-untyped-def]
    path = Path(__file__).resolve().parents[1] / "benchmarks" / "run.py"
    spec = importlib.util.spec_from_file_location("pipeflow_benchmarks_run", path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # dataclasses look their module up there
    spec.loader.exec_module(module)
    return module


def _script(name: str):  # type: ignore[no-untyped-def]
    """The benchmark script ``benchmarks/<name>.py`` as a module (not run)."""
    path = Path(__file__).resolve().parents[1] / "benchmarks" / f"{name}.py"
    spec = importlib.util.spec_from_file_location(f"pipeflow_{name}", path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_benchmark_runs_one_tiny_case() -> None:
    """The benchmark's reference is expm(S t) z0 for constant flow (exact) and magnus at
    dt/16 for v = 0.4 t m/s; scipy's DOP853 at rtol 1e-9, an independent integrator, must
    agree with it to 1e-8 relative state error (measured ~1e-11), and so must magnus
    (measured ~1e-13 to 1e-15): 2 modes, 0.02 s, 21 samples."""
    bench = _load()
    model = build_model(PAPER_PIPE, 2)
    s = bench.Setup(
        modes=2, t_end=0.02, samples=21, repeats=1, ivp_timeout=10.0, rtols=(1e-9,), model=model
    )
    t = np.linspace(0.0, s.t_end, s.samples)
    for flow in (Constant(0.4), polynomial(0, 0.4)):
        rows = bench.run_case(model, flow, t, s)
        names = {r["name"] for r in rows}
        assert {"pipeflow cma", "pipeflow magnus", "solve_ivp DOP853"} <= names
        magnus = next(r for r in rows if r["name"] == "pipeflow magnus")
        assert magnus["err"] < 1e-8
        dop853 = next(r for r in rows if r["name"] == "solve_ivp DOP853")
        assert dop853["err"] < 1e-8


@pytest.mark.slow  # a benchmark's smoke run, 15-55 s
def test_quick_run_prints_every_issue_9_target(capsys) -> None:  # type: ignore[no-untyped-def]
    """``run.py --quick`` (2 modes, 0.05 s) prints the targets table of issue 9 with one
    row per target and a verdict on each (numbers not asserted: timing is not a test)."""
    bench = _load()
    assert bench.main(["--quick", "--skip-service", "--skip-scaling"]) == 0
    text = capsys.readouterr().out
    table = text.split("## Issue 9, section 3")[1]
    for target in (
        "simulate() on v = 0.4 (LTI, cma) <= 3x the solver",
        "cma error check <= 25% of the cma solve (v=2+sin50t)",
        "rk4 error check",
        "time-variant cma by the batched exponential",
        "magnus >= 100x the fastest solve_ivp at 1e-8 tip error (v=2+sin50t)",
        "simulate() on the paper example",
        "peak memory at 10001 samples (LTI cma) <= 2x the output",
    ):
        row = next(line for line in table.splitlines() if target in line)
        assert row.rstrip().endswith(("met |", "**missed** |", "n/a |")), row


@pytest.mark.slow  # a benchmark's smoke run, 15-55 s
def test_service_benchmark_smoke(tmp_path: Path) -> None:
    """benchmarks/bench_service.py --smoke runs every row against a real server (wrk included)
    and writes its section; the mixed load has no errors.  No timing is asserted: the
    targets are the benchmark's business, not CI's."""
    import re
    import shutil
    import subprocess

    from tests.live import ROOT, need

    need(shutil.which("wrk") is not None, "wrk is absent (apt-get install -y wrk)")
    out = tmp_path / "RESULTS.md"
    out.write_text("# results\n\n## other section\n\nkept\n")
    proc = subprocess.run(
        [
            sys.executable,
            "benchmarks/bench_service.py",
            "--smoke",
            "--label",
            "smoke",
            "--out",
            str(out),
        ],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert proc.returncode == 0, proc.stdout + proc.stderr
    text = out.read_text()
    assert "## other section\n\nkept" in text
    section = text.split("## Service benchmark: smoke", 1)[1]
    rows = [line for line in section.splitlines() if line.startswith("| ") and "---" not in line]
    assert len(rows) == 1 + 7, rows  # header + the issue's six targets (wrk with and without gzip)
    for what in ("cold LTI", "fresh worker", "paper example", "one client", "wrk", "mixed"):
        assert any(what in r for r in rows), what
    assert re.search(r"\| 0 errors / [1-9]\d*", section), section


@pytest.mark.slow  # a benchmark's smoke run, 15-55 s
def test_fanout_benchmark_smoke(tmp_path: Path) -> None:
    """benchmarks/bench_fanout.py --smoke runs a tiny spin map job on a 1-worker and a
    2-worker server and writes its section: the 2-worker job reports pieces on 2 workers.
    No timing is asserted (the ratio is the benchmark's business)."""
    import subprocess

    from tests.live import ROOT

    out = tmp_path / "RESULTS.md"
    out.write_text("# results\n\n## other section\n\nkept\n")
    proc = subprocess.run(
        [sys.executable, "benchmarks/bench_fanout.py", "--smoke", "--label", "smoke", "--out",
         str(out)],
        cwd=ROOT, capture_output=True, text=True, timeout=600,
    )  # fmt: skip
    assert proc.returncode == 0, proc.stdout + proc.stderr
    text = out.read_text()
    assert "## other section\n\nkept" in text
    section = text.split("## Fan-out benchmark (issue 11): smoke", 1)[1]
    assert "2 workers vs 1:" in section
    row = next(line for line in section.splitlines() if "PIPEFLOW_WORKERS=2" in line)
    assert "'workers': 2" in row, row


def test_frequency_benchmark_smoke(capsys) -> None:  # type: ignore[no-untyped-def]
    """benchmarks/bench_frequency.py --smoke (about a second): the three ways agree to 1e-9
    and each target's ratio is printed with a verdict at the frequency count it is set for
    (timing is not asserted)."""
    assert _script("bench_frequency").main(["--smoke"]) == 0
    text = capsys.readouterr().out
    for row in ("frequency_response() |", "bare numpy modal sum |", "direct solves, batched |"):
        line = next(ln for ln in text.splitlines() if row in ln)
        assert float(line.rstrip(" |").rsplit("|", 1)[1]) < 1e-9, line
    for ratio in ("/ bare modal sum", "direct batched /"):
        lines = [ln for ln in text.splitlines() if ratio in ln]
        assert len(lines) == 2, lines  # 2,000 and 200 frequencies
        judged = [ln for ln in lines if ln.rstrip().endswith(("met |", "**missed** |"))]
        assert len(judged) == 1, lines
    assert any("load_vectors=2 / frequency_response()" in ln for ln in text.splitlines())


def test_forced_benchmark_smoke(capsys) -> None:  # type: ignore[no-untyped-def]
    """benchmarks/bench_forced.py --smoke (about a second): every forced run is answered
    (none refused) by the method auto picks, each with its ratio to the unforced peer."""
    assert _script("bench_forced").main(["--smoke"]) == 0
    text = capsys.readouterr().out
    assert "refused" not in text
    rows = [ln for ln in text.splitlines() if ln.startswith("| ") and "|---" not in ln]
    rows = [ln for ln in rows if not ln.startswith("| run ")]
    assert len(rows) == 9
    assert sum("| magnus |" in ln for ln in rows) == 3 and sum("| cma |" in ln for ln in rows) == 6


@pytest.mark.slow  # a benchmark's smoke run with a server of its own, ~30 s
def test_study_benchmark_smoke(tmp_path: Path) -> None:
    """benchmarks/bench_study.py --smoke (a 6 x 6 LTI grid) prints the floor, the library
    runner and the HTTP rows with their targets and writes its section; every case of the
    cold job is computed.  No timing is asserted."""
    import subprocess

    from tests.live import ROOT

    out = tmp_path / "RESULTS.md"
    out.write_text("# results\n\n## other section\n\nkept\n")
    proc = subprocess.run(
        [sys.executable, "benchmarks/bench_study.py", "--smoke", "--label", "smoke", "--out",
         str(out)],
        cwd=ROOT, capture_output=True, text=True, timeout=600,
    )  # fmt: skip
    assert proc.returncode == 0, proc.stdout + proc.stderr
    text = out.read_text()
    assert "## other section\n\nkept" in text
    section = text.split("## Study benchmark (issue 19): smoke", 1)[1]
    for row in ("batched numpy floor", "library study runner", "POST to result over HTTP"):
        assert row in section, row
    assert "'computed': 36" in section and "'failed': 0" in section


@pytest.mark.slow  # a benchmark's smoke run, ~5-15 s
def test_time_variant_study_benchmark_smoke(tmp_path: Path) -> None:
    """benchmarks/bench_study.py --time-variant --smoke (a 3 x 3 grid, 3 modes) prints the
    floor, the stacked and the per-case runner with the target, finds every row of the two
    runners identical, and writes its section first in the file.  No timing is asserted."""
    import subprocess

    from tests.live import ROOT

    out = tmp_path / "RESULTS.md"
    out.write_text("# results\n\n## other section\n\nkept\n")
    proc = subprocess.run(
        [sys.executable, "benchmarks/bench_study.py", "--time-variant", "--smoke", "--label",
         "smoke", "--out", str(out)],
        cwd=ROOT, capture_output=True, text=True, timeout=600,
    )  # fmt: skip
    assert proc.returncode == 0, proc.stdout + proc.stderr
    text = out.read_text()
    title = "## Study benchmark, time-variant (issue 19): smoke"
    assert text.startswith(f"# results\n\n{title}\n") and "## other section\n\nkept" in text
    for row in ("batched Magnus-4 floor", "stacked magnus (after)", "per case (before"):
        assert row in text, row
    assert "identical (every summary column, == on floats): 9 of 9" in text


@pytest.mark.slow
def test_bench_http_smoke() -> None:
    """benchmarks/bench_http.py --smoke (two real servers, a few rounds): every row answers
    as it should (200s, 304s; the script asserts each status) and the ratios are printed."""
    import subprocess

    root = Path(__file__).resolve().parents[1]
    done = subprocess.run(
        [sys.executable, "benchmarks/bench_http.py", "--smoke"],
        cwd=root,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
    assert "CSV written again / kept:" in done.stdout and "hit with key / without:" in done.stdout


@pytest.mark.slow  # a benchmark's smoke run, 3-10 s
def test_checkpoint_benchmark_smoke(capsys) -> None:  # type: ignore[no-untyped-def]
    """benchmarks/bench_checkpoint.py --smoke prints its two tables (it asserts itself that
    the resumed states equal the whole run's); no timing is asserted."""
    assert _script("bench_checkpoint").main(["--smoke"]) == 0
    out = capsys.readouterr().out
    for row in ("| plain |", "| idle |", "| memory |", "| sqlite |", "| from zero |"):
        assert row in out, row


@pytest.mark.slow
def test_bench_cold_paper_smoke() -> None:
    """benchmarks/bench_cold_paper.py --rounds 2 (two real servers): the rows are printed,
    and the servers' logs show each side where it claims to be: on the ``lane`` server the
    paper example and the LTI case in the API process, the tolerance-1e-10 case handed off and
    computed on its worker; on the ``worker`` server (``fast_lane_max_metered_s=0``) both
    time-variant cases on its worker (its LTI warm-up in its lane)."""
    import ast
    import subprocess

    root = Path(__file__).resolve().parents[1]
    done = subprocess.run(
        [sys.executable, "benchmarks/bench_cold_paper.py", "--rounds", "2"],
        cwd=root,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
    for row in ("paper example, fast lane (metered)", "paper example, Dask worker", "LTI"):
        assert f"| {row}" in done.stdout, done.stdout
    assert "paper example at tolerance 1e-10 (handed off by the lane server)" in done.stdout
    counts = {
        line.split(":")[0]: ast.literal_eval(line.split("lane/outcome ", 1)[1])
        for line in done.stdout.splitlines()
        if line.startswith("server ")
    }
    # (2 warm-up + 2 rounds) x (paper + LTI) in the lane; (1 + 2) x tolerance 1e-10 handed off
    lane = {"api/ok": 8, "api/handoff": 3, "worker/ok": 3}
    assert counts["server lane"] == lane, counts
    assert counts["server worker"] == {"worker/ok": 4 + 3, "api/ok": 2}, counts


def test_default_path_parts_smoke(capsys) -> None:  # type: ignore[no-untyped-def]
    """``bench_default_path.py --parts`` records the paper example's exponential stacks and
    eigenvalue stacks from a real run (3,000 exponentials of 20 x 20, two stacks of 201)
    and prints one row per part; and the recording leaves numpy and the solver unpatched.
    No time is asserted."""
    import numpy as np

    import pipeflow.solvers.magnus.generator as magnus

    expm, eigvals = magnus.expm_stack, np.linalg.eigvals
    _script("bench_default_path").parts(1)
    out = capsys.readouterr().out
    assert "3000 exponentials" in out and "eigenvalue stacks [201, 201]" in out
    for part in ("document", "exponentials", "their products alone", "eigenvalues", "rest"):
        assert f"| {part}" in out
    assert magnus.expm_stack is expm and np.linalg.eigvals is eigvals
