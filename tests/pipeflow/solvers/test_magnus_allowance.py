"""``magnus`` under a metered allowance (:func:`pipeflow.parallel.metered`): every
propagation its step control plans is charged (steps x :func:`step_seconds` of the
exponent's size) before any of it is computed, and the one that would pass the allowance
raises :class:`~pipeflow.errors.OverAllowance` with nothing of it paid.  The service's fast
lane runs time-variant simulations this way (``service/engine/runner.py``)."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from pipeflow import parallel
from pipeflow.errors import OverAllowance
from pipeflow.paper import PAPER_FLOWS
from pipeflow.profiles import Constant
from pipeflow.simulation import simulate
from pipeflow.solvers import magnus
from pipeflow.solvers.magnus import stepper
from tests.pipeflow.cases import paper_sim

#: v = 0.4 t on 4 modes, 0.25 s, 501 samples: a few milliseconds, several propagations
CASE = paper_sim(PAPER_FLOWS["v=0.4t"], method="magnus")


def _counting_products(monkeypatch: pytest.MonkeyPatch) -> list[int]:
    """Steps whose exponentials :func:`magnus.propagate` multiplied, per call of
    ``product_of_steps`` (only propagate calls it)."""
    seen: list[int] = []
    real = stepper.product_of_steps

    def counting(E: Any) -> Any:
        seen.append(int(E.shape[0] * E.shape[1]))
        return real(E)

    monkeypatch.setattr(stepper, "product_of_steps", counting)
    return seen


def test_every_propagation_is_charged_its_plan_before_it_runs(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    products = _counting_products(monkeypatch)
    with parallel.metered(1e9) as allowance:
        result = simulate(CASE)
    size = 2 * CASE.modes
    steps = [int(what.split(" of ")[1].split(" steps")[0]) for what, _ in allowance.charges]
    # the charge is the plan's step count times the cost of one step of that size
    assert [s for _, s in allowance.charges] == pytest.approx(
        [n * magnus.step_seconds(size) for n in steps], rel=1e-12
    )
    # every step computed was charged first (the sum over all propagations); the run kept
    # and its check with twice the step are among them
    assert sum(products) == sum(steps)
    kept = result.diagnostics["steps"]
    assert kept in steps and kept // 2 in steps, (steps, kept)


def test_the_propagation_over_the_allowance_is_refused_with_nothing_of_it_computed(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    with parallel.metered(1e9) as probe:
        simulate(CASE)
    first = probe.charges[0][1]
    products = _counting_products(monkeypatch)
    # room for the first propagation only: the second (the check) is refused
    with parallel.metered(first * (1 + 1e-9)) as allowance, pytest.raises(OverAllowance) as exc:
        simulate(CASE)
    assert len(allowance.charges) == 1
    assert exc.value.asked_s == pytest.approx(probe.charges[1][1], rel=1e-12)
    first_steps = int(probe.charges[0][0].split(" of ")[1].split(" steps")[0])
    assert sum(products) == first_steps  # the refused propagation computed no step


def test_metering_does_not_change_the_result() -> None:
    """Same process, same computation: the allowance only counts, so the states are
    identical to the last bit (not a comparison with a stored file)."""
    plain = simulate(CASE)
    with parallel.metered(1e9):
        metered = simulate(CASE)
    assert np.array_equal(plain.tip_displacement, metered.tip_displacement)
    assert np.array_equal(plain.frozen.sigma, metered.frozen.sigma)


def test_a_time_invariant_run_is_not_charged() -> None:
    """Constant coefficients: magnus is exact with one exponential, nothing to meter."""
    with parallel.metered(0.0) as allowance:
        simulate(paper_sim(Constant(0.4), method="magnus"))
    assert allowance.charges == []


def test_the_step_cost_grows_with_the_exponent_size() -> None:
    # the measured points the constants were fitted to (magnus.STEP_FIXED_S's comment):
    # within 30% at 6 to 80
    measured_us = {6: 5.0, 10: 6.5, 20: 12.5, 40: 66.0, 60: 190.0, 80: 362.0}
    for size, us in measured_us.items():
        assert magnus.step_seconds(size) * 1e6 == pytest.approx(us, rel=0.3), size


def test_the_dense_fill_is_charged_before_it_is_paid() -> None:
    """A run with dense output (8,001 samples: the step control on every m-th sample, the
    rest filled) charges the fill's stages too, each before it runs: so the fast lane's
    allowance bounds the whole run, not only its propagations.  With an allowance that
    covers the propagations and not the fill, the fill is refused; metering leaves the
    states bit-identical."""
    case = paper_sim(PAPER_FLOWS["v=0.4t"], method="magnus", samples=8001)
    plain = simulate(case)
    assert plain.diagnostics["dense_output"]["samples_filled"] > 0
    with parallel.metered(1e9) as allowance:
        metered = simulate(case)
    assert np.array_equal(metered.tip_displacement, plain.tip_displacement)
    fills = [(what, s) for what, s in allowance.charges if what.startswith("the dense fill")]
    assert fills, allowance.charges
    propagations = sum(s for what, s in allowance.charges if "propagation" in what)
    with pytest.raises(OverAllowance, match="the dense fill"):
        with parallel.metered(propagations + 0.5 * fills[0][1]):
            simulate(case)
