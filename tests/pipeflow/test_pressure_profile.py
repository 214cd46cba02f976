"""A time-varying internal pressure p(t) (issue 31: "flow.pressure p [Pa] (internal gauge
pressure, constant or any profile)").

Its force p A (1 - 2 nu delta) enters S(t) as a sixth piece (``PipeModel.with_pressure_piece``,
weight p(t)), the same term a constant pressure adds to K_0 (docs/model.md 9).  Checked
against things independent of that piece: the constant pressure's own path (K_0), an equal
compressive tension (Paidoussis vol. 1 eq. 3.70: only [M U^2 + p A (1 - 2 nu delta) - T]
enters), the reference integrator (scipy's DOP853 at rtol 1e-12) on S(t) assembled by the
same pieces but independent step control, and the cancellation at a free discharging end.
Unit pipe (E = I = L = 1, M1 = M2 = 0.5), flow area A = 1.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np
import pytest
from pydantic import ValidationError

from pipeflow import profiles
from pipeflow.model import Pipe
from pipeflow.schema.simulation import SimulationSpec
from pipeflow.schema.stability import StabilitySpec
from pipeflow.simulation import Options, Simulation, simulate
from pipeflow.supports import Support, Supports

P, C = Support("pinned"), Support("clamped")
SPOOL = Pipe(E=1.0, I=1.0, L=1.0, M1=0.5, M2=0.5, supports=Supports(P, P), flow_area=1.0)
#: Pi = p A L^2 / EI rises to 4 over 2 s: below pi^2 - u^2 = 8.87 at u = 1/sqrt(2)
RAMP = profiles.polynomial(0.0, 2.0)


def _run(pipe: Pipe, pressure: profiles.Profile | None, method: str = "auto", **kw: Any) -> Any:
    sim = Simulation(
        pipe=pipe, flow=profiles.Constant(1.0), spin=profiles.Constant(0.0), u0=1e-3,
        modes=6, t_end=2.0, samples=201, method=method, pressure=pressure, positions=(0.3,),
        **kw,
    )  # fmt: skip
    return simulate(sim)


def _u(result: Any) -> np.ndarray:
    return np.asarray(result.displacements)[0]


def _rel(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.max(np.abs(a - b)) / np.max(np.abs(b)))


@pytest.mark.parametrize(
    ("method", "tol"),
    [
        ("magnus", 1e-7),  # its tolerance 1e-8, with the estimate's margin
        ("auto", 1e-7),  # chooses magnus: the coefficients vary
        ("rk4", 1e-6),  # step 2e-4 s: RK4's h^4 error at omega_max h ~ 0.3
    ],
)
def test_a_pressure_ramp_against_the_reference_integrator(method: str, tol: float) -> None:
    ref = _u(_run(SPOOL, RAMP, "reference"))
    kw = {"options": Options(step=2e-4)} if method == "rk4" else {}
    got = _run(SPOOL, RAMP, method, **kw)
    assert got.method_used == ("magnus" if method == "auto" else method)
    assert _rel(_u(got), ref) < tol
    # the ramp changes the answer far beyond the tolerance (it is not ignored)
    assert _rel(_u(_run(SPOOL, None, "reference")), ref) > 1e-3


def test_a_pressure_step_from_a_table_against_the_reference_integrator() -> None:
    """A pressure switched on over 10 ms at t = 0.5 s (a table, held after its end) on an
    axially restrained clamped-clamped pipe (delta = 1, nu = 0.3: the force is
    0.4 p A)."""
    pipe = dataclasses.replace(SPOOL, supports=Supports(C, C), axially_restrained=True)
    step = profiles.table([0.0, 0.5, 0.51], [0.0, 0.0, 10.0], "linear", "hold")
    ref = _u(_run(pipe, step, "reference"))
    assert _rel(_u(_run(pipe, step, "magnus")), ref) < 1e-7


@pytest.mark.parametrize("method", ["cma", "magnus", "rk4", "reference", "auto"])
def test_a_constant_profile_is_the_constant_pressure(method: str) -> None:
    """The same run to rounding (1e-12 relative) as the pipe's constant pressure, for every
    method, and as the equal compressive tension T = -p A (1 - 2 nu delta)."""
    const = _u(_run(SPOOL, profiles.Constant(3.0), method))
    field = _u(_run(dataclasses.replace(SPOOL, pressure=3.0), None, method))
    tension = _u(_run(dataclasses.replace(SPOOL, tension=-3.0), None, method))
    assert _rel(const, field) < 1e-12
    assert _rel(field, tension) < 1e-12


def test_the_sixth_piece_is_the_constant_pressure_term() -> None:
    """A ramp sampled at one time is the constant pressure at that value: S(t) with the
    piece equals the model of the pipe at p = p(t) (1e-12 relative)."""
    from pipeflow.loading import Loading
    from pipeflow.model import build_model

    model = build_model(SPOOL, 6).with_pressure_piece()
    loading = Loading(profiles.Constant(1.0), profiles.Constant(0.0), RAMP)
    S = model.state_matrix(loading.coefficients(np.array([1.5])))[0]
    at = build_model(dataclasses.replace(SPOOL, pressure=3.0), 6)
    steady = Loading(profiles.Constant(1.0), profiles.Constant(0.0))
    S_ref = at.state_matrix(steady.coefficients(np.array([1.5])))[0]
    assert np.max(np.abs(S - S_ref)) <= 1e-12 * np.max(np.abs(S_ref))


def test_a_free_discharging_end_cancels_a_varying_pressure() -> None:
    """The cantilever discharging at x = L: p(t) changes nothing (exactly: no piece)."""
    cantilever = Pipe(E=1.0, I=1.0, L=1.0, M1=0.5, M2=0.5, flow_area=1.0)
    with_p = _run(cantilever, RAMP, "magnus")
    assert np.array_equal(_u(with_p), _u(_run(cantilever, None, "magnus")))


def test_the_pressure_is_given_once() -> None:
    from pipeflow.errors import InvalidInput

    with pytest.raises(InvalidInput, match="once"):
        _run(dataclasses.replace(SPOOL, pressure=1.0), RAMP)


# -- the request ----------------------------------------------------------------------------
BODY: dict[str, Any] = {
    "pipe": {"E": 1.0, "I": 1.0, "L": 1.0, "M1": 0.5, "M2": 0.5, "flow_area": 1.0,
             "supports": {"x0": "pinned", "xL": "pinned"}},
    "flow": {"velocity": {"kind": "constant", "value": 1.0}},
    "modes": 4,
    "time": {"t_end": 1.0, "samples": 11},
}  # fmt: skip


def _spec(pressure: Any) -> SimulationSpec:
    return SimulationSpec.model_validate({**BODY, "flow": {**BODY["flow"], "pressure": pressure}})


def test_request_keys_of_a_pressure() -> None:
    """A constant profile is the same request as its number (the same normal form, so the
    same key); a profile's key differs; the key of a request without a pressure has no
    pressure at all (unchanged from before the field took profiles)."""
    number = _spec(5.0).canonical()
    assert _spec({"kind": "constant", "value": 5.0}).canonical() == number
    ramp = _spec({"kind": "polynomial", "coefficients": [0.0, 5.0]}).canonical()
    assert ramp != number and ramp["flow"]["pressure"]["kind"] == "polynomial"
    assert "pressure" not in SimulationSpec.model_validate(BODY).canonical()["flow"]
    sim = _spec({"kind": "polynomial", "coefficients": [0.0, 5.0]}).to_simulation()
    assert sim.pipe.pressure == 0.0 and sim.pressure == profiles.polynomial(0.0, 5.0)


@pytest.mark.parametrize(
    "pressure",
    [
        2e10,  # |p| <= 1e10 Pa
        {"kind": "table", "t": [0.0, 2.0], "values": [0.0, 2e10]},
        {"kind": "harmonic", "mean": 0.0, "amplitude": 2e10, "frequency": 1.0},
    ],
)
def test_pressures_out_of_bounds_name_the_field(pressure: Any) -> None:
    with pytest.raises(ValidationError) as info:
        _spec(pressure)
    assert all(e["loc"][:2] == ("flow", "pressure") for e in info.value.errors())


def test_pressures_in_bar_convert_in_a_profile() -> None:
    """Units work inside a pressure profile as in the velocity's: 50 bar = 5e6 Pa."""
    spec = _spec({"kind": "harmonic", "mean": {"value": 50, "unit": "bar"}, "frequency": 2.0})
    assert spec.canonical()["flow"]["pressure"]["mean"] == pytest.approx(5e6, rel=1e-12)


