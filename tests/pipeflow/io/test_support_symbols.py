"""Support symbols on the figures along the pipe (issue 31): each support drawn at its x."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from pipeflow.computations import documents
from pipeflow.io.plots import figure, to_bytes
from pipeflow.model import Pipe
from pipeflow.paper import PAPER_PIPE
from pipeflow.profiles import Constant
from pipeflow.simulation import Simulation, simulate
from pipeflow.supports import PointSupport, Support, Supports

PP_SPRING = Pipe(
    E=1.0, I=1.0, L=2.0, M1=0.6, M2=0.4,
    supports=Supports(Support("pinned"), Support("pinned")),
    intermediate_supports=(PointSupport(1.0, translational=50.0),),
)  # fmt: skip


def _shapes(pipe: Pipe) -> dict[str, Any]:
    sim = Simulation(
        pipe, flow=Constant(0.1), spin=Constant(0.0), modes=4, t_end=0.1, samples=11,
        eigen_modes=2, eigen_samples=3, mode_shape_times=(0.0,),
    )  # fmt: skip
    return documents.simulation(simulate(sim))


def _support_artists(fig: Any) -> dict[str, list[Any]]:
    found: dict[str, list[Any]] = {}
    ax = fig.axes[0]
    for a in [*ax.lines, *ax.patches]:
        gid = a.get_gid()
        if gid and gid.startswith("support:"):
            found.setdefault(gid, []).append(a)
    return found


def _xs(artists: list[Any]) -> set[float]:
    out: set[float] = set()
    for a in artists:
        if hasattr(a, "get_xdata"):
            out.update(float(v) for v in np.asarray(a.get_xdata(), dtype=float))
        else:  # the clamp's hatched wall: its face edge
            out.update((a.get_x(), a.get_x() + a.get_width()))
    return out


def test_pinned_pinned_with_midspan_spring() -> None:
    fig = figure("mode_shapes", [(None, _shapes(PP_SPRING))], pipe=PP_SPRING)
    found = _support_artists(fig)
    assert set(found) == {"support:x0:pinned", "support:xL:pinned", "support:point0:elastic"}
    # each symbol sits exactly at its support's x [m] (set from the model, no arithmetic)
    assert _xs(found["support:x0:pinned"]) == {0.0}
    assert _xs(found["support:xL:pinned"]) == {2.0}
    assert _xs(found["support:point0:elastic"]) == {1.0}
    # no support symbol makes a legend entry
    legend = fig.axes[0].get_legend()
    assert legend is not None
    labels = [t.get_text() for t in legend.get_texts()]
    assert not any("support" in s for s in labels)
    assert to_bytes(fig)[:4] == b"\x89PNG"


@pytest.mark.parametrize(
    ("end", "gid"),
    [
        ("clamped", "support:xL:clamped"),
        ("sliding", "support:xL:sliding"),
        (Support("elastic", 10.0, 1.0), "support:xL:elastic"),
    ],
)
def test_each_end_kind_has_its_symbol(end: Any, gid: str) -> None:
    xl = end if isinstance(end, Support) else Support(end)
    pipe = Pipe(E=1.0, I=1.0, L=1.0, M1=0.6, M2=0.4, supports=Supports(Support("pinned"), xl))
    found = _support_artists(figure("mode_shapes", [(None, _shapes(pipe))], pipe=pipe))
    assert set(found) == {"support:x0:pinned", gid}
    assert 1.0 in _xs(found[gid])


def test_cantilever_adds_only_the_clamp() -> None:
    result = _shapes(PAPER_PIPE)
    plain = figure("mode_shapes", [(None, result)])
    marked = figure("mode_shapes", [(None, result)], pipe=PAPER_PIPE)
    assert _support_artists(plain) == {}
    found = _support_artists(marked)
    assert set(found) == {"support:x0:clamped"}  # the free tip draws nothing
    assert 0.0 in _xs(found["support:x0:clamped"])
    # the curves are the same artists with the same data

    def curves(fig: Any) -> list[Any]:
        return [np.asarray(ln.get_ydata()).tolist() for ln in fig.axes[0].lines if not ln.get_gid()]

    assert curves(plain) == curves(marked)
    # and the same axes limits (the symbols sit in axes-fraction y, within the x margins)
    assert plain.axes[0].get_xlim() == marked.axes[0].get_xlim()
    assert plain.axes[0].get_ylim() == marked.axes[0].get_ylim()


def test_plots_not_along_the_pipe_draw_no_supports() -> None:
    result = _shapes(PP_SPRING)
    assert _support_artists(figure("tip_displacement", [(None, result)], pipe=PP_SPRING)) == {}


def test_the_operating_deflection_shape_draws_the_supports() -> None:
    """The deflection shape runs along the pipe too (its name was misspelt in ALONG_PIPE,
    "deflection", so the supports were never drawn on it)."""
    import dataclasses

    from pipeflow.frequency import PointForce, frequency_response

    damped = dataclasses.replace(PP_SPRING, viscous=0.05)  # finite peaks
    r = frequency_response(
        damped, 0.0, 0.0, load=PointForce(0.3), positions=np.linspace(0.25, 2.0, 8),
        frequencies=np.linspace(0.5, 30.0, 200), modes=6,
    )  # fmt: skip
    doc = {"kind": "frequency_response", **documents.frequency_response([r])}  # as stored
    found = _support_artists(figure("deflection_shape", [(None, doc)], pipe=PP_SPRING))
    assert set(found) == {"support:x0:pinned", "support:xL:pinned", "support:point0:elastic"}
    assert _xs(found["support:point0:elastic"]) == {1.0}
