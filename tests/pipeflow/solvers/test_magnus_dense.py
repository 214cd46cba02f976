"""Dense output of the Magnus solver (issue 23): steps decoupled from the output samples.

On a uniform grid much finer than the step the tolerance needs, the step control runs on
every m-th output time and the samples between are filled from the coarse state at the
left end of each coarse interval (:func:`pipeflow.solvers.magnus.dense_fill`).  Checked
here: the coarse grid and its refinement, the coarse states against a run asked only for
the coarse times, every sample against a converged run (magnus at a user step of a quarter
of the sample spacing, which is never dense) and against DOP853, the estimate against the
true error at the samples, the fill's own estimate against an exact fill, the step count
against the 2,001-sample run's, and the stacked study solver.
"""

from __future__ import annotations

import numpy as np
import pytest

from pipeflow.paper import PAPER_FLOWS, PAPER_SPIN
from pipeflow.profiles import Constant, Harmonic, Profile
from pipeflow.solvers import SOLVERS, Options, Problem, SolverOutput, magnus
from pipeflow.solvers.base import relative_difference
from pipeflow.solvers.magnus import PILOT_STEPS, dense_refine, dense_selection
from pipeflow.solvers.magnus.stack import solve_many
from tests.pipeflow.cases import paper_sim
from tests.pipeflow.solvers.test_checkpoint import Memory, interrupted, run
from tests.pipeflow.solvers.test_magnus import _forced_problem
from tests.pipeflow.solvers.test_magnus import _problem as _magnus_problem

#: default options.tolerance [-]
TOLERANCE = 1e-8
#: DOP853 at rtol 1e-12 differs from a 64,000-step Magnus run by 3.4e-9..5.9e-9 on the
#: paper example (tests/pipeflow/solvers/test_magnus.py): its own error, which the
#: comparison cannot resolve below [-]
DOP853_FLOOR = 1e-8
PULSATING = Harmonic(2.0, 1.0, 50.0)  # v = 2 + sin 50 t [m/s]


def _problem(
    modes: int,
    t: np.ndarray,
    flow: Profile = PAPER_FLOWS["v=0.4t"],
    spin: Profile = PAPER_SPIN,
    loads: bool = False,
    **opts: float,
) -> Problem:
    """The paper's pipe from u0 = 1 mm (test_magnus's cases); ``loads``: its 700 rad/s
    harmonic tip force (at w0 = 100 rad/s)."""
    if loads:
        return _forced_problem(modes, t, 1e-3, flow, **opts)
    return _magnus_problem(modes, flow, spin, t, **opts)


def _converged(problem: Problem) -> np.ndarray:
    """The same problem by magnus at a user step of a quarter of the sample spacing (a user
    step is never dense): order 4 at 4x the samples' resolution, 160,000x below the error
    of the 2,000 coarse steps of the dense runs below (20x longer) and 256x below the
    fill's sample steps."""
    t = problem.t
    fine = Problem(
        problem.model,
        problem.loading,
        problem.z0,
        t,
        Options(step=float(t[1] - t[0]) / 4, max_steps=10**7),
        loads=problem.loads,
    )
    return SOLVERS["magnus"].solve(fine).z


def _samples_error(out: SolverOutput, ref: np.ndarray) -> float:
    """Largest relative state error over every output sample [-]."""
    return relative_difference(out.z, ref)


# -- the coarse grid -------------------------------------------------------------------------


def test_dense_selection_takes_every_mth_sample_of_a_fine_uniform_grid() -> None:
    """Coarse intervals of at most min(pilot step, t_end / DENSE_STEPS) = 1/2,000 s over
    1 s: every 10th of 20,001 samples, every 50th of 100,001 (the last time always in);
    2,001 or 3,001 samples are not dense (a coarse interval would be one sample), nor a
    non-uniform grid."""
    h0 = 1.0 / PILOT_STEPS
    sel = dense_selection(np.linspace(0.0, 1.0, 20001), h0)
    assert sel is not None and np.array_equal(sel, np.arange(0, 20001, 10))
    sel = dense_selection(np.linspace(0.0, 1.0, 100001), h0)
    assert sel is not None and np.array_equal(sel, np.arange(0, 100001, 50))
    sel = dense_selection(np.linspace(0.0, 1.0, 7001), h0)  # 3 samples per interval, 1 left
    assert sel is not None and sel[-1] == 7000 and np.all(np.diff(sel)[:-1] == 3)
    assert dense_selection(np.linspace(0.0, 1.0, 2001), h0) is None
    assert dense_selection(np.linspace(0.0, 1.0, 3001), h0) is None
    assert dense_selection(np.linspace(0.0, 1.0, 20001) ** 2, h0) is None


