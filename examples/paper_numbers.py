"""The numbers behind the paper's Figs. 2-4 (Wang & Zhong 2018, section 5).

v = a m/s (a = 0.1 ... 0.4), w0 = 100 rad/s, the paper's pipe, u0 = 1 mm, 10 modes, 1 s:
tip displacement at a few times (Fig. 2), damping sigma (Fig. 3) and fundamental frequency
omega (Fig. 4), plus the CMA and RK4 wall times of Table 1 measured on this machine and the
difference between the two solutions.

Run:  python examples/paper_numbers.py [--modes 10] [--rk4]
"""

from __future__ import annotations

import argparse

import numpy as np

from pipeflow.paper import PAPER_PIPE
from pipeflow.profiles import Constant
from pipeflow.simulation import Simulation, simulate


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--modes", type=int, default=10, help="Galerkin modes (default 10)")
    parser.add_argument("--rk4", action="store_true", help="also run RK4 (Table 1)")
    args = parser.parse_args(argv)
    probe = [0.0, 0.1, 0.25, 0.5, 1.0]
    print(f"paper pipe, w0 = 100 rad/s, u0 = 1 mm, {args.modes} modes, 1 s, 2001 samples")
    print(
        "v [m/s] | u_tip(t) [mm] at t = " + ", ".join(f"{t:g}" for t in probe) + " s"
        " | sigma_1 [1/s] | omega_1 [rad/s] | cma [s]"
        + (" | rk4 [s] | max|cma-rk4| [m]" if args.rk4 else "")
    )
    for a in (0.1, 0.2, 0.3, 0.4):
        sim = Simulation(PAPER_PIPE, flow=Constant(a), spin=Constant(100.0), modes=args.modes)
        res = simulate(sim)
        idx = [int(np.argmin(np.abs(res.t - t))) for t in probe]
        row = f"{a:7.1f} | " + ", ".join(f"{1e3 * res.tip_displacement[i]:+.5f}" for i in idx)
        row += f" | {res.frozen.sigma[0, 0]:.4f} | {res.frozen.omega[0, 0]:.4f}"
        row += f" | {res.diagnostics['solve_seconds']:.4f}"
        if args.rk4:
            rk = simulate(
                Simulation(
                    PAPER_PIPE,
                    flow=Constant(a),
                    spin=Constant(100.0),
                    modes=args.modes,
                    method="rk4",
                )
            )
            diff = float(np.max(np.abs(rk.tip_displacement - res.tip_displacement)))
            row += f" | {rk.diagnostics['solve_seconds']:.3f} | {diff:.2e}"
        print(row)


if __name__ == "__main__":
    main()
