"""Shared fixtures: small versions of the paper's example that keep the reference cheap."""

from __future__ import annotations

import functools

from pipeflow.model import PAPER_PIPE
from pipeflow.profiles import Constant, Profile, polynomial
from pipeflow.simulation import Result, Simulation, simulate
from pipeflow.solvers import Options

#: the paper's flow cases (section 5), a = 0.4 m/s
PAPER_FLOWS: dict[str, Profile] = {
    "v=0.4": Constant(0.4),
    "v=0.4t": polynomial(0, 0.4),
    "v=0.4t^2": polynomial(0, 0, 0.4),
    "v=-0.4": Constant(-0.4),
    "v=-0.4t": polynomial(0, -0.4),
}


def paper_sim(flow: Profile, method: str = "cma", **kw: object) -> Simulation:
    """The paper's pipe at w0 = 100 rad/s; 4 modes and 0.25 s unless overridden."""
    base: dict[str, object] = dict(
        flow=flow, spin=Constant(100.0), modes=4, t_end=0.25, samples=501, method=method
    )
    base.update(kw)
    return Simulation(PAPER_PIPE, **base)  # type: ignore[arg-type]


@functools.cache
def reference_run(case: str, modes: int = 4, t_end: float = 0.25) -> Result:
    """Tight-tolerance DOP853 solution of a paper case (cached across tests)."""
    return simulate(
        paper_sim(
            PAPER_FLOWS[case],
            "reference",
            modes=modes,
            t_end=t_end,
            options=Options(rtol=1e-12, atol=1e-16),
        )
    )
