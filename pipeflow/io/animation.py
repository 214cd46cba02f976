"""A complex mode shape in motion, as an animated GIF (matplotlib frames, Pillow).

A branch xi = sigma + i omega of the frozen spectrum with complex shape Phi(x) moves as
u(x, t) = Re(Phi(x) e^(xi t)); over one period 2 pi / omega its form is
Re(Phi(x) e^(i theta)) for theta in [0, 2 pi) (the envelope e^(sigma t) left out, so a
growing and a decaying branch are both shown at their shape's scale, max |Phi| = 1).  A
real Phi (an undamped, non-gyroscopic mode) is a standing wave; the flow's Coriolis term
makes Phi complex and the shape travels along the pipe, which is what this shows.

:func:`phases` gives the curves (the data), :func:`mode_shape_gif` draws them frame by
frame on an Agg canvas and writes a looping GIF with Pillow (matplotlib's own dependency):
deterministic bytes for a given result.
"""

from __future__ import annotations

import io
import math
from typing import TYPE_CHECKING, Any

import numpy as np

from pipeflow.io.plots import PlotError

if TYPE_CHECKING:
    from pipeflow.model import Pipe

#: frames of one period, and the most a request may ask
DEFAULT_FRAMES = 24
MAX_FRAMES = 96


def _branch(result: dict[str, Any], mode: int | None, time_index: int) -> tuple[Any, Any, dict]:
    block = result.get("mode_shapes") or {}
    if not block.get("modes"):
        raise PlotError("this result has no mode shapes (ask output.mode_shapes)", "mode")
    modes = block["modes"]
    if mode is None:
        branch = modes[0]
    else:
        found = [m for m in modes if m["mode"] == mode]
        if not found:
            have = ", ".join(str(m["mode"]) for m in modes)
            raise PlotError(f"no mode {mode} in this result's mode shapes; it has {have}", "mode")
        branch = found[0]
    if not 0 <= time_index < len(block["t"]):
        raise PlotError(
            f"time_index {time_index} is outside 0..{len(block['t']) - 1}", "time_index"
        )
    return np.asarray(block["x"], dtype=float), branch, block


def phases(
    result: dict[str, Any], mode: int | None = None, time_index: int = 0, frames: int = 24
) -> tuple[Any, Any]:
    """``(x [m], u [-])``: u[k] = Re(Phi(x) e^(i theta_k)), theta_k = 2 pi k / frames, for
    branch ``mode`` (default: the first) at mode-shape time ``time_index``."""
    if not 2 <= frames <= MAX_FRAMES:
        raise PlotError(f"frames must be between 2 and {MAX_FRAMES}", "frames")
    x, branch, _ = _branch(result, mode, time_index)
    phi = np.asarray(branch["real"][time_index]) + 1j * np.asarray(branch["imag"][time_index])
    theta = 2 * math.pi * np.arange(frames) / frames
    return x, (phi[None, :] * np.exp(1j * theta)[:, None]).real


def mode_shape_gif(
    result: dict[str, Any],
    mode: int | None = None,
    time_index: int = 0,
    frames: int = DEFAULT_FRAMES,
    duration_ms: int = 80,
    pipe: Pipe | None = None,
) -> bytes:
    """A looping GIF of branch ``mode`` at mode-shape time ``time_index`` moving over one
    period (:func:`phases`), ``frames`` frames of ``duration_ms`` each; ``pipe`` draws its
    supports (:mod:`pipeflow.io.support_symbols`), None none."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    from PIL import Image

    x, u = phases(result, mode, time_index, frames)
    _, branch, block = _branch(result, mode, time_index)
    t = block["t"][time_index]
    sigma, omega = branch["sigma"][time_index], branch["omega"][time_index]
    # one figure, its layout fixed once; each frame moves the line only
    fig = Figure(figsize=(5.0, 2.8), dpi=80)
    canvas = FigureCanvasAgg(fig)
    ax = fig.add_axes((0.14, 0.2, 0.82, 0.68))
    (line,) = ax.plot(x, u[0], lw=2.0, color="#1f77b4")
    ax.axhline(0.0, color="0.6", lw=0.8)
    ax.set_xlim(float(x[0]), float(x[-1]))
    ax.set_ylim(-1.05, 1.05)
    if pipe is not None:
        from pipeflow.io.support_symbols import draw_supports

        draw_supports(ax, pipe)
    ax.set_xlabel("position along the pipe x [m]")
    ax.set_ylabel("Re(Φ e^(iθ)) [-]")
    ax.set_title(
        f"mode {branch['mode']} at t = {t:g} s: σ = {sigma:.4g} 1/s, ω = {omega:.4g} rad/s",
        fontsize=9,
    )
    images = []
    for k in range(frames):
        line.set_ydata(u[k])
        canvas.draw()
        rgba = np.asarray(canvas.buffer_rgba())
        images.append(Image.fromarray(rgba[:, :, :3]).convert("P", palette=Image.Palette.ADAPTIVE))
    buf = io.BytesIO()
    images[0].save(
        buf, format="GIF", save_all=True, append_images=images[1:], duration=duration_ms, loop=0
    )
    return buf.getvalue()
