"""Figures of a simulation result as PNG or SVG bytes (matplotlib, Agg canvas, no pyplot).

The paper shows three kinds of figure for every case (Figs. 2-28): the tip displacement
u(L, t), the damping sigma(t) and the fundamental frequency omega(t) of the system.  This
module draws those, and a few more, from the JSON form of a result
(:func:`pipeflow.computations.documents.simulation`, which is what the service stores), so the
command line, the service and a notebook produce the same images.

Figures are built on :class:`matplotlib.figure.Figure` with an Agg canvas, never through
``pyplot``: no global figure registry, no GUI backend, safe to call from server threads.
Output is deterministic (no timestamps in the files), so equal results give equal bytes.

Several results can be overlaid on one axes (``figure(name, [(label, result), ...])``),
which is how ``examples/paper_figures.py`` draws the paper's families of curves.
"""

from __future__ import annotations

import io
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Literal

from pipeflow.io import stability_marks as marks
from pipeflow.io import study_plots

if TYPE_CHECKING:  # matplotlib is imported when a figure is drawn, not to list plot names
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

    from pipeflow.model import Pipe

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
    #: stacked axes sharing x (the Bode plot's magnitude and phase); ``draw`` gets the
    #: first and finds the others in ``ax.figure.axes``
    panels: int = 1
    #: the y axis is logarithmic (no scientific tick format)
    log_y: bool = False
    #: what the x and y axes show, where a display unit applies (:data:`DISPLAY_UNITS`):
    #: "spin" [rad/s] or "frequency" [rad/s]; None: the axis stays as drawn
    x_quantity: str | None = None
    y_quantity: str | None = None
    #: one panel per column, laid out by ``draw`` (:mod:`pipeflow.io.study_plots`): the
    #: title is the figure's, not the first panel's
    suptitle: bool = False


#: display units of the axes (the data stay SI): quantity -> {unit: factor from rad/s};
#: rpm is revolutions per minute (60 / 2 pi per rad/s), Hz cycles per second (1 / 2 pi)
DISPLAY_UNITS: dict[str, dict[str, float]] = {
    "spin": {"rad/s": 1.0, "rpm": 60.0 / (2.0 * math.pi), "Hz": 1.0 / (2.0 * math.pi)},
    "frequency": {"rad/s": 1.0, "Hz": 1.0 / (2.0 * math.pi), "rpm": 60.0 / (2.0 * math.pi)},
}


def _check_units(units: Mapping[str, str] | None) -> dict[str, str]:
    """``units`` (quantity -> display unit) checked against :data:`DISPLAY_UNITS`."""
    out = dict(units or {})
    for quantity, unit in out.items():
        if quantity not in DISPLAY_UNITS:
            raise PlotError(
                f"no display unit for {quantity!r}; choose among {', '.join(DISPLAY_UNITS)}",
                field="units",
            )
        if unit not in DISPLAY_UNITS[quantity]:
            raise PlotError(
                f"{quantity} in {unit!r}? choose one of {', '.join(DISPLAY_UNITS[quantity])}",
                field="units",
            )
    return out


def _display(axis: Any, factor: float, unit: str) -> None:
    """Show ``axis`` (data in rad/s) in ``unit``: ticks at round values of the display
    unit (the locator works on the scaled range), labels scaled, "[rad/s]" in the label
    replaced.  The data are not touched."""
    import numpy as np
    from matplotlib.ticker import FuncFormatter, LogLocator, MaxNLocator

    log = axis.get_scale() == "log"
    inner = LogLocator() if log else MaxNLocator(nbins="auto", steps=[1, 2, 2.5, 5, 10])

    class Scaled(type(inner)):  # type: ignore[misc]
        def tick_values(self, vmin: float, vmax: float) -> Any:
            return np.asarray(inner.tick_values(vmin * factor, vmax * factor)) / factor

        def __call__(self) -> Any:
            lo, hi = self.axis.get_view_interval()
            return self.tick_values(lo, hi)

    locator = Scaled()
    axis.set_major_locator(locator)
    axis.set_major_formatter(FuncFormatter(lambda v, _: f"{v * factor:.6g}"))
    label = axis.get_label_text()
    axis.set_label_text(label.replace("[rad/s]", f"[{unit}]").replace("rad/s", unit))


