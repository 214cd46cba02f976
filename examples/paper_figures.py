"""Reproduce the figures of Wang & Zhong (CMES 114(1), 2018), section 5, as PNG files.

The paper's pipe (E = 7.8e9 Pa, I = 1.21e-17 m^4, L = 0.025 m, M1 = 1.884e-5 kg/m,
M2 = 1.6485e-5 kg/m), u0 = 1 mm (shape phi_1 of eq. 3, tip 2.72 mm), du0 = 0, 10 modes,
t in [0, 1] s, complex modal analysis.  Every case gives three figures: the tip
displacement u(L, t) [m], the damping sigma [1/s] and the fundamental frequency
omega [rad/s] of the frozen state matrix.

- Figs. 2-16: w0 = 100 rad/s and v = a, a t, a t^2, -a, -a t with a = 0.1, 0.2, 0.3, 0.4
  (in m/s, m/s^2, m/s^3).
- Figs. 17-28: v = 0.2, 0.2 t, -0.2, -0.2 t with several spins w0 (the paper does not
  list its spins; we use 0, 100, 200 and 300 rad/s, see ``SPINS``).

Usage::

    python examples/paper_figures.py --out figures            # all 27 figures, ~15 s
    python examples/paper_figures.py --out figures --only 5 6 7 --format svg

The file names are ``fig05_tip_displacement.png`` and so on.
"""

from __future__ import annotations

import argparse
import sys
import time
from dataclasses import dataclass
from pathlib import Path

from pipeflow.computations import documents
from pipeflow.io.plots import figure, to_bytes
from pipeflow.paper import PAPER_PIPE
from pipeflow.profiles import Constant, Profile, polynomial
from pipeflow.simulation import Simulation, simulate

AMPLITUDES = (0.1, 0.2, 0.3, 0.4)  # a [m/s^(k+1)] for v = a t^k
SPINS = (0.0, 100.0, 200.0, 300.0)  # w0 [rad/s] for Figs. 17-28
KINDS = ("tip_displacement", "damping", "frequency")


@dataclass(frozen=True)
class Case:
    """One family of curves: its first figure number and the runs it overlays."""

    first_figure: int
    title: str  # the profile as the paper writes it
    runs: tuple[tuple[str, Profile, float], ...]  # (legend, v(t) [m/s], w0 [rad/s])


def _flow(sign: float, a: float, power: int) -> Profile:
    return polynomial(*([0.0] * power + [sign * a]))


def _v_label(sign: float, a: float, power: int) -> str:
    t = {0: "", 1: " t", 2: " t²"}[power]
    unit = {0: "m/s", 1: "m/s²", 2: "m/s³"}[power]
    return f"v = {sign * a:g}{t} ({unit})"


def cases() -> list[Case]:
    """The paper's nine families of curves (Figs. 2-28), in figure order."""
    out = []
    fig = 2
    for sign, power, title in (
        (1.0, 0, "v = a"),
        (1.0, 1, "v = a t"),
        (1.0, 2, "v = a t²"),
        (-1.0, 0, "v = -a"),
        (-1.0, 1, "v = -a t"),
    ):
        runs = tuple((_v_label(sign, a, power), _flow(sign, a, power), 100.0) for a in AMPLITUDES)
        out.append(Case(fig, f"{title}, ω0 = 100 rad/s", runs))
        fig += 3
    for sign, power in ((1.0, 0), (1.0, 1), (-1.0, 0), (-1.0, 1)):
        runs = tuple((f"ω0 = {w:g} rad/s", _flow(sign, 0.2, power), w) for w in SPINS)
        out.append(Case(fig, _v_label(sign, 0.2, power), runs))
        fig += 3
    return out


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    p.add_argument("--out", type=Path, default=Path("figures"), help="output directory")
    p.add_argument("--only", type=int, nargs="*", help="figure numbers to draw (default all)")
    p.add_argument("--format", choices=("png", "svg"), default="png")
    p.add_argument("--method", default="cma", help="solver (cma, rk4, reference, ...)")
    p.add_argument("--modes", type=int, default=10, help="Galerkin modes (paper: 10)")
    p.add_argument("--samples", type=int, default=2001, help="output times in [0, 1] s")
    p.add_argument("--dpi", type=int, default=100)
    args = p.parse_args(argv)

    args.out.mkdir(parents=True, exist_ok=True)
    wanted = set(args.only) if args.only else None
    start = time.perf_counter()
    for case in cases():
        numbers = {case.first_figure + k: kind for k, kind in enumerate(KINDS)}
        if wanted is not None and not wanted & numbers.keys():
            continue
        series = []
        for label, flow, spin in case.runs:
            sim = Simulation(
                PAPER_PIPE,
                flow=flow,
                spin=Constant(spin),
                modes=args.modes,
                t_end=1.0,
                samples=args.samples,
                method=args.method,
                eigen_modes=1,
                # the paper draws the linear equation's growth for v < 0 over the whole
                # second, far past the model's range (the default bound stops it at 2 u0)
                divergence_bound=1e300,
            )
            series.append((label, documents.simulation(simulate(sim))))
        for number, kind in numbers.items():
            if wanted is not None and number not in wanted:
                continue
            fig = figure(
                kind, series, title=f"Fig. {number}: {kind.replace('_', ' ')}, {case.title}"
            )
            path = args.out / f"fig{number:02d}_{kind}.{args.format}"
            path.write_bytes(to_bytes(fig, args.format, dpi=args.dpi))
            print(f"wrote {path}", file=sys.stderr)
    print(f"done in {time.perf_counter() - start:.1f} s", file=sys.stderr)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
