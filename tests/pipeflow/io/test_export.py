"""CSV and Parquet export of results: header names and units, exact round trip, every table."""

from __future__ import annotations

import csv
import io
import sys
from typing import Any

import pytest

from pipeflow.computations import documents
from pipeflow.io.export import (
    SIMULATION_TABLES,
    ExportError,
    available_tables,
    table,
    to_csv,
    to_parquet,
)
from pipeflow.paper import PAPER_PIPE
from pipeflow.profiles import Constant, polynomial
from pipeflow.simulation import Simulation, simulate


@pytest.fixture(scope="module")
def result() -> dict[str, Any]:
    sim = Simulation(
        PAPER_PIPE,
        flow=polynomial(0, 0.4),
        spin=Constant(100.0),
        modes=4,
        t_end=0.2,
        samples=51,
        eigen_modes=2,
        eigen_samples=11,
        positions=(0.0125,),
        include_modal=True,
        mode_shape_times=(0.1,),
        mode_shape_points=9,
    )
    return documents.simulation(simulate(sim))


def _rows(text: str) -> list[list[str]]:
    return list(csv.reader(io.StringIO(text)))


def test_history_header_names_columns_and_units(result: dict[str, Any]) -> None:
    rows = _rows(to_csv(result, "history"))
    header = rows[0]
    assert header[:3] == ["t [s]", "tip_displacement [m]", "u(x=0.0125) [m]"]
    assert header[3:7] == ["d_1 [m]", "d_2 [m]", "d_3 [m]", "d_4 [m]"]
    assert header[7:] == ["ddot_1 [m/s]", "ddot_2 [m/s]", "ddot_3 [m/s]", "ddot_4 [m/s]"]
    assert len(rows) == 1 + len(result["t"])


def test_history_round_trips_floats_exactly(result: dict[str, Any]) -> None:
    rows = _rows(to_csv(result))
    t = [float(r[0]) for r in rows[1:]]
    tip = [float(r[1]) for r in rows[1:]]
    assert t == result["t"]
    assert tip == result["tip_displacement"]
    assert [float(r[3]) for r in rows[1:]] == [d[0] for d in result["modal"]["d"]]


@pytest.mark.parametrize("name", ["eigenvalues", "cma_exponents"])
def test_eigenvalue_tables(result: dict[str, Any], name: str) -> None:
    rows = _rows(to_csv(result, name))
    assert rows[0] == [
        "t [s]",
        "sigma_1 [1/s]",
        "omega_1 [rad/s]",
        "confidence_1 [-]",
        "sigma_2 [1/s]",
        "omega_2 [rad/s]",
        "confidence_2 [-]",
    ]
    block = result[name]
    assert [float(r[2]) for r in rows[1:]] == block["modes"][0]["omega"]
    assert [float(r[4]) for r in rows[1:]] == block["modes"][1]["sigma"]


def test_available_tables_and_errors(result: dict[str, Any]) -> None:
    assert available_tables(result) == list(SIMULATION_TABLES)
    with pytest.raises(ExportError, match="unknown table 'nope'") as err:
        to_csv(result, "nope")
    assert err.value.field == "table"
    with pytest.raises(ExportError, match="no 'eigenvalues' table"):
        to_csv({"t": [0.0], "tip_displacement": [0.0]}, "eigenvalues")


def test_lines_end_with_crlf(result: dict[str, Any]) -> None:
    text = to_csv(result, "eigenvalues")
    assert text.endswith("\r\n")
    assert text.count("\r\n") == len(result["eigenvalues"]["t"]) + 1


@pytest.mark.parametrize("name", SIMULATION_TABLES)
def test_parquet_round_trips_every_table_with_units(result: dict[str, Any], name: str) -> None:
    """Parquet holds the CSV table's columns under the bare names, float64, bit-identical to
    the JSON floats, with the unit of the CSV header in each field's metadata."""
    pq = pytest.importorskip("pyarrow.parquet")  # in the dev extra: CI runs this
    back = pq.read_table(io.BytesIO(to_parquet(result, name)))
    header, columns = table(result, name)
    assert back.schema.metadata[b"table"] == name.encode()
    for label, values, fld in zip(header, columns, back.schema, strict=True):
        assert f"{fld.name} [{fld.metadata[b'unit'].decode()}]" == label
        assert str(fld.type) == "double"
        assert back.column(fld.name).to_pylist() == values
    if name == "history":
        assert back.column("tip_displacement").to_pylist() == result["tip_displacement"]
        assert back.schema.field("ddot_1").metadata[b"unit"] == b"m/s"


def test_parquet_without_pyarrow_says_how_to_install(
    result: dict[str, Any], monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setitem(sys.modules, "pyarrow", None)  # import pyarrow now raises
    with pytest.raises(ImportError, match=r"pip install 'pipeflow\[parquet\]'"):
        to_parquet(result, "history")
    with pytest.raises(ExportError, match="unknown table"):  # the table is checked first
        to_parquet(result, "nope")
