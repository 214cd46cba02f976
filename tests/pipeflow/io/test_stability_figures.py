"""The report and the figures of a pipe unstable at rest (issue 34, safety item 1).

The paper's pipe at 1000 rad/s diverges at v = 0, is stable from 17.51 to 34.31 m/s and
flutters above (``tests/pipeflow/stability/test_unstable_at_rest.py`` checks the numbers
against the spectrum).  Its report and figures show that picture and never its loss at
34.31 m/s as a critical velocity; at 100 rad/s (stable at rest) v_cr = 27.69 m/s stays.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from typing import Any

import pytest

from pipeflow.computations import documents
from pipeflow.io.plots import figure, render
from pipeflow.io.report import report
from pipeflow.paper import PAPER_PIPE
from pipeflow.stability import critical_velocities, spin_map, sweep

pytest.importorskip("matplotlib")


def _svg_text(data: bytes) -> str:
    root = ET.fromstring(data)
    return " ".join(t for el in root.iter() if el.tag.endswith("text") for t in el.itertext())


def _rows(result: dict[str, Any]) -> dict[str, str]:
    return dict(row for _, section in report(result).sections for row in section)


def _stability(w0: float) -> dict[str, Any]:
    res = critical_velocities(PAPER_PIPE, w0, (0.0, 60.0), modes=10)
    return {"kind": "stability", **documents.critical_velocities(res)}


def test_the_report_of_a_pipe_unstable_at_rest_gives_no_critical_velocity() -> None:
    doc = _stability(1000.0)
    assert doc["critical_velocity"] == pytest.approx(34.314, abs=1e-3)  # the API's field
    rows = _rows(doc)
    v_cr = "critical velocity v_cr [m/s]: the first loss of stability from v = 0 m/s"
    assert rows[v_cr] == "none: already unstable at v = 0 m/s"
    assert rows["stable at the start of the range, v = 0 m/s"] == "no: divergence"
    assert rows["stable intervals [m/s]"] == "[17.512, 34.314] m/s"
    assert rows["changes of stability"] == (
        "regains at 17.512 m/s (divergence, mode 1); loses at 34.314 m/s (flutter, mode 3)"
    )
    assert not any(k.startswith("critical velocity") and "34.31" in v for k, v in rows.items())
    rows = _rows(_stability(100.0))
    assert rows[v_cr] == "27.692" and rows["stable intervals [m/s]"] == "[0, 27.692] m/s"


@pytest.fixture(scope="module")
def spins() -> dict[str, Any]:
    m = spin_map(PAPER_PIPE, (0.0, 60.0), (0.0, 1000.0), modes=10, velocity_points=61,
                 spin_points=5)  # fmt: skip
    return {"kind": "spin_map", **documents.spin_map(m)}


def test_the_spin_map_report_gives_each_spins_picture(spins: dict[str, Any]) -> None:
    rows = _rows(spins)
    assert rows["w0 = 1000 rad/s"] == (
        "no: divergence; none: already unstable at v = 0 m/s; stable on [17.512, 34.314] m/s; "
        "regains at 17.512 m/s (divergence); loses at 34.314 m/s (flutter)"
    )
    assert rows["w0 = 0 rad/s"].startswith("yes; 27.6259; stable on [0, 27.626] m/s")


def test_the_spin_map_figure_draws_v_cr_only_from_a_stable_start(spins: dict[str, Any]) -> None:
    ax = figure("spin_map", [(None, spins)]).axes[0]
    [line] = [ln for ln in ax.get_lines() if str(ln.get_label()).startswith("v_cr")]
    v, w = (list(map(float, d)) for d in line.get_data())
    assert w == spins["spins"]
    for ok, first, vcr in zip(spins["stable_at_start"], spins["critical_velocity"], v, strict=True):
        assert (vcr == first) if ok else math.isnan(vcr)  # 34.31 at 1000 rad/s: not drawn
    labels = {str(ln.get_label()) for ln in ax.get_lines()}
    assert {
        "loses stability (flutter)",
        "regains stability (divergence)",
        "unstable at v = 0 m/s (divergence)",
    } <= labels


def test_the_sweeps_mark_the_pipes_stability() -> None:
    a = sweep(PAPER_PIPE, "velocity", (0.0, 60.0), fixed=1000.0, modes=10, tracked=4)
    argand = {"kind": "argand", **documents.sweep(a)}
    text = _svg_text(render(argand, "argand", "svg"))
    assert "critical point" not in text
    assert "unstable at v = 0 m/s (divergence): no critical v" in text
    damping = _svg_text(render(argand, "sweep_damping", "svg"))
    assert "pipe unstable (divergence)" in damping and "pipe unstable (flutter)" in damping
    c = sweep(PAPER_PIPE, "spin", (0.0, 1500.0), fixed=20.0, modes=10, tracked=4)
    campbell = {"kind": "campbell", **documents.sweep(c)}
    assert "pipe unstable (divergence)" in _svg_text(render(campbell, "campbell", "svg"))
