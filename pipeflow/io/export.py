"""CSV and Parquet export of a simulation result: time histories, eigenvalue traces, shapes.

Works on the JSON form of a result (:func:`pipeflow.computations.documents.simulation`, which is
also what the service stores), so the command line, the service and a notebook export the
same bytes.  Every table has one header row naming each column and its SI unit in
brackets, e.g. ``t [s],tip_displacement [m]``; numbers are written with Python's shortest
round-trip representation, so reading the CSV back gives the identical floats.

Tables
------
``history``
    ``t [s]``, ``tip_displacement [m]`` (u(L, t)), one ``u(x=<x>) [m]`` column per
    requested station x [m], and, when the result carries modal coordinates,
    ``d_j [m]`` and ``ddot_j [m/s]``.
``eigenvalues``
    Tracked eigenvalues xi = sigma + i omega of the frozen state matrix S(t):
    ``t [s]`` then ``sigma_j [1/s]`` (damping, negative: decaying), ``omega_j [rad/s]``
    (frequency) and ``confidence_j [-]`` (tracking confidence, 0..1) for each branch j.
``cma_exponents``
    The same columns for the eigenvalues of P(t)/t, the exponents the paper's CMA applies.
``mode_shapes``
    When the result carries mode shapes (``output.mode_shapes``): ``x [m]`` then, for each
    time t and branch j, ``real_j(t=<t>) [-]`` and ``imag_j(t=<t>) [-]`` of the normalised
    complex shape (:mod:`pipeflow.modeshapes`).
``frequency_response``
    A frequency response (:mod:`pipeflow.schema.frequency`): ``frequency [rad/s]`` then,
    per operating point and position, ``real``, ``imag``, ``magnitude`` of H in the
    result's unit (``m/N``, ...) and ``phase [rad]``; the column names carry the position
    (``magnitude(x=0.025) [m/N]``) and, with several operating points, the point
    (``magnitude(v=5.0,w0=100.0,x=0.025) [m/N]``).  An unbounded value (a frequency on an
    undamped resonance) is an empty cell.
``peaks``
    Its resonances inside the range, one row per operating point and mode: ``velocity
    [m/s]``, ``omega0 [rad/s]``, ``mode [-]``, ``frequency [rad/s]``,
    ``natural_frequency [rad/s]``, ``damping_ratio [-]`` and ``|H|`` at the peak per
    position (``magnitude(x=0.025) [m/N]``).
``study``
    A design study's table (:mod:`pipeflow.computations.study_runner`): one row per case, its
    columns as the result names them, each number's unit in brackets (``pipe.E [Pa]``,
    ``peak_tip_displacement [m]``); text and flag columns (``key``, ``status``) have none.

Parquet (:func:`to_parquet`, needs the optional ``pyarrow``: ``pip install
'pipeflow[parquet]'``) writes the same tables with the bare column names (``t``,
``tip_displacement``, ...) and each column's unit in its field metadata (``unit``), float64
throughout (but for the study's text and flag columns: string, bool), so the values are the
identical floats.
"""

from __future__ import annotations

import csv
import io
import json
from collections.abc import Iterable, Sequence
from typing import Any

from pipeflow.optional import require

#: table name -> one-line description (units in the column headers)
TABLES: dict[str, str] = {
    "history": "time history: t [s], tip displacement [m], stations [m], modal coordinates",
    "eigenvalues": "frozen-time eigenvalues of S(t): sigma [1/s], omega [rad/s] per branch",
    "cma_exponents": "eigenvalues of P(t)/t (the CMA exponents): sigma [1/s], omega [rad/s]",
    "mode_shapes": "complex mode shapes along x [m]: real and imaginary parts [-] per time",
    "study": "a design study: one row per case, its overrides and summaries (units in the header)",
    "frequency_response": "frequency response: frequency [rad/s], real, imag, magnitude of H "
    "(in its unit) and phase [rad] per operating point and position",
    "peaks": "resonances of a frequency response: operating point, mode, frequency [rad/s], "
    "damping ratio [-], |H| at the peak per position",
}

#: the tables of a frequency response's result
FREQUENCY_TABLES: tuple[str, ...] = ("frequency_response", "peaks")
#: the tables of a simulation's result (all but a study's and a frequency response's)
SIMULATION_TABLES: tuple[str, ...] = tuple(
    t for t in TABLES if t != "study" and t not in FREQUENCY_TABLES
)

