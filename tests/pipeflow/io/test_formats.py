"""UFF (pyuff) and netCDF export (pipeflow.io.formats, issue 32), read back by independent
readers (pyuff's reader, xarray's scipy netCDF reader) and compared with the JSON result.

UFF 58 writes each ordinate value in ASCII with 12 significant digits (E20.11): tolerance
1e-11 relative to the curve's largest value; the abscissa, the frequency in Hz (W / 2 pi),
with 6 (E13.5, the format's field): 5e-6 relative.  UFF 55 writes shapes and eigenvalues
with 6 digits: 5e-6 of the unit maximum modulus.  netCDF stores the float64 values
themselves: compared exactly.
"""

from __future__ import annotations

import copy
import io
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from pipeflow.computations import documents
from pipeflow.computations.registry import COMPUTATIONS, SWEEP_KINDS, computation_for, parse
from pipeflow.io.export import ExportError
from pipeflow.io.formats import to_netcdf, to_uff, uff_available
from pipeflow.io.notebook import to_xarray
from pipeflow.paper import PAPER_PIPE
from pipeflow.profiles import Constant, polynomial
from pipeflow.schema.frequency import HAMMER_EXAMPLE, FrequencyResponseSpec
from pipeflow.schema.stability import PAPER_PIPE_JSON, StabilitySpec
from pipeflow.schema.study import StudySpec
from pipeflow.simulation import Simulation, simulate
from tests.pipeflow.io.test_notebook_kinds import SWEEPS

pyuff = pytest.importorskip("pyuff")
xr = pytest.importorskip("xarray")


@pytest.fixture(scope="module")
def frf() -> dict[str, Any]:
    body = copy.deepcopy(HAMMER_EXAMPLE)
    body.pop("flow", None)
    body["rotation"] = {"hub_radius": 0.0}
    body["operating_points"] = [
        {"velocity": 0.0, "omega0": 0.0},
        {"velocity": 5.0, "omega0": 100.0},
    ]
    body["response"] = {"positions": [0.0125, 0.025], "quantity": "displacement"}
    body["frequencies"] = {"min": 10.0, "max": 8000.0, "count": 60, "spacing": "log"}
    return COMPUTATIONS["frequency_response"].execute(FrequencyResponseSpec.model_validate(body))


@pytest.fixture(scope="module")
def simulation() -> dict[str, Any]:
    sim = Simulation(
        PAPER_PIPE,
        flow=polynomial(0, 0.4),
        spin=Constant(100.0),
        modes=4,
        t_end=0.1,
        samples=11,
        eigen_modes=3,
        eigen_samples=5,
        mode_shape_times=(0.0, 0.1),
        mode_shape_points=7,
    )
    return documents.simulation(simulate(sim))


def _read_uff(data: bytes, tmp_path: Path) -> list[dict[str, Any]]:
    path = tmp_path / "r.uff"
    path.write_bytes(data)
    sets = pyuff.UFF(str(path)).read_sets()
    return sets if isinstance(sets, list) else [sets]


def test_frf_uff58_read_back(frf: dict[str, Any], tmp_path: Path) -> None:
    sets = _read_uff(to_uff(frf), tmp_path)
    points, positions = frf["operating_points"], frf["positions"]
    assert len(sets) == len(points) * len(positions)
    hz = np.asarray(frf["frequencies"]) / (2 * math.pi)
    k = 0
    for p, point in enumerate(points):
        for i, curve in enumerate(point["responses"]):
            s = sets[k]
            k += 1
            assert s["type"] == 58 and s["func_type"] == 4
            assert s["rsp_node"] == i + 1 and s["load_case_id"] == p + 1
            assert s["ordinate_axis_units_lab"].strip() == "m/N"
            assert s["abscissa_axis_units_lab"].strip() == "Hz"
            assert s["ordinate_spec_data_type"] == 8 and s["orddenom_spec_data_type"] == 13
            assert f"x = {curve['position']!r} m" in s["id4"]
            assert repr(point["velocity"]) in s["id3"]
            np.testing.assert_allclose(s["x"], hz, rtol=5e-6)
            h = np.asarray(curve["real"]) + 1j * np.asarray(curve["imag"])
            assert np.iscomplexobj(s["data"])
            assert np.max(np.abs(s["data"] - h)) <= 1e-11 * np.max(np.abs(h))