def _has_history(r: dict[str, Any]) -> bool:
    return "t" in r and "tip_displacement" in r


def _has_eigen(r: dict[str, Any]) -> bool:
    return bool(isinstance(r.get("eigenvalues"), dict) and r["eigenvalues"].get("modes"))


def _is_sweep(r: dict[str, Any]) -> bool:
    """An Argand (against flow velocity) or Campbell (against spin) sweep result."""
    return r.get("kind") in ("argand", "campbell") and bool(r.get("modes"))


def _branches(r: dict[str, Any]) -> list[dict[str, Any]]:
    return list(r["modes"] if _is_sweep(r) else r["eigenvalues"]["modes"])


def _draw_tip(ax: Axes, r: dict[str, Any], label: str | None) -> None:
    (line,) = ax.plot(r["t"], r["tip_displacement"], lw=1.0, label=label)
    if r.get("status") == "diverged" and r.get("divergence_bound") is not None:
        # the linear model's range, and where the run was stopped (pipeflow.divergence)
        b, t = r["divergence_bound"], r["divergence_time"]
        for sign in (1.0, -1.0):
            ax.axhline(sign * b, color="0.5", lw=0.8, ls=":", zorder=0)
        ax.plot([t], [r["tip_displacement"][-1]], "x", ms=8, color=line.get_color(),
                label=f"diverged: |u| > {b:.3g} m at t = {t:.4g} s")  # fmt: skip
        ax.legend(fontsize=8)


def _fundamental(r: dict[str, Any]) -> dict[str, Any]:
    return r["eigenvalues"]["modes"][0]


def _least_stable(r: dict[str, Any]) -> dict[str, Any] | None:
    """The least stable branch of an unstable run (growth somewhere in the frozen
    spectrum, or stopped or overflowed), when it is not the fundamental: the branch that
    decides the run (at v = 40 m/s on the paper's pipe, mode 5, while mode 1 decays)."""
    unstable = r.get("first_unstable_time") is not None or r.get("status") in (
        "diverging",
        "diverged",
        "overflow",
    )
    modes = r["eigenvalues"]["modes"]
    least = next((m for m in modes if m.get("least_stable")), None)
    return least if unstable and least is not None and least is not modes[0] else None


def _draw_branches(part: str) -> Callable[[Axes, dict[str, Any], str | None], None]:
    """The fundamental's ``part`` ("sigma" or "omega") against time; an unstable run's
    least stable branch dashed in the same colour."""

    def draw(ax: Axes, r: dict[str, Any], label: str | None) -> None:
        t = r["eigenvalues"]["t"]
        (line,) = ax.plot(t, _fundamental(r)[part], lw=1.2, label=label)
        least = _least_stable(r)
        if least is not None:
            name = f"mode {least['mode']}, least stable"
            ax.plot(t, least[part], lw=1.4, ls="--", color=line.get_color(),
                    label=name if label is None else f"{label}, {name}")  # fmt: skip
            if part == "sigma":
                ax.axhline(0.0, color="0.6", lw=0.8, zorder=0)
            ax.legend(fontsize=8)

    return draw


def _draw_argand(ax: Axes, r: dict[str, Any], label: str | None) -> None:
    for mode in _branches(r):
        name = f"mode {mode['mode']}" if label is None else f"{label}, mode {mode['mode']}"
        (line,) = ax.plot(mode["sigma"], mode["omega"], lw=1.2, label=name)
        # mark the start of each branch: the direction of travel is the information here
        ax.plot(mode["sigma"][:1], mode["omega"][:1], "o", ms=3, color=line.get_color())
    ax.axvline(0.0, color="0.6", lw=0.8, zorder=0)
    if not _is_sweep(r):
        return
    # the critical point: the first loss of stability from a stable start of the sweep (the
    # pipe's, every eigenvalue); a sweep that starts unstable has none and says so
    unit = r["parameter"]["unit"]
    if "stable_at_start" in r:
        marks.sweep_note(ax, r)
        first = marks.first_loss(r["stable_at_start"], r.get("boundary") or [], "value")
        c = next((c for c in r["boundary"] if c["value"] == first), None)
        if c is not None:
            ax.plot([0.0], [c["frequency"]], "*", ms=12, color="k", zorder=5,
                    label=f"critical point: {c['value']:.4g} {unit} ({c['kind']})")  # fmt: skip
        return
    loss = [c for c in r.get("zero_crossings", []) if c["direction"] == "loss"]
    if loss:  # a result of an earlier version: the tracked branches' first loss
        c = loss[0]
        ax.plot([0.0], [c["frequency"]], "*", ms=12, color="k", zorder=5,
                label=f"σ = 0: {c['value']:.4g} {unit}, mode {c['mode']}")  # fmt: skip


