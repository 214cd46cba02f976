"""Universal file (UFF), netCDF and MATLAB export of a JSON result (issue 32), for
modal-test, data and control tools (MATLAB: :func:`to_mat`, a state-space result).

UFF (:func:`to_uff`, needs ``pyuff``: ``pip install 'pipeflow[formats]'``), ASCII:

- a frequency response: one **dataset 58** record per operating point x position,
  function type 4 (frequency response function), complex double ordinate (the response
  per unit load, H in the result's unit: m/N, m/(N s), 1/kg, or per unit clamp
  acceleration s^2, s, -), abscissa the frequency in **Hz** (W / 2 pi, as the format
  expects; uneven spacing, so every abscissa value is written).  ASCII: the ordinate
  with 12 significant digits (E20.11), the abscissa with 6 (E13.5, the format's field for
  an uneven abscissa of a double-precision record).  Response node = position
  index + 1 (record ``id4`` gives x [m]), direction +Y (transverse), reference node = the
  load's (0 for a clamp acceleration); ``id3`` names the operating point (v [m/s], w0
  [rad/s]); the units are in the record's axis labels.
- a simulation with mode shapes (``output.mode_shapes``): one **dataset 55** record per
  time and branch, complex eigenvalue analysis (type 3): eigenvalue sigma + i omega [1/s],
  the normalised complex shape (max modulus 1) as the Y component at nodes 1..n (``id4``
  lists the stations x [m]); the time [s] in ``id3``; 6 significant digits (E13.5).

netCDF (:func:`to_netcdf`, needs ``xarray``; written with xarray's ``scipy`` engine,
netCDF-3 64-bit offset, so no HDF5 or netCDF-C library): the Dataset of
:func:`pipeflow.io.notebook.to_xarray` for every result kind (its dims, coordinates and
``units`` attributes).  netCDF-3 has no complex, 64-bit integer or boolean type: a complex
variable ``H`` becomes ``H_real`` and ``H_imag`` (same dims and units), integers int32,
flags int8 (0/1), and ``None`` attributes are left out.
"""

from __future__ import annotations

import io
import math
from typing import Any

import numpy as np

from pipeflow.io.export import ExportError
from pipeflow.optional import require

UFF_MEDIA_TYPE = "application/vnd.uff"
MAT_MEDIA_TYPE = "application/x-matlab-data"
NETCDF_MEDIA_TYPE = "application/x-netcdf"

#: UFF 58 specific data types of the ordinate (numerator) by quantity (the format's table)
_ORDINATE = {"displacement": 8, "velocity": 11, "acceleration": 12}
#: UFF 58 length / force exponents of the ordinate unit [length, force] per result unit
_EXPONENTS = {
    "m/N": (1, -1),
    "m/(N s)": (1, -1),
    "1/kg": (1, -1),  # m/(N s^2)
    "s^2": (0, 0),
    "s": (0, 0),
    "-": (0, 0),
}


def uff_available(result: dict[str, Any]) -> bool:
    """Whether :func:`to_uff` can write ``result``: a frequency response, or a simulation
    that carries mode shapes."""
    if result.get("kind") == "frequency_response" and result.get("operating_points"):
        return True
    shapes = result.get("mode_shapes")
    return isinstance(shapes, dict) and bool(shapes.get("modes"))


def uff_records(result: dict[str, Any]) -> list[dict[str, Any]]:
    """The pyuff dataset dictionaries (58 or 55) of ``result`` (see the module docstring)."""
    pyuff = require("pyuff", "formats", "UFF export")
    if result.get("kind") == "frequency_response" and result.get("operating_points"):
        return _frf_records(pyuff, result)
    if uff_available(result):
        return _shape_records(pyuff, result)
    raise ExportError(
        "UFF holds frequency responses (dataset 58) and mode shapes (dataset 55); this "
        "result has neither (ask for a simulation with output.mode_shapes)",
        "format",
    )


def _frf_records(pyuff: Any, result: dict[str, Any]) -> list[dict[str, Any]]:
    unit = result["unit"]
    quantity = result["quantity"]
    load = result["load"]
    point_force = load.get("kind") == "point_force"
    length_exp, force_exp = _EXPONENTS.get(unit, (0, 0))
    hz = np.asarray(result["frequencies"], dtype=float) / (2 * math.pi)
    positions = result["positions"]
    ref_node = positions.index(load["position"]) + 1 if load.get("position") in positions else 0
    records = []
    for p, point in enumerate(result["operating_points"]):
        for i, curve in enumerate(point["responses"]):
            re = np.array([np.nan if v is None else v for v in curve["real"]], dtype=float)
            im = np.array([np.nan if v is None else v for v in curve["imag"]], dtype=float)
            what = "force" if point_force else "clamp acceleration"
            records.append(
                pyuff.prepare_58(
                    id1=f"pipeflow {quantity} per unit {what} [{unit}]",
                    id2=f"operating point {p + 1}, position {i + 1}",
                    id3=f"v = {point['velocity']!r} m/s, w0 = {point['omega0']!r} rad/s",
                    id4=f"x = {curve['position']!r} m",
                    id5=_load_text(load),
                    func_type=4,
                    ord_data_type=6,
                    load_case_id=p + 1,
                    rsp_node=i + 1,
                    rsp_dir=2,
                    ref_node=ref_node,
                    ref_dir=2 if point_force else 0,
                    abscissa_spacing=0,
                    abscissa_spec_data_type=18,
                    abscissa_axis_units_lab="Hz",
                    ordinate_spec_data_type=_ORDINATE[quantity],
                    ordinate_len_unit_exp=length_exp,
                    ordinate_force_unit_exp=force_exp,
                    ordinate_axis_units_lab=unit,
                    orddenom_spec_data_type=13 if point_force else 12,
                    orddenom_axis_units_lab="N" if point_force else "m/s^2",
                    data=re + 1j * im,
                    x=hz,
                )
            )
    return records