def test_dense_refinement_splits_coarse_intervals_at_samples() -> None:
    """A refinement to counts (3, 1, 5) of coarse intervals of 10, 10 and 3 samples: the
    first split at the samples nearest thirds (0, 3, 7), the second kept, the third (fewer
    samples than steps) every sample with ceil(5/3) = 2 steps; the old coarse times are
    kept (the refined attempt is compared with the previous one there)."""
    sel = np.array([0, 10, 20, 23])
    new, substeps = dense_refine(sel, np.array([3, 1, 5]))
    assert new.tolist() == [0, 3, 7, 10, 20, 21, 22, 23]
    assert substeps.tolist() == [1, 1, 1, 1, 2, 2, 2]
    assert set(sel.tolist()) <= set(new.tolist())


def test_coarse_states_equal_a_run_on_the_coarse_times() -> None:
    """4 modes over 1 s at 10,001 samples (dense: every 5th): the states at the coarse
    times are those of a run asked only for those 2,001 times (not dense), the same
    computation, so equal to the last bit; the same steps, and the same exponentials but
    the fill's."""
    t = np.linspace(0.0, 1.0, 10001)
    sel = dense_selection(t, 1.0 / PILOT_STEPS)
    assert sel is not None and sel.size == 2001
    dense = SOLVERS["magnus"].solve(_problem(4, t))
    coarse = SOLVERS["magnus"].solve(_problem(4, t[sel]))
    assert "dense_output" not in coarse.diagnostics
    info = dense.diagnostics["dense_output"]
    assert info["samples_filled"] == t.size - sel.size
    assert np.array_equal(dense.z[sel], coarse.z)
    assert dense.stats.steps == coarse.stats.steps == 2000
    exps = dense.stats.matrix_exponentials - info["fill_exponentials"]
    assert exps == coarse.stats.matrix_exponentials


def test_steps_follow_the_physics_not_the_samples() -> None:
    """The paper's example (10 modes, 1 s, v = 0.4 t, w0 = 100 rad/s) takes the steps of
    its 2,001-sample run (2,000) at 20,001 samples; before dense output it took one step per
    sample (20,000 and a 10,000-step check).  The filled run's exponentials are below 2x the
    2,001-sample run's (measured 5,136 against 3,000: 2,001 for the fill's nodes, 135 for
    its check)."""
    sparse = SOLVERS["magnus"].solve(_problem(10, np.linspace(0.0, 1.0, 2001)))
    dense = SOLVERS["magnus"].solve(_problem(10, np.linspace(0.0, 1.0, 20001)))
    assert dense.stats.steps == sparse.stats.steps == 2000
    assert dense.stats.matrix_exponentials < 2 * sparse.stats.matrix_exponentials
    info = dense.diagnostics["dense_output"]
    assert info["steps"] == 2000 and info["samples_filled"] == 18000
    assert info["method"] == "propagator linear in the sample"
    assert dense.diagnostics["estimated_relative_error"] <= TOLERANCE
    assert not dense.warnings


# -- accuracy at every sample ----------------------------------------------------------------

CASES = {
    # the paper's flow on 4 modes over 1 s (coarse steps of 5e-4 s: state error ~3e-9)
    "v=0.4t": (1.0, 10001, {}),
    # pulsating flow v = 2 + sin 50 t, forced by tip loads, forced by a varying spin: 0.2 s
    # (the exponent varies more within a coarse interval: the quadratic fill, ~1e-11..5e-10)
    "pulsating": (0.2, 20001, {"flow": PULSATING}),
    "tip force": (0.2, 20001, {"loads": True}),
    "oscillating spin": (
        0.2,
        20001,
        {"flow": Constant(0.4), "spin": Harmonic(100.0, 50.0, 2 * np.pi * 10.0)},
    ),
}