def _draw_campbell(ax: Axes, r: dict[str, Any], label: str | None) -> None:
    """ROSS-style Campbell diagram: |omega| [rad/s] of each tracked branch against spin
    [rad/s], coloured by the damping ratio; excitation lines n w0; their crossings marked."""
    import numpy as np
    from matplotlib.collections import LineCollection
    from matplotlib.colors import Normalize

    x = np.asarray(r["parameter"]["values"], dtype=float)
    zeta_all = [z for m in r["modes"] for z in m["damping_ratio"] if z is not None]
    lo, hi = (min(zeta_all), max(zeta_all)) if zeta_all else (0.0, 1.0)
    norm = Normalize(vmin=lo, vmax=hi if hi > lo else lo + 1e-12)
    top = 0.0
    for mode in r["modes"]:
        y = np.array([np.nan if v is None else v for v in mode["omega"]], dtype=float)
        z = np.array([np.nan if v is None else v for v in mode["damping_ratio"]], dtype=float)
        pts = np.column_stack([x, y])
        segments = np.stack([pts[:-1], pts[1:]], axis=1)
        lc = LineCollection(list(segments), cmap="viridis", norm=norm, linewidths=2.5)
        lc.set_array(0.5 * (z[:-1] + z[1:]))
        ax.add_collection(lc)
        if np.isfinite(y).any():
            top = max(top, float(np.nanmax(y)))
            k = int(np.nanargmax(y))
            ax.annotate(f"mode {mode['mode']}", (x[k], y[k]), fontsize=7, ha="right", va="bottom")
    ax.figure.colorbar(lc, ax=ax, label="damping ratio ζ [-] (< 0: growing)")
    exc = r.get("excitation") or {}
    styles = ("--", "-.", ":", (0, (5, 1, 1, 1, 1, 1)))
    for i, n in enumerate(exc.get("orders", [])):
        ax.plot(x, n * x, ls=styles[i % len(styles)], lw=1.0, color="0.25", label=f"{n:g}x")
    crossings = exc.get("crossings", [])
    if crossings:
        ax.plot([c["spin"] for c in crossings], [c["frequency"] for c in crossings], "o",
                ms=6, mfc="none", mec="k", label=label or "crossings")  # fmt: skip
    marks.shade_unstable(ax, r)
    ax.set_xlim(float(x[0]), float(x[-1]))
    ax.set_ylim(0.0, 1.05 * top if top > 0 else 1.0)
    ax.legend(fontsize=8, loc="upper left")


def _draw_stations(ax: Axes, r: dict[str, Any], label: str | None) -> None:
    for st in r.get("displacements", []):
        name = f"x = {st['x']:g} m" if label is None else f"{label}, x = {st['x']:g} m"
        ax.plot(r["t"], st["u"], lw=1.0, label=name)


def _has_shapes(r: dict[str, Any]) -> bool:
    return bool(isinstance(r.get("mode_shapes"), dict) and r["mode_shapes"].get("modes"))


def _draw_mode_shapes(ax: Axes, r: dict[str, Any], label: str | None) -> None:
    """Real part solid, imaginary part dashed, one colour per branch and time."""
    block = r["mode_shapes"]
    for i, t in enumerate(block["t"]):
        for mode in block["modes"]:
            name = f"mode {mode['mode']}, t = {t:g} s"
            name = name if label is None else f"{label}, {name}"
            (line,) = ax.plot(block["x"], mode["real"][i], lw=1.2, label=f"{name} (Re)")
            ax.plot(block["x"], mode["imag"][i], lw=1.0, ls="--", color=line.get_color())
    ax.axhline(0.0, color="0.6", lw=0.8, zorder=0)


def _parameter_label(r: dict[str, Any]) -> str:
    par = r["parameter"]
    what = {"velocity": "flow velocity v", "spin": "spin ω0"}.get(par["name"], par["name"])
    return f"{what} [{par['unit']}]"


