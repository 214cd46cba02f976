"""Simulation driver: validation, non-finite handling, JSON output."""

import dataclasses
import json
import math
import sys
from typing import Any

import numpy as np
import pytest

from pipeflow.computations import documents
from pipeflow.errors import PipeflowError
from pipeflow.io.json import json_safe
from pipeflow.loading import Loading
from pipeflow.model import build_model
from pipeflow.paper import PAPER_PIPE
from pipeflow.profiles import Constant, polynomial, table
from pipeflow.schema.simulation import SIMULATION_FIELDS, request_fields
from pipeflow.simulation import Simulation, simulate
from pipeflow.solvers import Options
from tests.pipeflow.cases import paper_sim


def test_overflow_is_reported_not_serialised() -> None:
    """v = -0.4 m/s grows like e^(14.9 t); over 60 s that overflows double precision. The
    result keeps the finite prefix, says 'overflow', and its JSON has no NaN/Inf.  (A
    bound of the largest double lets it grow that far: the default one stops it long before.)"""
    big = sys.float_info.max
    r = simulate(paper_sim(Constant(-0.4), modes=3, t_end=60.0, samples=601, divergence_bound=big))
    assert r.status == "overflow"
    assert r.divergence_time is None
    assert np.all(np.isfinite(r.tip_displacement)) and r.t.size < 601
    text = json.dumps(documents.simulation(r), allow_nan=False)
    assert "NaN" not in text and "Infinity" not in text


def test_divergence_time_is_when_bound_is_passed() -> None:
    """The history stops at the first sample past the bound: the same samples as the run
    with no stop (a bound of 1e300 m) up to there, to 1e-12 of the largest (the same solver
    on the same grid; only the post-processing differs)."""
    sim = paper_sim(Constant(-0.4), modes=3, t_end=1.0, samples=1001, divergence_bound=0.01)
    r = simulate(sim)
    whole = simulate(dataclasses.replace(sim, divergence_bound=1e300))
    assert r.status == "diverged" and whole.status == "diverging"
    k = int(np.flatnonzero(np.abs(whole.tip_displacement) > 0.01)[0])
    assert r.t.size == k + 1 and r.divergence_time == r.t[k] == whole.t[k]
    np.testing.assert_allclose(
        r.tip_displacement, whole.tip_displacement[: k + 1], rtol=0, atol=1e-12 * 0.01
    )
    assert r.divergence_bound == 0.01 and r.divergence_growth_rate is not None
    assert any("status 'diverged'" in w for w in r.warnings)


@pytest.mark.parametrize(
    ("kw", "parameter", "field"),
    [
        ({"method": "nope"}, "method", "method"),
        ({"t_end": -1.0}, "t_end", "time.t_end"),
        ({"t_end": math.inf}, "t_end", "time.t_end"),
        ({"samples": 1}, "samples", "time.samples"),
        ({"modes": 41}, "modes", "modes"),
        ({"positions": (0.5,)}, "positions", "output.positions"),
        ({"initial_shape": "mode2"}, "initial_shape", "initial.shape"),
        ({"flow": table([0, 0.5], [0.1, 0.2])}, "flow", "flow.velocity"),
        ({"method": "rk4", "options": Options(step=1e-300)}, "step", "options.step"),
    ],
)
def test_invalid_input_names_the_parameter(
    kw: dict[str, object], parameter: str, field: str
) -> None:
    """The library names its own parameter (no JSON path); the schema layer's one mapping
    (pipeflow.schema.simulation.SIMULATION_FIELDS) turns it into the request field."""
    with pytest.raises(PipeflowError) as err:
        simulate(Simulation(PAPER_PIPE, **kw))  # type: ignore[arg-type]
    assert err.value.parameter == parameter
    assert err.value.field is None
    with pytest.raises(PipeflowError) as err, request_fields(SIMULATION_FIELDS):
        simulate(Simulation(PAPER_PIPE, **kw))  # type: ignore[arg-type]
    assert err.value.field == field


