"""pipeflow.io.notebook's to_xarray / to_dataframe / plot of a local Result (or its JSON
form): the arrays of the result, bit for bit, with SI units in the attributes; a clear
error without the extras."""

from __future__ import annotations

import sys

import numpy as np
import pytest

from pipeflow.computations import documents
from pipeflow.io.export import SIMULATION_TABLES, table
from pipeflow.io.notebook import inputs_of, plot, to_dataframe, to_xarray
from pipeflow.io.plots import PLOTS
from pipeflow.paper import PAPER_PIPE
from pipeflow.profiles import Constant, polynomial
from pipeflow.simulation import Result, Simulation, simulate

xr = pytest.importorskip("xarray")  # the notebook extra; in the dev extra, so CI runs these
pd = pytest.importorskip("pandas")


@pytest.fixture(scope="module")
def result() -> Result:
    sim = Simulation(
        PAPER_PIPE,
        flow=polynomial(0, 0.4),
        spin=Constant(100.0),
        modes=4,
        t_end=0.2,
        samples=41,
        eigen_modes=3,
        eigen_samples=9,
        positions=(0.01, 0.02),
        include_modal=True,
        mode_shape_times=(0.0, 0.2),
        mode_shape_points=7,
    )
    return simulate(sim)


def test_dataset_holds_the_result_arrays_with_units(result: Result) -> None:
    ds = to_xarray(result)
    np.testing.assert_array_equal(ds["t"].values, result.t)
    np.testing.assert_array_equal(ds["tip_displacement"].values, result.tip_displacement)
    np.testing.assert_array_equal(ds["displacement"].values, result.displacements)
    np.testing.assert_array_equal(ds["x"].values, [0.01, 0.02])
    np.testing.assert_array_equal(ds["eigen_t"].values, result.eigen_t)
    np.testing.assert_array_equal(ds["mode"].values, [1, 2, 3])
    np.testing.assert_array_equal(ds["sigma"].values, result.frozen.sigma)
    np.testing.assert_array_equal(ds["omega"].values, result.frozen.omega)
    np.testing.assert_array_equal(ds["confidence"].values, result.frozen.confidence)
    np.testing.assert_array_equal(ds["cma_omega"].values, result.exponents.omega)
    np.testing.assert_array_equal(ds["d"].values, result.d)
    np.testing.assert_array_equal(ds["ddot"].values, result.ddot)
    assert result.mode_shapes is not None
    np.testing.assert_array_equal(ds["mode_shape"].values, result.mode_shapes.shapes)
    assert ds["mode_shape"].dims == ("shape_t", "mode", "shape_x")
    assert ds["sigma"].dims == ("eigen_t", "mode") and ds["tip_displacement"].dims == ("t",)
    units = {name: ds[name].attrs["units"] for name in [*ds.data_vars, *ds.coords]}
    assert units == {
        "tip_displacement": "m",
        "displacement": "m",
        "sigma": "1/s",
        "omega": "rad/s",
        "confidence": "1",
        "cma_sigma": "1/s",
        "cma_omega": "rad/s",
        "d": "m",
        "ddot": "m/s",
        "mode_shape": "1",
        "t": "s",
        "x": "m",
        "eigen_t": "s",
        "mode": "1",
        "galerkin": "1",
        "shape_t": "s",
        "shape_x": "m",
    }
    assert all(ds[name].attrs["long_name"] for name in units)
    assert ds.attrs["status"] == "ok" and ds.attrs["method"] == "auto"  # the default
    # selection by label works as a notebook user expects
    assert float(ds["omega"].sel(mode=1).isel(eigen_t=0)) == result.frozen.omega[0, 0]


@pytest.mark.parametrize("name", SIMULATION_TABLES)
def test_dataframes_are_the_export_tables(result: Result, name: str) -> None:
    frame = to_dataframe(result, name)
    header, columns = table(documents.simulation(result), name)
    assert frame.index.name == header[0].split(" [")[0]
    assert [f"{c} [{frame.attrs['units'][c]}]" for c in [frame.index.name, *frame.columns]] == (
        header
    )
    np.testing.assert_array_equal(frame.index.to_numpy(), columns[0])
    for col, values in zip(frame.columns, columns[1:], strict=True):
        assert frame[col].tolist() == values
    assert frame.attrs["table"] == name


def test_the_io_functions_take_a_result_or_its_json(result: Result) -> None:
    """pipeflow.io.notebook's functions take a local Result (its document written by
    pipeflow.computations.documents) or that document, and give the same views."""
    doc = documents.simulation(result)
    # the document carries no request: the local result's inputs are given to it
    assert to_xarray(result).identical(to_xarray(doc, inputs=inputs_of(result)))
    assert "inputs" in to_xarray(result).attrs and "inputs" not in to_xarray(doc).attrs
    assert to_dataframe(result, "eigenvalues").equals(to_dataframe(doc, "eigenvalues"))
    assert plot(result, "damping").axes[0].lines[0].get_ydata().tolist() == (
        plot(doc, "damping").axes[0].lines[0].get_ydata().tolist()
    )


def test_plot_returns_a_labelled_figure(result: Result) -> None:
    fig = plot(result, "damping")
    ax = fig.axes[0]
    assert ax.get_xlabel() == PLOTS["damping"].xlabel
    assert ax.get_ylabel() == PLOTS["damping"].ylabel
    np.testing.assert_array_equal(ax.lines[0].get_ydata(), result.frozen.sigma[:, 0])
    assert plot(result, "tip_displacement", title="mine").axes[0].get_title() == "mine"


@pytest.mark.parametrize(
    ("module", "call"),
    [("xarray", to_xarray), ("pandas", to_dataframe)],
)
def test_missing_extra_names_the_install_command(
    result: Result, monkeypatch: pytest.MonkeyPatch, module: str, call: object
) -> None:
    monkeypatch.setitem(sys.modules, module, None)  # importing it now raises ImportError
    with pytest.raises(ImportError, match=rf"needs {module}: pip install 'pipeflow\[notebook\]'"):
        call(result)  # type: ignore[operator]


def test_dataset_of_an_unstable_run_carries_the_least_stable_branch() -> None:
    """v = 40 m/s > v_cr: four traced branches (the three lowest and the flutter branch,
    mode 5) in both the frozen eigenvalues and the CMA exponents, one mode coordinate."""
    r = simulate(
        Simulation(PAPER_PIPE, flow=Constant(40.0), spin=Constant(100.0), t_end=0.01, samples=11)
    )
    ds = to_xarray(r)
    np.testing.assert_array_equal(ds["mode"].values, [1, 2, 3, 5])
    np.testing.assert_array_equal(ds["sigma"].values, r.frozen.sigma)
    np.testing.assert_array_equal(ds["cma_sigma"].values, r.exponents.sigma)
