"""The pipeflow command line: example, run (JSON/CSV), plot, errors naming fields, help."""

from __future__ import annotations

import io
import json
import shutil
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest

from pipeflow.schema.simulation import PAPER_EXAMPLE, SimulationSpec
from pipeflow_cli.cli import ProgressBar, main


@pytest.fixture
def small_spec(tmp_path: Path) -> Path:
    spec = json.loads(json.dumps(PAPER_EXAMPLE))
    spec.update(modes=4, time={"t_end": 0.1, "samples": 41})
    spec["output"] = {"eigen_modes": 2, "eigen_samples": 11}
    path = tmp_path / "spec.json"
    path.write_text(json.dumps(spec))
    return path


def test_example_is_the_papers_spec(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["example"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert data == PAPER_EXAMPLE
    SimulationSpec.model_validate(data)


def test_run_json_then_csv_then_plot(
    small_spec: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "result.json"
    assert main(["run", str(small_spec), "-o", str(out), "--quiet"]) == 0
    result = json.loads(out.read_text())
    assert result["status"] == "ok" and len(result["t"]) == 41
    assert result["initial_tip_displacement"] == pytest.approx(2.7242e-3, rel=1e-3)

    assert main(["run", str(out), "--format", "csv", "--table", "eigenvalues"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[0].startswith("t [s],sigma_1 [1/s],omega_1 [rad/s]")
    assert len(lines) == 12

    pq = pytest.importorskip("pyarrow.parquet")  # the parquet extra, in dev: CI runs it
    parquet = tmp_path / "history.parquet"
    assert main(["run", str(out), "--format", "parquet", "-o", str(parquet)]) == 0
    table = pq.read_table(parquet)
    assert table.column("tip_displacement").to_pylist() == result["tip_displacement"]
    assert table.schema.field("t").metadata[b"unit"] == b"s"

    png = tmp_path / "tip.png"
    assert main(["plot", str(out), "--name", "tip_displacement", "--out", str(png)]) == 0
    assert png.read_bytes().startswith(b"\x89PNG")
    svg = tmp_path / "f.svg"
    # a spec is run first, then plotted
    assert main(["plot", str(small_spec), "--name", "frequency", "--out", str(svg), "--quiet"]) == 0
    assert b"frequency" in svg.read_bytes()


def test_invalid_spec_names_the_field(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    spec = json.loads(json.dumps(PAPER_EXAMPLE))
    spec["pipe"]["L"] = -1.0
    path = tmp_path / "bad.json"
    path.write_text(json.dumps(spec))
    assert main(["run", str(path)]) == 2
    err = capsys.readouterr().err
    assert "pipe.L" in err and "greater than 0" in err


def test_invalid_spec_messages_are_readable(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Issue 34, item 8: an unknown field gets a "did you mean", "3000 rpm" as text the
    {"value", "unit"} form."""
    spec = json.loads(json.dumps(PAPER_EXAMPLE))
    spec["rotation"]["omega0"]["value"] = "3000 rpm"
    spec["modse"] = spec.pop("modes")
    path = tmp_path / "bad.json"
    path.write_text(json.dumps(spec))
    assert main(["run", str(path)]) == 2
    err = capsys.readouterr().err
    assert "error: modse: Extra inputs are not permitted; did you mean 'modes'?" in err
    assert '{"value": 3000, "unit": "rpm"}' in err


def test_a_spin_meant_in_rpm_is_warned_about_on_stderr(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Issue 34, item 8: the plausibility warning of the result, with the rpm form."""
    spec = json.loads(json.dumps(PAPER_EXAMPLE))
    spec.update(modes=3, time={"t_end": 0.01, "samples": 11})
    spec["rotation"]["omega0"]["value"] = 3000.0
    path = tmp_path / "spin.json"
    path.write_text(json.dumps(spec))
    assert main(["run", str(path), "-o", str(tmp_path / "r.json"), "--quiet"]) == 0
    err = capsys.readouterr().err
    assert "warning: rotation.omega0 = 3000 rad/s is 10.3x the pipe's first bending" in err
    assert '{"value": 3000, "unit": "rpm"} (314 rad/s)' in err


def test_bad_json_and_bad_plot_output(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "x.json"
    path.write_text("{not json")
    assert main(["run", str(path)]) == 2
    assert "not valid JSON" in capsys.readouterr().err
    assert main(["plot", str(path), "--out", "x.gif"]) == 2
    assert "--out" in capsys.readouterr().err


def test_progress_bar_only_on_tty_or_forced() -> None:
    quiet = io.StringIO()
    bar = ProgressBar("x", stream=quiet)  # StringIO is not a terminal
    bar(0.5)
    bar.close()
    assert quiet.getvalue() == ""
    forced = io.StringIO()
    bar = ProgressBar("simulating", stream=forced, enabled=True)
    bar(0.25)
    bar(1.0)
    bar.close()
    text = forced.getvalue()
    assert "simulating [" in text and "100.0%" in text and text.endswith("\n")


def test_console_script_help_shows_the_papers_example() -> None:
    exe = shutil.which("pipeflow")
    if exe is None:
        pytest.fail("the pipeflow console script is not installed (pip install -e .)")
    out = subprocess.run([exe, "run", "--help"], capture_output=True, text=True, check=True)
    assert "v = 0.4 t m/s, w0 = 100 rad/s" in out.stdout
    assert "--format {json,csv,parquet,uff,netcdf,mat}" in out.stdout


PIPE = PAPER_EXAMPLE["pipe"]


def test_stability_critical_velocity_and_sweep_plot(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    spec = tmp_path / "stab.json"
    spec.write_text(json.dumps({"pipe": PIPE, "modes": 4, "velocity_range": [0, 60], "points": 41}))
    out = tmp_path / "stab_result.json"
    assert main(["stability", str(spec), "-o", str(out), "--quiet"]) == 0
    result = json.loads(out.read_text())
    assert result["kind"] == "stability" and result["critical_velocity"] > 0
    assert "critical flow velocity:" in capsys.readouterr().err

    # spinning at 1000 rad/s the pipe diverges at rest: no critical velocity, where it is
    # stable instead (not the API's critical_velocity, the loss after the regain)
    fast = {"pipe": PIPE, "modes": 10, "velocity_range": [0, 60]}
    spec.write_text(json.dumps(fast | {"rotation": {"omega0": {"value": 1000.0}}}))
    assert main(["stability", str(spec), "-o", str(out), "--quiet"]) == 0
    result = json.loads(out.read_text())
    [(a, b)] = result["stable_intervals"]
    assert result["critical_velocity"] == b and result["stable_at_start"] is False
    assert (
        f"critical flow velocity: none: already unstable at v = 0 m/s (divergence); stable "
        f"on [{a:.5g}, {b:.5g}] m/s"
    ) in capsys.readouterr().err

    sweep = tmp_path / "argand.json"
    sweep.write_text(
        json.dumps({"kind": "argand", "pipe": PIPE, "modes": 4, "velocity_range": [0, 40]})
    )
    out = tmp_path / "argand_result.json"
    assert main(["stability", str(sweep), "-o", str(out), "--quiet"]) == 0
    png = tmp_path / "argand.png"
    assert main(["plot", str(out), "--out", str(png)]) == 0  # default: the first plot it has
    assert png.read_bytes().startswith(b"\x89PNG")
    assert main(["plot", str(out), "--name", "damping", "--out", str(png)]) == 2
    assert "has no 'damping' plot" in capsys.readouterr().err


def test_stability_refuses_a_simulation_spec(
    small_spec: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["stability", str(small_spec)]) == 2
    assert "not a valid 'stability' request" in capsys.readouterr().err
    assert main(["stability", str(small_spec), "--kind", "simulation"]) == 2
    err = capsys.readouterr().err
    assert "unknown kind 'simulation'; choose one of: stability, argand, campbell" in err


def test_a_wrong_kind_names_the_allowed_ones(
    tmp_path: Path, small_spec: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["run", str(small_spec), "--kind", "nope"]) == 2
    err = capsys.readouterr().err
    assert "unknown kind 'nope'; choose one of: simulation, compare, stability, argand" in err
    tagged = tmp_path / "bogus.json"
    tagged.write_text(json.dumps({"kind": "bogus", "pipe": PIPE}))
    assert main(["run", str(tagged)]) == 2
    assert "the spec's kind 'bogus' names no computation" in capsys.readouterr().err
    sweep = tmp_path / "argand.json"
    sweep.write_text(json.dumps({"kind": "argand", "pipe": PIPE}))
    assert main(["stability", str(sweep), "--kind", "campbell"]) == 2
    assert "--kind campbell but the spec's kind is 'argand'" in capsys.readouterr().err


def test_kind_selects_the_computation_of_a_spec_without_one(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    spec = tmp_path / "argand.json"
    spec.write_text(json.dumps({"pipe": PIPE, "modes": 4, "velocity_range": [0, 40], "points": 11}))
    out = tmp_path / "out.json"
    assert main(["run", str(spec), "--kind", "argand", "-o", str(out), "--quiet"]) == 0
    assert json.loads(out.read_text())["kind"] == "argand"


def test_serve_runs_python_m_service_with_the_same_flags(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    """``pipeflow serve`` imports no service module: it runs ``python -m service`` with its
    flags in a child process and returns the child's exit status."""
    calls: list[list[str]] = []

    class Child:
        def __init__(self, argv: list[str]) -> None:
            calls.append(argv)

        def wait(self) -> int:
            return 2

    monkeypatch.setattr(subprocess, "Popen", Child)
    before = {m for m in sys.modules if m == "service" or m.startswith("service.")}
    argv = ["serve", "--port", "8123", "--workers", "3", "--data-dir", str(tmp_path)]
    assert main(argv) == 2
    head = [sys.executable, "-m", "service", "--host", "127.0.0.1"]
    assert calls == [[*head, "--port", "8123", "--workers", "3", "--data-dir", str(tmp_path)]]
    calls.clear()
    assert main(["serve"]) == 2
    assert calls == [[*head, "--port", "8000"]]
    assert {m for m in sys.modules if m == "service" or m.startswith("service.")} == before


def test_python_m_service_runs_one_server_process_with_n_compute_workers(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """--workers is the compute pool (PIPEFLOW_WORKERS), never uvicorn's server processes:
    N servers on one data directory is what the store forbids."""
    import uvicorn

    from service.__main__ import main as service_main

    calls: list[tuple[Any, dict[str, Any]]] = []
    monkeypatch.setattr(uvicorn, "run", lambda app, **kw: calls.append((app, kw)))
    monkeypatch.setenv("PIPEFLOW_WORKERS", "2")
    monkeypatch.setenv("PIPEFLOW_QUEUE_SIZE", "7")
    monkeypatch.setenv("PIPEFLOW_DATA_DIR", str(tmp_path / "env"))
    argv = ["--port", "8123", "--workers", "3", "--data-dir", str(tmp_path)]
    assert service_main(argv) == 0
    ((app, kw),) = calls
    # no "workers": one server process; uvicorn's protocol with the request deadline
    http = kw.pop("http")
    assert kw == {"host": "127.0.0.1", "port": 8123}
    assert http.__module__ == "service.http.deadline", http
    settings = app.state.settings
    assert (settings.workers, settings.data_dir, settings.queue_size) == (3, tmp_path, 7)
    assert f"data in {tmp_path}, 3 worker(s)" in capsys.readouterr().err

    # without the flags the environment decides, as for uvicorn service.main:app
    calls.clear()
    assert service_main([]) == 0
    settings = calls[0][0].state.settings
    assert (settings.workers, settings.data_dir) == (2, tmp_path / "env")

    assert service_main(["--workers", "0"]) == 2
    assert "workers: Input should be greater than or equal to 1" in capsys.readouterr().err


def test_study_runs_a_sampled_study_and_prints_its_statistics(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    spec = {
        "base": {
            "kind": "simulation",
            "spec": {
                "pipe": PAPER_EXAMPLE["pipe"],
                "modes": 2,
                "time": {"t_end": 0.01, "samples": 3},
                "output": {"eigen_samples": 3},
            },
        },
        "samples": {
            "count": 2,
            "method": "saltelli",
            "parameters": {
                "pipe.E": {"distribution": "lognormal", "median": 7.8e9, "sigma": 0.1},
                "pipe.M2": {"distribution": "uniform", "low": 1e-5, "high": 2e-5},
            },
        },
    }
    path = tmp_path / "study.json"
    path.write_text(json.dumps(spec))
    out = tmp_path / "result.json"
    assert main(["study", str(path), "-o", str(out), "--quiet"]) == 0
    doc = json.loads(out.read_text())
    err = capsys.readouterr().err
    assert doc["kind"] == "study" and doc["counts"]["total"] == 12
    assert "12 cases: 12 ok, 0 failed" in err
    mean = doc["statistics"]["columns"]["final_omega_1"]["mean"]
    assert f"final_omega_1 [rad/s]: mean {mean:.6g}" in err
    assert "P(unstable) = 0 +- 0 (0 of 12" in err
    assert "Sobol final_omega_1 / pipe.E: S1 " in err
    assert main(["study", str(path), "--format", "csv", "-o", str(tmp_path / "t.csv")]) == 0
    header = (tmp_path / "t.csv").read_text().splitlines()[0]
    assert header.startswith("index [-],key,status,cached,pipe.E [Pa],pipe.M2 [kg/m]")


def test_server_without_the_client_extra_says_what_to_install(
    small_spec: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """After the README's first command alone (the service extra, no httpx), `--server`
    names the extra to install instead of a bare "No module named 'httpx'"."""
    monkeypatch.setitem(sys.modules, "httpx", None)  # import httpx now fails
    for name in [m for m in sys.modules if m.split(".")[0] == "pipeflow_client"]:
        monkeypatch.delitem(sys.modules, name)
    assert main(["run", str(small_spec), "--server", "http://127.0.0.1:9"]) == 2
    err = capsys.readouterr().err
    assert "pip install 'pipeflow[client]'" in err and "httpx" in err, err


def test_run_a_hammer_blow_and_a_half_sine_pulse(tmp_path: Path) -> None:
    """The CLI runs the issue 32 load kinds (an impulse, a half-sine pulse, a table held past
    its end), and the result echoes them as they were asked."""
    spec = json.loads(json.dumps(PAPER_EXAMPLE))
    spec.update(
        modes=4,
        time={"t_end": 0.02, "samples": 41},
        flow={"velocity": {"kind": "constant", "value": 0.0}},
        initial={"u0": 0.0},
    )
    spec["output"] = {"eigen_modes": 2, "eigen_samples": 11}
    spec["loads"] = [
        {"kind": "impulse", "position": 0.025, "impulse": 1e-9, "time": 0.005},
        {
            "kind": "point_force",
            "position": 0.02,
            "force": {"kind": "half_sine", "peak": 1e-7, "start": 0.01, "duration": 1e-3},
        },
        {
            "kind": "point_force",
            "position": 0.02,
            "force": {"kind": "table", "t": [0, 0.001], "values": [0, 1e-8], "after": "hold"},
        },
    ]
    path, out = tmp_path / "spec.json", tmp_path / "out.json"
    path.write_text(json.dumps(spec))
    assert main(["run", str(path), "-o", str(out), "--quiet"]) == 0
    result = json.loads(out.read_text())
    assert result["status"] == "ok"
    assert result["loads"][0] == spec["loads"][0]
    assert result["loads"][2]["force"]["after"] == "hold"


def test_stability_of_a_supported_pipe(tmp_path: Path) -> None:
    """A pinned-pinned spool from a spec file (issue 31): divergence at u = pi, named."""
    spec = tmp_path / "spool.json"
    spec.write_text(
        json.dumps(
            {
                "pipe": {"E": 1.0, "I": 1.0, "L": 1.0, "M1": 0.5, "M2": 0.5,
                         "supports": {"x0": "pinned", "xL": "pinned"}},
                "modes": 8,
                "velocity_range": [0.0, 6.0],
                "points": 61,
            }
        )
    )  # fmt: skip
    out = tmp_path / "out.json"
    assert main(["stability", str(spec), "-o", str(out), "--quiet"]) == 0
    result = json.loads(out.read_text())
    assert result["mechanism"] == "divergence"
    assert result["critical_velocity"] == pytest.approx(3.141592653589793 / 0.5**0.5, rel=1e-9)


def test_plot_of_a_spec_draws_its_supports(tmp_path: Path) -> None:
    """`pipeflow plot SPEC` draws the spec's supports on the mode shapes (issue 31)."""
    spec = json.loads(json.dumps(PAPER_EXAMPLE))
    spec.update(modes=4, time={"t_end": 0.05, "samples": 11})
    spec["pipe"]["supports"] = {"x0": "pinned", "xL": "pinned"}
    spec["pipe"]["intermediate_supports"] = [
        {"position": spec["pipe"]["L"] / 2, "translational": 1e3}
    ]
    spec["output"] = {"eigen_modes": 2, "eigen_samples": 3, "mode_shapes": {"times": [0.0]}}
    path = tmp_path / "pp.json"
    path.write_text(json.dumps(spec))
    svg = tmp_path / "shapes.svg"
    argv = ["plot", str(path), "--name", "mode_shapes", "--out", str(svg), "--quiet"]
    assert main(argv) == 0
    text = svg.read_text()
    for gid in ("support:x0:pinned", "support:xL:pinned", "support:point0:elastic"):
        assert f'id="{gid}"' in text
