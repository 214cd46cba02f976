"""Shared fixtures: small versions of the paper's example that keep the reference cheap."""

from __future__ import annotations

import functools
from typing import Any

from pydantic import BaseModel

from pipeflow.paper import PAPER_FLOWS, PAPER_PIPE, PAPER_PIPE_JSON, PAPER_SPIN
from pipeflow.profiles import Profile
from pipeflow.simulation import Result, Simulation, simulate
from pipeflow.solvers import Options


def paper_sim(flow: Profile, method: str = "cma", **kw: object) -> Simulation:
    """The paper's pipe at w0 = 100 rad/s; 4 modes and 0.25 s unless overridden."""
    base: dict[str, object] = dict(
        flow=flow, spin=PAPER_SPIN, modes=4, t_end=0.25, samples=501, method=method
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


#: the paper's pipe as JSON
PIPE: dict[str, Any] = dict(PAPER_PIPE_JSON)
#: a tiny real request of every computation
TINY: dict[str, dict[str, Any]] = {
    "simulation": {"pipe": PIPE, "modes": 2, "time": {"t_end": 0.01, "samples": 11}},
    "compare": {
        "simulation": {"pipe": PIPE, "modes": 2, "time": {"t_end": 0.01, "samples": 11}},
        "methods": ["cma", "rk4"],
    },
    "stability": {"pipe": PIPE, "modes": 3, "velocity_range": [0.0, 40.0], "points": 11},
    "argand": {"pipe": PIPE, "modes": 3, "tracked_modes": 2, "points": 5}
    | {"velocity_range": [0.0, 40.0]},
    "campbell": {"pipe": PIPE, "modes": 3, "tracked_modes": 2, "points": 5}
    | {"spin_range": [0.0, 1000.0]},
    "spin_map": {"pipe": PIPE, "modes": 3, "velocity_points": 5, "spin_points": 2}
    | {"velocity_range": [0.0, 60.0], "spin_range": [0.0, 1000.0]},
    "beta_map": {"modes": 3, "beta_points": 2, "u_points": 11},
    "resonance_chart": {"pipe": PIPE, "modes": 2, "mean_velocity": 10.0}
    | {"amplitude_range": [0.0, 5.0], "frequency_range": [500.0, 1500.0]}
    | {"amplitude_points": 2, "frequency_points": 2},
    "floquet": {"pipe": PIPE, "modes": 2}
    | {"flow": {"velocity": {"kind": "harmonic", "mean": 10.0, "amplitude": 5.0}}},
}
TINY["floquet"]["flow"]["velocity"]["frequency"] = 1000.0
TINY["frequency_response"] = {
    "pipe": PIPE,
    "modes": 3,
    "operating_points": [{"velocity": 5.0, "omega0": 100.0}, {"velocity": 10.0, "omega0": 100.0}],
    "load": {"kind": "point_force", "position": PIPE["L"]},
    "response": {"positions": [PIPE["L"] / 3, 2 * PIPE["L"] / 3, PIPE["L"]]},
    "frequencies": {"min": 10.0, "max": 6000.0, "count": 50, "spacing": "log"},
}
TINY["state_space"] = {
    "pipe": PIPE,
    "modes": 3,
    "flow": {"velocity": {"kind": "constant", "value": 5.0}},
    "rotation": {"omega0": {"kind": "constant", "value": 100.0}},
    "load": {"kind": "point_force", "position": PIPE["L"]},
    "response": {"positions": [PIPE["L"]]},
}
TINY["study"] = {
    "base": {"kind": "simulation", "spec": TINY["simulation"]},
    "cases": [{}, {"pipe.E": 8e9}],
}


def tiny_request(name: str) -> BaseModel:
    """The validated tiny request of computation ``name`` (its ``kind`` added if it has one)."""
    from pipeflow.computations.registry import COMPUTATIONS

    model = COMPUTATIONS[name].request
    body = TINY[name]
    return model.model_validate({"kind": name, **body} if "kind" in model.model_fields else body)