def _draw_sweep(part: str) -> Callable[[Axes, dict[str, Any], str | None], None]:
    def draw(ax: Axes, r: dict[str, Any], label: str | None) -> None:
        x = r["parameter"]["values"]
        for mode in r["modes"]:
            name = f"mode {mode['mode']}" if label is None else f"{label}, mode {mode['mode']}"
            # null marks a point where a branch is undefined: matplotlib leaves a gap for NaN
            y = [float("nan") if v is None else v for v in mode[part]]
            ax.plot(x, y, lw=1.2, label=name)
        if part == "sigma":
            ax.axhline(0.0, color="0.6", lw=0.8, zorder=0)
        marks.shade_unstable(ax, r)
        ax.set_xlabel(_parameter_label(r))

    return draw


def _growth_mesh(ax: Axes, x: Any, y: Any, r: dict[str, Any], label: str) -> None:
    """``r["growth_rate"]`` [1/s] (null: undefined, left blank) over ``x``, ``y`` on a
    diverging colour scale symmetric about 0 (red: growing), with a colour bar."""
    import numpy as np

    g = np.array([[np.nan if v is None else v for v in row] for row in r["growth_rate"]])
    lim = (float(np.nanmax(np.abs(g))) if np.isfinite(g).any() else 0.0) or 1.0
    mesh = ax.pcolormesh(x, y, g, cmap="RdBu_r", vmin=-lim, vmax=lim, shading="nearest")
    ax.figure.colorbar(mesh, ax=ax, label=label)


def _draw_map_lines(
    ax: Axes, r: dict[str, Any], lines: list[float], value: str, lo: float, where: str,
    label: str, horizontal: bool,
) -> None:  # fmt: skip
    """A map's lines of constant spin or beta: the critical value (first loss from a stable
    start; none where a line starts unstable), every change of stability, and the lines
    unstable at their start (:mod:`pipeflow.io.stability_marks`).  ``horizontal``: the
    lines run along x (the spin map: v on x, spin on y)."""
    if "stable_at_start" not in r or "crossings" not in r:
        return  # not a whole map document: its growth rates only
    first = [
        marks.first_loss(ok, line, value)
        for ok, line in zip(r["stable_at_start"], r["crossings"], strict=True)
    ]
    crit = [float("nan") if v is None else v for v in first]
    points = [(c[value], y, c) for y, line in zip(lines, r["crossings"], strict=True) for c in line]
    start = [(lo, y) for y, ok in zip(lines, r["stable_at_start"], strict=True) if not ok]
    how = sorted({k for ks in r.get("instability_at_start") or [] for k in ks})
    if not horizontal:
        points = [(y, x, c) for x, y, c in points]
        start = [(y, x) for x, y in start]
        ax.plot(lines, crit, "k-", lw=1.5, label=label)
    else:
        ax.plot(crit, lines, "k-", lw=1.5, label=label)
    marks.crossing_marks(ax, points)
    marks.start_marks(ax, start, marks.mechanism(how), where)
    ax.legend(fontsize=7, loc="lower right" if horizontal else "upper left", framealpha=0.85)


def _draw_spin_map(ax: Axes, r: dict[str, Any], label: str | None) -> None:
    _growth_mesh(ax, r["velocities"], r["spins"], r, "largest growth rate max σ [1/s]")
    lo = max(float(r["velocities"][0]), 0.0)
    name = label or f"v_cr: first loss of stability from v = {lo:g} m/s"
    _draw_map_lines(ax, r, r["spins"], "velocity", lo, f"v = {lo:g} m/s", name, True)


def _draw_beta_map(ax: Axes, r: dict[str, Any], label: str | None) -> None:
    lo = float(r["u_range"][0])
    name = label or f"u_cr at γ = {r.get('gamma', 0):g}: first loss from u = {lo:g}"
    _draw_map_lines(ax, r, r["betas"], "u", lo, f"u = {lo:g}", name, False)