def _load_text(load: dict[str, Any]) -> str:
    if load.get("kind") == "point_force":
        return f"point force at x = {load['position']!r} m"
    return "clamp acceleration"


def _shape_records(pyuff: Any, result: dict[str, Any]) -> list[dict[str, Any]]:
    shapes = result["mode_shapes"]
    x = shapes["x"]
    nodes = np.arange(1, len(x) + 1)
    records = []
    for k, t in enumerate(shapes["t"]):
        for mode in shapes["modes"]:
            phi = np.asarray(mode["real"][k], float) + 1j * np.asarray(mode["imag"][k], float)
            zero = np.zeros_like(phi)
            eig = complex(mode["sigma"][k], mode["omega"][k])
            records.append(
                pyuff.prepare_55(
                    id1=f"pipeflow complex mode shape, branch {mode['mode']}",
                    id2="normalised: max |Phi| = 1 [-]",
                    id3=f"t = {float(t)!r} s",
                    id4="x [m] of nodes 1..n: " + " ".join(repr(float(v)) for v in x)[:70],
                    id5=f"eigenvalue sigma + i omega = {eig!r} 1/s",
                    model_type=1,
                    analysis_type=3,
                    data_ch=2,
                    spec_data_type=8,
                    data_type=5,
                    n_data_per_node=3,
                    r1=zero,
                    r2=phi,
                    r3=zero,
                    load_case=k + 1,
                    mode_n=int(mode["mode"]),
                    eig=eig,
                    modal_a=0j,
                    modal_b=0j,
                    node_nums=nodes,
                )
            )
    return records


def to_uff(result: dict[str, Any]) -> bytes:
    """The UFF (ASCII universal file) of a JSON result: dataset 58 records of a frequency
    response, or dataset 55 records of a simulation's mode shapes (module docstring)."""
    import os
    import tempfile

    pyuff = require("pyuff", "formats", "UFF export")
    records = uff_records(result)
    fd, path = tempfile.mkstemp(suffix=".uff")  # pyuff writes to a path only
    os.close(fd)
    try:
        os.remove(path)
        uff = pyuff.UFF(path)
        uff.write_sets(records, mode="add")
        with open(path, "rb") as fh:
            return fh.read()
    finally:
        if os.path.exists(path):
            os.remove(path)


def _netcdf3(ds: Any) -> Any:
    """``ds`` with netCDF-3 types only (module docstring)."""
    out = ds.copy()
    for name in list(out.variables):
        var = out[name]
        if np.iscomplexobj(var.values):
            attrs = dict(var.attrs)
            for part, values in (("real", var.values.real), ("imag", var.values.imag)):
                out[f"{name}_{part}"] = (var.dims, values, {**attrs, "part": part})
            out = out.drop_vars(name)
        elif var.dtype == bool:
            out[name] = var.astype(np.int8)
        elif var.dtype.kind in "iu" and var.dtype.itemsize > 4:
            out[name] = var.astype(np.int32)
    out.attrs = {k: v for k, v in out.attrs.items() if v is not None}
    for k, v in out.attrs.items():
        if isinstance(v, bool):
            out.attrs[k] = int(v)
    return out


def to_netcdf(result: Any, inputs: dict[str, Any] | None = None) -> bytes:
    """The netCDF (classic, 64-bit offset) bytes of any result: the Dataset of
    :func:`pipeflow.io.notebook.to_xarray` (dims, coordinates, ``units`` attributes), with
    complex variables split into ``_real`` / ``_imag``.  ``inputs``: the request, kept in
    the attributes as ``to_xarray`` keeps it."""
    require("xarray", "formats", "netCDF export")
    require("scipy.io", "formats", "netCDF export")
    from pipeflow.io.notebook import to_xarray

    ds = _netcdf3(to_xarray(result, inputs))
    data = ds.to_netcdf(path=None, engine="scipy", format="NETCDF3_64BIT")
    return bytes(data)


def to_mat(result: dict[str, Any]) -> bytes:
    """A state-space result (``kind: state_space``) as a MATLAB 5 file
    (:func:`scipy.io.savemat`): the matrices ``A``, ``B``, ``C``, ``D`` (double), the
    cell arrays of names ``states``, ``inputs``, ``outputs``, the operating point
    ``velocity`` [m/s] and ``omega0`` [rad/s], ``positions`` [m] and a struct ``units``
    (``sys = ss(A, B, C, D)`` in MATLAB)."""
    import scipy.io

    if result.get("kind") != "state_space":
        raise ExportError(
            "a MATLAB file holds a state-space result (POST /v1/state-space)", "format"
        )
    out: dict[str, Any] = {k: np.asarray(result[k], dtype=float) for k in ("A", "B", "C", "D")}
    for k in ("states", "inputs", "outputs"):
        out[k] = np.array(result[k], dtype=object)
    out["velocity"] = float(result["velocity"])
    out["omega0"] = float(result["omega0"])
    out["positions"] = np.asarray(result["positions"], dtype=float)
    out["units"] = dict(result["units"])
    buf = io.BytesIO()
    scipy.io.savemat(buf, out, do_compression=True)
    return buf.getvalue()
