"""A simulation result in a notebook: xarray Dataset, pandas DataFrame, matplotlib Figure.

Works on the JSON form of a result (:func:`pipeflow.schema.documents.simulation`, which is
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
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

from pipeflow.io.export import split_header, table
from pipeflow.optional import require

if TYPE_CHECKING:
    from matplotlib.figure import Figure


def document(result: Any) -> dict[str, Any]:
    """The JSON form of ``result``: a dictionary as it is, a :class:`NotebookViews`'s
    ``_document()``, else that of a local :class:`~pipeflow.simulation.Result`
    (:func:`pipeflow.schema.documents.simulation`, imported on first use)."""
    if isinstance(result, Mapping):
        return dict(result)
    if isinstance(result, NotebookViews):
        return result._document()
    from pipeflow.schema import documents

    return documents.simulation(result)


def to_xarray(result: Any) -> Any:
    """The result as an :class:`xarray.Dataset` (see the module docstring for its layout)."""
    xr = require("xarray", "notebook", "to_xarray()")
    import numpy as np

    result = document(result)

    def var(dims: tuple[str, ...], data: Any, units: str, long_name: str) -> Any:
        return xr.Variable(dims, np.asarray(data), {"units": units, "long_name": long_name})

    if result.get("kind") == "frequency_response":
        return _frf_xarray(xr, var, result)

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
    attrs = {
        k: result[k]
        for k in ("key", "status", "method", "initial_tip_displacement", "divergence_time")
        if result.get(k) is not None
    }
    return xr.Dataset(data, coords=coords, attrs=attrs)


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
    attrs = {k: result[k] for k in ("key", "quantity", "unit", "modes") if k in result}
    return xr.Dataset(data, coords=coords, attrs=attrs)


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