@pytest.mark.parametrize("case", list(CASES))
def test_dense_samples_are_within_the_estimate(case: str) -> None:
    """At every output sample, filled or coarse, the relative state error against a
    converged run (:func:`_converged`) is at most the reported estimate, which is at most
    the tolerance: the estimate counts the fill's own error (measured: errors 3.0e-9,
    1.5e-11, 5.3e-10, 9.5e-12 for estimates 8.5e-9, 2.0e-10, 7.9e-10, 1.6e-10; the tip
    force case's error is the fill's, 5.3e-10 against 3.7e-12 at the coarse times)."""
    t_end, samples, kw = CASES[case]
    t = np.linspace(0.0, t_end, samples)
    problem = _problem(4, t, **kw)  # type: ignore[arg-type]
    out = SOLVERS["magnus"].solve(problem)
    info = out.diagnostics["dense_output"]
    assert info["samples_filled"] >= 0.75 * samples, info
    err = _samples_error(out, _converged(problem))
    estimate = out.diagnostics["estimated_relative_error"]
    assert err <= estimate <= TOLERANCE, (err, out.diagnostics)
    assert info["fill_estimated_relative_error"] <= estimate
    assert not out.warnings


def test_a_refined_dense_run_splits_its_coarse_intervals_at_samples() -> None:
    """4 modes over 1 s at 20,001 samples, tolerance 1e-9: the first attempt (2,000 steps,
    every 10th sample) is refined by splitting coarse intervals at samples (6,000 steps,
    one per coarse interval of 3 or 4 samples, checked against the previous attempt at its
    coarse times); the samples between are still filled, and every sample is within the
    estimate against a converged run (measured: error 3.9e-12, estimate 3.8e-10)."""
    t = np.linspace(0.0, 1.0, 20001)
    problem = _problem(4, t, tolerance=1e-9)
    out = SOLVERS["magnus"].solve(problem)
    info = out.diagnostics["dense_output"]
    assert out.stats.attempts == 2
    assert "previous attempt" in out.diagnostics["error_estimate_method"]
    assert info["coarse_times"] == out.stats.steps + 1 > 2001  # one step per coarse interval
    assert info["samples_filled"] == t.size - info["coarse_times"] > 0
    err = _samples_error(out, _converged(problem))
    assert err <= out.diagnostics["estimated_relative_error"] <= 1e-9


def test_fill_estimate_bounds_the_fill_at_every_sample(monkeypatch: pytest.MonkeyPatch) -> None:
    """The cheap fill (the sample-step propagator linear in the sample) is checked on ~16
    coarse intervals; its estimate must bound its difference from the exact fill (one
    exponential per sample step, forced by FILL_SHARE = 0) at all 8,000 filled samples.
    The exact fill reports a smaller fill error (measured: 9.3e-12 and 3.4e-14)."""
    t = np.linspace(0.0, 1.0, 10001)
    linear = SOLVERS["magnus"].solve(_problem(4, t))
    monkeypatch.setattr(magnus.dense, "FILL_SHARE", 0.0)
    exact = SOLVERS["magnus"].solve(_problem(4, t))
    fast, slow = linear.diagnostics["dense_output"], exact.diagnostics["dense_output"]
    assert fast["method"] == "propagator linear in the sample"
    assert slow["method"] == "exponential per sample"
    assert slow["fill_exponentials"] > 4 * fast["fill_exponentials"]
    assert relative_difference(linear.z, exact.z) <= fast["fill_estimated_relative_error"]
    assert slow["fill_estimated_relative_error"] < fast["fill_estimated_relative_error"]


