"""The loads as exact states of the Magnus step (:mod:`pipeflow.solvers.magnus.states`).

Checked against the loads' own evaluation (:meth:`pipeflow.loads.ExternalForcing.vector`,
sampled: an identity, 1e-12 relative: the states' matrix exponential and trigonometric
closed forms round differently) and, for whole runs at constant coefficients, against cma's
closed-form particular solution (independent: modal decomposition and exact integrals).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
import scipy.linalg

from pipeflow.loads import ExternalForcing, PointForce, project_loads
from pipeflow.model import build_model
from pipeflow.paper import PAPER_PIPE
from pipeflow.profiles import (
    Constant,
    HalfSine,
    Harmonic,
    Impulse,
    Profile,
    polynomial,
    table,
)
from pipeflow.simulation import Simulation, simulate
from pipeflow.solvers.magnus.states import MAX_STATES, ForcingStates

L = PAPER_PIPE.L
MODEL = build_model(PAPER_PIPE, 4)

EXACT: dict[str, tuple[Profile, ...]] = {
    "constant": (Constant(2.0),),
    "harmonic": (Harmonic(0.0, 1.5, 700.0, 0.4),),
    "harmonic with a mean": (Harmonic(0.7, 1.5, 300.0, -1.1),),
    "cubic": (polynomial(1.0, -2.0, 3.0, -4.0),),
    "two loads, shared rate": (Constant(1.0), Harmonic(-0.5, 2.0, 0.0)),
    "two loads": (Constant(1.0), Harmonic(0.0, 2.0, 50.0)),
}


def _forcing(profiles: tuple[Profile, ...]) -> ExternalForcing | None:
    stations = np.linspace(0.4, 1.0, len(profiles)) * L
    loads = tuple(PointForce(x, p) for x, p in zip(stations, profiles, strict=True))
    return project_loads(MODEL, loads)


@pytest.mark.parametrize("case", list(EXACT))
def test_the_states_reproduce_the_loads(case: str) -> None:
    """C_n exp(s Lambda') e_0 = f(t_n + s): at step starts t_n and offsets s inside a
    step (the step's forcing), for every exact profile kind and sums of loads."""
    forcing = _forcing(EXACT[case])
    assert forcing is not None
    states = ForcingStates.of(forcing, MODEL.size)
    assert states is not None and states.count <= MAX_STATES
    rng = np.random.default_rng(1)
    starts = rng.uniform(0.0, 2.0, 7)
    C = states.border(starts)
    for s in (0.0, 1e-3, 0.05):
        w = scipy.linalg.expm(s * states.generator)[:, 0]
        got = C @ w
        want = forcing.vector(starts + s)
        scale = np.abs(forcing.vector(np.linspace(0.0, 2.0, 201))).max()
        assert np.abs(got - want).max() <= 1e-12 * scale, (case, s)


@pytest.mark.parametrize(
    "profile",
    [
        table([0.0, 1.0, 2.0], [0.0, 1.0, 0.0]),
        HalfSine(1.0, 0.1, 0.2),
        Impulse(1.0, 0.1),
        Harmonic(1.0, 1.0, 10.0),  # with the second load below: 5 states
    ],
)
def test_profiles_without_global_states_are_interpolated(profile: Profile) -> None:
    """Tables, pulses and impulses have no form on the whole run, and more than MAX_STATES
    states would make the exponential dearer than the interpolation's: None."""
    forcing = _forcing((profile, Harmonic(0.0, 1.0, 20.0)))
    assert forcing is not None
    assert ForcingStates.of(forcing, MODEL.size) is None


@pytest.mark.parametrize(
    "profile",
    [
        Harmonic(0.0, 1e-6, 700.0),
        Harmonic(1e-6, 1e-6, 300.0, 0.3),
        polynomial(1e-6, 2e-6, -1e-6),
    ],
)
def test_magnus_is_exact_for_constant_coefficients_with_exact_loads(profile: Profile) -> None:
    """The paper's pipe at v = 0.4 m/s, w0 = 100 rad/s, 10 modes, 1 s, 2,001 samples, a tip
    force from rest: magnus equals cma's closed form to rounding (one unit roundoff per
    step, 2,000 steps: ~4e-13; measured 3e-13 .. 1.1e-12; 1e-10 leaves room for other
    CPUs), on its first attempt.  With the forcing interpolated on each step the 700 rad/s
    case refined to 4,000 steps and differed by 6e-10."""
    sim = Simulation(
        pipe=PAPER_PIPE,
        flow=Constant(0.4),
        spin=Constant(100.0),
        u0=0.0,
        modes=10,
        t_end=1.0,
        samples=2001,
        loads=(PointForce(L, profile),),
    )
    exact = simulate(replace(sim, method="cma"))
    magnus = simulate(replace(sim, method="magnus"))
    assert magnus.method_used == "magnus"
    assert magnus.diagnostics["attempts"] == 1 and magnus.diagnostics["steps"] == 2000
    peak = np.abs(exact.d).max()
    assert peak > 0 and np.abs(magnus.d - exact.d).max() <= 1e-10 * peak
