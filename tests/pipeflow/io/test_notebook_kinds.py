"""Notebook views of every result kind (issue 24): xarray with units and the inputs in
attrs; Parquet read back by pandas keeps the units.

Each Dataset's numbers are the result document's own (compared exactly: the same floats
copied into arrays, null becoming NaN); the inputs given are found whole and flattened in
``attrs``.
"""

from __future__ import annotations

import io
import json
from typing import Any

import numpy as np
import pytest

from pipeflow.computations.registry import COMPUTATIONS, SWEEP_KINDS, computation_for, parse
from pipeflow.io.export import to_parquet
from pipeflow.io.notebook import to_dataframe, to_xarray
from pipeflow.paper import PAPER_PIPE
from pipeflow.profiles import Constant
from pipeflow.schema.stability import PAPER_PIPE_JSON, StabilitySpec
from pipeflow.schema.study import StudySpec
from pipeflow.simulation import Simulation, simulate

pytest.importorskip("xarray")
pytest.importorskip("pandas")

SWEEPS: dict[str, dict[str, Any]] = {
    "argand": {"kind": "argand", "pipe": PAPER_PIPE_JSON, "modes": 4, "velocity_range": [0, 40]},
    "campbell": {"kind": "campbell", "pipe": PAPER_PIPE_JSON, "modes": 4, "spin_range": [0, 300]},
    "spin_map": {
        "kind": "spin_map",
        "pipe": PAPER_PIPE_JSON,
        "modes": 4,
        "velocity_range": [0, 40],
        "spin_range": [0, 300],
        "velocity_points": 6,
        "spin_points": 3,
    },
    "beta_map": {
        "kind": "beta_map",
        "modes": 4,
        "beta_range": [0.1, 0.5],
        "u_range": [0, 15],
        "beta_points": 3,
        "u_points": 11,
    },
    "resonance_chart": {
        "kind": "resonance_chart",
        "pipe": {"E": 1.0, "I": 1.0, "L": 1.0, "M1": 0.8, "M2": 0.2},
        "modes": 3,
        "mean_velocity": 8.944,
        "amplitude_range": [0, 7.2],
        "frequency_range": [25, 43],
        "amplitude_points": 3,
        "frequency_points": 4,
    },
    "floquet": {
        "kind": "floquet",
        "pipe": PAPER_PIPE_JSON,
        "modes": 2,
        "flow": {"velocity": {"kind": "harmonic", "mean": 10, "amplitude": 5, "frequency": 1e3}},
    },
}

#: per kind: a variable of the Dataset, its unit, and the document's numbers it holds
EXPECTED = {
    "argand": ("sigma", "1/s", lambda r: [m["sigma"] for m in r["modes"]], True),
    "campbell": ("omega", "rad/s", lambda r: [m["omega"] for m in r["modes"]], True),
    "spin_map": ("growth_rate", "1/s", lambda r: r["growth_rate"], False),
    "beta_map": ("u_cr", "1", lambda r: r["u_cr"], False),
    "resonance_chart": ("growth_rate", "1/s", lambda r: r["growth_rate"], False),
    "floquet": ("exponent_sigma", "1/s", lambda r: r["exponents"]["sigma"], False),
}


def _nan(a: Any) -> Any:
    return np.array(a, dtype=object).astype(float)  # None -> nan


@pytest.mark.parametrize("kind", list(SWEEPS))
def test_sweeps_and_maps(kind: str) -> None:
    body = SWEEPS[kind]
    request = parse(SWEEP_KINDS, body)
    result = computation_for(request).execute(request)
    ds = to_xarray(result, inputs=body)
    name, unit, numbers, transposed = EXPECTED[kind]
    want = _nan(numbers(result))
    got = ds[name].values.T if transposed else ds[name].values
    np.testing.assert_array_equal(got, want)
    assert ds[name].attrs["units"] == unit
    assert ds.attrs["kind"] == kind
    assert json.loads(ds.attrs["inputs"]) == body
    assert ds.attrs["input.modes"] == body["modes"]
    if "pipe" in body:
        assert ds.attrs["input.pipe.L"] == body["pipe"]["L"]


def test_stability() -> None:
    body = {"pipe": PAPER_PIPE_JSON, "velocity_range": [0, 40], "modes": 4}
    result = COMPUTATIONS["stability"].execute(StabilitySpec.model_validate(body))
    ds = to_xarray(result, inputs=body)
    assert ds.attrs["critical_velocity"] == result["critical_velocity"]
    assert ds["crossing_velocity"].attrs["units"] == "m/s"
    np.testing.assert_array_equal(
        ds["crossing_velocity"].values, [c["velocity"] for c in result["crossings"]]
    )
    assert ds.attrs["input.velocity_range"] == [0, 40]


def test_study() -> None:
    base = {"pipe": PAPER_PIPE_JSON, "modes": 3, "time": {"t_end": 0.05, "samples": 11}}
    body = {
        "base": {"kind": "simulation", "spec": base},
        "grid": {"flow.velocity.value": [0.0, 10.0]},
    }
    result = COMPUTATIONS["study"].execute(StudySpec.model_validate(body))
    ds = to_xarray(result, inputs=body)
    names = [c["name"] for c in result["columns"]]
    j = names.index("peak_tip_displacement")
    np.testing.assert_array_equal(
        ds["peak_tip_displacement"].values, [row[j] for row in result["rows"]]
    )
    assert ds["peak_tip_displacement"].attrs["units"] == "m"
    assert ds.sizes["case"] == 2
    assert json.loads(ds.attrs["inputs"]) == body


def test_a_local_simulation_brings_its_inputs() -> None:
    r = simulate(Simulation(PAPER_PIPE, Constant(5.0), Constant(100.0), modes=3, samples=11))
    ds = to_xarray(r)
    assert ds.attrs["input.simulation.pipe.L"] == PAPER_PIPE.L
    assert ds.attrs["input.simulation.modes"] == 3
    assert ds.attrs["status"] == "ok" and ds.attrs["divergence_bound"] == r.divergence_bound


def test_parquet_read_by_pandas_keeps_the_units() -> None:
    import pandas as pd

    pytest.importorskip("pyarrow")
    r = simulate(Simulation(PAPER_PIPE, Constant(5.0), Constant(100.0), modes=3, samples=11))
    from pipeflow.computations import documents

    doc = documents.simulation(r)
    for table in ("history", "eigenvalues"):
        frame = pd.read_parquet(io.BytesIO(to_parquet(doc, table)))
        assert frame.attrs["units"] == to_dataframe(doc, table).attrs["units"]
        assert frame.attrs["table"] == table
    assert frame.attrs["units"]["t"] == "s"