CSV_MEDIA_TYPE = "text/csv"
PARQUET_MEDIA_TYPE = "application/vnd.apache.parquet"


class ExportError(ValueError):
    """The requested table cannot be made from this result (names the table)."""

    def __init__(self, message: str, field: str = "table") -> None:
        super().__init__(message)
        self.message = message
        self.field = field


def available_tables(result: dict[str, Any]) -> list[str]:
    """Names of the tables that :func:`to_csv` can produce from ``result``."""
    names = []
    if "t" in result and "tip_displacement" in result:
        names.append("history")
    for name in ("eigenvalues", "cma_exponents"):
        if isinstance(result.get(name), dict) and result[name].get("modes"):
            names.append(name)
    if isinstance(result.get("mode_shapes"), dict) and result["mode_shapes"].get("modes"):
        names.append("mode_shapes")
    if result.get("kind") == "study" and "rows" in result:
        names.append("study")
    if result.get("kind") == "frequency_response" and result.get("operating_points"):
        names += list(FREQUENCY_TABLES)
    return names


def table(result: dict[str, Any], name: str = "history") -> tuple[list[str], list[list[Any]]]:
    """Header (``"name [unit]"`` strings) and columns of table ``name`` of ``result``."""
    if name not in TABLES:
        raise ExportError(f"unknown table {name!r}; choose one of {', '.join(TABLES)}")
    if name not in available_tables(result):
        raise ExportError(f"this result has no {name!r} table")
    if name == "history":
        return _history(result)
    if name == "mode_shapes":
        return _shapes(result["mode_shapes"])
    if name == "study":
        return _study(result)
    if name == "frequency_response":
        return _frf(result)
    if name == "peaks":
        return _peaks(result)
    return _traces(result[name])


def split_header(label: str) -> tuple[str, str]:
    """``"t [s]"`` -> ``("t", "s")``: a column name and its unit (``""`` for a text column,
    whose header has none: ``"key"``)."""
    if not label.endswith("]") or " [" not in label:
        return label, ""
    name, _, unit = label.rpartition(" [")
    return name, unit.removesuffix("]")


def _history(result: dict[str, Any]) -> tuple[list[str], list[list[float]]]:
    header = ["t [s]", "tip_displacement [m]"]
    columns: list[list[float]] = [list(result["t"]), list(result["tip_displacement"])]
    for station in result.get("displacements", []):
        header.append(f"u(x={_num(station['x'])}) [m]")
        columns.append(list(station["u"]))
    modal = result.get("modal")
    if modal:
        for key, unit in (("d", "m"), ("ddot", "m/s")):
            rows = modal[key]
            n = len(rows[0]) if rows else 0
            for j in range(n):
                header.append(f"{key}_{j + 1} [{unit}]")
                columns.append([r[j] for r in rows])
    return header, columns


def _traces(block: dict[str, Any]) -> tuple[list[str], list[list[float]]]:
    header = ["t [s]"]
    columns: list[list[float]] = [list(block["t"])]
    for mode in block["modes"]:
        j = mode["mode"]
        header += [f"sigma_{j} [1/s]", f"omega_{j} [rad/s]", f"confidence_{j} [-]"]
        columns += [list(mode["sigma"]), list(mode["omega"]), list(mode["confidence"])]
    return header, columns


def _shapes(block: dict[str, Any]) -> tuple[list[str], list[list[float]]]:
    header = ["x [m]"]
    columns: list[list[float]] = [list(block["x"])]
    for i, t in enumerate(block["t"]):
        for mode in block["modes"]:
            j = mode["mode"]
            header += [f"real_{j}(t={_num(t)}) [-]", f"imag_{j}(t={_num(t)}) [-]"]
            columns += [list(mode["real"][i]), list(mode["imag"][i])]
    return header, columns


def _study(result: dict[str, Any]) -> tuple[list[str], list[list[Any]]]:
    header = [f"{c['name']} [{c['unit']}]" if c["unit"] else c["name"] for c in result["columns"]]
    rows = result["rows"]
    return header, [[row[j] for row in rows] for j in range(len(header))]


def _point_label(result: dict[str, Any], point: dict[str, Any], x: float) -> str:
    """``x=0.025``, or ``v=5.0,w0=100.0,x=0.025`` when the result has several points."""
    where = f"x={_num(x)}"
    if len(result["operating_points"]) > 1:
        where = f"v={_num(point['velocity'])},w0={_num(point['omega0'])},{where}"
    return where


