"""Figures of a design study (:class:`~pipeflow.schema.results.StudyResponse`, its JSON form):
the histogram of each numeric summary column over the ok cases and the Sobol' indices of a
saltelli study with their confidence intervals.  Registered in :data:`pipeflow.io.plots.PLOTS`
as ``study_histograms`` and ``sobol_indices``: one panel per column, laid out on the figure
the plot module gives (its first axes is the first panel, the others are added beside and
below it).  Drawn from the result alone (its table's rows and its statistics), in the
columns' own units.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from matplotlib.axes import Axes

#: the panels of a study figure a row
PER_ROW = 2
#: a panel's size [in]
PANEL = (4.3, 3.0)
#: the histograms' markers: statistic -> (label, colour, line style)
MARKERS = {
    "mean": ("mean", "#d62728", "-"),
    "0.05": ("5 %", "#2ca02c", "--"),
    "0.5": ("50 %", "#111111", ":"),
    "0.95": ("95 %", "#2ca02c", "--"),
}


def column_values(result: dict[str, Any], name: str) -> list[float]:
    """The finite values of column ``name`` over the study's ok cases."""
    names = [c["name"] for c in result["columns"]]
    j, status = names.index(name), names.index("status")
    out = []
    for row in result["rows"]:
        v = row[j]
        if row[status] == "ok" and isinstance(v, int | float) and not isinstance(v, bool):
            if math.isfinite(v):
                out.append(float(v))
    return out


def histogram_columns(result: dict[str, Any]) -> list[str]:
    """The numeric summary columns with at least one value (the histograms drawn)."""
    names = {c["name"] for c in result.get("columns") or []}
    stats = (result.get("statistics") or {}).get("columns") or {}
    return [n for n in stats if n in names and column_values(result, n)]


def sobol_columns(result: dict[str, Any]) -> list[str]:
    """The columns with Sobol' indices (a saltelli study's available ones)."""
    sens = result.get("sensitivity") or {}
    return [n for n, c in (sens.get("columns") or {}).items() if c.get("available")]


def _panels(ax: Axes, n: int) -> list[Axes]:
    """``ax`` and ``n - 1`` more axes on its figure, :data:`PER_ROW` a row, the figure
    sized for them."""
    from matplotlib.figure import Figure

    fig = ax.get_figure()
    assert isinstance(fig, Figure)  # the plot module's figure, never a subfigure
    cols = min(PER_ROW, n)
    rows = math.ceil(n / cols)
    fig.set_size_inches(PANEL[0] * cols, PANEL[1] * rows + 0.4)
    grid = fig.add_gridspec(rows, cols)
    ax.set_subplotspec(grid[0, 0])
    return [ax] + [fig.add_subplot(grid[i // cols, i % cols]) for i in range(1, n)]


def _unit(result: dict[str, Any], name: str) -> str:
    unit = next((c["unit"] for c in result["columns"] if c["name"] == name), "")
    return unit or "-"


def draw_histograms(ax: Axes, result: dict[str, Any], label: str | None) -> None:
    """A histogram per numeric summary column (about sqrt(n) equal bins, 5 to 40), with
    the mean and the 5, 50 and 95 % quantiles of the result's statistics marked."""
    names = histogram_columns(result)
    stats = result["statistics"]["columns"]
    for a, name in zip(_panels(ax, len(names)), names, strict=True):
        values = column_values(result, name)
        bins = max(5, min(40, math.ceil(math.sqrt(len(values)))))
        lo, hi = min(values), max(values)
        if hi - lo <= 1e-12 * max(abs(lo), abs(hi)):  # one value: a bar 2 % wide around it
            half = 0.01 * abs(lo) if lo else 0.5
            lo, hi = lo - half, hi + half
        a.hist(values, bins=bins, range=(lo, hi), color="#4c78a8", alpha=0.8, edgecolor="white")
        s = stats[name]
        for key, (text, color, style) in MARKERS.items():
            x = s["mean"] if key == "mean" else (s.get("quantiles") or {}).get(key)
            if x is not None:
                a.axvline(x, color=color, ls=style, lw=1.4, label=f"{text} = {x:.4g}")
        unit = _unit(result, name)
        a.set_xlabel(f"{name} [{unit}]", fontsize=8)
        a.set_ylabel("cases [-]", fontsize=8)
        a.set_title(f"{name}: {len(values)} ok cases", fontsize=8)
        a.tick_params(labelsize=7)
        a.grid(True, lw=0.4, alpha=0.5)
        a.legend(fontsize=6)


def draw_sobol(ax: Axes, result: dict[str, Any], label: str | None) -> None:
    """First-order (S1) and total (ST) Sobol' indices of each column per parameter, bars
    with their bootstrap confidence intervals (the half-widths S1_conf, ST_conf)."""
    import numpy as np

    sens = result["sensitivity"]
    names = sobol_columns(result)
    level = round(100 * sens["conf_level"])
    for a, name in zip(_panels(ax, len(names)), names, strict=True):
        params = sens["columns"][name]["parameters"]
        x = np.arange(len(params))
        for offset, index, color in ((-0.2, "S1", "#4c78a8"), (0.2, "ST", "#f58518")):
            values = [p[index] for p in params.values()]
            halves = [p[index + "_conf"] for p in params.values()]
            a.bar(x + offset, values, 0.38, yerr=halves, capsize=3, color=color, label=index)
        a.axhline(0.0, color="#888", lw=0.8)
        a.axhline(1.0, color="#888", lw=0.8, ls="--")
        a.set_xticks(x, list(params), fontsize=7)
        a.set_xlabel("parameter", fontsize=8)
        a.set_ylabel("Sobol' index [-]", fontsize=8)
        a.set_title(f"{name} (whiskers: {level} % intervals)", fontsize=8)
        a.tick_params(labelsize=7)
        a.grid(True, axis="y", lw=0.4, alpha=0.5)
        a.legend(fontsize=7)