def test_mode_shapes_uff55_read_back(simulation: dict[str, Any], tmp_path: Path) -> None:
    assert uff_available(simulation)
    shapes = simulation["mode_shapes"]
    sets = _read_uff(to_uff(simulation), tmp_path)
    assert len(sets) == len(shapes["t"]) * len(shapes["modes"])
    k = 0
    for j, _t in enumerate(shapes["t"]):
        for mode in shapes["modes"]:
            s = sets[k]
            k += 1
            assert s["type"] == 55 and s["analysis_type"] == 3 and s["mode_n"] == mode["mode"]
            phi = np.asarray(mode["real"][j]) + 1j * np.asarray(mode["imag"][j])
            np.testing.assert_allclose(s["r2"], phi, rtol=0, atol=5e-6)
            np.testing.assert_array_equal(s["node_nums"], np.arange(1, len(shapes["x"]) + 1))
            eig = complex(mode["sigma"][j], mode["omega"][j])
            assert abs(s["eig"] - eig) <= 1e-5 * abs(eig)


def test_uff_refuses_a_result_without_curves_or_shapes() -> None:
    result = COMPUTATIONS["stability"].execute(
        StabilitySpec.model_validate(
            {"pipe": PAPER_PIPE_JSON, "velocity_range": [0, 40], "modes": 4}
        )
    )
    assert not uff_available(result)
    with pytest.raises(ExportError, match="dataset 58"):
        to_uff(result)


def _read_netcdf(data: bytes) -> Any:
    return xr.open_dataset(io.BytesIO(data), engine="scipy").load()


def test_frf_netcdf(frf: dict[str, Any]) -> None:
    ds = _read_netcdf(to_netcdf(frf))
    ref = to_xarray(frf)
    assert ds["H_real"].dims == ref["H"].dims == ("operating_point", "position", "frequency")
    np.testing.assert_array_equal(ds["H_real"].values, ref["H"].values.real)
    np.testing.assert_array_equal(ds["H_imag"].values, ref["H"].values.imag)
    assert ds["H_real"].attrs["units"] == "m/N" and ds["frequency"].attrs["units"] == "rad/s"
    np.testing.assert_array_equal(ds["frequency"].values, frf["frequencies"])
    np.testing.assert_array_equal(ds["stable"].values, [1, 1])


def test_simulation_netcdf(simulation: dict[str, Any]) -> None:
    ds = _read_netcdf(to_netcdf(simulation))
    ref = to_xarray(simulation)
    for name in ("tip_displacement", "sigma", "omega"):
        np.testing.assert_array_equal(ds[name].values, ref[name].values)
        assert ds[name].attrs["units"] == ref[name].attrs["units"]
    np.testing.assert_array_equal(ds["mode_shape_imag"].values, ref["mode_shape"].values.imag)
    assert ds["mode_shape_real"].dims == ("shape_t", "mode", "shape_x")


def test_stability_and_study_netcdf() -> None:
    body = {"pipe": PAPER_PIPE_JSON, "velocity_range": [0, 40], "modes": 4}
    result = COMPUTATIONS["stability"].execute(StabilitySpec.model_validate(body))
    ds = _read_netcdf(to_netcdf(result, inputs=body))
    ref = to_xarray(result, inputs=body)
    for name in ref.data_vars:
        np.testing.assert_array_equal(ds[name].values, ref[name].values)
    assert ds.attrs["input.modes"] == 4


@pytest.mark.parametrize("kind", [*SWEEPS, "study"])
def test_every_other_kind_netcdf(kind: str) -> None:
    """Sweeps, maps, Floquet and a study: every numeric variable of to_xarray read back
    from netCDF-3 equal (NaN where null), units kept (flags as int8 0/1)."""
    if kind == "study":
        base = {"pipe": PAPER_PIPE_JSON, "modes": 3, "time": {"t_end": 0.05, "samples": 11}}
        body: dict[str, Any] = {
            "base": {"kind": "simulation", "spec": base},
            "grid": {"flow.velocity.value": [0.0, 10.0]},
        }
        result = COMPUTATIONS["study"].execute(StudySpec.model_validate(body))
    else:
        body = SWEEPS[kind]
        request = parse(SWEEP_KINDS, body)
        result = computation_for(request).execute(request)
    ds = _read_netcdf(to_netcdf(result, inputs=body))
    ref = to_xarray(result, inputs=body)
    for name, var in ref.data_vars.items():
        if var.dtype.kind in "fiub":
            np.testing.assert_array_equal(ds[name].values, var.values.astype(ds[name].dtype))
            assert ds[name].attrs.get("units") == var.attrs.get("units"), name
    assert ds.attrs["kind"] == kind
