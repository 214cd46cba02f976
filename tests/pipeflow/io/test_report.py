"""The report of a result (pipeflow.io.report, issue 24): HTML and PDF, pages rendered.

The PDF is read back by pypdf (an independent parser): its text holds the key numbers as
the result states them, one page per figure after the text; the HTML's images decode as
PNG.  The numbers are the result's own (formatted with 6 significant digits).
"""

from __future__ import annotations

import base64
import io
import re
from typing import Any

import pytest

from pipeflow import __version__
from pipeflow.computations import documents
from pipeflow.computations.registry import COMPUTATIONS
from pipeflow.io.report import report, to_html, to_pdf
from pipeflow.paper import PAPER_PIPE
from pipeflow.profiles import Constant
from pipeflow.schema.stability import PAPER_PIPE_JSON, StabilitySpec
from pipeflow.simulation import Simulation, simulate

pytest.importorskip("matplotlib")
pypdf = pytest.importorskip("pypdf")


@pytest.fixture(scope="module")
def diverged() -> dict[str, Any]:
    sim = Simulation(PAPER_PIPE, Constant(40.0), Constant(100.0), modes=6, t_end=0.05, samples=501)
    return documents.simulation(simulate(sim))


def _pdf_text(data: bytes) -> tuple[int, list[str]]:
    reader = pypdf.PdfReader(io.BytesIO(data))
    return len(reader.pages), [p.extract_text() for p in reader.pages]


@pytest.mark.slow  # two PDFs of 6 figures each: about 5 s on a quiet machine
def test_pdf_pages_hold_the_key_numbers(diverged: dict[str, Any]) -> None:
    inputs = {"pipe": PAPER_PIPE_JSON, "flow": {"velocity": {"kind": "constant", "value": 40}}}
    data = to_pdf(diverged, inputs, key="abc123")
    assert data.startswith(b"%PDF")
    pages, texts = _pdf_text(data)
    rep = report(diverged, inputs)
    assert len(rep.figures) >= 3
    text = " ".join(texts)
    text_pages = pages - len(rep.figures)
    assert text_pages >= 1
    flat = re.sub(r"\s+", " ", text)
    for want in (
        "pipeflow report: simulation",
        f"pipeflow version {__version__}",
        "status diverged",
        f"divergence time [s] {diverged['divergence_time']:.6g}",
        f"growth rate at divergence [1/s] {diverged['divergence_growth_rate']:.6g}",
        "estimated relative error",
        "method auto -> cma",
        "pipe.L 0.025",
        "key (parameter hash) abc123",
    ):
        assert want in flat, want
    # the figure pages come after the text: each is a drawn plot with its axis labels
    assert "tip displacement u(L, t) [m]" in " ".join(texts[text_pages:])
    assert to_pdf(diverged, inputs, key="abc123") == data  # no timestamp: same bytes


def test_html_embeds_every_figure(diverged: dict[str, Any]) -> None:
    page = to_html(diverged)
    images = re.findall(r'src="data:image/png;base64,([^"]+)"', page)
    assert len(images) == len(report(diverged).figures)
    for data in images:
        assert base64.b64decode(data).startswith(b"\x89PNG\r\n\x1a\n")
    assert "<td>status</td><td>diverged</td>" in page
    assert "not stored with this result" in page  # no inputs given


def test_stability_report_states_the_critical_velocity() -> None:
    body = {"pipe": PAPER_PIPE_JSON, "velocity_range": [0, 40], "modes": 4}
    result = COMPUTATIONS["stability"].execute(StabilitySpec.model_validate(body))
    _, texts = _pdf_text(to_pdf(result, body))
    flat = re.sub(r"\s+", " ", " ".join(texts))
    v_cr = f"{result['critical_velocity']:.6g}"
    label = "critical velocity v_cr [m/s]: the first loss of stability from v = 0 m/s"
    assert f"{label} {v_cr}" in flat
    assert f"stable intervals [m/s] [0, {result['critical_velocity']:.5g}] m/s" in flat


def test_the_end_values_of_a_diverged_run_are_stated_at_its_divergence_time(
    diverged: dict[str, Any],
) -> None:
    """The traces of a stopped run end at its divergence time (issue 24), not at the
    t_end asked: the report names that time with the fundamental's last values."""
    t = diverged["divergence_time"]
    assert diverged["eigenvalues"]["t"][-1] == t < 0.05  # 0.05 s asked
    first = diverged["eigenvalues"]["modes"][0]
    rows = dict(row for _, section in report(diverged).sections for row in section)
    label = f"mode {first['mode']} at t = {t:.6g} s: sigma [1/s], omega [rad/s]"
    assert rows[label] == f"{first['sigma'][-1]:.6g}, {first['omega'][-1]:.6g}"
    assert not any("t_end" in name for name in rows)