def test_table_profile_matches_polynomial() -> None:
    """A linear table of v = 0.4 t gives the same run as the polynomial (same closed forms)."""
    from pipeflow.profiles import polynomial

    a = simulate(paper_sim(polynomial(0, 0.4), modes=3, t_end=0.1, samples=101))
    b = simulate(paper_sim(table([0.0, 0.1], [0.0, 0.04]), modes=3, t_end=0.1, samples=101))
    assert np.allclose(a.tip_displacement, b.tip_displacement, rtol=0, atol=1e-14)


#: the paper pipe's critical flow velocity at w0 = 100 rad/s, 10 modes [m/s] (the
#: stability test suite checks it against the published 27.69 m/s / u_cr = 9.15)
V_CR = 27.69


@pytest.mark.parametrize(("v", "unstable"), [(20.0, False), (40.0, True)])
def test_growth_rate_comes_from_the_whole_spectrum(v: float, unstable: bool) -> None:
    """Paper pipe, w0 = 100 rad/s, 10 modes, below and above v_cr = 27.69 m/s.  Above it
    the flutter branch (mode 5 at v = 40: two over-damped real modes come first) grows;
    before the fix the three lowest branches were traced and max_growth_rate was -925 1/s.
    Now max_growth_rate is the largest sigma of the whole frozen spectrum (the same
    eigenvalues as pipeflow.stability.growth_rate, to rounding: 1e-9 relative), its sign
    says stable/unstable, the branch that carries it is traced and flagged least_stable,
    and first_unstable_time is 0 (constant v) or null."""
    from pipeflow.model import build_model
    from pipeflow.stability import growth_rate

    r = simulate(Simulation(PAPER_PIPE, flow=Constant(v), spin=Constant(100.0), t_end=0.05))
    rate = r.diagnostics["max_growth_rate"]
    expected = float(growth_rate(build_model(PAPER_PIPE, 10), v, 100.0)[0])
    assert rate == pytest.approx(expected, rel=1e-9)
    assert (rate > 0) is unstable
    modes = documents.simulation(r)["eigenvalues"]["modes"]
    flagged = [m for m in modes if m["least_stable"]]
    assert len(flagged) == 1
    assert max(flagged[0]["sigma"]) == pytest.approx(rate, rel=1e-12)
    assert r.first_unstable_time == (0.0 if unstable else None)
    assert (r.status != "ok") is unstable
    if unstable:
        assert len(modes) == 4 and modes[-1]["least_stable"] and modes[-1]["mode"] == 5


@pytest.mark.parametrize("viscous", [0.0, 1e9])
def test_rounding_is_not_growth(viscous: float) -> None:
    """The paper's example (v = 0.4 t, w0 = 100 rad/s): at t = 0 the undamped spectrum is on
    the imaginary axis (sigma = 0 exactly), computed as +1.4e-12 1/s, and with v > 0 every
    branch decays, so the largest growth rate is exactly 0, not unstable.  With viscous
    damping 1e9 N s/m^2 the spectral radius is 3e13 1/s and the largest sigma came out
    +1.9e-3 1/s: below the rounding level (1e-11 x radius = 0.28 1/s), so also 0.  Before
    the fix max_growth_rate was the raw max and the viewer showed "Unstable run"."""
    import dataclasses

    r = simulate(Simulation(dataclasses.replace(PAPER_PIPE, viscous=viscous)))
    assert r.status == "ok"
    assert r.diagnostics["max_growth_rate"] == 0.0
    assert r.first_unstable_time is None


