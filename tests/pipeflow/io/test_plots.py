"""Figures of results: PNG/SVG bytes, axis labels with units, overlays, determinism."""

from __future__ import annotations

import importlib.util
import sys
import xml.etree.ElementTree as ET
from pathlib import Path
from typing import Any

import pytest

from pipeflow.computations import documents
from pipeflow.io.plots import PlotError, available_plots, figure, render, to_bytes
from pipeflow.paper import PAPER_PIPE
from pipeflow.profiles import Constant, polynomial
from pipeflow.simulation import Simulation, simulate

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


def _run(a: float, positions: tuple[float, ...] = ()) -> dict[str, Any]:
    sim = Simulation(
        PAPER_PIPE,
        flow=polynomial(0, a),
        spin=Constant(100.0),
        modes=4,
        t_end=0.2,
        samples=81,
        eigen_modes=2,
        eigen_samples=11,
        positions=positions,
    )
    return documents.simulation(simulate(sim))


@pytest.fixture(scope="module")
def result() -> dict[str, Any]:
    return _run(0.4, positions=(0.0125,))


def _svg_text(data: bytes) -> str:
    root = ET.fromstring(data)  # well-formed XML
    return " ".join(t for el in root.iter() if el.tag.endswith("text") for t in el.itertext())


def test_available_plots(result: dict[str, Any]) -> None:
    assert available_plots(result) == [
        "tip_displacement",
        "damping",
        "frequency",
        "argand",
        "displacements",
    ]
    no_stations = dict(result, displacements=[])
    assert "displacements" not in available_plots(no_stations)
    assert available_plots({"t": [0.0], "tip_displacement": [0.0]}) == ["tip_displacement"]


@pytest.mark.parametrize(
    ("name", "labels"),
    [
        ("tip_displacement", ["time t [s]", "tip displacement u(L, t) [m]"]),
        ("damping", ["time t [s]", "damping σ [1/s]"]),
        ("frequency", ["time t [s]", "frequency ω [rad/s]"]),
        ("argand", ["damping σ [1/s]", "frequency ω [rad/s]"]),
        ("displacements", ["time t [s]", "displacement u(x, t) [m]", "x = 0.0125 m"]),
    ],
)
def test_svg_has_axis_labels_with_units(
    result: dict[str, Any], name: str, labels: list[str]
) -> None:
    text = _svg_text(render(result, name, "svg"))
    for label in labels:
        assert label in text


def test_png_bytes_and_determinism(result: dict[str, Any]) -> None:
    a = render(result, "tip_displacement", "png")
    assert a.startswith(PNG_MAGIC)
    assert render(result, "tip_displacement", "png") == a
    assert render(result, "damping", "svg") == render(result, "damping", "svg")


def test_overlay_legend_and_title(result: dict[str, Any]) -> None:
    other = _run(0.2)
    fig = figure("frequency", [("v = 0.4 t m/s", result), ("v = 0.2 t m/s", other)], title="Fig. 7")
    ax = fig.axes[0]
    assert len(ax.lines) == 2
    assert ax.get_title() == "Fig. 7"
    text = _svg_text(to_bytes(fig, "svg"))
    assert "v = 0.4 t m/s" in text and "v = 0.2 t m/s" in text


def test_errors_name_the_field(result: dict[str, Any]) -> None:
    with pytest.raises(PlotError, match="unknown plot 'smith_chart'") as err:
        render(result, "smith_chart")
    assert err.value.field == "name"
    with pytest.raises(PlotError) as err:
        render(result, "damping", "jpg")
    assert err.value.field == "format"
    with pytest.raises(PlotError, match="no data for the 'damping' plot"):
        render({"t": [0.0, 1.0], "tip_displacement": [0.0, 0.0]}, "damping")


def test_paper_figures_example_script(tmp_path: Path) -> None:
    """examples/paper_figures.py draws the requested figures (coarse settings: a smoke test)."""
    script = Path(__file__).resolve().parents[3] / "examples" / "paper_figures.py"
    spec = importlib.util.spec_from_file_location("paper_figures", script)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # dataclasses look their module up there
    try:
        spec.loader.exec_module(module)
    finally:
        del sys.modules[spec.name]
    assert [c.first_figure for c in module.cases()] == [2, 5, 8, 11, 14, 17, 20, 23, 26]
    args = ["--out", str(tmp_path), "--only", "6", "27", "--modes", "2", "--samples", "51"]
    assert module.main(args) == 0
    files = sorted(p.name for p in tmp_path.iterdir())
    assert files == ["fig06_damping.png", "fig27_damping.png"]
    assert (tmp_path / files[0]).read_bytes().startswith(PNG_MAGIC)


