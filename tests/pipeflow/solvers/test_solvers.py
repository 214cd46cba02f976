"""The solver base class: one template (timing, counters, step budget), and the questions
diagnostics and compare ask a solver instead of branching on its name."""

from __future__ import annotations

import math
from dataclasses import fields
from typing import ClassVar

import numpy as np
import pytest

from pipeflow.compare import compare, default_methods
from pipeflow.diagnostics import add_error_estimate
from pipeflow.loading import Loading
from pipeflow.model import build_model
from pipeflow.profiles import Constant, polynomial
from pipeflow.simulation import frozen_spectrum, simulate
from pipeflow.solvers import SOLVERS, Options, Problem, Solver, SolverOutput, SolverStats
from pipeflow.solvers.base import relative_difference
from pipeflow.spectra import spectrum
from tests.pipeflow.cases import paper_sim


@pytest.mark.parametrize("method", sorted(SOLVERS))
@pytest.mark.parametrize("flow", [Constant(0.4), polynomial(0, 0.4)], ids=["lti", "ramp"])
def test_every_solver_reports_the_same_counters(method: str, flow: object) -> None:
    """Each solver is a Solver whose diagnostics carry every SolverStats counter, filled
    consistently with what the method does: RK4 evaluates S z + f four times per step,
    magnus forms at least one exponential per step (one in all for constant coefficients
    on a uniform grid), cma decomposes once for constant coefficients and otherwise forms
    one exponential of P(t) per output time (no decomposition), the reference counts
    solve_ivp's nfev."""
    solver = SOLVERS[method]
    assert isinstance(solver, Solver)
    r = simulate(paper_sim(flow, method, modes=2, t_end=0.02, samples=21))  # type: ignore[arg-type]
    d = r.diagnostics
    for f in fields(SolverStats):
        assert f.name in d, f.name
    assert d["solve_seconds"] > 0 and d["attempts"] >= 1
    used = r.method_used
    invariant = isinstance(flow, Constant)
    if used == "rk4":
        assert d["steps"] >= 20 and d["rhs_evaluations"] == 4 * d["steps"]
    elif used == "magnus":
        if invariant:
            assert d["matrix_exponentials"] == 1
        else:
            assert d["matrix_exponentials"] >= d["steps"] >= 20
    elif used == "cma":
        assert d["eigendecompositions"] == (1 if invariant else 0)
        assert d["matrix_exponentials"] == (0 if invariant else 21)
    elif used == "reference":
        assert d["rhs_evaluations"] > 0
    if method == "auto":
        assert used == ("cma" if invariant else "magnus")


def test_relative_difference_is_one_rule() -> None:
    """max_k |a_k - b_k| / max_k |b_k|: rows are states (2-norm), 1-D entries samples;
    identities: 0 for equal inputs, scaling invariance, the first `size` components only,
    inf for a non-finite difference or a vanishing reference."""
    b = np.array([[3.0, 4.0, 100.0], [0.0, 1.0, 0.0]])
    a = b + np.array([[0.0, 0.5, 7.0], [0.0, 0.0, 0.0]])
    assert relative_difference(a, b, size=2) == pytest.approx(0.5 / 5.0, rel=1e-15)
    assert relative_difference(10 * a, 10 * b, size=2) == pytest.approx(0.1, rel=1e-15)
    assert relative_difference(b, b) == 0.0
    assert relative_difference(np.array([1.0, 2.0]), np.array([1.0, 4.0])) == 0.5
    assert relative_difference(np.zeros(3), np.zeros(3)) == 0.0
    assert relative_difference(np.ones(3), np.zeros(3)) == math.inf
    assert relative_difference(np.array([np.inf, 0.0]), np.ones(2)) == math.inf


class _Oracle(Solver):
    """A test solver: the exact propagator of constant coefficients, claiming an error."""

    name: ClassVar[str] = "oracle-test"
    description: ClassVar[str] = "test only"
    option_names: ClassVar[tuple[str, ...]] = ()
    estimates_own_error: ClassVar[bool] = True
    error_advice: ClassVar[str] = "ask the oracle again"
    compared_by_default: ClassVar[bool] = False

    def _solve_impl(self, problem: Problem, stats: SolverStats) -> SolverOutput:
        out = SOLVERS["cma"]._solve_impl(problem, stats)
        out.diagnostics["estimated_relative_error"] = 0.5
        return out


