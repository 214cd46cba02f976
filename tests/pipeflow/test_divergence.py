"""Runs that leave the linear model's range stop there (pipeflow.divergence, issue 24).

At v = 40 m/s the paper's pipe (w0 = 100 rad/s) is past its critical velocity, 27.69 m/s:
the flutter branch grows at sigma = 1694 1/s and the unstopped history overflowed double
precision (1e304 m for a 25 mm pipe) before this module.  Now the run stops at the first
sample whose |u| passes the bound, with status 'diverged', that time and the growth rate.
"""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest
import scipy.linalg

from pipeflow.computations import documents
from pipeflow.divergence import DEFAULT_RANGE, default_bound, divergence
from pipeflow.errors import InvalidInput
from pipeflow.loading import Loading
from pipeflow.model import build_model
from pipeflow.paper import PAPER_PIPE, PAPER_PIPE_JSON
from pipeflow.profiles import Constant, polynomial
from pipeflow.schema.simulation import SimulationSpec
from pipeflow.simulation import Simulation, simulate

L = PAPER_PIPE.L


def _flutter(**kw: object) -> Simulation:
    base: dict[str, object] = dict(
        flow=Constant(40.0), spin=Constant(100.0), u0=1e-6, modes=10, t_end=0.02, samples=4001
    )
    base.update(kw)
    return Simulation(PAPER_PIPE, **base)  # type: ignore[arg-type]


def test_past_the_critical_velocity_the_run_stops_with_time_and_growth_rate() -> None:
    """u0 = 1 um starts the tip at 2.7 um; the default bound is 0.1 L = 2.5 mm.  The
    growth rate reported is the largest real part of the eigenvalues of S at that time,
    computed here again by scipy.linalg.eigvals (1e-9 relative: two LAPACK calls on one
    matrix agree to rounding times its condition); the history's own growth over its
    last 2 ms, a log-linear fit of its successive peaks, agrees with it to 3% (the decaying
    branches are e^-(1694+185) x 2 ms ~ 1e-2 of the flutter one by then)."""
    sim = _flutter()
    r = simulate(sim)
    assert r.status == "diverged"
    assert r.divergence_bound == pytest.approx(DEFAULT_RANGE * L, rel=1e-15)
    assert r.t[-1] == r.divergence_time and r.t.size < sim.samples
    assert abs(r.tip_displacement[-1]) > r.divergence_bound
    assert np.all(np.abs(r.tip_displacement[:-1]) <= r.divergence_bound)

    model = build_model(PAPER_PIPE, sim.modes)
    S = model.state_matrix(Loading(sim.flow, sim.spin).coefficients(np.array([r.t[-1]])))[0]
    sigma = float(scipy.linalg.eigvals(S).real.max())
    assert sigma == pytest.approx(1694.26, rel=1e-5)
    assert r.divergence_growth_rate == pytest.approx(sigma, rel=1e-9)

    late = r.t >= r.t[-1] - 2e-3
    u = np.abs(r.tip_displacement[late])
    peaks = np.flatnonzero((u[1:-1] > u[:-2]) & (u[1:-1] >= u[2:])) + 1
    assert peaks.size >= 3
    slope = np.polyfit(r.t[late][peaks], np.log(u[peaks]), 1)[0]
    assert slope == pytest.approx(sigma, rel=0.03)

    doc = documents.simulation(r)
    assert doc["status"] == "diverged" and doc["divergence_growth_rate"] == r.divergence_growth_rate
    assert len(doc["t"]) == r.t.size
    json.dumps(doc, allow_nan=False)  # every number finite


def test_the_history_up_to_the_stop_is_the_unstopped_run() -> None:
    """The stop is post-processing: the samples kept are the run's own (same solver, same
    grid), compared with a run whose bound is never reached to 1e-12 of the bound."""
    sim = _flutter(t_end=0.006, samples=1201)
    r = simulate(sim)
    whole = simulate(dataclasses.replace(sim, divergence_bound=1e300))
    assert whole.status == "diverging" and whole.t.size == sim.samples
    k = r.t.size
    np.testing.assert_allclose(r.d, whole.d[:k], rtol=0, atol=1e-12 * r.divergence_bound)
    assert np.abs(whole.tip_displacement[k - 1]) > r.divergence_bound


def test_a_stable_run_is_unchanged() -> None:
    """The paper's example (v = 0.4 t, stable) never nears the bound (2 x 2.72 mm): the
    same history, status and warnings as with no bound at all, every sample kept."""
    sim = Simulation(PAPER_PIPE, flow=polynomial(0, 0.4), spin=Constant(100.0), t_end=0.3)
    r = simulate(sim)
    free = simulate(dataclasses.replace(sim, divergence_bound=1e300))
    assert r.status == free.status == "ok"
    assert r.divergence_time is None and r.divergence_growth_rate is None
    assert r.t.size == sim.samples
    np.testing.assert_array_equal(r.tip_displacement, free.tip_displacement)  # same process
    assert r.warnings == free.warnings
    assert r.divergence_bound == pytest.approx(2 * r.initial_tip_displacement, rel=1e-15)


