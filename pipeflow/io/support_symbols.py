"""Support symbols on figures whose x axis runs along the pipe (issue 31): a hatched wall
for a clamped end, a triangle for a pinned end or point, rollers on a guide for a sliding
end, a zigzag spring for an elastic end or a spring point support, nothing for a free end.

Each artist carries ``gid`` ``"support:<where>:<kind>"`` (``where``: ``x0``, ``xL`` or
``point<i>``) and a label starting with ``_`` (no legend entry), so tests and SVG readers
find them.  The symbols are drawn in data x [m] and axes-fraction y (the bottom band of the
axes); the x limits are the curves' own, widened only to show both ends.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from pipeflow.supports import PointSupport, Support

if TYPE_CHECKING:
    from matplotlib.axes import Axes

    from pipeflow.model import Pipe

#: the band of the axes the symbols occupy (axes fraction)
BASE, HEIGHT = 0.04, 0.10
COLOR = "0.25"


def _mark(artist: Any, where: str, kind: str) -> None:
    artist.set_gid(f"support:{where}:{kind}")
    artist.set_label(f"_support {where} {kind}")
    artist.set_zorder(6)  # above the legend (5): a symbol is never hidden


def _spring(ax: Axes, x: float, where: str) -> None:
    """A spring at ``x`` [m]: a vertical coil line with teeth (markers, sized in points so
    the symbol stays readable at any x scale) standing on a ground bar."""
    tr = ax.get_xaxis_transform()
    ys = [BASE + HEIGHT * k / 8 for k in range(9)]
    (coil,) = ax.plot([x] * len(ys), ys, color=COLOR, lw=1.0, transform=tr, clip_on=False)
    _mark(coil, where, "elastic")
    (teeth,) = ax.plot([x] * 7, ys[1:-1], ls="none", marker="_", ms=8, color=COLOR,
                       transform=tr, clip_on=False)  # fmt: skip
    _mark(teeth, where, "elastic")
    (ground,) = ax.plot([x], [BASE], ls="none", marker="_", ms=14, mew=2, color=COLOR,
                        transform=tr, clip_on=False)  # fmt: skip
    _mark(ground, where, "elastic")


def _end(ax: Axes, support: Support, x: float, where: str, outward: float, L: float) -> None:
    """The symbol of an end ``support`` at ``x`` [m]; ``outward`` is -1 at x = 0, +1 at L."""
    from matplotlib.patches import Rectangle

    tr = ax.get_xaxis_transform()
    kind = support.kind
    if kind == "free":
        return
    if kind == "clamped":
        w = 0.03 * L
        wall = Rectangle(
            (x if outward > 0 else x - w, 0.0), w, 1.0, transform=tr, hatch="///",
            facecolor="none", edgecolor=COLOR, lw=0.0, clip_on=False,
        )  # fmt: skip
        _mark(wall, where, kind)
        ax.add_patch(wall)
        (face,) = ax.plot([x, x], [0.0, 1.0], color=COLOR, lw=2.0, transform=tr)
        _mark(face, where, kind)
    elif kind == "pinned":
        (tri,) = ax.plot([x], [BASE + 0.04], ls="none", marker="^", ms=11, mfc="none",
                         mec=COLOR, mew=1.5, transform=tr, clip_on=False)  # fmt: skip
        _mark(tri, where, kind)
    elif kind == "sliding":
        (guide,) = ax.plot([x, x], [0.0, 1.0], color=COLOR, lw=1.0, ls="-.", transform=tr)
        _mark(guide, where, kind)
        (rollers,) = ax.plot([x - outward * 0.01 * L] * 2, [BASE + 0.02, BASE + 0.10],
                             ls="none", marker="o", ms=6, mfc="none", mec=COLOR,
                             transform=tr, clip_on=False)  # fmt: skip
        _mark(rollers, where, kind)
    else:  # elastic
        _spring(ax, x, where)


def _point(ax: Axes, p: PointSupport, i: int) -> None:
    where = f"point{i}"
    if p.pinned:
        tr = ax.get_xaxis_transform()
        (tri,) = ax.plot([p.position], [BASE + 0.04], ls="none", marker="^", ms=11,
                         mfc="none", mec=COLOR, mew=1.5, transform=tr)  # fmt: skip
        _mark(tri, where, "pinned")
    else:
        _spring(ax, p.position, where)


def draw_supports(ax: Axes, pipe: Pipe) -> None:
    """Draw ``pipe``'s end and intermediate supports on ``ax`` (x along the pipe [m])."""
    L = float(pipe.L)
    lo, hi = ax.get_xlim()  # the curves' limits, before the symbols (the wall) extend them
    _end(ax, pipe.supports.x0, 0.0, "x0", -1.0, L)
    _end(ax, pipe.supports.xL, L, "xL", 1.0, L)
    for i, p in enumerate(pipe.intermediate_supports):
        _point(ax, p, i)
    ax.set_xlim(min(lo, -0.04 * L), max(hi, 1.04 * L))