def _draw_resonance_chart(ax: Axes, r: dict[str, Any], label: str | None) -> None:
    import numpy as np

    freq, amp = r["frequencies"], r["amplitudes"]
    _growth_mesh(ax, freq, amp, r, "growth rate log(max |λ|)/T [1/s]")
    unstable = np.asarray(r["unstable"], dtype=float)
    if unstable.ndim == 2 and min(unstable.shape) > 1 and 0 < unstable.sum() < unstable.size:
        ax.contour(freq, amp, unstable, levels=[0.5], colors="k", linewidths=1.2)
    # principal parametric resonances Omega = 2 omega_j of the frozen mean-flow frequencies
    lo, hi = min(freq), max(freq)
    for j, w in enumerate(r.get("natural_frequencies", []), start=1):
        if lo <= 2 * w <= hi:
            ax.axvline(2 * w, color="0.3", lw=0.8, ls="--", label=f"Ω = 2ω{j}")
    if any(lo <= 2 * w <= hi for w in r.get("natural_frequencies", [])):
        ax.legend(fontsize=8)


def _draw_multipliers(ax: Axes, r: dict[str, Any], label: str | None) -> None:
    import numpy as np

    theta = np.linspace(0.0, 2 * np.pi, 361)
    ax.plot(np.cos(theta), np.sin(theta), color="0.6", lw=0.8, zorder=0)
    m = r["multipliers"]
    ax.plot(m["real"], m["imag"], "x", ms=6, label=label or f"verdict: {r.get('verdict', '')}")
    ax.set_aspect("equal", adjustable="datalim")
    ax.legend(fontsize=8)


def _is_frf(r: dict[str, Any]) -> bool:
    return r.get("kind") == "frequency_response" and bool(r.get("operating_points"))


def _finite(values: Sequence[float | None]) -> list[float]:
    """null (an unbounded value in the JSON) as NaN: matplotlib leaves a gap."""
    return [float("nan") if v is None else float(v) for v in values]


def _point_name(r: dict[str, Any], point: dict[str, Any], x: float | None = None) -> str:
    parts = []
    if len(r["operating_points"]) > 1:
        parts.append(f"v = {point['velocity']:g} m/s, ω0 = {point['omega0']:g} rad/s")
    if x is not None and len(r["positions"]) > 1:
        parts.append(f"x = {x:g} m")
    return ", ".join(parts)


def _frf_label(r: dict[str, Any]) -> str:
    return f"{r['quantity']} per unit load"


def _draw_bode(ax: Axes, r: dict[str, Any], label: str | None) -> None:
    """|H| (log-log, peaks marked) above arg H [rad] (log frequency)."""
    phase_ax = ax.figure.axes[1]
    W = r["frequencies"]
    for point in r["operating_points"]:
        for i, curve in enumerate(point["responses"]):
            name = ", ".join(p for p in (label, _point_name(r, point, curve["position"])) if p)
            (line,) = ax.plot(W, _finite(curve["magnitude"]), lw=1.1, label=name or None)
            phase_ax.plot(W, _finite(curve["phase"]), lw=1.0, color=line.get_color())
            peaks = [p for p in point["peaks"] if p["magnitude"][i] is not None]
            ax.plot([p["frequency"] for p in peaks], [p["magnitude"][i] for p in peaks], "v",
                    ms=5, color=line.get_color())  # fmt: skip
    for p in r["operating_points"][0]["peaks"] if len(r["operating_points"]) == 1 else []:
        if p["magnitude"][0] is not None:
            ax.annotate(f"{p['mode']}: ζ = {p['damping_ratio']:.3g}", (p["frequency"],
                        p["magnitude"][0]), fontsize=7, xytext=(4, 4),
                        textcoords="offset points")  # fmt: skip
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_ylabel(f"|H| [{r['unit']}]")
    phase_ax.set_xscale("log")
    phase_ax.set_ylabel("phase arg H [rad]")
    phase_ax.set_xlabel("frequency Ω [rad/s]")
    phase_ax.set_ylim(-3.3, 3.3)
    phase_ax.grid(True, lw=0.4, alpha=0.5)
    ax.set_xlabel("")
    if any(not str(line.get_label()).startswith("_") for line in ax.lines):
        ax.legend(fontsize=7)


