"""Figures of an unstable run (issue 24): the least stable branch, not only the fundamental.

At v = 40 m/s the paper's pipe (w0 = 100 rad/s) flutters in branch 5 while mode 1 decays
at about -3509 1/s: a damping plot of mode 1 alone reads as a heavily damped run.  The
damping and frequency figures add the least stable branch (dashed) and the tip figure
marks the bound where the run was stopped.  The lines drawn are compared with the
result's own numbers (the same floats: matplotlib keeps the data it is given).
"""

from __future__ import annotations

import numpy as np
import pytest

from pipeflow.computations import documents
from pipeflow.io.plots import figure, render
from pipeflow.paper import PAPER_PIPE
from pipeflow.profiles import Constant, polynomial
from pipeflow.simulation import Simulation, simulate

pytest.importorskip("matplotlib")


def _doc(v: float | None) -> dict:
    flow = Constant(v) if v is not None else polynomial(0, 0.4)
    sim = Simulation(PAPER_PIPE, flow=flow, spin=Constant(100.0), t_end=0.05, samples=501)
    return documents.simulation(simulate(sim))


def test_unstable_run_shows_the_least_stable_branch() -> None:
    doc = _doc(40.0)
    assert doc["status"] == "diverged"
    least = next(m for m in doc["eigenvalues"]["modes"] if m["least_stable"])
    assert least["mode"] != 1 and least["sigma"][0] > 0 > doc["eigenvalues"]["modes"][0]["sigma"][0]
    for name, part in (("damping", "sigma"), ("frequency", "omega")):
        ax = figure(name, [(None, doc)]).axes[0]
        drawn = [line for line in ax.lines if len(line.get_ydata()) == len(least[part])]
        assert len(drawn) == 2, name
        np.testing.assert_array_equal(drawn[1].get_ydata(), least[part])
        assert f"mode {least['mode']}, least stable" in drawn[1].get_label()
    tip = figure("tip_displacement", [(None, doc)]).axes[0]
    marks = [line for line in tip.lines if "diverged" in str(line.get_label())]
    assert len(marks) == 1 and marks[0].get_xdata()[0] == doc["divergence_time"]
    assert render(doc, "damping")[:8] == b"\x89PNG\r\n\x1a\n"


def test_stable_run_draws_the_fundamental_alone() -> None:
    doc = _doc(None)
    assert doc["status"] == "ok"
    for name in ("damping", "frequency"):
        ax = figure(name, [(None, doc)]).axes[0]
        assert len(ax.lines) == 1