def test_first_unstable_time_of_a_ramp_through_the_critical_velocity() -> None:
    """v = 20 + 100 t m/s passes the critical velocity (27.69 m/s; located to 1e-10 by
    pipeflow.stability.critical_velocities, Brent on the tracked branch) at t_cr = 0.0769 s:
    first_unstable_time is the first output time after t_cr (output step 0.1 ms), found
    between the eigenvalue times (step 10 ms) that bracket it; the growing branch is traced
    and flagged, and max_growth_rate is its largest sigma."""
    from pipeflow.stability import critical_velocities

    v_cr = critical_velocities(PAPER_PIPE, 100.0, (0.0, 60.0), 10).critical_velocity
    assert v_cr == pytest.approx(V_CR, abs=0.005)
    r = simulate(
        Simulation(
            PAPER_PIPE,
            flow=polynomial(20.0, 100.0),
            spin=Constant(100.0),
            t_end=0.1,
            samples=1001,
            eigen_samples=11,
        )
    )
    t_cr = (v_cr - 20.0) / 100.0
    assert r.first_unstable_time is not None
    assert 0.0 < r.first_unstable_time - t_cr <= 1e-4 + 1e-12
    assert r.first_unstable_time in set(r.t.tolist())
    j = r.frozen.least_stable
    assert j is not None and documents.simulation(r)["eigenvalues"]["modes"][j]["least_stable"]
    k = int(np.searchsorted(r.eigen_t, r.first_unstable_time))
    assert r.frozen.sigma[k, j] > 0 > r.frozen.sigma[k - 1, j]
    assert r.diagnostics["max_growth_rate"] == pytest.approx(float(r.frozen.sigma[:, j].max()))
    # the CMA exponents follow the same branches: P(t)/t = S(0) at t = 0
    assert r.exponents.xi.shape == r.frozen.xi.shape
    np.testing.assert_allclose(r.exponents.xi[0], r.frozen.xi[0], rtol=1e-13)
    d = documents.simulation(r)
    assert [m["mode"] for m in d["cma_exponents"]["modes"]] == [
        m["mode"] for m in d["eigenvalues"]["modes"]
    ]
    assert "least_stable" not in d["cma_exponents"]["modes"][0]


def test_auto_runs_cma_where_exact_and_magnus_otherwise() -> None:
    """method 'auto' (the default): cma for constant v and w0, magnus for v = 0.4 t; the
    result says which ran and why; cma chosen by auto equals cma asked for, bit for bit."""
    const = simulate(paper_sim(Constant(0.4), method="auto", modes=3, t_end=0.05, samples=51))
    assert (const.simulation.method, const.method_used) == ("auto", "cma")
    assert "exact" in const.method_reason
    direct = simulate(paper_sim(Constant(0.4), method="cma", modes=3, t_end=0.05, samples=51))
    np.testing.assert_array_equal(const.tip_displacement, direct.tip_displacement)
    ramp = simulate(paper_sim(polynomial(0, 0.4), method="auto", modes=3, t_end=0.05, samples=51))
    assert ramp.method_used == "magnus" and "time-variant" in ramp.method_reason
    d = documents.simulation(ramp)
    assert (d["method"], d["method_used"]) == ("auto", "magnus")
    assert d["diagnostics"]["method_used"] == "magnus"
    assert Simulation(PAPER_PIPE).method == "auto"


@pytest.mark.slow  # DOP853 at rtol 1e-12 on the paper's example, 5-12 s
def test_paper_example_by_default_is_right_to_1e_8() -> None:
    """The README / `pipeflow example` case (v = 0.4 t, w0 = 100 rad/s, 10 modes, 2001
    samples per second) with the default method runs without a warning, estimates its own
    error below 1e-8, and is within 1e-8 of the tight reference (DOP853, rtol 1e-12,
    whose own error is ~3e-10) on the balanced state and the tip.  The reference costs
    ~80 s over the full second (stiff: the 10th mode is at 8e4 rad/s), so it is compared
    on the first 0.1 s at the example's sample spacing; measured over the full second:
    6.8e-9 (state) and 6.0e-9 (tip)."""
    from pipeflow.model import build_model
    from pipeflow.schema.simulation import PAPER_EXAMPLE, SimulationSpec
    from pipeflow.solvers.base import relative_difference

    spec = SimulationSpec.model_validate(PAPER_EXAMPLE)
    assert spec.method == "auto"
    full = simulate(spec.to_simulation())
    assert full.warnings == [] and full.status == "ok" and full.method_used == "magnus"
    assert full.diagnostics["estimated_relative_error"] <= 1e-8
    sim = spec.to_simulation()
    short = Simulation(**{**sim.__dict__, "t_end": 0.1, "samples": 201})  # the same grid
    ref = simulate(
        Simulation(
            **{**short.__dict__, "method": "reference", "options": Options(rtol=1e-12, atol=1e-16)}
        )
    )
    np.testing.assert_allclose(ref.t, full.t[:201], rtol=0, atol=1e-15)
    model = build_model(PAPER_PIPE, 10)
    z = model.to_balanced(full.d[:201], full.ddot[:201])
    assert relative_difference(z, model.to_balanced(ref.d, ref.ddot)) < 1e-8
    assert relative_difference(full.tip_displacement[:201], ref.tip_displacement) < 1e-8