def _draw_nyquist(ax: Axes, r: dict[str, Any], label: str | None) -> None:
    """Im H against Re H, the frequency increasing along each curve (o: lowest)."""
    for point in r["operating_points"]:
        for curve in point["responses"]:
            name = ", ".join(p for p in (label, _point_name(r, point, curve["position"])) if p)
            (line,) = ax.plot(_finite(curve["real"]), _finite(curve["imag"]), lw=1.0,
                              label=name or None)  # fmt: skip
            ax.plot(_finite(curve["real"][:1]), _finite(curve["imag"][:1]), "o", ms=3,
                    color=line.get_color())  # fmt: skip
    ax.set_xlabel(f"Re H [{r['unit']}]")
    ax.set_ylabel(f"Im H [{r['unit']}]")
    ax.axhline(0.0, color="0.6", lw=0.8, zorder=0)
    ax.axvline(0.0, color="0.6", lw=0.8, zorder=0)
    if any(not str(line.get_label()).startswith("_") for line in ax.lines):
        ax.legend(fontsize=7)


def _draw_waterfall(ax: Axes, r: dict[str, Any], label: str | None) -> None:
    """|H| at the first position, one curve per operating point, coloured by the point's
    flow velocity (or spin, when only the spin varies), peaks marked."""
    import numpy as np
    from matplotlib import colormaps
    from matplotlib.cm import ScalarMappable
    from matplotlib.colors import Normalize

    points = r["operating_points"]
    v = np.array([p["velocity"] for p in points], dtype=float)
    w = np.array([p["omega0"] for p in points], dtype=float)
    by_spin = bool(np.ptp(v) == 0 and np.ptp(w) > 0)
    values = w if by_spin else v
    norm = Normalize(vmin=float(values.min()), vmax=float(values.max()) + (np.ptp(values) == 0))
    cmap = colormaps["viridis"]
    for p, value in zip(points, values, strict=True):
        colour = cmap(norm(value))
        ax.plot(r["frequencies"], _finite(p["responses"][0]["magnitude"]), lw=1.0, color=colour)
        peaks = [k for k in p["peaks"] if k["magnitude"][0] is not None]
        ax.plot([k["frequency"] for k in peaks], [k["magnitude"][0] for k in peaks], "v", ms=4,
                color=colour)  # fmt: skip
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_ylabel(f"|H(x = {r['positions'][0]:g} m)| [{r['unit']}]")
    what = "spin ω0 [rad/s]" if by_spin else "flow velocity v [m/s]"
    ax.figure.colorbar(ScalarMappable(norm=norm, cmap=cmap), ax=ax, label=what)