def test_stability_plots() -> None:
    """Argand/Campbell sweeps and the stability maps of pipeflow.schema.stability draw."""
    from pipeflow.computations.registry import SWEEP_KINDS, computation_for, parse
    from pipeflow.schema.stability import PAPER_PIPE_JSON

    cases = {
        "argand": (
            {"kind": "argand", "pipe": PAPER_PIPE_JSON, "modes": 4, "velocity_range": [0, 40]},
            ["argand", "sweep_frequency", "sweep_damping"],
            "flow velocity v [m/s]",
        ),
        "campbell": (
            {"kind": "campbell", "pipe": PAPER_PIPE_JSON, "modes": 4, "spin_range": [0, 300]},
            ["argand", "campbell", "sweep_frequency", "sweep_damping"],
            "spin ω0 [rad/s]",
        ),
        "spin_map": (
            {
                "kind": "spin_map",
                "pipe": PAPER_PIPE_JSON,
                "modes": 4,
                "velocity_range": [0, 60],
                "spin_range": [0, 300],
                "velocity_points": 21,
                "spin_points": 4,
            },
            ["spin_map"],
            "flow velocity v [m/s]",
        ),
        "beta_map": (
            {
                "kind": "beta_map",
                "modes": 4,
                "beta_range": [0.1, 0.5],
                "u_range": [0, 15],
                "beta_points": 5,
                "u_points": 21,
            },
            ["beta_map"],
            "mass ratio β = M2/(M1+M2) [-]",
        ),
        "resonance_chart": (
            {
                "kind": "resonance_chart",
                "pipe": {"E": 1.0, "I": 1.0, "L": 1.0, "M1": 0.8, "M2": 0.2},  # beta = 0.2
                "modes": 3,
                "mean_velocity": 8.944,  # u = 4: omega_2 = 17.13 rad/s, lightly damped
                "amplitude_range": [0, 7.2],
                "frequency_range": [25, 43],
                "amplitude_points": 4,
                "frequency_points": 7,
            },
            ["resonance_chart"],
            "pulsation amplitude a [m/s]",
        ),
        "floquet": (
            {
                "kind": "floquet",
                "pipe": PAPER_PIPE_JSON,
                "modes": 2,
                "flow": {
                    "velocity": {"kind": "harmonic", "mean": 10, "amplitude": 5, "frequency": 1e3}
                },
            },
            ["floquet_multipliers"],
            "Re λ [-]",
        ),
    }
    for data, names, xlabel in cases.values():
        request = parse(SWEEP_KINDS, data)
        result = computation_for(request).execute(request)
        assert available_plots(result) == names
        text = _svg_text(render(result, names[-1], "svg"))
        assert xlabel in text


def test_growth_maps_with_no_growth_keep_a_symmetric_scale() -> None:
    """A stability map whose growth rates [1/s] are all 0 (or all undefined) still gets the
    symmetric colour scale [-1, 1] instead of a degenerate [0, 0]."""
    for grid in ([[0.0, 0.0, 0.0], [0.0, 0.0, 0.0]], [[None, None, None]] * 2):
        r = {
            "kind": "spin_map",
            "velocities": [0.0, 1.0, 2.0],
            "spins": [0.0, 10.0],
            "growth_rate": grid,
            "critical_velocity": [None, None],
        }
        mesh = figure("spin_map", [(None, r)]).axes[0].collections[0]
        assert (mesh.norm.vmin, mesh.norm.vmax) == (-1.0, 1.0)


def test_campbell_and_argand_mark_the_crossings() -> None:
    """The Campbell figure draws one dashed line per excitation order (legend "1x", "2x"),
    the crossings and a damping-ratio colour bar; the Argand figure marks the critical point
    (the paper pipe at 100 rad/s: 27.69 m/s by flutter, as in the README)."""
    from pipeflow.computations.registry import SWEEP_KINDS, computation_for, parse
    from pipeflow.schema.stability import PAPER_PIPE_JSON

    def parse_sweep(body: dict[str, Any]) -> Any:
        return parse(SWEEP_KINDS, body)

    def run_sweep(request: Any) -> dict[str, Any]:
        return computation_for(request).execute(request)

    c = run_sweep(
        parse_sweep(
            {
                "kind": "campbell",
                "pipe": PAPER_PIPE_JSON,
                "modes": 4,
                "spin_range": [0, 600],
                "flow": {"velocity": {"kind": "constant", "value": 10}},
                "orders": [1, 2],
            }
        )
    )
    assert c["excitation"]["crossings"]
    text = _svg_text(render(c, "campbell", "svg"))
    for want in ("1x", "2x", "crossings", "damping ratio ζ [-]", "spin ω0 [rad/s]"):
        assert want in text, want
    a = run_sweep(
        parse_sweep(
            {
                "kind": "argand",
                "pipe": PAPER_PIPE_JSON,
                "velocity_range": [0, 40],
                "rotation": {"omega0": {"kind": "constant", "value": 100}},
            }
        )
    )
    assert "critical point: 27.69 m/s (flutter)" in _svg_text(render(a, "argand", "svg"))
