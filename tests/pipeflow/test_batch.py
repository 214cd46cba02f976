"""The batched summaries (pipeflow.batch) against the single run of every case.

Each case is also run by :func:`pipeflow.simulation.simulate` and reduced by the registry's
own ``summarize`` (the per-case path of a study): every column agrees to 1e-10 relative
(sigma, which is rounding at v = 0, relative to the eigenvalue's modulus), over a grid
that includes v = 0, w0 = 0, flows past the critical velocity (diverged: stopped at the
bound), slow growth under fast spin (diverging), a tip mass, damping,
the 'tip' initial shape and a tight divergence bound.

Time-variant cases (the stacked magnus, :mod:`pipeflow.solvers.magnus.stack`) are held to
the same 1e-10, not only to their tolerance: the stacked run takes each case's own step
control, so the same steps, orders, attempts and estimates as the single run (asserted on
the diagnostics), and the same step exponentials; only the order of the additions in the
stacked products can differ, rounding (measured: the states agree bit for bit on this
machine).  That the stacked states are right, not only equal to the single run's, is
checked against the reference integrator (DOP853 at rtol 1e-12) within the run's own
tolerance.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from pipeflow.batch import eligible, lti_summaries, summaries, time_variant
from pipeflow.computations import documents
from pipeflow.computations.registry import COMPUTATIONS, summarize_simulation
from pipeflow.computations.study_runner import Piece, run_cases
from pipeflow.errors import BudgetExceeded, InvalidInput
from pipeflow.loading import Loading
from pipeflow.loads import PointForce
from pipeflow.model import build_model
from pipeflow.paper import PAPER_PIPE
from pipeflow.profiles import Constant, Harmonic, polynomial
from pipeflow.schema.simulation import PAPER_EXAMPLE, SimulationSpec
from pipeflow.simulation import Simulation, simulate
from pipeflow.solvers import SOLVERS, Options, Problem, SolverOutput
from pipeflow.solvers.base import relative_difference
from pipeflow.solvers.magnus.stack import solve_many

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


def _assert_rows_equal(sims: list[Simulation], rows: list[object]) -> set[str]:
    statuses = set()
    for sim, row in zip(sims, rows, strict=True):
        assert row is not None, sim
        single = summarize_simulation(documents.simulation(simulate(sim)))
        statuses.add(single["result_status"])
        assert vars(row)["method_used"] == single["method_used"], sim
        assert vars(row)["result_status"] == single["result_status"], sim
        peak = single["peak_tip_displacement"]
        assert _relative(vars(row)["peak_tip_displacement"], peak, abs(peak)) <= RTOL, sim
        scale = abs(complex(single["final_sigma_1"], single["final_omega_1"]))
        for name in ("final_sigma_1", "final_omega_1"):
            assert _relative(vars(row)[name], single[name], scale) <= RTOL, (sim, name)
    return statuses


def _varying_cases() -> list[Simulation]:
    """Time-variant cases, 4 modes and 0.2 s (each single run well under a second)."""
    base = Simulation(
        PAPER_PIPE, polynomial(0, 0.4), Constant(100.0), modes=4, t_end=0.2, samples=101
    )
    damped = dataclasses.replace(PAPER_PIPE, kelvin_voigt=1e-4, viscous=2.0)
    return [
        base,
        dataclasses.replace(base, flow=polynomial(0, 40.0), spin=Constant(0.0)),
        # the flow past v_cr = 27.69 m/s: a growing branch at t_end (diverging)
        dataclasses.replace(base, flow=polynomial(30.0, 1.0)),
        # spin-up: the forcing in the border column of the Magnus generator
        dataclasses.replace(base, flow=Constant(5.0), spin=polynomial(0, 500.0)),
        dataclasses.replace(base, spin=Harmonic(100.0, 20.0, 10.0)),
        dataclasses.replace(base, pipe=damped),
        # from the straight pipe with a tip velocity: the peak is late, not at t = 0
        dataclasses.replace(base, initial_shape="tip", u0=0.0, du0=0.1),
        dataclasses.replace(base, divergence_bound=1e-3),  # diverging by the bound
        dataclasses.replace(base, options=Options(tolerance=1e-10)),  # refines (attempts > 1)
        dataclasses.replace(base, method="magnus", options=Options(step=1e-3)),  # a user step
        dataclasses.replace(base, samples=41, t_end=0.5, eigen_samples=17),  # another grid
        dataclasses.replace(base, modes=6),  # another state size
    ]


def test_time_variant_summaries_equal_the_single_runs() -> None:
    sims = _varying_cases()
    assert all(time_variant(s) for s in sims)
    statuses = _assert_rows_equal(sims, summaries(sims))
    assert statuses == {"ok", "diverged"}  # the growing case passes the divergence bound


def _problem(sim: Simulation) -> Problem:
    model = build_model(sim.pipe, sim.modes)
    d0, v0 = model.initial_state(sim.u0, sim.du0, sim.initial_shape)
    t = np.linspace(0.0, sim.t_end, sim.samples)
    return Problem(model, Loading(sim.flow, sim.spin), model.to_balanced(d0, v0), t, sim.options)


def test_stacked_magnus_has_the_single_runs_control_and_diagnostics() -> None:
    cases = _varying_cases()
    problems = [_problem(cases[i]) for i in (0, 2, 3, 8, 10, 11)]  # refining, diverging, grids
    stacked = solve_many(problems)
    attempts = set()
    for problem, out in zip(problems, stacked, strict=True):
        assert isinstance(out, SolverOutput)
        single = SOLVERS["magnus"].solve(problem)
        # the estimate is a difference of two runs' states (~1e-9 of them): the states'
        # rounding (1e-16, different product orders in the stack) moves it by up to ~1e-7
        # of itself; every other entry (steps, attempts, orders, method) is equal
        ignore = {"solve_seconds", "estimated_relative_error"}
        assert {k: v for k, v in out.diagnostics.items() if k not in ignore} == {
            k: v for k, v in single.diagnostics.items() if k not in ignore
        }
        assert out.diagnostics["estimated_relative_error"] == pytest.approx(
            single.diagnostics["estimated_relative_error"], rel=1e-6
        )
        assert out.warnings == single.warnings
        # the same steps and exponentials: rounding only (see the module docstring)
        assert relative_difference(out.z, single.z) <= 1e-12
        attempts.add(out.diagnostics["attempts"])
    assert max(attempts) > 1  # the refining control is exercised


@pytest.mark.slow  # ~9 s: DOP853 at rtol 1e-12 over three runs
def test_stacked_magnus_against_the_reference_integrator() -> None:
    """Independent of the exponentials: DOP853 at rtol 1e-12 (its own error ~1e-12). The
    stacked runs' true relative state error must be within their tolerance (1e-8), with a
    factor 3 of margin: the tolerance bounds an *estimate* of the global error (the
    Richardson check is conservative for order 4 but not a strict bound)."""
    sims = [_varying_cases()[i] for i in (0, 3, 6)]
    problems = [_problem(s) for s in sims]
    for problem, out in zip(problems, solve_many(problems), strict=True):
        assert isinstance(out, SolverOutput)
        ref_problem = dataclasses.replace(problem, options=Options(rtol=1e-12, atol=1e-15))
        ref = SOLVERS["reference"].solve(ref_problem)
        N = problem.model.size
        assert relative_difference(out.z, ref.z, N) <= 3 * problem.options.tolerance


def test_time_variant_cases_the_stack_does_not_take() -> None:
    base = _varying_cases()[0]
    load = PointForce(position=PAPER_PIPE.L, force=Harmonic(0.0, 1e-3, 50.0))
    refused = [
        dataclasses.replace(base, options=Options(max_steps=10)),  # budget: single run says
        dataclasses.replace(base, options=Options(tolerance=2.0)),  # invalid tolerance
        dataclasses.replace(base, t_end=-1.0),  # refused at validation
    ]
    other = [
        dataclasses.replace(base, method="rk4"),
        dataclasses.replace(base, loads=(load,)),
        dataclasses.replace(base, mode_shape_times=(0.0,)),
    ]
    assert [time_variant(s) for s in other] == [False, False, False]
    rows = summaries([base, *refused, *other])
    assert rows[0] is not None and rows[1:] == [None] * (len(refused) + len(other))
    with pytest.raises(BudgetExceeded):
        simulate(refused[0])
    with pytest.raises(InvalidInput):
        simulate(refused[1])
    # the stack hands the single run's exception back
    outs = solve_many([_problem(refused[0]), _problem(base)])
    assert isinstance(outs[0], BudgetExceeded) and isinstance(outs[1], SolverOutput)


def test_a_study_piece_of_time_variant_cases_equals_the_per_case_path() -> None:
    """The study runner's dispatch: a piece through the simulation's ``summarize_many``
    (the stacked path) gives the rows of the per-case path (``execute`` + ``summarize``)."""
    base = COMPUTATIONS["simulation"]
    requests = [
        SimulationSpec.model_validate(
            {
                **PAPER_EXAMPLE,
                "flow": {"velocity": {"kind": "polynomial", "coefficients": [0.0, a]}},
                "rotation": {"omega0": {"kind": "constant", "value": w0}},
                "modes": 3,
                "time": {"t_end": 0.1, "samples": 51},
            }
        )
        for a in (0.5, 5.0)
        for w0 in (0.0, 80.0)
    ]
    stacked = run_cases(Piece(base, requests=requests))
    per_case = [
        {"status": "ok", **summarize_simulation(base.execute(request))} for request in requests
    ]
    for got, want in zip(stacked, per_case, strict=True):
        assert got.keys() == want.keys()
        for name, value in want.items():
            if isinstance(value, float):
                assert _relative(got[name], value, abs(value)) <= RTOL, name
            else:
                assert got[name] == value, name


def test_time_variant_chunks_bound_the_stacked_state_histories(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """At most MAX_RUNS cases a chunk, fewer where their state histories would pass
    STACK_BYTES (a 40-mode, 20,001-sample case alone holds ~40 MB)."""
    from pipeflow import batch

    cases = [(i, batch._Varying(s, build_model(s.pipe, s.modes), _problem(s)))
             for i, s in enumerate(_varying_cases() * 2)]  # fmt: skip
    sizes = [len(c) for c in batch._chunks(cases)]
    assert sizes == [16, 8]
    one = 3 * 8 * cases[0][1].problem.t.size * (cases[0][1].problem.model.size + 1)
    monkeypatch.setattr(batch, "STACK_BYTES", 2 * one)
    chunks = batch._chunks(cases)
    assert max(len(c) for c in chunks) <= 2 and sum(len(c) for c in chunks) == len(cases)
    assert [i for c in chunks for i, _ in c] == list(range(len(cases)))


def test_a_supported_pipe_is_left_to_the_single_run() -> None:
    """A held tip (pinned-pinned, issue 31) is rounding in the tip's series, so the batched
    summaries (which read the tip only) would call a diverging span's peak a number made of
    noise: the single run, which watches interior stations, takes it (seam found at the merge:
    peak 0.135 m from the batch against 7e-18 m from simulate at u = 4)."""
    from pipeflow.supports import Support, Supports

    spool = dataclasses.replace(PAPER_PIPE, supports=Supports(Support("pinned"), Support("pinned")))
    lti = Simulation(spool, Constant(5.0), Constant(0.0), modes=4, t_end=0.1, samples=11)
    tv = dataclasses.replace(lti, flow=polynomial(0, 0.4))
    assert not eligible(lti) and not time_variant(tv)
    assert lti_summaries([lti]) == [None]
    cantilever = dataclasses.replace(lti, pipe=PAPER_PIPE)
    assert eligible(cantilever) and time_variant(dataclasses.replace(tv, pipe=PAPER_PIPE))
