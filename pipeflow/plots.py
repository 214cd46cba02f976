"""Figures of a simulation result as PNG or SVG bytes (matplotlib, Agg canvas, no pyplot).

The paper shows three kinds of figure for every case (Figs. 2-28): the tip displacement
u(L, t), the damping sigma(t) and the fundamental frequency omega(t) of the system.  This
module draws those, and a few more, from the JSON form of a result
(:meth:`pipeflow.simulation.Result.to_dict`, which is what the service stores), so the
command line, the service and a notebook produce the same images.

Figures are built on :class:`matplotlib.figure.Figure` with an Agg canvas, never through
``pyplot``: no global figure registry, no GUI backend, safe to call from server threads.
Output is deterministic (no timestamps in the files), so equal results give equal bytes.

Several results can be overlaid on one axes (``figure(name, [(label, result), ...])``),
which is how ``examples/paper_figures.py`` draws the paper's families of curves.
"""

from __future__ import annotations

import io
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Literal

if TYPE_CHECKING:  # matplotlib is imported when a figure is drawn, not to list plot names
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

Format = Literal["png", "svg"]
MEDIA_TYPES: dict[str, str] = {"png": "image/png", "svg": "image/svg+xml"}
Series = tuple[str | None, dict[str, Any]]


class PlotError(ValueError):
    """A plot that cannot be drawn (unknown name or format, or data missing); names the field."""

    def __init__(self, message: str, field: str = "name") -> None:
        super().__init__(message)
        self.message = message
        self.field = field


@dataclass(frozen=True)
class PlotKind:
    """One kind of figure: labels with units, how to draw one result, when it applies."""

    name: str
    title: str
    xlabel: str
    ylabel: str
    draw: Callable[[Axes, dict[str, Any], str | None], None]
    applies: Callable[[dict[str, Any]], bool]


def _has_history(r: dict[str, Any]) -> bool:
    return "t" in r and "tip_displacement" in r


def _has_eigen(r: dict[str, Any]) -> bool:
    return bool(isinstance(r.get("eigenvalues"), dict) and r["eigenvalues"].get("modes"))


def _draw_tip(ax: Axes, r: dict[str, Any], label: str | None) -> None:
    ax.plot(r["t"], r["tip_displacement"], lw=1.0, label=label)


def _fundamental(r: dict[str, Any]) -> dict[str, Any]:
    return r["eigenvalues"]["modes"][0]


def _draw_damping(ax: Axes, r: dict[str, Any], label: str | None) -> None:
    ax.plot(r["eigenvalues"]["t"], _fundamental(r)["sigma"], lw=1.2, label=label)


def _draw_frequency(ax: Axes, r: dict[str, Any], label: str | None) -> None:
    ax.plot(r["eigenvalues"]["t"], _fundamental(r)["omega"], lw=1.2, label=label)


def _draw_argand(ax: Axes, r: dict[str, Any], label: str | None) -> None:
    for mode in r["eigenvalues"]["modes"]:
        name = f"mode {mode['mode']}" if label is None else f"{label}, mode {mode['mode']}"
        (line,) = ax.plot(mode["sigma"], mode["omega"], lw=1.2, label=name)
        # mark the start of each branch: the direction of travel is the information here
        ax.plot(mode["sigma"][:1], mode["omega"][:1], "o", ms=3, color=line.get_color())
    ax.axvline(0.0, color="0.6", lw=0.8, zorder=0)


def _draw_stations(ax: Axes, r: dict[str, Any], label: str | None) -> None:
    for st in r.get("displacements", []):
        name = f"x = {st['x']:g} m" if label is None else f"{label}, x = {st['x']:g} m"
        ax.plot(r["t"], st["u"], lw=1.0, label=name)


#: every plot kind, by the name used in URLs and on the command line
PLOTS: dict[str, PlotKind] = {
    k.name: k
    for k in (
        PlotKind(
            "tip_displacement",
            "Tip displacement",
            "time t [s]",
            "tip displacement u(L, t) [m]",
            _draw_tip,
            _has_history,
        ),
        PlotKind(
            "damping",
            "Damping of the fundamental mode",
            "time t [s]",
            "damping σ [1/s]",
            _draw_damping,
            _has_eigen,
        ),
        PlotKind(
            "frequency",
            "Fundamental frequency",
            "time t [s]",
            "frequency ω [rad/s]",
            _draw_frequency,
            _has_eigen,
        ),
        PlotKind(
            "argand",
            "Eigenvalue paths in the complex plane (o: t = 0)",
            "damping σ [1/s]",
            "frequency ω [rad/s]",
            _draw_argand,
            _has_eigen,
        ),
        PlotKind(
            "displacements",
            "Displacement at the requested stations",
            "time t [s]",
            "displacement u(x, t) [m]",
            _draw_stations,
            lambda r: _has_history(r) and bool(r.get("displacements")),
        ),
    )
}


def available_plots(result: dict[str, Any]) -> list[str]:
    """Names of the plots that can be drawn from ``result`` (in :data:`PLOTS` order)."""
    return [name for name, kind in PLOTS.items() if kind.applies(result)]


def figure(
    name: str,
    series: Sequence[Series],
    *,
    title: str | None = None,
    size: tuple[float, float] = (6.4, 4.0),
) -> Figure:
    """A figure of kind ``name`` with one curve (family) per ``(label, result)`` in ``series``.

    ``title`` overrides the kind's default title; labels of ``None`` draw no legend entry.
    """
    if name not in PLOTS:
        raise PlotError(f"unknown plot {name!r}; choose one of {', '.join(PLOTS)}")
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    kind = PLOTS[name]
    for _, result in series:
        if not kind.applies(result):
            raise PlotError(f"this result has no data for the {name!r} plot")
    fig = Figure(figsize=size, layout="constrained")
    FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    for label, result in series:
        kind.draw(ax, result, label)
    ax.set_title(title if title is not None else kind.title, fontsize=10)
    ax.set_xlabel(kind.xlabel)
    ax.set_ylabel(kind.ylabel)
    ax.grid(True, lw=0.4, alpha=0.5)
    ax.ticklabel_format(axis="y", style="sci", scilimits=(-3, 4), useMathText=True)
    if any(label is not None for label, _ in series) or name in ("argand", "displacements"):
        ax.legend(fontsize=8)
    return fig


def to_bytes(fig: Figure, fmt: str = "png", dpi: int = 100) -> bytes:
    """Encode ``fig`` as PNG or SVG bytes, with no timestamp (same figure, same bytes)."""
    if fmt not in MEDIA_TYPES:
        raise PlotError(f"unknown image format {fmt!r}; choose png or svg", field="format")
    import matplotlib

    buf = io.BytesIO()
    meta: dict[str, Any] = {"Software": None} if fmt == "png" else {"Date": None}
    with matplotlib.rc_context({"svg.hashsalt": "pipeflow", "svg.fonttype": "none"}):
        fig.savefig(buf, format=fmt, dpi=dpi, metadata=meta)
    return buf.getvalue()


def render(
    result: dict[str, Any], name: str, fmt: str = "png", *, title: str | None = None
) -> bytes:
    """PNG or SVG bytes of plot ``name`` of one JSON result."""
    if fmt not in MEDIA_TYPES:
        raise PlotError(f"unknown image format {fmt!r}; choose png or svg", field="format")
    return to_bytes(figure(name, [(None, result)], title=title), fmt)
