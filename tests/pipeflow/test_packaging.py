"""Packaging: the numerical library and its schema need numpy, scipy, pydantic and rfc8785
(the cache key, pipeflow.schema.keys) only; the service, the client and the plots are
extras (pyproject.toml)."""

from __future__ import annotations

import json
import subprocess
import sys
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
#: modules of the extras, which ``import pipeflow`` and the library must not load
EXTRAS = ("fastapi", "starlette", "uvicorn", "httpx", "matplotlib", "pydantic_settings")


def test_library_imports_no_extra() -> None:
    """Importing every library module, schema and registry included, loads no extra (checked
    in a fresh interpreter: the test process has them all loaded)."""
    code = (
        "import sys, json\n"
        "import pipeflow, pipeflow.simulation, pipeflow.compare, pipeflow.stability\n"
        "import pipeflow.computations.registry, pipeflow.io.export, pipeflow.io.plots\n"
        "import pipeflow_cli\n"
        f"print(json.dumps([m for m in {list(EXTRAS)!r} if m in sys.modules]))\n"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, check=True
    )
    assert json.loads(out.stdout) == []


def test_results_do_not_load_the_presentation_layer() -> None:
    """A simulation's result is plain: running one and writing its document loads no
    exporter, plot or notebook module (pipeflow.io.json, the non-finite rule of its JSON
    form, is the one io module the document uses), and the run alone loads no schema."""
    code = (
        "import sys, json\n"
        "from pipeflow.paper import PAPER_PIPE\n"
        "from pipeflow.simulation import Simulation, simulate\n"
        "result = simulate(Simulation(PAPER_PIPE, modes=2, t_end=0.01, samples=11))\n"
        "assert not [m for m in sys.modules if m.startswith('pipeflow.schema')]\n"
        "from pipeflow.computations import documents\n"
        "documents.simulation(result)\n"
        "print(json.dumps(sorted(m for m in sys.modules if m.startswith('pipeflow.io'))))\n"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, check=True
    )
    assert json.loads(out.stdout) == ["pipeflow.io", "pipeflow.io.json"]


def test_dependencies_and_extras() -> None:
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    base = {d.split(">")[0].split("=")[0] for d in project["dependencies"]}
    assert base == {"numpy", "scipy", "pydantic", "rfc8785", "pint"}  # pint: units on input
    extras = project["optional-dependencies"]
    assert {"service", "client", "plots", "dev"} <= set(extras)
    assert any(d.startswith("fastapi") for d in extras["service"])
    assert any(d.startswith("schemathesis") for d in extras["dev"])
