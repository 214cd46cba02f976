"""``pipeflow report`` and ``pipeflow plot --spin-unit/--frequency-unit`` (issue 24)."""

from __future__ import annotations

import io
import json
import re
from pathlib import Path

import pytest

from pipeflow.schema.simulation import PAPER_EXAMPLE
from pipeflow_cli.cli import main


@pytest.fixture
def small_spec(tmp_path: Path) -> Path:
    spec = json.loads(json.dumps(PAPER_EXAMPLE))
    spec.update(modes=3, time={"t_end": 0.05, "samples": 21})
    spec["rotation"]["omega0"] = {"kind": "constant", "value": {"value": 955, "unit": "rpm"}}
    path = tmp_path / "spec.json"
    path.write_text(json.dumps(spec))
    return path


@pytest.mark.slow  # a run and two reports with their figures: several seconds
def test_report_of_a_spec_holds_its_inputs(small_spec: Path, tmp_path: Path) -> None:
    """A spec is run, then reported with its inputs (as written: the unit too); a result
    JSON is reported without them."""
    pypdf = pytest.importorskip("pypdf")
    pdf = tmp_path / "r.pdf"
    assert main(["report", str(small_spec), "--out", str(pdf), "--quiet"]) == 0
    reader = pypdf.PdfReader(io.BytesIO(pdf.read_bytes()))
    flat = re.sub(r"\s+", " ", " ".join(p.extract_text() for p in reader.pages))
    assert "status ok" in flat and "rotation.omega0.value.unit rpm" in flat

    result = tmp_path / "result.json"
    assert main(["run", str(small_spec), "-o", str(result), "--quiet"]) == 0
    page = tmp_path / "r.html"
    assert main(["report", str(result), "--out", str(page)]) == 0
    assert "not stored with this result" in page.read_text()
    assert main(["report", str(result), "--out", str(tmp_path / "r.docx")]) == 2


def test_plot_in_hz(small_spec: Path, tmp_path: Path) -> None:
    svg = tmp_path / "f.svg"
    args = ["plot", str(small_spec), "--name", "frequency", "--out", str(svg), "--quiet"]
    assert main([*args, "--frequency-unit", "Hz"]) == 0
    assert "frequency ω [Hz]" in svg.read_text()
