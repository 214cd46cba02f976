"""Spin in rpm and frequencies in Hz on the figures' axes (issue 24).

The data stay in rad/s; the axes show ticks at round values of the display unit.  Checked
against the factors written out (1 rpm = 2 pi / 60 rad/s, 1 Hz = 2 pi rad/s): a tick
drawn at position p [rad/s] is labelled p x factor, and that label is a round number.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest

from pipeflow.computations.registry import SWEEP_KINDS, computation_for, parse
from pipeflow.io.plots import PlotError, figure
from pipeflow.schema.stability import PAPER_PIPE_JSON

pytest.importorskip("matplotlib")

RPM = 60 / (2 * math.pi)
HZ = 1 / (2 * math.pi)


def _campbell() -> dict[str, Any]:
    body = {"kind": "campbell", "pipe": PAPER_PIPE_JSON, "modes": 4, "spin_range": [0, 600]}
    request = parse(SWEEP_KINDS, body)
    result: dict[str, Any] = computation_for(request).execute(request)
    return result


def _ticks(axis: Any) -> list[tuple[float, str]]:
    axis.axes.figure.canvas.draw()
    lo, hi = axis.get_view_interval()
    return [
        (float(t.get_loc()), t.label1.get_text())
        for t in axis.get_major_ticks()
        if lo <= t.get_loc() <= hi
    ]


def test_campbell_in_rpm_and_hz() -> None:
    c = _campbell()
    plain = figure("campbell", [(None, c)]).axes[0]
    fig = figure("campbell", [(None, c)], units={"spin": "rpm", "frequency": "Hz"})
    ax = fig.axes[0]
    assert ax.get_xlabel() == "spin ω0 [rpm]" and ax.get_ylabel() == "frequency |ω| [Hz]"
    for axis, factor in ((ax.xaxis, RPM), (ax.yaxis, HZ)):
        ticks = _ticks(axis)
        assert len(ticks) >= 3
        for loc, text in ticks:
            value = float(text.replace("−", "-"))
            assert value == pytest.approx(loc * factor, rel=1e-9, abs=1e-9)
            step = np.diff([float(t.replace("−", "-")) for _, t in ticks])
            assert np.allclose(step, step[0])  # evenly spaced round values
        assert all(float(t.replace("−", "-")) % 1 == 0 for _, t in ticks)  # integers here
    # the data are the same rad/s numbers as without display units
    for a, b in zip(plain.lines, ax.lines, strict=True):
        np.testing.assert_array_equal(a.get_xydata(), b.get_xydata())


def test_an_unknown_display_unit_is_refused() -> None:
    with pytest.raises(PlotError) as err:
        figure("campbell", [(None, _campbell())], units={"spin": "furlong"})
    assert err.value.field == "units"