def _draw_deflection(ax: Axes, r: dict[str, Any], label: str | None) -> None:
    """The operating deflection shape |H(x)| along the pipe at each peak frequency (the
    grid point nearest to it) of the first operating point, phase as dashes on a twin axis."""
    import numpy as np

    point = r["operating_points"][0]
    W = np.asarray(r["frequencies"], dtype=float)
    x = r["positions"]
    order = np.argsort(x)
    twin = ax.twinx()
    for peak in point["peaks"] or []:
        k = int(np.argmin(np.abs(W - peak["frequency"])))
        amp = np.array(_finite([c["magnitude"][k] for c in point["responses"]]))[order]
        ph = np.array(_finite([c["phase"][k] for c in point["responses"]]))[order]
        (line,) = ax.plot(np.asarray(x)[order], amp, "-o", ms=2.5, lw=1.2,
                          label=f"mode {peak['mode']}, Ω = {W[k]:.4g} rad/s")  # fmt: skip
        twin.plot(np.asarray(x)[order], ph, "--", lw=0.8, color=line.get_color())
    ax.set_ylabel(f"amplitude |H(x)| [{r['unit']}]")
    twin.set_ylabel("phase arg H [rad] (dashed)")
    if point["peaks"]:
        ax.legend(fontsize=7)


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
            "Damping of the fundamental mode (dashed: least stable branch, unstable runs)",
            "time t [s]",
            "damping σ [1/s]",
            _draw_branches("sigma"),
            _has_eigen,
        ),
        PlotKind(
            "frequency",
            "Fundamental frequency (dashed: least stable branch, unstable runs)",
            "time t [s]",
            "frequency ω [rad/s]",
            _draw_branches("omega"),
            _has_eigen,
            y_quantity="frequency",
        ),
        PlotKind(
            "argand",
            "Eigenvalue paths in the complex plane (o: start)",
            "damping σ [1/s]",
            "frequency ω [rad/s]",
            _draw_argand,
            lambda r: _has_eigen(r) or _is_sweep(r),
            y_quantity="frequency",
        ),
        PlotKind(
            "campbell",
            "Campbell diagram: frequencies, excitation lines n x ω0, crossings (o)",
            "spin ω0 [rad/s]",
            "frequency |ω| [rad/s]",
            _draw_campbell,
            lambda r: r.get("kind") == "campbell" and bool(r.get("modes")),
            x_quantity="spin",
            y_quantity="frequency",
        ),
        PlotKind(
            "sweep_frequency",
            "Frequencies of the tracked branches",
            "swept parameter",
            "frequency ω [rad/s]",
            _draw_sweep("omega"),
            _is_sweep,
            y_quantity="frequency",
        ),
        PlotKind(
            "sweep_damping",
            "Damping of the tracked branches (σ > 0: unstable)",
            "swept parameter",
            "damping σ [1/s]",
            _draw_sweep("sigma"),
            _is_sweep,
        ),
        PlotKind(
            "spin_map",
            "Stability map: growth rate over flow velocity and spin, changes of stability",
            "flow velocity v [m/s]",
            "spin ω0 [rad/s]",
            _draw_spin_map,
            lambda r: r.get("kind") == "spin_map" and bool(r.get("growth_rate")),
            y_quantity="spin",
        ),
        PlotKind(
            "beta_map",
            "Stability boundary against mass ratio: u_cr and every change of stability",
            "mass ratio β = M2/(M1+M2) [-]",
            "flow number u [-]",
            _draw_beta_map,
            lambda r: r.get("kind") == "beta_map" and bool(r.get("curve")),
        ),
        PlotKind(
            "resonance_chart",
            "Parametric resonance chart of pulsating flow (black: unstable boundary)",
            "pulsation frequency Ω [rad/s]",
            "pulsation amplitude a [m/s]",
            _draw_resonance_chart,
            lambda r: r.get("kind") == "resonance_chart" and bool(r.get("growth_rate")),
            x_quantity="frequency",
        ),
        PlotKind(
            "floquet_multipliers",
            "Floquet multipliers λ and the unit circle (|λ| > 1: unstable)",
            "Re λ [-]",
            "Im λ [-]",
            _draw_multipliers,
            lambda r: isinstance(r.get("multipliers"), dict) and bool(r["multipliers"].get("real")),
        ),
        PlotKind(
            "displacements",
            "Displacement at the requested stations",
            "time t [s]",
            "displacement u(x, t) [m]",
            _draw_stations,
            lambda r: _has_history(r) and bool(r.get("displacements")),
        ),
        PlotKind(
            "mode_shapes",
            "Complex mode shapes of the frozen spectrum (solid: Re, dashed: Im)",
            "position along the pipe x [m]",
            "mode shape Φ(x) [-] (max |Φ| = 1)",
            _draw_mode_shapes,
            _has_shapes,
        ),
        PlotKind(
            "bode",
            "Bode plot: magnitude and phase of the frequency response (▼: peaks)",
            "frequency Ω [rad/s]",
            "|H|",
            _draw_bode,
            _is_frf,
            panels=2,
            log_y=True,
            x_quantity="frequency",
        ),
        PlotKind(
            "nyquist",
            "Nyquist plot of the frequency response (o: lowest frequency)",
            "Re H",
            "Im H",
            _draw_nyquist,
            _is_frf,
        ),
        PlotKind(
            "waterfall",
            "Frequency response over the operating points (▼: peaks)",
            "frequency Ω [rad/s]",
            "|H|",
            _draw_waterfall,
            lambda r: _is_frf(r) and len(r["operating_points"]) > 1,
            log_y=True,
            x_quantity="frequency",
        ),
        PlotKind(
            "deflection_shape",
            "Operating deflection shape at each peak (solid: amplitude, dashed: phase)",
            "position along the pipe x [m]",
            "amplitude |H(x)|",
            _draw_deflection,
            lambda r: (
                _is_frf(r) and len(r["positions"]) >= 3 and bool(r["operating_points"][0]["peaks"])
            ),
        ),
        PlotKind(
            "study_histograms",
            "Histograms of the study's outputs over its ok cases (mean, 5/50/95 % quantiles)",
            "",
            "cases [-]",
            study_plots.draw_histograms,
            lambda r: r.get("kind") == "study" and bool(study_plots.histogram_columns(r)),
            suptitle=True,
        ),
        PlotKind(
            "sobol_indices",
            "Sobol' indices S1 and ST per parameter with their confidence intervals",
            "parameter",
            "Sobol' index [-]",
            study_plots.draw_sobol,
            lambda r: r.get("kind") == "study" and bool(study_plots.sobol_columns(r)),
            suptitle=True,
        ),
    )
}