def test_frozen_kinds_take_a_constant_pressure_only() -> None:
    """A stability sweep freezes the operating point: a pressure profile is refused there,
    naming flow.pressure."""
    body = {"pipe": BODY["pipe"], "modes": 4, "velocity_range": [0.0, 2.0], "points": 11}
    StabilitySpec.model_validate({**body, "flow": {"pressure": 1.0}})
    with pytest.raises(ValidationError) as info:
        StabilitySpec.model_validate(
            {**body, "flow": {"pressure": {"kind": "polynomial", "coefficients": [0.0, 1.0]}}}
        )
    assert info.value.errors()[0]["loc"][:2] == ("flow", "pressure")


def test_the_frozen_frequency_follows_the_pressure_in_time() -> None:
    """The frozen spectrum follows p(t): on a pinned-pinned pipe (beta = 1, u = v = 1) the
    fundamental's one-mode estimate is omega^2 = pi^2 (pi^2 - u^2 - Pi(t)) (Paidoussis
    vol. 1 sec. 3.3, the sine mode without the Coriolis coupling, which lowers it by about
    1 % at u = 1: the tolerance 2 %), Pi = 5 t falling from 9.36 to 6.18 rad/s."""
    pipe = dataclasses.replace(SPOOL, M1=0.0, M2=1.0)
    r = simulate(
        Simulation(pipe=pipe, flow=profiles.Constant(1.0), spin=profiles.Constant(0.0),
                   u0=1e-4, modes=6, t_end=1.0, samples=101,
                   pressure=profiles.polynomial(0.0, 5.0), eigen_samples=11)
    )  # fmt: skip
    omega = np.asarray(r.fundamental.omega).ravel()
    t = np.asarray(r.eigen_t)
    expected = np.sqrt(math.pi**2 * (math.pi**2 - 1.0 - 5.0 * t))
    assert np.allclose(omega, expected, rtol=2e-2)
    assert omega[-1] < 0.7 * omega[0]
