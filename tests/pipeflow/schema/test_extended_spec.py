"""The extended model's fields in the JSON specs (issue 14): pipe.damping.kelvin_voigt,
pipe.damping.viscous, pipe.tip_mass, pipe.tip_inertia, rotation.hub_radius and plane reach
the library in every simulation and stability request, are validated with the field
named, and default to the paper's model."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest
from pydantic import ValidationError

from pipeflow.computations import documents
from pipeflow.computations.registry import STABILITY, SWEEP_KINDS, computation_for, parse
from pipeflow.model import GROUPS, Pipe
from pipeflow.paper import PAPER_PIPE
from pipeflow.schema.results import StabilityDimensionless
from pipeflow.schema.simulation import SimulationSpec
from pipeflow.schema.stability import PAPER_PIPE_JSON, BetaMapSweep, StabilitySpec
from pipeflow.stability.core import nondimensional_pipe
from pipeflow.stability.critical import critical_velocities
from pipeflow.stability.maps import beta_map


def parse_sweep(body: Any) -> Any:
    return parse(SWEEP_KINDS, body)


def run_sweep(spec: Any, progress: Any = None) -> dict[str, Any]:
    return computation_for(spec).execute(spec, progress)


def run_stability(spec: StabilitySpec, progress: Any = None) -> dict[str, Any]:
    return STABILITY.execute(spec, progress)


EXTENDED_PIPE: dict[str, Any] = {
    **PAPER_PIPE_JSON,
    "damping": {"kelvin_voigt": 2e-6, "viscous": 2e-4},
    "tip_mass": 1e-7,
    "tip_inertia": 1e-13,
}
EXPECTED = Pipe(
    E=PAPER_PIPE.E,
    I=PAPER_PIPE.I,
    L=PAPER_PIPE.L,
    M1=PAPER_PIPE.M1,
    M2=PAPER_PIPE.M2,
    kelvin_voigt=2e-6,
    viscous=2e-4,
    tip_mass=1e-7,
    tip_inertia=1e-13,
    hub_radius=0.01,
    plane="out-of-plane",
)
HUB = {"hub_radius": 0.01}
CONSTANT = {"kind": "constant", "value": 100.0}


def test_simulation_spec_carries_every_field_to_the_library() -> None:
    spec = SimulationSpec.model_validate(
        {
            "pipe": EXTENDED_PIPE,
            "rotation": {"omega0": CONSTANT, **HUB},
            "plane": "out-of-plane",
        }
    )
    assert spec.to_simulation().pipe == EXPECTED


def test_defaults_are_the_paper_model() -> None:
    spec = SimulationSpec.model_validate({"pipe": PAPER_PIPE_JSON})
    assert spec.to_simulation().pipe == PAPER_PIPE
    assert PAPER_PIPE.is_paper_model
    canonical = spec.canonical()
    assert canonical["pipe"]["damping"] == {"kelvin_voigt": 0.0, "viscous": 0.0}
    assert canonical["pipe"]["tip_mass"] == 0.0 and canonical["pipe"]["tip_inertia"] == 0.0
    assert canonical["rotation"]["hub_radius"] == 0.0 and canonical["plane"] == "in-plane"


@pytest.mark.parametrize(
    ("patch", "loc"),
    [
        ({"pipe": {**PAPER_PIPE_JSON, "damping": {"kelvin_voigt": -1}}}, "pipe.damping.kelvin_voigt"),  # noqa: E501
        ({"pipe": {**PAPER_PIPE_JSON, "damping": {"viscous": -1.0}}}, "pipe.damping.viscous"),
        ({"pipe": {**PAPER_PIPE_JSON, "damping": {"hysteretic": 0.1}}}, "pipe.damping.hysteretic"),
        ({"pipe": {**PAPER_PIPE_JSON, "tip_mass": -1e-3}}, "pipe.tip_mass"),
        ({"pipe": {**PAPER_PIPE_JSON, "tip_inertia": 1e30}}, "pipe.tip_inertia"),
        ({"rotation": {"hub_radius": -0.1}}, "rotation.hub_radius"),
        ({"plane": "sideways"}, "plane"),
    ],
)  # fmt: skip
def test_bad_values_name_their_field(patch: dict[str, Any], loc: str) -> None:
    body = {"pipe": PAPER_PIPE_JSON, **patch}
    with pytest.raises(ValidationError) as info:
        SimulationSpec.model_validate(body)
    assert loc in {".".join(str(p) for p in e["loc"]) for e in info.value.errors()}
    with pytest.raises(ValidationError) as info:
        StabilitySpec.model_validate({**body, "velocity_range": [0, 1]})
    assert loc in {".".join(str(p) for p in e["loc"]) for e in info.value.errors()}


SWEEPS: list[dict[str, Any]] = [
    {"kind": "argand", "rotation": {"omega0": CONSTANT, **HUB}, "velocity_range": [0, 1]},
    {"kind": "campbell", "rotation": HUB, "spin_range": [0, 100]},
    {"kind": "spin_map", "rotation": HUB, "velocity_range": [0, 1], "spin_range": [0, 100]},
    {
        "kind": "resonance_chart",
        "rotation": {"omega0": CONSTANT, **HUB},
        "mean_velocity": 1.0,
        "amplitude_range": [0, 1],
        "frequency_range": [1000, 2000],
    },
    {
        "kind": "floquet",
        "rotation": {"omega0": CONSTANT, **HUB},
        "flow": {"velocity": {"kind": "harmonic", "mean": 1, "amplitude": 1, "frequency": 1e3}},
    },
]


@pytest.mark.parametrize("body", SWEEPS, ids=[b["kind"] for b in SWEEPS])
def test_every_sweep_with_a_pipe_mounts_it(body: dict[str, Any]) -> None:
    spec = parse_sweep({**body, "pipe": EXTENDED_PIPE, "plane": "out-of-plane"})
    assert spec.mounted_pipe() == EXPECTED
    bare = {k: v for k, v in body.items() if k != "rotation"}
    assert parse_sweep({**bare, "pipe": PAPER_PIPE_JSON}).mounted_pipe() == PAPER_PIPE


def test_stability_spec_reproduces_paidoussis_damped_gravity_case() -> None:
    """End to end through the JSON spec: the case of test_extended_model's Paidoussis (1998,
    p. 118) check, beta = 0.65, gravity gamma_g = 10 as the hub term (R = 1e5 L, the spec's
    bound; the leftover w0^2 terms are 1e-5 of it), Kelvin-Voigt alpha = 0.0189: u_cf = 9.85
    published. Tolerance 0.02 as there; 12 modes."""
    beta, delta = 0.65, 1e5
    w0 = math.sqrt(10.0 / ((1 - beta) * delta))
    spec = StabilitySpec.model_validate(
        {
            "pipe": {
                "E": 1.0,
                "I": 1.0,
                "L": 1.0,
                "M1": 1 - beta,
                "M2": beta,
                "damping": {"kelvin_voigt": 0.0189},
            },
            "rotation": {"omega0": {"kind": "constant", "value": w0}, "hub_radius": delta},
            "plane": "out-of-plane",
            "modes": 12,
            "velocity_range": [0.0, 20.0],
        }
    )
    out = run_stability(spec)
    assert abs(out["dimensionless"]["u_cr"] - 9.85) < 0.02
    assert out["dimensionless"]["alpha"] == pytest.approx(0.0189, rel=1e-12)
    assert out["dimensionless"]["hub_ratio"] == delta


def test_beta_map_groups_match_the_dimensional_pipe() -> None:
    """beta_map's groups (alpha, viscous_ratio, tip_mass_ratio, tip_inertia_ratio, hub_ratio) at
    beta give the same u_cr as critical_velocities on a dimensional pipe with those groups
    (the paper's E, I, L; M1, M2 from beta): the definitions of Pipe.dimensionless_groups are
    the ones the map uses. Tolerance 1e-7 in u (both locate the crossing to 1e-10 relative;
    the grids differ)."""
    groups = {
        "alpha": 2e-3,
        "viscous_ratio": 0.1,
        "tip_mass_ratio": 0.1,
        "tip_inertia_ratio": 1e-4,
        "hub_ratio": 0.5,
    }
    beta, gamma = 0.3, 2.0
    m = beta_map((beta, beta + 0.1), (0.0, 12.0), gamma, modes=8, beta_points=2, u_points=241,
                 groups=groups, plane="out-of-plane")  # fmt: skip
    assert documents.beta_map(m)["groups"] == pytest.approx(groups, rel=1e-14)
    u_map = m.u_cr[0]
    E, I, L = PAPER_PIPE.E, PAPER_PIPE.I, PAPER_PIPE.L
    mass = 3e-5
    ref = Pipe(E=E, I=I, L=L, M1=(1 - beta) * mass, M2=beta * mass, plane="out-of-plane")
    ts = ref.time_scale
    pipe = Pipe(
        E=E,
        I=I,
        L=L,
        M1=(1 - beta) * mass,
        M2=beta * mass,
        kelvin_voigt=groups["alpha"] * ts,
        viscous=groups["viscous_ratio"] * math.sqrt(ref.EI * mass) / L**2,
        tip_mass=groups["tip_mass_ratio"] * mass * L,
        tip_inertia=groups["tip_inertia_ratio"] * mass * L**3,
        hub_radius=groups["hub_ratio"] * L,
        plane="out-of-plane",
    )
    assert pipe.dimensionless_groups() == pytest.approx(groups, rel=1e-12)
    w0 = float(pipe.spin_from_number(gamma))
    v_max = float(pipe.velocity_from_flow_number(12.0))
    res = critical_velocities(pipe, omega0=w0, velocity_range=(0.0, v_max), modes=8, points=241)
    assert u_map is not None and res.critical_velocity is not None
    assert abs(float(pipe.flow_number(res.critical_velocity)) - u_map) < 1e-7
    assert np.isclose(res.u_cr, u_map, rtol=0, atol=1e-7)


def test_beta_map_refuses_bad_groups() -> None:
    with pytest.raises(ValueError, match="unknown group"):
        nondimensional_pipe(0.5, {"zeta": 1.0})
    with pytest.raises(ValueError, match="alpha"):
        nondimensional_pipe(0.5, {"alpha": -1.0})
    with pytest.raises(ValidationError):
        parse_sweep({"kind": "beta_map", "hub_ratio": -1.0})


def test_group_fields_of_the_schemas_are_the_model_groups() -> None:
    """One definition: the beta_map request and the stability result carry exactly the groups
    of pipeflow.model.GROUPS, with their descriptions; the request still takes the former
    name 'sigma' of viscous_ratio (it clashed with the growth rate sigma [1/s]), but not
    both names at once (422: the extra 'sigma' is named)."""
    fields = BetaMapSweep.model_fields
    result = StabilityDimensionless.model_fields
    for name, group in GROUPS.items():
        assert (fields[name].description or "").startswith(group.description)
        assert (result[name].description or "").startswith(group.description)
    assert "sigma" not in fields and "sigma" not in result
    old = parse_sweep({"kind": "beta_map", "sigma": 0.25})
    assert isinstance(old, BetaMapSweep) and old.viscous_ratio == 0.25
    assert old.canonical() == parse_sweep({"kind": "beta_map", "viscous_ratio": 0.25}).canonical()
    with pytest.raises(ValidationError, match="sigma"):
        parse_sweep({"kind": "beta_map", "sigma": 0.25, "viscous_ratio": 0.25})


def test_beta_map_sweep_json_reports_groups_and_plane() -> None:
    out = run_sweep(
        parse_sweep(
            {
                "kind": "beta_map",
                "beta_range": [0.2, 0.3],
                "beta_points": 2,
                "u_points": 41,
                "modes": 6,
                "alpha": 1e-3,
                "plane": "out-of-plane",
            }
        )
    )
    assert out["groups"]["alpha"] == 1e-3 and out["groups"]["hub_ratio"] == 0.0
    assert out["plane"] == "out-of-plane"