#: the plots whose x axis is the position along the pipe x [m]: they draw the supports
ALONG_PIPE = ("mode_shapes", "deflection_shape")


def available_plots(result: dict[str, Any]) -> list[str]:
    """Names of the plots that can be drawn from ``result`` (in :data:`PLOTS` order)."""
    return [name for name, kind in PLOTS.items() if kind.applies(result)]


def figure(
    name: str,
    series: Sequence[Series],
    *,
    title: str | None = None,
    size: tuple[float, float] = (6.4, 4.0),
    units: Mapping[str, str] | None = None,
    pipe: Pipe | None = None,
) -> Figure:
    """A figure of kind ``name`` with one curve (family) per ``(label, result)`` in ``series``.

    ``title`` overrides the kind's default title; labels of ``None`` draw no legend entry.
    ``units`` shows spin and frequency axes in another unit (``{"spin": "rpm",
    "frequency": "Hz"}``, :data:`DISPLAY_UNITS`); the data stay in rad/s.  ``pipe`` draws
    its supports (:mod:`pipeflow.io.support_symbols`) on the plots along x [m]
    (:data:`ALONG_PIPE`); ``None`` draws none.
    """
    if name not in PLOTS:
        raise PlotError(f"unknown plot {name!r}; choose one of {', '.join(PLOTS)}")
    shown = _check_units(units)
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    kind = PLOTS[name]
    for _, result in series:
        if not kind.applies(result):
            raise PlotError(f"this result has no data for the {name!r} plot")
    if kind.panels > 1 and size == (6.4, 4.0):
        size = (6.4, 2.4 + 2.0 * kind.panels)
    fig = Figure(figsize=size, layout="constrained")
    FigureCanvasAgg(fig)
    ax = fig.subplots(kind.panels, 1, sharex=True, squeeze=False)[0, 0]
    ax.set_xlabel(kind.xlabel)
    ax.set_ylabel(kind.ylabel)
    for label, result in series:
        kind.draw(ax, result, label)  # may refine the labels (e.g. the swept parameter)
    if pipe is not None and name in ALONG_PIPE:
        from pipeflow.io.support_symbols import draw_supports

        draw_supports(ax, pipe)
    if kind.suptitle:
        fig.suptitle(title if title is not None else kind.title, fontsize=10)
    else:
        ax.set_title(title if title is not None else kind.title, fontsize=10)
    ax.grid(True, lw=0.4, alpha=0.5)
    if name not in ("spin_map", "resonance_chart", "floquet_multipliers") and not kind.log_y:
        ax.ticklabel_format(axis="y", style="sci", scilimits=(-3, 4), useMathText=True)
    multi = ("argand", "displacements", "sweep_frequency", "sweep_damping", "mode_shapes")
    if any(label is not None for label, _ in series) or name in multi:
        ax.legend(fontsize=8)
    # display units last: the drawing has set the scales and the labels
    axes = fig.axes[: kind.panels]
    for quantity, which in ((kind.x_quantity, "x"), (kind.y_quantity, "y")):
        unit = shown.get(quantity or "")
        if quantity is None or unit is None or unit == "rad/s":
            continue
        factor = DISPLAY_UNITS[quantity][unit]
        for a in axes if which == "x" else axes[:1]:
            _display(a.xaxis if which == "x" else a.yaxis, factor, unit)
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
    result: dict[str, Any],
    name: str,
    fmt: str = "png",
    *,
    title: str | None = None,
    units: Mapping[str, str] | None = None,
    pipe: Pipe | None = None,
) -> bytes:
    """PNG or SVG bytes of plot ``name`` of one JSON result (``units``, ``pipe``: see
    :func:`figure`)."""
    if fmt not in MEDIA_TYPES:
        raise PlotError(f"unknown image format {fmt!r}; choose png or svg", field="format")
    return to_bytes(figure(name, [(None, result)], title=title, units=units, pipe=pipe), fmt)