def _element_wise_reference(data: Any) -> Any:
    """json_safe's rule written out element by element (the reference for its fast path)."""
    if isinstance(data, dict):
        return {k: _element_wise_reference(v) for k, v in data.items()}
    if isinstance(data, list | tuple):
        return [_element_wise_reference(v) for v in data]
    if isinstance(data, np.generic):
        data = data.item()
    if isinstance(data, float) and not math.isfinite(data):
        return None
    return data


@pytest.mark.parametrize(
    "data",
    [
        [0.1, -2.5, 3.0],
        [],
        [1.0, math.nan, 2.0],
        [math.inf, 1.0],
        [1.0, -math.inf],
        [math.inf, -math.inf],  # sums to NaN
        [1e308, 1e308, -1e308],  # finite values whose sum overflows: element-wise path
        [1.0, np.float64(2.0), np.float64("nan")],  # numpy scalars are not Python floats
        [1.0, 2, True, None, "x"],
        # a study's rows: plain scalars copied at once unless a float is not finite
        [3, "a" * 64, "ok", False, 0.5, None, -1.25, 7],
        [3, None, "ok", True, math.nan, 2.0],
        [0, "k", 1e308, 1e308],  # finite floats whose sum overflows: element-wise path
        [1, np.int64(2), 3.0],  # a numpy integer: walked (item())
        [1, [2.0, math.inf], "x"],  # a nested list: walked
        [[1, "a", 0.5], [2, "b", math.nan], [3, "c", -math.inf]],
        ([0.5, math.nan], (1.0, 2.0)),
        {"a": [[1.0, 2.0], [math.nan, 3.0]], "b": (np.float32(1.5), 4.0)},
    ],
)
def test_json_safe_float_lists_fast_path_matches_the_rule(data: Any) -> None:
    """The fast path for all-float lists (copied when their sum is finite) gives exactly
    the element-wise rule: every non-finite float null, finite floats unchanged (==, so no
    tolerance), numpy scalars as Python numbers, tuples as lists; the input is not shared."""
    out = json_safe(data)
    expected = _element_wise_reference(data)
    assert out == expected
    assert _types(out) == _types(expected)  # == alone takes True for 1 and 1 for 1.0
    if isinstance(data, list):
        assert out is not data


def _types(data: Any) -> Any:
    if isinstance(data, dict):
        return {k: _types(v) for k, v in data.items()}
    if isinstance(data, list):
        return [_types(v) for v in data]
    return type(data)


def test_cma_exponents_are_computed_only_when_asked(monkeypatch: pytest.MonkeyPatch) -> None:
    """With time-varying coefficients (v = 0.4 t, auto = magnus) simulate() does not
    decompose P(t)/t: nothing in the run needs the CMA exponents. The first use
    (Result.exponents, to_dict) computes them once, and they are exactly (bit for bit) what
    cma_exponents gives on the frozen branches, as before the deferral."""
    import pipeflow.simulation as simulation

    calls: list[int] = []
    real = simulation.cma_exponents

    def counted(*args: Any) -> Any:
        calls.append(1)
        return real(*args)

    monkeypatch.setattr(simulation, "cma_exponents", counted)
    sim = paper_sim(polynomial(0.0, 0.4), "auto", modes=4, t_end=0.2, samples=201)
    r = simulate(sim)
    assert r.method_used == "magnus" and calls == []
    d = documents.simulation(r)
    assert len(calls) == 1
    assert documents.simulation(r)["cma_exponents"] == d["cma_exponents"] and len(calls) == 1
    model = build_model(sim.pipe, sim.modes)
    ref = real(model, Loading(sim.flow, sim.spin), r.eigen_t, r.frozen.xi[0])
    np.testing.assert_array_equal(r.exponents.xi, ref.xi)
    np.testing.assert_array_equal(r.exponents.confidence, ref.confidence)
    assert [m["sigma"] for m in d["cma_exponents"]["modes"]] == ref.sigma.T.tolist()
