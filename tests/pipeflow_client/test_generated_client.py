"""A client generated from the committed ``openapi/openapi.json`` by openapi-python-client
works against a live server, the plot endpoint included.

The client is generated into a temporary directory with the committed configuration
``openapi/openapi-python-client.yml`` (package ``pipeflow_generated_client``: no clash with
``pipeflow`` or ``pipeflow_client``; image/png and image/svg+xml read as bytes), imported
from there, and used against uvicorn in a subprocess for one simulation and one plot in
each image format.  The numbers it returns are checked against the library run in-process
(identical code path, so equal to rounding of the JSON: relative 1e-12).
"""

from __future__ import annotations

import importlib
import shutil
import subprocess
import sys
from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest

from pipeflow.schema.simulation import SimulationSpec
from pipeflow.simulation import simulate
from tests.live import ROOT, need
from tests.service.conftest import SMALL

PACKAGE = "pipeflow_generated_client"


@pytest.fixture(scope="module")
def generated(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Any]:
    """The generated package, imported from a temporary directory."""
    need(
        shutil.which("openapi-python-client") is not None,
        "openapi-python-client is not installed (pip install -e '.[dev]')",
    )
    where = tmp_path_factory.mktemp("generated")
    done = subprocess.run(
        [
            "openapi-python-client",
            "generate",
            "--path",
            str(ROOT / "openapi" / "openapi.json"),
            "--config",
            str(ROOT / "openapi" / "openapi-python-client.yml"),
            "--meta",
            "none",
            "--output-path",
            str(where / PACKAGE),
        ],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert done.returncode == 0, done.stdout + done.stderr
    # a warning means an operation or response was left out of the generated client
    assert "Warning" not in done.stdout + done.stderr, done.stdout + done.stderr
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