def _frf(result: dict[str, Any]) -> tuple[list[str], list[list[Any]]]:
    unit = result["unit"]
    header = ["frequency [rad/s]"]
    columns: list[list[Any]] = [list(result["frequencies"])]
    for point in result["operating_points"]:
        for curve in point["responses"]:
            where = _point_label(result, point, curve["position"])
            for part, u in (("real", unit), ("imag", unit), ("magnitude", unit), ("phase", "rad")):
                header.append(f"{part}({where}) [{u}]")
                columns.append(list(curve[part]))
    return header, columns


def _peaks(result: dict[str, Any]) -> tuple[list[str], list[list[Any]]]:
    unit = result["unit"]
    names = [
        ("velocity", "m/s"),
        ("omega0", "rad/s"),
        ("mode", "-"),
        ("frequency", "rad/s"),
        ("natural_frequency", "rad/s"),
        ("damping_ratio", "-"),
    ]
    header = [f"{n} [{u}]" for n, u in names]
    header += [f"magnitude(x={_num(x)}) [{unit}]" for x in result["positions"]]
    rows = []
    for point in result["operating_points"]:
        for peak in point["peaks"]:
            row = [point["velocity"], point["omega0"]]
            row += [peak[n] for n, _ in names[2:]]
            rows.append(row + list(peak["magnitude"]))
    return header, [[row[j] for row in rows] for j in range(len(header))]


def _num(x: Any) -> str:
    return repr(float(x))


def _cell(x: Any) -> str:
    """A CSV cell: numbers round-trip (integers as integers), text as is, flags as
    true/false, null empty."""
    if x is None:
        return ""
    if isinstance(x, bool):
        return "true" if x else "false"
    if isinstance(x, str):
        return x
    if isinstance(x, int):
        return str(x)
    return _num(x)


def write_csv(header: Sequence[str], columns: Sequence[Sequence[Any]]) -> str:
    """CSV text (``\\r\\n`` line ends, RFC 4180) of equal-length ``columns`` under ``header``."""
    lengths = {len(c) for c in columns}
    if len(lengths) > 1:
        raise ExportError(f"columns have different lengths {sorted(lengths)}")
    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator="\r\n")
    writer.writerow(header)
    rows: Iterable[tuple[Any, ...]] = zip(*columns, strict=True)
    writer.writerows([_cell(x) for x in row] for row in rows)
    return buf.getvalue()


def to_csv(result: dict[str, Any], name: str = "history") -> str:
    """Table ``name`` (see :data:`TABLES`) of a JSON result as CSV text with a unit header."""
    header, columns = table(result, name)
    return write_csv(header, columns)


def _arrow_type(pa: Any, values: Sequence[Any]) -> Any:
    """float64 for numbers (every table but the study's text and flag columns)."""
    present = [v for v in values if v is not None]
    if present and all(isinstance(v, str) for v in present):
        return pa.string()
    if present and all(isinstance(v, bool) for v in present):
        return pa.bool_()
    return pa.float64()


def to_parquet(result: dict[str, Any], name: str = "history") -> bytes:
    """Table ``name`` of a JSON result as Parquet bytes: bare column names, float64 columns,
    each field's metadata ``{"unit": ...}`` (SI), the table's name and description in the
    schema metadata.  Needs the optional ``pyarrow`` (``pip install 'pipeflow[parquet]'``)."""
    header, columns = table(result, name)
    pa = require("pyarrow", "parquet", "Parquet export")
    pq = require("pyarrow.parquet", "parquet", "Parquet export")

    fields, arrays, units = [], [], {}
    for label, values in zip(header, columns, strict=True):
        col, unit = split_header(label)
        kind = _arrow_type(pa, values)
        fields.append(pa.field(col, kind, metadata={"unit": unit}))
        arrays.append(pa.array(values, type=kind))
        units[col] = unit
    meta = {
        "table": name,
        "description": TABLES[name],
        # pandas (>= 2.1) restores DataFrame.attrs from this key on read_parquet: the units
        # reach a notebook as pipeflow.io.notebook.to_dataframe gives them
        "PANDAS_ATTRS": json.dumps({"units": units, "table": name}),
    }
    schema = pa.schema(fields, metadata=meta)
    buf = pa.BufferOutputStream()
    pq.write_table(pa.Table.from_arrays(arrays, schema=schema), buf)
    return bytes(buf.getvalue().to_pybytes())
