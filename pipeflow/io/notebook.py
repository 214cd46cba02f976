"""Results in a notebook: xarray Dataset, pandas DataFrame, matplotlib Figure.

Works on the JSON form of a result (:func:`pipeflow.computations.documents.simulation`, which is
also what the service returns): every function takes that dictionary, a local
:class:`~pipeflow.simulation.Result` or the client's :class:`pipeflow_client.SimulationResult`
and gives the same objects (``to_xarray(result)``; the client's result offers them as
methods too, through :class:`NotebookViews`).  xarray and pandas are the optional
``notebook`` extra (``pip install 'pipeflow[notebook]'``), imported on first use.

Dataset layout (:func:`to_xarray`), every variable with ``units`` (SI) and ``long_name``:

- ``tip_displacement(t)`` [m]; ``displacement(x, t)`` [m] at the requested stations;
  ``d(t, galerkin)`` [m] and ``ddot(t, galerkin)`` [m/s] when modal coordinates were asked;
- ``sigma(eigen_t, mode)`` [1/s], ``omega(eigen_t, mode)`` [rad/s] and
  ``confidence(eigen_t, mode)`` [-]: the tracked frozen eigenvalues (``mode`` is the branch
  number, 1 = lowest frequency at t = 0), ``cma_sigma``/``cma_omega`` for P(t)/t;
- ``mode_shape(shape_t, mode, shape_x)`` [-] (complex) when mode shapes were asked.

A frequency response (``kind`` ``frequency_response``) has its own layout:
``H(operating_point, position, frequency)`` (complex, in the result's unit per unit load:
m/N, ...), ``magnitude`` and ``phase`` [rad] alike; coordinates ``frequency`` [rad/s],
``position`` [m], ``operating_point`` (0, 1, ...) with ``velocity`` [m/s] and ``omega0``
[rad/s] along it; ``stable(operating_point)`` and ``max_growth_rate(operating_point)``
[1/s]; unbounded values (on an undamped resonance) are NaN.

Every other kind has its Dataset too (``crossing`` rows of a critical-velocity analysis;
``(velocity or spin, mode)`` of an Argand or Campbell sweep; ``(spin, velocity)`` of a spin
map; ``beta`` of a beta map; ``(amplitude, frequency)`` of a resonance chart; ``index`` of
the Floquet multipliers; ``case`` of a study, a variable per column), every variable with
its SI ``units``.  Each Dataset's ``attrs`` hold the result's own scalars (key, kind,
status, critical velocity [m/s] ...) and the inputs: ``inputs`` (the request, JSON text)
and its scalars flattened (``input.pipe.L``), from ``to_xarray(result, inputs=spec)`` or,
for a local simulation result, from its :class:`~pipeflow.simulation.Simulation`.
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

from pipeflow.io.export import split_header, table
from pipeflow.optional import require

if TYPE_CHECKING:
    from matplotlib.figure import Figure


def document(result: Any) -> dict[str, Any]:
    """The JSON form of ``result``: a dictionary as it is, a :class:`NotebookViews`'s
    ``_document()``, else that of a local :class:`~pipeflow.simulation.Result`
    (:func:`pipeflow.computations.documents.simulation`, imported on first use)."""
    if isinstance(result, Mapping):
        return dict(result)
    if isinstance(result, NotebookViews):
        return result._document()
    from pipeflow.computations import documents

    return documents.simulation(result)


def inputs_of(result: Any) -> dict[str, Any] | None:
    """The inputs of a local :class:`~pipeflow.simulation.Result` (its
    :class:`~pipeflow.simulation.Simulation`, profiles and options as their fields), or
    None for a JSON result (the service's documents carry no request: pass ``inputs``)."""
    import dataclasses

    from pipeflow.simulation import Simulation

    sim = getattr(result, "simulation", None)
    if not isinstance(sim, Simulation):
        return None
    return {"simulation": json.loads(json.dumps(dataclasses.asdict(sim), default=repr))}


def _flat(prefix: str, value: Any, out: dict[str, Any]) -> None:
    """``value``'s scalars under dotted names (lists of numbers kept as lists)."""
    if isinstance(value, Mapping):
        for k, v in value.items():
            _flat(f"{prefix}.{k}" if prefix else str(k), v, out)
    elif isinstance(value, bool):
        out[prefix] = int(value)  # netCDF attributes have no booleans
    elif isinstance(value, int | float | str):
        out[prefix] = value
    elif (
        isinstance(value, list)
        and value
        and all(isinstance(v, int | float) and not isinstance(v, bool) for v in value)
    ):
        out[prefix] = list(value)


def input_attrs(result: dict[str, Any], inputs: Mapping[str, Any] | None) -> dict[str, Any]:
    """The attributes every view carries: the result's own scalars (key, kind, status,
    critical_velocity [m/s], ...) and, when known, the inputs, both whole (``inputs``: the
    request as JSON text) and flattened (``input.pipe.L`` = 0.025, SI as in the request)."""
    attrs: dict[str, Any] = {}
    for k, v in result.items():
        if k in ("warnings", "plots", "cached"):
            continue
        if isinstance(v, bool):
            attrs[k] = int(v)
        elif isinstance(v, int | float | str):
            attrs[k] = v
    if result.get("warnings"):
        attrs["warnings"] = "\n".join(result["warnings"])
    if inputs:
        attrs["inputs"] = json.dumps(inputs, sort_keys=True)
        flat: dict[str, Any] = {}
        _flat("", dict(inputs), flat)
        attrs.update({f"input.{k}": v for k, v in flat.items()})
    return attrs


def to_xarray(result: Any, inputs: Mapping[str, Any] | None = None) -> Any:
    """The result as an :class:`xarray.Dataset` (see the module docstring for its layout),
    for every kind of result: simulation, stability, argand/campbell sweeps, spin and beta
    maps, resonance chart, Floquet, study and frequency response.  ``inputs``: the request
    (JSON form), stored in ``attrs`` (a local simulation result brings its own)."""
    xr = require("xarray", "notebook", "to_xarray()")
    import numpy as np

    if inputs is None:
        inputs = inputs_of(result)
    result = document(result)

    def var(dims: tuple[str, ...], data: Any, units: str, long_name: str) -> Any:
        return xr.Variable(dims, np.asarray(data), {"units": units, "long_name": long_name})

    kind = result.get("kind")
    view = _VIEWS.get(kind) if isinstance(kind, str) else None
    if view is not None:
        ds = view(xr, var, result)
        ds.attrs.update(input_attrs(result, inputs))
        return ds

    coords: dict[str, Any] = {
        "t": var(("t",), result["t"], "s", "time"),
        "eigen_t": var(("eigen_t",), result["eigenvalues"]["t"], "s", "time of the eigenvalues"),
        "mode": var(
            ("mode",),
            [m["mode"] for m in result["eigenvalues"]["modes"]],
            "1",
            "eigenvalue branch (1 = lowest frequency at t = 0)",
        ),
    }
    data: dict[str, Any] = {
        "tip_displacement": var(("t",), result["tip_displacement"], "m", "tip displacement u(L, t)")
    }
    stations = result.get("displacements") or []
    if stations:
        coords["x"] = var(("x",), [s["x"] for s in stations], "m", "station along the pipe")
        data["displacement"] = var(
            ("x", "t"), [s["u"] for s in stations], "m", "displacement u(x, t)"
        )
    for prefix, block, what in (
        ("", result["eigenvalues"], "of the frozen state matrix S(t)"),
        ("cma_", result.get("cma_exponents"), "of P(t)/t (CMA exponents)"),
    ):
        if not block or not block.get("modes"):
            continue
        for part, units, name in (
            ("sigma", "1/s", "damping (real part)"),
            ("omega", "rad/s", "frequency (imaginary part)"),
        ):
            rows = np.asarray([m[part] for m in block["modes"]]).T
            data[prefix + part] = var(("eigen_t", "mode"), rows, units, f"{name} {what}")
        if not prefix:
            rows = np.asarray([m["confidence"] for m in block["modes"]]).T
            data["confidence"] = var(("eigen_t", "mode"), rows, "1", "tracking confidence 0..1")
    modal = result.get("modal")
    if modal:
        n = len(modal["d"][0]) if modal["d"] else 0
        coords["galerkin"] = var(("galerkin",), np.arange(1, n + 1), "1", "Galerkin mode index")
        data["d"] = var(("t", "galerkin"), modal["d"], "m", "modal coordinate d_j")
        data["ddot"] = var(("t", "galerkin"), modal["ddot"], "m/s", "modal velocity d'_j")
    shapes = result.get("mode_shapes")
    if shapes and shapes.get("modes"):
        coords["shape_t"] = var(("shape_t",), shapes["t"], "s", "time of the mode shapes")
        coords["shape_x"] = var(("shape_x",), shapes["x"], "m", "position along the pipe")
        re = np.asarray([m["real"] for m in shapes["modes"]])  # (mode, shape_t, shape_x)
        im = np.asarray([m["imag"] for m in shapes["modes"]])
        data["mode_shape"] = var(
            ("shape_t", "mode", "shape_x"),
            np.transpose(re + 1j * im, (1, 0, 2)),
            "1",
            "complex mode shape of the frozen spectrum, max modulus 1",
        )
    return xr.Dataset(data, coords=coords, attrs=input_attrs(result, inputs))


def _frf_xarray(xr: Any, var: Any, result: dict[str, Any]) -> Any:
    """The Dataset of a frequency response (see the module docstring)."""
    import numpy as np

    def arr(part: str) -> Any:
        return np.array(
            [[c[part] for c in p["responses"]] for p in result["operating_points"]], dtype=float
        )  # null -> nan

    points = result["operating_points"]
    unit = result["unit"]
    dims = ("operating_point", "position", "frequency")
    what = f"{result['quantity']} per unit load"
    coords = {
        "frequency": var(("frequency",), result["frequencies"], "rad/s", "excitation frequency"),
        "position": var(("position",), result["positions"], "m", "position along the pipe"),
        "operating_point": var(
            ("operating_point",), np.arange(len(points)), "1", "operating point index"
        ),
        "velocity": var(
            ("operating_point",), [p["velocity"] for p in points], "m/s", "flow velocity"
        ),
        "omega0": var(("operating_point",), [p["omega0"] for p in points], "rad/s", "spin"),
    }
    data = {
        "H": var(dims, arr("real") + 1j * arr("imag"), unit, f"frequency response: {what}"),
        "magnitude": var(dims, arr("magnitude"), unit, f"|H|: {what}"),
        "phase": var(dims, arr("phase"), "rad", "arg H"),
        "stable": var(("operating_point",), [p["stable"] for p in points], "1", "stable"),
        "max_growth_rate": var(
            ("operating_point",),
            [p["max_growth_rate"] for p in points],
            "1/s",
            "largest growth rate Re xi",
        ),
    }
    return xr.Dataset(data, coords=coords)


def _nan(values: Any) -> Any:
    """null -> NaN, as a float array."""
    import numpy as np

    return np.array(
        [[np.nan if v is None else v for v in row] for row in values]
        if values and isinstance(values[0], list)
        else [np.nan if v is None else v for v in values],
        dtype=float,
    )


def _crossings(var: Any, rows: list[dict[str, Any]], dim: str = "crossing") -> dict[str, Any]:
    """The stability crossings (velocity [m/s], frequency [rad/s], mode, kind, direction)."""
    return {
        "crossing_velocity": var((dim,), [c["velocity"] for c in rows], "m/s", "velocity"),
        "crossing_frequency": var(
            (dim,), [c["frequency"] for c in rows], "rad/s", "frequency of the crossing branch"
        ),
        "crossing_mode": var((dim,), [c["mode"] for c in rows], "1", "branch number"),
        "crossing_kind": var((dim,), [c["kind"] for c in rows], "", "flutter or divergence"),
        "crossing_direction": var(
            (dim,), [c["direction"] for c in rows], "", "loss or gain of stability"
        ),
    }


def _stability_xarray(xr: Any, var: Any, result: dict[str, Any]) -> Any:
    """Critical velocity: one row per crossing of sigma = 0 along the velocity range;
    the critical velocity [m/s] and the verdicts in attrs."""
    return xr.Dataset(_crossings(var, result.get("crossings") or []))


def _sweep_xarray(xr: Any, var: Any, result: dict[str, Any]) -> Any:
    """Argand (against v [m/s]) or Campbell (against w0 [rad/s]) sweep: sigma [1/s],
    omega [rad/s], damping ratio [-], confidence [-] per (parameter, mode)."""
    import numpy as np

    par = result["parameter"]
    name = par["name"]
    coords: dict[str, Any] = {
        name: var((name,), par["values"], par["unit"], f"swept {name}"),
        "mode": var(("mode",), [m["mode"] for m in result["modes"]], "1", "branch number"),
    }
    if "values_rpm" in par:
        coords[f"{name}_rpm"] = var((name,), par["values_rpm"], "rpm", f"{name} in rpm")
    data: dict[str, Any] = {}
    for part, units, what in (
        ("sigma", "1/s", "damping (real part)"),
        ("omega", "rad/s", "frequency (imaginary part)"),
        ("damping_ratio", "1", "damping ratio -sigma/|xi|"),
        ("confidence", "1", "tracking confidence 0..1"),
        ("frequency_hz", "Hz", "frequency |omega|/2 pi"),
    ):
        if all(part in m for m in result["modes"]):
            rows = np.array([_nan(m[part]) for m in result["modes"]]).T
            data[part] = var((name, "mode"), rows, units, what)
    return xr.Dataset(data, coords=coords)


def _spin_map_xarray(xr: Any, var: Any, result: dict[str, Any]) -> Any:
    """Growth rate max sigma [1/s] over (spin [rad/s], velocity [m/s]), critical velocity
    [m/s] per spin."""
    coords = {
        "spin": var(("spin",), result["spins"], "rad/s", "spin w0"),
        "velocity": var(("velocity",), result["velocities"], "m/s", "flow velocity"),
    }
    if "spins_rpm" in result:
        coords["spin_rpm"] = var(("spin",), result["spins_rpm"], "rpm", "spin in rpm")
    data = {
        "growth_rate": var(
            ("spin", "velocity"), _nan(result["growth_rate"]), "1/s", "largest sigma"
        ),
        "critical_velocity": var(
            ("spin",), _nan(result["critical_velocity"]), "m/s", "critical flow velocity"
        ),
        "stable_at_start": var(("spin",), result["stable_at_start"], "1", "stable at v_min"),
    }
    return xr.Dataset(data, coords=coords)


def _beta_map_xarray(xr: Any, var: Any, result: dict[str, Any]) -> Any:
    """Critical flow number u_cr [-] against the mass ratio beta [-]."""
    coords = {"beta": var(("beta",), result["betas"], "1", "mass ratio M2/(M1+M2)")}
    data = {
        "u_cr": var(("beta",), _nan(result["u_cr"]), "1", "critical flow number"),
        "stable_at_start": var(("beta",), result["stable_at_start"], "1", "stable at u_min"),
    }
    return xr.Dataset(data, coords=coords)


def _resonance_xarray(xr: Any, var: Any, result: dict[str, Any]) -> Any:
    """Growth rate [1/s], largest multiplier [-] and the unstable flag over (pulsation
    amplitude [m/s], pulsation frequency [rad/s])."""
    dims = ("amplitude", "frequency")
    coords = {
        "amplitude": var(("amplitude",), result["amplitudes"], "m/s", "pulsation amplitude"),
        "frequency": var(("frequency",), result["frequencies"], "rad/s", "pulsation frequency"),
    }
    data = {
        "growth_rate": var(dims, _nan(result["growth_rate"]), "1/s", "log(max |lambda|)/T"),
        "max_multiplier": var(dims, _nan(result["max_multiplier"]), "1", "max |lambda|"),
        "unstable": var(dims, result["unstable"], "1", "unstable (max |lambda| > 1)"),
    }
    return xr.Dataset(data, coords=coords)


def _floquet_xarray(xr: Any, var: Any, result: dict[str, Any]) -> Any:
    """Floquet multipliers lambda [-] (complex) and exponents [1/s], rad/s."""
    import numpy as np

    m, e = result["multipliers"], result["exponents"]
    dims = ("index",)
    data = {
        "multiplier": var(
            dims, np.asarray(m["real"]) + 1j * np.asarray(m["imag"]), "1", "Floquet multiplier"
        ),
        "exponent_sigma": var(dims, e["sigma"], "1/s", "Re mu = log|lambda|/T"),
        "exponent_omega": var(dims, e["omega"], "rad/s", "Im mu = arg(lambda)/T"),
    }
    return xr.Dataset(data)


def _study_xarray(xr: Any, var: Any, result: dict[str, Any]) -> Any:
    """One row per case (dimension ``case``), a variable per column with its unit."""
    columns = result["columns"]
    rows = result["rows"]
    data = {}
    for j, col in enumerate(columns):
        values = [row[j] for row in rows]
        numeric = all(v is None or isinstance(v, int | float) for v in values)
        data[col["name"]] = var(
            ("case",),
            _nan(values) if numeric and not all(isinstance(v, bool) for v in values) else values,
            col.get("unit", ""),
            col.get("description", col["name"]),
        )
    return xr.Dataset(data)


def _state_space_xarray(xr: Any, var: Any, result: dict[str, Any]) -> Any:
    """A state-space result: A (state, state_in), B (state, input), C (output, state_in),
    D (output, input), the names as coordinates."""
    u = result["units"]
    coords = {
        "state": var(("state",), result["states"], u["states"], "state (row)"),
        "state_in": var(("state_in",), result["states"], u["states"], "state (column)"),
        "input": var(("input",), result["inputs"], u["inputs"], "input"),
        "output": var(("output",), result["outputs"], u["outputs"], "output"),
        "position": var(("output",), result["positions"], "m", "output position"),
    }
    data = {
        "A": var(("state", "state_in"), result["A"], u["A"], "state matrix"),
        "B": var(("state", "input"), result["B"], u["B"], "input matrix"),
        "C": var(("output", "state_in"), result["C"], u["C"], "output matrix"),
        "D": var(("output", "input"), result["D"], u["D"], "feed-through"),
    }
    return xr.Dataset(data, coords=coords)


#: result kind -> its Dataset (simulations: :func:`to_xarray` itself)
_VIEWS: dict[str, Any] = {
    "frequency_response": _frf_xarray,
    "stability": _stability_xarray,
    "argand": _sweep_xarray,
    "campbell": _sweep_xarray,
    "spin_map": _spin_map_xarray,
    "beta_map": _beta_map_xarray,
    "resonance_chart": _resonance_xarray,
    "floquet": _floquet_xarray,
    "study": _study_xarray,
    "state_space": _state_space_xarray,
}


def to_dataframe(result: Any, name: str = "history") -> Any:
    """Table ``name`` of :data:`pipeflow.io.export.TABLES` as a :class:`pandas.DataFrame`:
    bare column names, indexed by its first column (``t`` [s], or ``x`` [m] for
    ``mode_shapes``), units in ``df.attrs["units"]`` (``{"tip_displacement": "m", ...}``)."""
    pd = require("pandas", "notebook", "to_dataframe()")
    header, columns = table(document(result), name)
    names, units = zip(*(split_header(h) for h in header), strict=True)
    frame = pd.DataFrame(dict(zip(names, columns, strict=True))).set_index(names[0])
    frame.attrs["units"] = dict(zip(names, units, strict=True))
    frame.attrs["table"] = name
    return frame


def plot(result: Any, name: str = "tip_displacement", **kwargs: Any) -> Figure:
    """Figure ``name`` of :data:`pipeflow.io.plots.PLOTS` (a matplotlib Figure, which a
    notebook displays); ``kwargs`` go to :func:`pipeflow.io.plots.figure` (``title``, ``size``)."""
    from pipeflow.io.plots import figure

    return figure(name, [(None, document(result))], **kwargs)


class NotebookViews:
    """``to_xarray()``, ``to_dataframe(table)`` and ``plot(name)`` for any class that can
    give its result's JSON form through ``_document()``."""

    def _document(self) -> dict[str, Any]:
        raise NotImplementedError

    def to_xarray(self) -> Any:
        """The result as an :class:`xarray.Dataset` (coordinates t, eigen_t, mode; units in
        attrs); see :mod:`pipeflow.io.notebook`."""
        return to_xarray(self._document())

    def to_dataframe(self, table: str = "history") -> Any:
        """One table (``history``, ``eigenvalues``, ``cma_exponents``, ``mode_shapes``) as a
        :class:`pandas.DataFrame`, units in ``attrs["units"]``."""
        return to_dataframe(self._document(), table)

    def plot(self, name: str = "tip_displacement", **kwargs: Any) -> Figure:
        """A matplotlib Figure of plot ``name`` (see :data:`pipeflow.io.plots.PLOTS`)."""
        return plot(self._document(), name, **kwargs)