def test_a_station_past_the_bound_stops_the_run_and_is_named() -> None:
    """Any output station counts, not only the tip: a bound between the station's and
    the tip's largest |u| stops at the station's first sample past it."""
    sim = _flutter(t_end=0.006, samples=1201, positions=(0.0125,), divergence_bound=1e300)
    whole = simulate(sim)
    station, tip = np.abs(whole.displacements[0]), np.abs(whole.tip_displacement)
    bound = 0.5 * float(station.max())
    expected = int(np.flatnonzero((station > bound) | (tip > bound))[0])
    r = simulate(dataclasses.replace(sim, divergence_bound=bound))
    assert r.t.size == expected + 1
    model = build_model(PAPER_PIPE, sim.modes)
    stop = divergence(
        whole.t,
        np.zeros_like(tip),  # the tip never passes: the station is named
        whole.displacements,
        np.array([0.0125]),
        bound,
        model,
        Loading(sim.flow, sim.spin),
    )
    assert stop is not None and stop.where == "x = 0.0125 m"
    assert stop.index == int(np.flatnonzero(station > bound)[0])


def test_default_bound() -> None:
    assert default_bound(0.025, 0.0) == pytest.approx(0.0025)
    assert default_bound(0.025, 0.0027244) == pytest.approx(0.0054488)


@pytest.mark.parametrize("bound", [0.0, -1.0, float("inf"), float("nan")])
def test_a_bound_that_is_not_a_positive_length_is_refused(bound: float) -> None:
    with pytest.raises(InvalidInput) as err:
        simulate(_flutter(divergence_bound=bound))
    assert err.value.parameter == "divergence_bound"


def test_the_request_field_carries_the_bound_in_metres() -> None:
    spec = SimulationSpec.model_validate(
        {"pipe": dict(PAPER_PIPE_JSON), "output": {"divergence_bound": 0.002}}
    )
    assert spec.to_simulation().divergence_bound == 0.002
    schema = SimulationSpec.model_json_schema()["$defs"]["OutputSpec"]["properties"]
    assert "[m]" in schema["divergence_bound"]["description"]


def test_the_eigenvalue_traces_stop_where_the_history_stops() -> None:
    """Issue 24: a diverged run's traces covered the whole requested time (to 0.05 s
    here) while its history stopped at the divergence time (0.0212 s); the growth
    diagnostics read the spectrum after the stop (max_growth_rate 8087 1/s at 0.05 s).
    Now the traces run from 0 to the history's last time, with as many samples as asked.

    The flow ramps through v_cr (v = 20 + 1000 t m/s, unstable from 7.7 ms), so the
    traces change along the run.  Checked against scipy.linalg.eigvals of S at the last
    trace time, computed here again (1e-9 relative: two LAPACK calls on one matrix agree
    to rounding times its condition): every traced branch at that time is an eigenvalue
    of S(t_stop), and the least stable one (flagged) is the growth rate reported at the
    divergence time; sigma grows along the ramp, so the run's max_growth_rate is it too.
    """
    sim = _flutter(flow=polynomial(20.0, 1000.0), t_end=0.05, samples=2001, eigen_samples=201)
    r = simulate(sim)
    assert r.status == "diverged" and r.t.size < sim.samples
    assert r.divergence_time is not None and r.divergence_time < 0.6 * sim.t_end
    assert r.eigen_t[0] == 0.0 and r.eigen_t[-1] == r.t[-1] == r.divergence_time
    assert r.eigen_t.size == min(sim.eigen_samples, r.t.size)
    np.testing.assert_allclose(np.diff(r.eigen_t), r.t[-1] / (r.eigen_t.size - 1), rtol=1e-9)
    assert r.frozen.xi.shape[0] == r.eigen_t.size == r.exponents.xi.shape[0]

    model = build_model(PAPER_PIPE, sim.modes)
    loading = Loading(sim.flow, sim.spin)
    S = model.state_matrix(loading.coefficients(np.array([r.eigen_t[-1]])))[0]
    spectrum = scipy.linalg.eigvals(S)
    for xi in r.frozen.xi[-1]:
        assert np.min(np.abs(spectrum - xi)) <= 1e-9 * np.max(np.abs(spectrum))
    assert r.frozen.least_stable is not None
    end_sigma = r.frozen.sigma[-1, r.frozen.least_stable]
    assert end_sigma == pytest.approx(spectrum.real.max(), rel=1e-9)
    assert r.divergence_growth_rate == pytest.approx(end_sigma, rel=1e-9)
    assert r.diagnostics["max_growth_rate"] == pytest.approx(end_sigma, rel=1e-9)
    assert r.first_unstable_time is not None and r.first_unstable_time < r.divergence_time

    doc = documents.simulation(r)
    assert doc["eigenvalues"]["t"][-1] == doc["t"][-1] == r.divergence_time
