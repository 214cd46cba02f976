"""A client generated from the committed ``openapi/openapi.json`` by openapi-python-client
works against a live server, the plot endpoint and the PDF report included.

The client is generated into a temporary directory with the committed configuration
``openapi/openapi-python-client.yml`` (package ``pipeflow_api_client``: no clash with
``pipeflow`` or ``pipeflow_client``; image/png, image/svg+xml and application/pdf read as
bytes), imported from there, and used against uvicorn in a subprocess for one simulation,
one plot in each image format, the report in each format and a job of every job-only
computation.  The numbers it returns are checked against the library run in-process
(identical code path, so equal to rounding of the JSON: relative 1e-12).  A client
generated from the document alone, without the configuration (as an integrator may), gets
the same package name from the document's title and never reads the PDF as text.
"""

from __future__ import annotations

import importlib
import io
import shutil
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import httpx
import numpy as np
import pytest
import yaml

from pipeflow.computations.registry import COMPUTATIONS
from pipeflow.schema.simulation import SimulationSpec
from pipeflow.simulation import simulate
from tests.live import ROOT, need
from tests.service.conftest import SMALL

PACKAGE = "pipeflow_api_client"
CONFIG = ROOT / "openapi" / "openapi-python-client.yml"


def _generate(cwd: Path, *options: str) -> str:
    """Run openapi-python-client on the committed document in ``cwd``; its output."""
    need(
        shutil.which("openapi-python-client") is not None,
        "openapi-python-client is not installed (pip install -e '.[dev]')",
    )
    done = subprocess.run(
        [
            "openapi-python-client",
            "generate",
            "--path",
            str(ROOT / "openapi" / "openapi.json"),
            "--meta",
            "none",
            *options,
        ],
        cwd=cwd,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert done.returncode == 0, done.stdout + done.stderr
    return done.stdout + done.stderr


@pytest.fixture(scope="module")
def generated(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Any]:
    """The generated package, imported from a temporary directory."""
    where = tmp_path_factory.mktemp("generated")
    output = _generate(where, "--config", str(CONFIG), "--output-path", str(where / PACKAGE))
    # a warning means an operation or response was left out of the generated client
    assert "Warning" not in output, output
    sys.path.insert(0, str(where))
    try:
        yield importlib.import_module(PACKAGE)
    finally:
        sys.path.remove(str(where))
        for name in [m for m in sys.modules if m == PACKAGE or m.startswith(PACKAGE + ".")]:
            del sys.modules[name]


def test_simulation_and_plots_through_the_generated_client(generated: Any, server: str) -> None:
    run_simulation = importlib.import_module(f"{PACKAGE}.api.simulations.run_simulation")
    get_result_plot = importlib.import_module(f"{PACKAGE}.api.results.get_result_plot")
    models = importlib.import_module(f"{PACKAGE}.models")
    types = importlib.import_module(f"{PACKAGE}.types")

    with generated.Client(base_url=server, raise_on_unexpected_status=True, timeout=60) as c:
        r = run_simulation.sync_detailed(client=c, body=models.SimulationSpec.from_dict(SMALL))
        assert r.status_code == 200, r.content
        result = r.parsed
        assert isinstance(result, models.SimulationResponse)
        expected = simulate(SimulationSpec.model_validate(SMALL).to_simulation())
        tip = np.array(result.tip_displacement)
        np.testing.assert_allclose(tip, expected.tip_displacement, rtol=1e-12, atol=0)
        key = result.key

        png = get_result_plot.sync_detailed(
            key, "tip_displacement", models.GetResultPlotFmt.PNG, client=c
        )
        assert png.status_code == 200
        assert png.headers["content-type"] == "image/png"
        assert isinstance(png.parsed, types.File)
        assert png.parsed.payload.read().startswith(b"\x89PNG\r\n\x1a\n")

        svg = get_result_plot.sync_detailed(key, "frequency", models.GetResultPlotFmt.SVG, client=c)
        assert svg.status_code == 200
        assert isinstance(svg.parsed, types.File)
        assert b"<svg" in svg.parsed.payload.read()

        # an unknown plot is the documented 404 problem, parsed as such
        missing = get_result_plot.sync_detailed(key, "nope", models.GetResultPlotFmt.PNG, client=c)
        assert missing.status_code == 404
        assert isinstance(missing.parsed, models.Problem)


def test_tables_and_typed_diagnostics_through_the_generated_client(
    generated: Any, server: str
) -> None:
    """CSV and Parquet come from their own operation (getResultTable), which declares both
    media types: the generated client returns their bytes (it used to parse a CSV answer
    of getResult as JSON and crash); the result's diagnostics are a typed model."""
    run_simulation = importlib.import_module(f"{PACKAGE}.api.simulations.run_simulation")
    get_result = importlib.import_module(f"{PACKAGE}.api.results.get_result")
    get_result_table = importlib.import_module(f"{PACKAGE}.api.results.get_result_table")
    models = importlib.import_module(f"{PACKAGE}.models")
    types = importlib.import_module(f"{PACKAGE}.types")

    with generated.Client(base_url=server, raise_on_unexpected_status=True, timeout=60) as c:
        body = models.SimulationSpec.from_dict({**SMALL, "initial": {"u0": 0.0017}})
        run = run_simulation.sync_detailed(client=c, body=body)
        assert run.status_code == 200, run.content
        key = run.parsed.key
        diagnostics = run.parsed.diagnostics
        assert isinstance(diagnostics, models.SimulationDiagnostics)
        assert diagnostics.modes == SMALL["modes"] and diagnostics.samples == 101
        assert diagnostics.method_used in ("cma", "magnus")

        stored = get_result.sync_detailed(key, client=c)
        assert stored.status_code == 200
        assert isinstance(stored.parsed, models.SimulationResponse)

        history = models.GetResultTableTable("history")
        csv = get_result_table.sync_detailed(key, history, models.GetResultTableFmt.CSV, client=c)
        assert csv.status_code == 200 and csv.headers["content-type"].startswith("text/csv")
        assert isinstance(csv.parsed, types.File)
        lines = csv.parsed.payload.read().decode().splitlines()
        assert lines[0].startswith("t [s],tip_displacement [m]") and len(lines) == 1 + 101
        tip = np.array([float(line.split(",")[1]) for line in lines[1:]])
        # the CSV's numbers are the JSON result's (both written from one stored result)
        np.testing.assert_allclose(tip, run.parsed.tip_displacement, rtol=1e-12, atol=0)

        parquet = get_result_table.sync_detailed(
            key, history, models.GetResultTableFmt.PARQUET, client=c
        )
        assert parquet.status_code == 200
        assert isinstance(parquet.parsed, types.File)
        assert parquet.parsed.payload.read()[:4] == b"PAR1"

        unknown = get_result_table.sync_detailed(
            "0" * 64, history, models.GetResultTableFmt.CSV, client=c
        )
        assert unknown.status_code == 404 and isinstance(unknown.parsed, models.Problem)


def test_reports_through_the_generated_client(generated: Any, server: str) -> None:
    """One operation per media type: the PDF report comes back as bytes (a File) that
    parse as a PDF, the HTML report as text.  (When one operation declared both, the
    generated client read the PDF as text, and saving it wrote a corrupt file.)"""
    pypdf = pytest.importorskip("pypdf")
    run_simulation = importlib.import_module(f"{PACKAGE}.api.simulations.run_simulation")
    report_pdf = importlib.import_module(f"{PACKAGE}.api.results.get_result_report_pdf")
    report_html = importlib.import_module(f"{PACKAGE}.api.results.get_result_report_html")
    models = importlib.import_module(f"{PACKAGE}.models")
    types = importlib.import_module(f"{PACKAGE}.types")

    with generated.Client(base_url=server, raise_on_unexpected_status=True, timeout=120) as c:
        body = models.SimulationSpec.from_dict({**SMALL, "initial": {"u0": 0.0011}})
        run = run_simulation.sync_detailed(client=c, body=body)
        assert run.status_code == 200, run.content
        key = run.parsed.key

        pdf = report_pdf.sync_detailed(key, client=c)
        assert pdf.status_code == 200 and pdf.headers["content-type"] == "application/pdf"
        assert isinstance(pdf.parsed, types.File)
        data = pdf.parsed.payload.read()
        assert data == pdf.content  # the bytes as sent, not text decoded and re-encoded
        reader = pypdf.PdfReader(io.BytesIO(data))
        assert len(reader.pages) >= 2  # the text page, then the figures
        assert key[:12] in reader.pages[0].extract_text()

        html = report_html.sync_detailed(key, client=c)
        assert html.status_code == 200 and html.headers["content-type"].startswith("text/html")
        assert isinstance(html.parsed, str) and html.parsed.lstrip().lower().startswith(
            "<!doctype html>"
        )

        missing = report_pdf.sync_detailed("0" * 64, client=c)
        assert missing.status_code == 404 and isinstance(missing.parsed, models.Problem)


def test_a_client_generated_without_the_configuration(tmp_path: Path, server: str) -> None:
    """From the document alone the generator names the package after the title: the
    configuration's name, not this repository's ``pipeflow_client``; and the PDF report is
    never handed out as text (the generator reads only application/octet-stream as bytes
    without the configuration, so it leaves that answer unparsed: ``content`` has it)."""
    pypdf = pytest.importorskip("pypdf")
    _generate(tmp_path)
    (made,) = [p.name for p in tmp_path.iterdir() if p.is_dir()]
    config = yaml.safe_load(CONFIG.read_text())
    assert made == config["package_name_override"] == PACKAGE != "pipeflow_client"
    assert config["project_name_override"] == PACKAGE.replace("_", "-")

    name = f"{PACKAGE}_plain"  # its own name here: the configured package is imported too
    (tmp_path / made).rename(tmp_path / name)
    for path in (tmp_path / name).rglob("*.py"):
        path.write_text(path.read_text().replace(PACKAGE, name))
    sys.path.insert(0, str(tmp_path))
    try:
        plain = importlib.import_module(name)
        run_simulation = importlib.import_module(f"{name}.api.simulations.run_simulation")
        report_pdf = importlib.import_module(f"{name}.api.results.get_result_report_pdf")
        models = importlib.import_module(f"{name}.models")
        with plain.Client(base_url=server, timeout=120) as c:
            body = models.SimulationSpec.from_dict({**SMALL, "initial": {"u0": 0.0012}})
            key = run_simulation.sync_detailed(client=c, body=body).parsed.key
            pdf = report_pdf.sync_detailed(key, client=c)
            assert pdf.status_code == 200
            assert not isinstance(pdf.parsed, str)  # never text
            assert len(pypdf.PdfReader(io.BytesIO(pdf.content)).pages) >= 2
    finally:
        sys.path.remove(str(tmp_path))
        for module in [m for m in sys.modules if m == name or m.startswith(name + ".")]:
            del sys.modules[module]


def test_every_computation_has_jobs_and_unknown_paths_are_problems(
    generated: Any, server: str
) -> None:
    """``POST /v1/<name>/jobs`` answers 202 with a job for every computation, the job-only
    ones (sweeps, studies) included, through the generated client's operations; an unknown
    path is a 404 problem document whatever its method."""
    submit_sweep_job = importlib.import_module(f"{PACKAGE}.api.sweeps.submit_sweep_job")
    submit_study_job = importlib.import_module(f"{PACKAGE}.api.studies.submit_study_job")
    models = importlib.import_module(f"{PACKAGE}.models")

    sweep = {"kind": "beta_map", "modes": 4, "beta_range": [0.2, 0.8], "beta_points": 3}
    study = COMPUTATIONS["study"].examples["simulation_grid"]["value"]
    with generated.Client(base_url=server, raise_on_unexpected_status=True, timeout=60) as c:
        for submitted in (
            submit_sweep_job.sync_detailed(client=c, body=models.BetaMapSweep.from_dict(sweep)),
            submit_study_job.sync_detailed(client=c, body=models.StudySpec.from_dict(study)),
        ):
            assert submitted.status_code == 202, submitted.content
            assert isinstance(submitted.parsed, models.JobStatus)
            assert submitted.headers["location"] == f"/v1/jobs/{submitted.parsed.key}"
    # the same operation as POST /v1/sweeps: the same job
    again = httpx.post(f"{server}/v1/sweeps", json=sweep, timeout=60)
    assert again.status_code == 202 and again.json()["key"] == submitted_key(server, sweep)

    for method, path in [
        ("POST", "/v1/studies/jobs/extra"),
        ("POST", "/v1/nothing/jobs"),
        ("GET", "/v1/results/" + "0" * 64 + "/report.txt"),
        ("GET", "/nothing"),
        ("DELETE", "/v1"),
    ]:
        r = httpx.request(method, server + path, timeout=30)
        assert r.status_code == 404, (method, path, r.status_code)
        assert r.headers["content-type"] == "application/problem+json", (method, path)
        assert r.json()["status"] == 404 and r.json()["instance"] == path


def submitted_key(server: str, sweep: dict[str, Any]) -> str:
    """The job key ``POST /v1/sweeps/jobs`` gives ``sweep``."""
    r = httpx.post(f"{server}/v1/sweeps/jobs", json=sweep, timeout=60)
    assert r.status_code == 202, r.text
    return str(r.json()["key"])
