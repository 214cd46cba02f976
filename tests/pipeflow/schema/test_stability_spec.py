"""Request models of /v1/stability and /v1/sweeps: validation, normal forms, JSON output."""

from __future__ import annotations

import json

import pytest
from pydantic import ValidationError

from pipeflow.computations.registry import STABILITY as STABILITY_COMPUTATION
from pipeflow.computations.registry import SWEEP_KINDS, computation_for, parse
from pipeflow.errors import Cancelled
from pipeflow.schema.stability import PAPER_PIPE_JSON, StabilitySpec


def parse_sweep(body):
    return parse(SWEEP_KINDS, body)


def run_sweep(spec, progress=None):
    return computation_for(spec).execute(spec, progress)


STABILITY = {
    "pipe": PAPER_PIPE_JSON,
    "rotation": {"omega0": {"kind": "constant", "value": 100.0}},
    "modes": 6,
    "velocity_range": [-1.0, 40.0],
    "points": 41,
}


def test_stability_roundtrip_json_and_progress():
    spec = StabilitySpec.model_validate(STABILITY)
    seen: list[float] = []
    out = STABILITY_COMPUTATION.execute(spec, progress=seen.append)
    text = json.dumps(out, allow_nan=False)
    assert json.loads(text)["kind"] == "stability"
    assert out["critical_velocity"] is not None
    assert out["reverse_flow"]["caveat"]
    assert {"velocity", "frequency", "mode", "kind", "direction"} <= set(out["crossings"][0])
    assert {"u_cr", "beta", "gamma"} <= set(out["dimensionless"])
    assert seen and seen[-1] == 1.0 and all(0 <= x <= 1 for x in seen)


def test_normal_form_ignores_spelling_and_sees_changes():
    a = StabilitySpec.model_validate(STABILITY)
    b = StabilitySpec.model_validate({**{k: STABILITY[k] for k in reversed(STABILITY)}})
    c = StabilitySpec.model_validate({**STABILITY, "velocity_range": [-1.0, 41.0]})
    d = StabilitySpec.model_validate({k: v for k, v in STABILITY.items() if k != "rotation"})
    assert a.canonical() == b.canonical()
    assert a.canonical() != c.canonical()
    assert d.canonical()["rotation"]["omega0"] == {"kind": "constant", "value": 0.0}


@pytest.mark.parametrize(
    ("field", "value"),
    [("modes", "6"), ("modes", True), ("modes", 6.0), ("points", "41"), ("velocity_range", "0,1")],
)
def test_loose_types_are_refused(field, value):
    """Strict inputs: a string or a boolean where a number belongs is an error naming it."""
    with pytest.raises(ValidationError) as err:
        StabilitySpec.model_validate({**STABILITY, field: value})
    assert err.value.errors()[0]["loc"][0] == field


@pytest.mark.parametrize(
    ("body", "where"),
    [
        ({**STABILITY, "velocity_range": [5.0, 1.0]}, "increasing"),
        ({**STABILITY, "modes": 41}, "modes"),
        ({**STABILITY, "rotation": {"omega0": {"kind": "harmonic"}}}, "rotation"),
        ({**STABILITY, "extra": 1}, "extra"),
    ],
)
def test_bad_stability_requests_are_refused(body, where):
    with pytest.raises(ValidationError) as e:
        StabilitySpec.model_validate(body)
    assert where in str(e.value)


SWEEPS = [
    {
        "kind": "argand",
        "pipe": PAPER_PIPE_JSON,
        "modes": 6,
        "velocity_range": [0, 40],
        "points": 21,
    },
    {
        "kind": "campbell",
        "pipe": PAPER_PIPE_JSON,
        "modes": 6,
        "spin_range": [0, 400],
        "points": 21,
        "flow": {"velocity": {"kind": "constant", "value": 5.0}},
    },
    {
        "kind": "spin_map",
        "pipe": PAPER_PIPE_JSON,
        "modes": 6,
        "velocity_range": [0, 40],
        "spin_range": [0, 400],
        "velocity_points": 20,
        "spin_points": 3,
    },
    {"kind": "beta_map", "modes": 6, "beta_range": [0.2, 0.5], "beta_points": 3, "u_points": 41},
    {
        "kind": "resonance_chart",
        "pipe": PAPER_PIPE_JSON,
        "modes": 3,
        "mean_velocity": 10.0,
        "amplitude_range": [0, 5],
        "frequency_range": [500, 3000],
        "amplitude_points": 3,
        "frequency_points": 4,
    },
    {
        "kind": "floquet",
        "pipe": PAPER_PIPE_JSON,
        "modes": 3,
        "flow": {"velocity": {"kind": "harmonic", "mean": 10, "amplitude": 5, "frequency": 1000}},
    },
]


@pytest.mark.parametrize("body", SWEEPS, ids=[b["kind"] for b in SWEEPS])
def test_every_sweep_kind_runs_to_finite_json(body):
    spec = parse_sweep(body)
    out = run_sweep(spec)
    assert out["kind"] == body["kind"]
    json.dumps(out, allow_nan=False)
    assert spec.canonical()["kind"] == body["kind"]


def test_sweep_validation_and_cancel():
    with pytest.raises(ValidationError):
        parse_sweep(
            {
                "kind": "argand",
                "pipe": PAPER_PIPE_JSON,
                "velocity_range": [0, 1],
                "tracked_modes": 12,
                "modes": 4,
            }
        )
    with pytest.raises(ValidationError):
        parse_sweep({"kind": "beta_map", "beta_range": [0.5, 1.0]})
    with pytest.raises(ValidationError):
        parse_sweep(
            {
                "kind": "floquet",
                "pipe": PAPER_PIPE_JSON,
                "flow": {"velocity": {"kind": "constant", "value": 1}},
            }
        )
    with pytest.raises(ValidationError):
        parse_sweep({"kind": "nope"})

    def stop(_: float) -> None:
        raise Cancelled()

    with pytest.raises(Cancelled):
        run_sweep(parse_sweep(SWEEPS[2]), progress=stop)
