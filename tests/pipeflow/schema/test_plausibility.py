"""Plausibility warnings (issue 34, item 8): a spin or a flow velocity far outside the
pipe's own scales is warned about in the result, naming the field, the value, the scale
and the unit that would make it ordinary.

The paper's pipe (E I = 9.438e-8 N m^2, M1 + M2 = 3.5325e-5 kg/m, L = 0.025 m): its first
bending frequency by hand is 1.8751^2 sqrt(EI / (m L^4)) = 291 rad/s, so 3000 rad/s is
10.3 of it and 3000 rpm (314 rad/s) is ordinary.
"""

from __future__ import annotations

import copy
import math
from typing import Any

import pytest

from pipeflow.computations.simulation import simulate_spec
from pipeflow.model import Pipe
from pipeflow.schema import plausibility
from pipeflow.schema.simulation import PAPER_EXAMPLE, SimulationSpec


def _spec(**changes: Any) -> SimulationSpec:
    body = copy.deepcopy(PAPER_EXAMPLE)
    body.update(modes=3, time={"t_end": 0.01, "samples": 11})
    for path, value in changes.items():
        head, tail = path.split("__")
        body[head][tail] = value
    return SimulationSpec.model_validate(body)


def test_first_bending_frequency_by_hand() -> None:
    E, I, L, M1, M2 = 7.8e9, 1.21e-17, 0.025, 1.884e-5, 1.6485e-5
    hand = 1.8751**2 * math.sqrt(E * I / ((M1 + M2) * L**4))
    assert abs(hand - 291.0) < 0.5
    # 1.8751 by hand, 1.8751040687 in the library: 4e-5 relative
    w1 = Pipe(E=E, I=I, L=L, M1=M1, M2=M2).first_bending_frequency
    assert w1 == pytest.approx(hand, rel=5e-5)


@pytest.mark.parametrize(
    ("x0", "xL", "lam1"),
    [
        ("clamped", "clamped", 4.730040745),  # Blevins 1979, table 8-1
        ("pinned", "pinned", math.pi),
        ("clamped", "pinned", 3.926602312),
        ("pinned", "free", 3.926602312),  # the rigid rotation (lambda = 0) is skipped
    ],
)
def test_the_spin_scale_is_the_supported_pipes_own(x0: str, xL: str, lam1: float) -> None:
    """The spin warning's scale w1 is the first bending frequency of the pipe on its own
    supports (Blevins' lambda_1; before, the clamped-free 1.8751 for every support set), so a
    spin of 5 w1(clamped-free) is ordinary for the clamped-clamped pipe and the message
    quotes that pipe's w1."""
    body = copy.deepcopy(PAPER_EXAMPLE)
    p = body["pipe"]
    scale = math.sqrt(p["E"] * p["I"] / ((p["M1"] + p["M2"]) * p["L"] ** 4))
    spin = 12.0 * lam1**2 * scale
    body.update(
        modes=3,
        time={"t_end": 0.01, "samples": 11},
        rotation={"omega0": {"kind": "constant", "value": spin}},
        flow={"velocity": {"kind": "constant", "value": 0.0}},
    )
    body["pipe"]["supports"] = {"x0": x0, "xL": xL}
    spec = SimulationSpec.model_validate(body)
    (warning,) = plausibility.warnings(spec, spec.to_simulation())
    assert warning.startswith(f"rotation.omega0 = {spin:.4g} rad/s is 12x the pipe's first ")
    assert f"({lam1**2 * scale:.3g} rad/s)" in warning
    body["rotation"]["omega0"]["value"] = 8.0 * lam1**2 * scale
    spec = SimulationSpec.model_validate(body)
    assert plausibility.warnings(spec, spec.to_simulation()) == []


def test_a_spin_meant_in_rpm_is_warned_about_in_the_result() -> None:
    spec = _spec(rotation__omega0={"kind": "constant", "value": 3000.0})
    result = simulate_spec(spec)
    (warning,) = [w for w in result.warnings if w.startswith("rotation.omega0")]
    assert warning == (
        "rotation.omega0 = 3000 rad/s is 10.3x the pipe's first bending frequency "
        '(291 rad/s); if you meant rpm, send rotation.omega0.value = {"value": 3000, '
        '"unit": "rpm"} (314 rad/s)'
    )
    # the same number sent in rpm is ordinary
    rpm = _spec(rotation__omega0={"kind": "constant", "value": {"value": 3000, "unit": "rpm"}})
    assert plausibility.warnings(rpm) == []


def test_a_velocity_past_ten_critical_flow_numbers_is_warned_about() -> None:
    (warning,) = plausibility.warnings(_spec(flow__velocity={"kind": "constant", "value": 500.0}))
    assert warning.startswith("flow.velocity = 500 m/s is u = 165, 18.1x the pipe's critical ")
    assert "(u_cr = 9.13, v_cr = 27.6 m/s)" in warning
    assert warning.endswith(
        'if you meant cm/s, send flow.velocity.value = {"value": 500, "unit": "cm/s"} (5 m/s)'
    )
    ramp = _spec(flow__velocity={"kind": "polynomial", "coefficients": [0.0, 50000.0]})
    (warning,) = plausibility.warnings(ramp)  # 500 m/s at t_end = 0.01 s
    assert "give the profile's numbers as" in warning


def test_ordinary_values_give_no_warning() -> None:
    assert plausibility.warnings(SimulationSpec.model_validate(PAPER_EXAMPLE)) == []
    # 20 m/s is past u_cr (a run that flutters) but not ten times: no warning
    assert plausibility.warnings(_spec(flow__velocity={"kind": "constant", "value": 60.0})) == []
    assert (
        plausibility.warnings(_spec(rotation__omega0={"kind": "constant", "value": 1500.0})) == []
    )
