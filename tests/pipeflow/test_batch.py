"""The batched LTI summaries (pipeflow.batch) against the single run of every case.

Each case is also run by :func:`pipeflow.simulation.simulate` and reduced by the registry's
own ``summarize`` (the per-case path of a study): every column agrees to 1e-10 relative
(sigma, which is rounding at v = 0, relative to the eigenvalue's modulus), over a grid
that includes v = 0, w0 = 0, flows past the critical velocity (diverged: stopped at the
bound), slow growth under fast spin (diverging), a tip mass, damping,
the 'tip' initial shape and a tight divergence bound.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from pipeflow.batch import eligible, lti_summaries
from pipeflow.paper import PAPER_PIPE
from pipeflow.profiles import Constant, polynomial
from pipeflow.schema import documents
from pipeflow.schema.registry import summarize_simulation
from pipeflow.simulation import Simulation, simulate
from pipeflow.solvers import Options

RTOL = 1e-10


def _cases() -> list[Simulation]:
    damped = dataclasses.replace(PAPER_PIPE, kelvin_voigt=1e-4, viscous=2.0)
    nozzle = dataclasses.replace(PAPER_PIPE, tip_mass=0.01)
    out = []
    for pipe in (PAPER_PIPE, damped, nozzle):
        for v in (0.0, 5.0, 27.0, 40.0):  # v_cr = 27.69 m/s at w0 = 100 rad/s
            for w0 in (0.0, 100.0, 200.0):
                out.append(
                    Simulation(pipe, Constant(v), Constant(w0), modes=6, t_end=0.2, samples=201)
                )
    base = Simulation(PAPER_PIPE, Constant(10.0), Constant(50.0), modes=4, t_end=0.2, samples=51)
    out += [
        dataclasses.replace(base, initial_shape="tip", u0=0.002, du0=0.1),
        # diverged: stopped at the bound
        dataclasses.replace(base, divergence_bound=1e-4, method="cma"),
        dataclasses.replace(base, samples=1001, t_end=1.0),  # the uniform-grid tables
        dataclasses.replace(base, modes=10, samples=201, t_end=1.0),
    ]
    return out


def _relative(a: float, b: float, scale: float) -> float:
    return abs(a - b) / max(scale, 1e-300)


def test_batched_summaries_equal_the_single_runs() -> None:
    sims = _cases()
    rows = lti_summaries(sims)
    statuses = set()
    for sim, row in zip(sims, rows, strict=True):
        assert row is not None, sim
        single = summarize_simulation(documents.simulation(simulate(sim)))
        statuses.add(single["result_status"])
        assert row.method_used == single["method_used"] == "cma"
        assert row.result_status == single["result_status"], sim
        peak = single["peak_tip_displacement"]
        assert _relative(row.peak_tip_displacement, peak, abs(peak)) <= RTOL, sim
        scale = abs(complex(single["final_sigma_1"], single["final_omega_1"]))
        assert _relative(row.final_omega_1, single["final_omega_1"], scale) <= RTOL, sim
        assert _relative(row.final_sigma_1, single["final_sigma_1"], scale) <= RTOL, sim
        if abs(single["final_sigma_1"]) > 1e-6 * scale:  # not rounding: relative to itself
            sig = single["final_sigma_1"]
            assert _relative(row.final_sigma_1, sig, abs(sig)) <= RTOL, sim
    assert statuses == {"ok", "diverging", "diverged"}


def test_cases_the_batch_does_not_take_are_left_to_the_single_run() -> None:
    base = Simulation(PAPER_PIPE, Constant(5.0), Constant(100.0), modes=4, t_end=0.1, samples=11)
    others = [
        dataclasses.replace(base, flow=polynomial(0, 0.4)),  # time-variant
        dataclasses.replace(base, method="rk4"),
        dataclasses.replace(base, mode_shape_times=(0.0,)),
        dataclasses.replace(base, t_end=-1.0),  # refused by the library: its error row
        dataclasses.replace(base, options=Options(condition_limit=1.0)),  # cma would march
        dataclasses.replace(base, flow=Constant(1e4), t_end=10.0),  # could overflow
    ]
    assert [eligible(s) for s in others[:3]] == [False, False, False]
    assert lti_summaries([base, *others]) == [lti_summaries([base])[0], *[None] * len(others)]
    np.testing.assert_equal(lti_summaries([]), [])


@pytest.mark.parametrize("modes", [1, 2])
def test_tiny_models(modes: int) -> None:
    sim = Simulation(PAPER_PIPE, Constant(3.0), Constant(0.0), modes=modes, t_end=0.1, samples=3)
    [row] = lti_summaries([sim])
    single = summarize_simulation(documents.simulation(simulate(sim)))
    assert row is not None and row.result_status == single["result_status"]
    assert abs(row.peak_tip_displacement - single["peak_tip_displacement"]) <= RTOL * abs(
        single["peak_tip_displacement"]
    )
