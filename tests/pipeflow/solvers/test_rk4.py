"""Classical RK4: stability-limited step, order 4, agreement with the reference."""

from dataclasses import replace

import numpy as np
import pytest

from pipeflow.errors import BudgetExceeded, InvalidInput, UnstableStep
from pipeflow.profiles import Constant, polynomial
from pipeflow.simulation import simulate
from pipeflow.solvers import Options
from pipeflow.solvers.rk4 import largest_stable_step, rk4_amplification
from tests.pipeflow.cases import PAPER_FLOWS, paper_sim, reference_run


def test_stability_boundary_on_imaginary_axis() -> None:
    """RK4's region meets the imaginary axis at |z| = 2 sqrt(2) (Hairer & Wanner, Solving
    ODEs II, sec. IV.2): for lambda = i, the largest stable step is 2 sqrt(2) to 1e-9."""
    assert abs(largest_stable_step(np.array([1j, -1j])) - 2 * np.sqrt(2)) < 1e-9
    # on the negative real axis the boundary is at -2.7853 (same reference)
    assert abs(largest_stable_step(np.array([-1.0])) - 2.785293563) < 1e-6
    h = largest_stable_step(np.array([-0.3 + 2j]))
    assert abs(rk4_amplification(np.array([h * (-0.3 + 2j)]))[0]) <= 1 + 1e-9


def test_user_step_outside_region_is_refused_with_largest_stable_step() -> None:
    """The paper's eq. (32) as a feature: the error names the largest stable step."""
    sim = paper_sim(Constant(0.4), "rk4", modes=4, t_end=0.01, samples=11)
    res = simulate(sim)
    h_max = res.diagnostics["largest_stable_step"]
    with pytest.raises(UnstableStep) as err:
        simulate(
            paper_sim(
                Constant(0.4),
                "rk4",
                modes=4,
                t_end=0.01,
                samples=11,
                options=Options(step=1.5 * h_max),
            )
        )
    assert err.value.parameter == "step"
    assert abs(err.value.largest_stable_step - h_max) < 1e-15
    assert f"{h_max:.6g}" in str(err.value)
    # and a step just inside is accepted; the solution stays bounded
    ok = simulate(
        paper_sim(
            Constant(0.4),
            "rk4",
            modes=4,
            t_end=0.01,
            samples=11,
            options=Options(step=0.99 * h_max),
        )
    )
    assert np.max(np.abs(ok.tip_displacement)) < 2 * abs(ok.initial_tip_displacement)


def test_step_budget_is_enforced() -> None:
    with pytest.raises(BudgetExceeded) as err:
        simulate(
            paper_sim(Constant(0.4), "rk4", modes=10, t_end=1.0, options=Options(max_steps=1000))
        )
    assert err.value.parameter == "max_steps"
    assert "step budget" in str(err.value)


@pytest.mark.parametrize("case", ["v=0.4", "v=0.4t", "v=-0.4t"])
def test_rk4_agrees_with_reference(case: str) -> None:
    """At its default (stability-limited) step RK4 is accurate to ~1e-4 relative on 4 modes:
    the global error C h^4 with h ~ 0.9 * 2.8 / |lambda_max| (5e-5 to 2e-4 seen)."""
    ref = reference_run(case)
    rk = simulate(paper_sim(PAPER_FLOWS[case], "rk4"))
    err = np.max(np.abs(rk.tip_displacement - ref.tip_displacement)) / np.max(
        np.abs(ref.tip_displacement)
    )
    assert err < 1e-3
    assert rk.diagnostics["stability_margin"] >= 1.0


def test_rk4_observed_order_four() -> None:
    """Step halving: the error against the reference falls by 2^4 = 16 per halving.

    Time-variant case (v = 0.4 t) on 2 modes over 0.02 s, steps well inside the stability
    region so the asymptotic regime holds; observed order within 0.3 of 4."""
    kw = dict(flow=polynomial(0, 0.4), modes=2, t_end=0.02, samples=5)
    ref = simulate(paper_sim(method="reference", options=Options(rtol=1e-13, atol=1e-18), **kw))  # type: ignore[arg-type]
    errors = []
    for h in (2e-4, 1e-4, 5e-5):
        rk = simulate(paper_sim(method="rk4", options=Options(step=h), **kw))  # type: ignore[arg-type]
        errors.append(np.max(np.abs(rk.tip_displacement - ref.tip_displacement)))
    orders = np.log2(np.array(errors[:-1]) / np.array(errors[1:]))
    assert np.all(np.abs(orders - 4.0) < 0.3), orders


@pytest.mark.parametrize("method", ["rk4", "magnus"])
@pytest.mark.parametrize("step", [-1e-5, 0.0, float("nan")])
def test_non_positive_step_is_refused(method: str, step: float) -> None:
    """A step <= 0 or NaN is an error naming options.step (rk4 used to run with one step
    per output interval instead)."""
    sim = paper_sim(Constant(0.4), method, modes=2, t_end=0.01, samples=11)
    with pytest.raises(InvalidInput) as err:
        simulate(replace(sim, options=Options(step=step)))
    assert err.value.parameter == "step"


@pytest.mark.parametrize("method", ["rk4", "magnus"])
@pytest.mark.parametrize("step", [1e-22, 1e-300, 5e-324])
def test_step_too_small_for_the_budget_is_refused(method: str, step: float) -> None:
    """Defect: a step of 1e-22 s (or 1e-300, or the smallest subnormal) made
    ceil(dt / h) wrap to a negative int64 that passed the budget check: rk4 answered 'ok'
    with 0 steps and a constant tip, magnus 'negative dimensions'.  Counts are now bounded
    in floating point first: BudgetExceeded naming 'step', with the smallest step the
    budget allows (11 samples over 0.01 s, budget 1000 steps: 100 per interval of 1 ms,
    so 1e-5 s for rk4; magnus keeps a third for its error check: 66 per interval)."""
    sim = paper_sim(polynomial(0, 0.4), method, modes=4, t_end=0.01, samples=11)
    with pytest.raises(BudgetExceeded) as err:
        simulate(replace(sim, options=Options(step=step, max_steps=1000)))
    assert err.value.parameter == "step"
    smallest = {"rk4": 1e-3 / 100, "magnus": 1e-3 / 66}[method]
    assert err.value.smallest_step == pytest.approx(smallest, rel=1e-12)
    assert f"smallest step this budget allows is {smallest:.3g} s" in err.value.message
    # the smallest step it names is accepted
    ok = simulate(replace(sim, options=Options(step=smallest, max_steps=1000)))
    assert ok.status == "ok" and 0 < ok.diagnostics["steps"] <= 1000