def test_diagnostics_and_compare_ask_the_solver() -> None:
    """A solver the library has never heard of is handled by what it says about itself:
    it estimates its own error (no magnus check), its advice is in the warning, compare
    ranks it by its claimed error and leaves it out of the default set."""
    oracle = SOLVERS["oracle-test"] = _Oracle()
    try:
        sim = paper_sim(Constant(0.4), "oracle-test", modes=2, t_end=0.02, samples=21)
        r = simulate(sim)
        assert r.method_used == "oracle-test"
        assert "error_estimate_seconds" not in r.diagnostics  # no check was run
        assert any("ask the oracle again" in w for w in r.warnings)
        out = compare(sim, ["oracle-test", "cma"])
        assert out.baseline.simulation.method == "cma"  # rounding-level claim beats 0.5
        assert "oracle-test" not in default_methods()
        assert set(default_methods()) == {"cma", "magnus", "rk4"}
        # and the check is skipped by asking, not by name: the same output, flag off
        model = build_model(sim.pipe, 2)
        z0 = model.to_balanced(*model.initial_state(1e-3, 0.0))
        p = Problem(model, Loading(Constant(0.4), Constant(100.0)), z0, np.linspace(0, 0.02, 21))
        o = oracle.solve(p)
        add_error_estimate(SOLVERS["cma"], p, o)
        assert o.diagnostics["estimated_relative_error"] < 1e-13  # cma's exact_error
    finally:
        del SOLVERS["oracle-test"]


def test_constant_coefficients_decompose_the_frozen_spectrum_once(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """LTI (v = 0.4 m/s, w0 = 100 rad/s): the frozen spectrum is one decomposition of S
    (it was 2 x 201 identical ones), the traces are constant in time and the CMA exponents
    equal the frozen eigenvalues (P(t)/t = S exactly); a ramp still decomposes every time
    (P(t)/t at the first use of the exponents, test_simulation)."""
    import pipeflow.simulation as simulation

    sizes: list[int] = []

    def counting(S: np.ndarray, damped: bool = False) -> object:
        sizes.append(int(S.shape[0]))
        return spectrum(S, damped)

    monkeypatch.setattr(simulation, "spectrum", counting)
    r = simulate(paper_sim(Constant(0.4), modes=10, t_end=1.0, samples=2001))
    assert sizes == [1] and r.method_used == "cma"
    assert np.all(r.frozen.xi == r.frozen.xi[0]) and r.eigen_t.size == 201
    np.testing.assert_array_equal(r.exponents.xi, r.frozen.xi)
    model = build_model(r.simulation.pipe, 10)
    S = model.state_matrix(Loading(Constant(0.4), Constant(100.0)).coefficients(np.zeros(1)))
    w = np.linalg.eigvals(S[0])
    for xi in r.frozen.xi[0]:
        assert np.min(np.abs(w - xi)) <= 1e-12 * np.max(np.abs(w))
    sizes.clear()
    ramp = simulate(
        paper_sim(polynomial(0, 0.4), modes=2, t_end=0.02, samples=21, eigen_samples=21)
    )
    assert sizes == [21]  # frozen S(t) at every eigenvalue time; P(t)/t only when asked:
    assert ramp.exponents.xi.shape == (21, 2) and sizes == [21, 21]
    xi, _, _ = frozen_spectrum(model, Loading(Constant(0.4), Constant(100.0)), np.zeros(3))
    assert xi.shape == (3, 20)


def test_options_default_budget_is_bounded() -> None:
    """The step budget never exceeds the hard ceiling, whatever max_steps asks."""
    from pipeflow.solvers.base import MAX_STEPS_CEILING, step_budget

    assert step_budget(Options(max_steps=10**12)) == MAX_STEPS_CEILING
    assert step_budget(Options(max_steps=5)) == 5
