"""What the stability figures mark (issue 34): where the pipe is stable along a range.

A critical velocity is only ever the first loss of stability from a stable start; a range
that starts unstable (e.g. divergence by fast spin at v = 0) has none, and its figures show
instead where it is unstable at the start, every change of stability with its mechanism
(loss: filled marker, gain: open; flutter: circle, divergence: square) and, on a swept axis,
the unstable stretches shaded.  Drawn from the JSON results
(:mod:`pipeflow.computations.documents`); results of earlier versions without the fields get the
marks they can.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from matplotlib.axes import Axes

#: marker by mechanism; filled for a loss of stability, open for a gain
MARKERS = {"flutter": "o", "divergence": "s"}
UNSTABLE = "#c0392b"


def mechanism(how: Sequence[str] | None) -> str:
    return " and ".join(how) if how else "mechanism not recorded"


def first_loss(stable: Any, crossings: Sequence[dict[str, Any]], value: str) -> float | None:
    """The critical value of a line: its first loss of stability when it starts stable,
    else None (a line that starts unstable has no critical value)."""
    if not stable:
        return None
    return next((float(c[value]) for c in crossings if c["direction"] == "loss"), None)


def crossing_marks(ax: Axes, points: Sequence[tuple[float, float, dict[str, Any]]]) -> None:
    """Every change of stability, at (x, y), styled by its direction and kind; one legend
    entry per style."""
    seen: set[tuple[str, str]] = set()
    for x, y, c in points:
        style = (c["direction"], c["kind"])
        words = "loses stability" if c["direction"] == "loss" else "regains stability"
        ax.plot(
            [x],
            [y],
            MARKERS.get(c["kind"], "o"),
            ms=4.5,
            mec="k",
            mfc="k" if c["direction"] == "loss" else "white",
            mew=0.9,
            zorder=6,
            label=None if style in seen else f"{words} ({c['kind']})",
        )
        seen.add(style)


def start_marks(ax: Axes, points: Sequence[tuple[float, float]], how: str, where: str) -> None:
    """The lines that are unstable at the start of their range, marked there."""
    if points:
        ax.plot([p[0] for p in points], [p[1] for p in points], "x", ms=5, mew=1.4,
                color=UNSTABLE, zorder=6, label=f"unstable at {where} ({how})")  # fmt: skip


def unstable_spans(r: dict[str, Any]) -> list[tuple[float, float, str]]:
    """The stretches of a sweep's parameter where the pipe is unstable, each with how it
    is unstable there (its start's mechanism, or the kind of the loss that begins it)."""
    values = r["parameter"]["values"]
    lo, hi = float(values[0]), float(values[-1])
    spans: list[tuple[float, float, str]] = []
    begin = None if r["stable_at_start"] else lo
    kind = mechanism(r.get("instability_at_start"))
    for c in r.get("boundary") or []:
        if c["direction"] == "loss" and begin is None:
            begin, kind = float(c["value"]), c["kind"]
        elif c["direction"] == "gain" and begin is not None:
            spans.append((begin, float(c["value"]), kind))
            begin = None
    if begin is not None:
        spans.append((begin, hi, kind))
    return spans


def shade_unstable(ax: Axes, r: dict[str, Any]) -> None:
    """Shade the unstable stretches of a sweep on its parameter (x) axis."""
    if "stable_at_start" not in r:
        return
    labelled: set[str] = set()
    for a, b, kind in unstable_spans(r):
        ax.axvspan(a, b, color=UNSTABLE, alpha=0.13, lw=0, zorder=0,
                   label=None if kind in labelled else f"pipe unstable ({kind})")  # fmt: skip
        labelled.add(kind)


def sweep_note(ax: Axes, r: dict[str, Any]) -> None:
    """A sweep that starts unstable says so in the corner of a figure without its
    parameter on an axis (the Argand plot)."""
    if r.get("stable_at_start") is not False:
        return
    par = r["parameter"]
    name = "ω0" if par["name"] == "spin" else "v"
    stable = r.get("stable_intervals") or []
    where = ", ".join(f"[{a:.4g}, {b:.4g}]" for a, b in stable) or "nowhere"
    ax.text(
        0.02,
        0.98,
        f"unstable at {name} = {par['values'][0]:.4g} {par['unit']} "
        f"({mechanism(r.get('instability_at_start'))}): no critical {name}\n"
        f"stable on {where} {par['unit']}",
        transform=ax.transAxes,
        va="top",
        fontsize=7.5,
        color="#7b1f16",
        bbox={"facecolor": "white", "edgecolor": UNSTABLE, "alpha": 0.9},
    )