@pytest.mark.slow  # DOP853 at rtol 1e-12 on the paper example: 10-20 s
def test_paper_example_dense_samples_match_the_reference() -> None:
    """The paper's example (10 modes, 1 s, v = 0.4 t, w0 = 100 rad/s) at 20,001 samples:
    every sample within tolerance + DOP853's own floor of DOP853 at rtol 1e-12 (measured
    6.8e-9, as at 2,001 samples: the filled samples add nothing the comparison resolves,
    their largest error within 1% of the coarse samples'), the tip history likewise."""
    t = np.linspace(0.0, 1.0, 20001)
    problem = _problem(10, t)
    out = SOLVERS["magnus"].solve(problem)
    ref = SOLVERS["reference"].solve(_problem(10, t, max_steps=10**7)).z
    sel = dense_selection(t, 1.0 / PILOT_STEPS)
    assert sel is not None and "dense_output" in out.diagnostics
    assert _samples_error(out, ref) < TOLERANCE + DOP853_FLOOR
    scale = np.max(np.linalg.norm(ref, axis=1))
    err = np.linalg.norm(out.z - ref, axis=1) / scale
    filled = np.setdiff1d(np.arange(t.size), sel)
    assert err[filled].max() <= 1.01 * err[sel].max() + 1e-10
    tip = problem.model.from_balanced(out.z)[0] @ problem.model.tip
    tip_ref = problem.model.from_balanced(ref)[0] @ problem.model.tip
    assert np.max(np.abs(tip - tip_ref)) / np.max(np.abs(tip_ref)) < TOLERANCE + DOP853_FLOOR
    assert out.diagnostics["estimated_relative_error"] <= TOLERANCE


# -- what does not change --------------------------------------------------------------------


def test_constant_coefficients_and_user_steps_are_not_dense() -> None:
    """The time-invariant path stays exact, one exponential per distinct interval length
    (linspace's rounding makes several here); a user step keeps its meaning (steps per
    output interval), so neither is filled."""
    t = np.linspace(0.0, 0.2, 20001)
    lti = SOLVERS["magnus"].solve(_problem(4, t, flow=Constant(0.4)))
    assert "dense_output" not in lti.diagnostics
    assert lti.stats.matrix_exponentials == np.unique(np.diff(t)).size
    stepped = SOLVERS["magnus"].solve(_problem(4, t, step=1e-5))
    assert "dense_output" not in stepped.diagnostics
    assert stepped.stats.steps == 20000


def test_stacked_dense_runs_equal_the_single_runs() -> None:
    """The stacked study solver drives the same step control: on dense grids its outputs
    are the single runs' (the fill runs per problem), states to rounding and the same
    diagnostics (the estimates, differences of states, to 1e-6 of themselves)."""
    t = np.linspace(0.0, 0.2, 8001)
    problems = [_problem(4, t), _problem(4, t, flow=PULSATING)]
    for problem, out in zip(problems, solve_many(problems), strict=True):
        assert isinstance(out, SolverOutput)
        single = SOLVERS["magnus"].solve(problem)
        assert relative_difference(out.z, single.z) <= 1e-12
        a, b = dict(out.diagnostics), dict(single.diagnostics)
        da, db = a.pop("dense_output"), b.pop("dense_output")
        a.pop("solve_seconds"), b.pop("solve_seconds")
        key = "estimated_relative_error"
        assert a.pop(key) == pytest.approx(b.pop(key), rel=1e-6)
        assert a == b
        assert da["fill_estimated_relative_error"] == pytest.approx(
            db.pop("fill_estimated_relative_error"), rel=1e-6, abs=1e-15
        )
        da.pop("fill_estimated_relative_error")
        assert da == db


def test_a_dense_run_resumes_from_a_checkpoint_bit_for_bit() -> None:
    """The checkpoints of a magnus solve (:mod:`pipeflow.solvers.checkpoint`) replay the
    step control, which on a dense grid runs on the coarse times; the fill runs after its
    last propagation.  A dense run (4 modes over 0.25 s at 8,001 samples, pulsating flow,
    tolerance 1e-9: a refinement) killed after its 3rd checkpoint and resumed ends with
    the uninterrupted run's states at every sample, bit for bit (one process), and the
    same counters and fill."""
    sim = paper_sim(PULSATING, "magnus", samples=8001, options=Options(tolerance=1e-9))
    whole = run(sim, None)
    assert whole.diagnostics["dense_output"]["samples_filled"] > 0
    cp = Memory(kill_at=3)
    interrupted(sim, cp)
    cp.kill_at = None
    resumed = run(sim, cp)
    assert resumed.diagnostics["resumed_exponentials"] > 0
    assert np.array_equal(resumed.d, whole.d) and np.array_equal(resumed.ddot, whole.ddot)
    for name in ("steps", "attempts", "matrix_exponentials", "dense_output"):
        assert resumed.diagnostics[name] == whole.diagnostics[name], name
