"""The supports, axial loads and gravity over HTTP (issue 31): POST /v1/stability and
/v1/simulate with pipe.supports, pipe.intermediate_supports, pipe.tension and gravity.

The numbers are checked in tests/pipeflow/test_supports.py and
tests/pipeflow/stability/test_mechanism.py; here: the service carries them, refuses bad
mountings with a 422 naming the field, answers a buckled pipe as divergence, and leaves the
cache key of a request without the new fields unchanged.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from typing import Any

import pytest
from fastapi.testclient import TestClient

from pipeflow.schema.simulation import SimulationSpec
from pipeflow.schema.stability import StabilitySpec
from tests.service.conftest import make_client, wait_ready
from tests.service.test_stability_api import _fields, _problem

UNIT = {"E": 1.0, "I": 1.0, "L": 1.0, "M1": 0.5, "M2": 0.5}
SPOOL: dict[str, Any] = {
    "pipe": {**UNIT, "supports": {"x0": "pinned", "xL": "pinned"}},
    "modes": 10,
    "velocity_range": [0.0, 5.0 / math.sqrt(0.5)],
    "points": 101,
}


@pytest.fixture(scope="module")
def api(tmp_path_factory: pytest.TempPathFactory) -> Iterator[TestClient]:
    with make_client(tmp_path_factory.mktemp("supports"), workers=1, queue_size=4) as c:
        wait_ready(c)
        yield c


def test_spool_diverges_at_pi(api: TestClient) -> None:
    """Pinned-pinned (Paidoussis sec. 3.3): divergence at u = pi, v = pi / sqrt(beta)."""
    doc = api.post("/v1/stability", json=SPOOL).json()
    assert doc["mechanism"] == "divergence"
    assert doc["critical_velocity"] == pytest.approx(math.pi / math.sqrt(0.5), rel=1e-10)
    assert doc["crossings"][0]["kind"] == "divergence"


def test_hanging_pipe_flutters_later(api: TestClient) -> None:
    """A hanging cantilever (gamma = 10, beta = 0.65) flutters at u = 12.88 (Paidoussis
    1998 p. 118; 12.8826 at 12 modes), well above the bare pipe."""
    body = {
        "pipe": {**UNIT, "M1": 0.35, "M2": 0.65},
        "gravity": {"g": 10.0, "orientation": "hanging"},
        "modes": 12,
        "velocity_range": [10.0 / math.sqrt(0.65), 14.0 / math.sqrt(0.65)],
        "points": 81,
    }
    doc = api.post("/v1/stability", json=body).json()
    assert doc["mechanism"] == "flutter"
    assert doc["critical_velocity"] * math.sqrt(0.65) == pytest.approx(12.88, abs=0.02)


def test_compression_beyond_buckling_is_divergence_not_500(api: TestClient) -> None:
    body = {**SPOOL, "pipe": {**SPOOL["pipe"], "tension": -1.5 * math.pi**2}}
    doc = api.post("/v1/stability", json=body).json()
    assert doc["stable_at_start"] is False
    assert doc["instability_at_start"] == ["divergence"]


def test_supported_simulation_runs(api: TestClient) -> None:
    """A clamped-clamped pipe with a midspan spring, tension and the 'paper' initial shape
    (largest deflection u0), below divergence: bounded, completed."""
    body = {
        "pipe": {**UNIT, "supports": {"x0": "clamped", "xL": "clamped"}, "tension": 2.0,
                 "intermediate_supports": [{"position": 0.5, "translational": 100.0}]},
        "flow": {"velocity": {"kind": "constant", "value": 2.0}},
        "initial": {"u0": 0.001, "du0": 0.0},
        "modes": 8,
        "time": {"t_end": 1.0, "samples": 51},
        "output": {"positions": [0.5]},
    }  # fmt: skip
    r = api.post("/v1/simulations", json=body)
    assert r.status_code == 200, r.text
    doc = r.json()
    mid = doc["displacements"][0]["u"]
    assert doc["status"] == "ok"
    assert mid[0] == pytest.approx(0.001, rel=1e-9)  # symmetric first mode: midspan largest
    assert max(abs(x) for x in mid) < 0.0011  # stable, undamped: bounded


@pytest.mark.parametrize(
    ("pipe", "field"),
    [
        ({"supports": {"x0": "clamped", "xL": "pinned"}, "tip_mass": 1.0}, "pipe.tip_mass"),
        ({"axially_restrained": True}, "pipe.axially_restrained"),
        ({"supports": {"x0": "welded"}}, "pipe.supports.x0"),
        ({"supports": {"xL": {"translational": -1.0}}}, "pipe.supports.xL"),
        ({"intermediate_supports": [{"position": 2.0, "kind": "pinned"}]},
         "pipe.intermediate_supports.0.position"),
        ({"intermediate_supports": [{"position": 0.5}]}, "pipe.intermediate_supports.0"),
        ({"intermediate_supports": [{"position": 0.1 * (i + 1), "kind": "pinned"}
                                    for i in range(9)]}, "pipe.intermediate_supports"),
        ({"poisson": 0.7}, "pipe.poisson"),
        ({"supports": {"x0": "free", "xL": "free"}}, "pipe.supports"),
        # a 0 N/m intermediate spring holds nothing: the pipe would still translate freely
        ({"supports": {"x0": "sliding", "xL": "free"},
          "intermediate_supports": [{"position": 0.5, "translational": 0.0}]}, "pipe.supports"),
        ({"tension": 1e13}, "pipe.tension"),
    ],
)  # fmt: skip
def test_bad_mountings_422_name_the_field(
    api: TestClient, pipe: dict[str, Any], field: str
) -> None:
    body = {**SPOOL, "pipe": {**UNIT, **pipe}}
    doc = _problem(api.post("/v1/stability", json=body), 422)
    assert any(f.startswith(field) for f in _fields(doc)), doc


def test_gravity_422_names_the_field(api: TestClient) -> None:
    body = {**SPOOL, "gravity": {"g": -1.0}}
    assert "gravity.g" in _fields(_problem(api.post("/v1/stability", json=body), 422))


def test_cache_keys_without_the_new_fields_are_unchanged() -> None:
    """The canonical form of a request leaving the new fields out has none of them, and
    giving them at their defaults is the same request (same canonical form, same key)."""
    plain = StabilitySpec.model_validate({**SPOOL, "pipe": UNIT}).canonical()
    explicit = StabilitySpec.model_validate(
        {**SPOOL, "pipe": {**UNIT, "supports": {"x0": "clamped", "xL": "free"}, "tension": 0.0,
                           "poisson": 0.3, "intermediate_supports": []}}
    ).canonical()  # fmt: skip
    assert plain == explicit
    for name in ("supports", "tension", "poisson", "flow_area", "intermediate_supports"):
        assert name not in plain["pipe"]
    assert "gravity" not in plain
    sim = SimulationSpec.model_validate({"pipe": UNIT}).canonical()
    assert "gravity" not in sim and "supports" not in sim["pipe"]


def test_pressure_shifts_the_spool_divergence(api: TestClient) -> None:
    """u^2 + Pi = pi^2 (pinned-pinned, not axially restrained: delta = 0): Pi = p A L^2/EI
    = 2 lowers u_cr to sqrt(pi^2 - 2)."""
    body = {**SPOOL, "pipe": {**SPOOL["pipe"], "flow_area": 0.5}, "flow": {"pressure": 4.0}}
    doc = api.post("/v1/stability", json=body).json()
    assert doc["critical_velocity"] * math.sqrt(0.5) == pytest.approx(
        math.sqrt(math.pi**2 - 2.0), rel=1e-8
    )


def test_pressure_needs_the_flow_area(api: TestClient) -> None:
    body = {**SPOOL, "flow": {"pressure": 4.0}}
    assert "pipe.flow_area" in _fields(_problem(api.post("/v1/stability", json=body), 422))
    sim = {"pipe": UNIT, "flow": {"pressure": 1e5}}
    assert "pipe.flow_area" in _fields(_problem(api.post("/v1/simulations", json=sim), 422))


def test_stability_canonical_without_pressure_has_no_flow() -> None:
    assert "flow" not in StabilitySpec.model_validate(SPOOL).canonical()


def test_the_new_fields_take_units_like_every_field() -> None:
    """Quantities {value, unit} convert to the SI unit each description states: 2 kN of
    tension, a support 500 mm along, a 5 kN/m spring, 50 bar, g in ft/s^2."""
    spring = {"translational": {"value": 5, "unit": "kN/m"}}
    point = {"position": {"value": 500, "unit": "mm"}, "kind": "pinned"}
    pipe_json = {
        **UNIT,
        "flow_area": 1e-3,
        "tension": {"value": 2, "unit": "kN"},
        "supports": {"x0": "pinned", "xL": spring},
        "intermediate_supports": [point],
    }
    spec = SimulationSpec.model_validate(
        {
            "pipe": pipe_json,
            "flow": {"pressure": {"value": 50, "unit": "bar"}},
            "gravity": {"g": {"value": 32.174, "unit": "ft/s^2"}},
        }
    )  # fmt: skip
    pipe = spec.to_simulation().pipe
    assert pipe.tension == pytest.approx(2000.0)
    assert pipe.supports.xL.translational == pytest.approx(5000.0)
    assert pipe.intermediate_supports[0].position == pytest.approx(0.5)
    assert pipe.pressure == pytest.approx(5e6)
    assert pipe.gravity == pytest.approx(9.80665, rel=1e-5)


def test_a_study_varies_tension_and_pressure() -> None:
    """A grid over pipe.tension and flow.pressure (fields whose defaults the dump leaves
    out) on the pinned-pinned pipe: every case diverges at u = sqrt(pi^2 - Pi + Gamma)
    (Paidoussis sec. 3.3; Pi = p A L^2/EI, Gamma = T L^2/EI), to 1e-10 (the basis holds
    the buckling mode)."""
    from pipeflow.computations.registry import COMPUTATIONS
    from pipeflow.schema.study import StudySpec

    base = {**SPOOL, "pipe": {**SPOOL["pipe"], "flow_area": 1.0}, "modes": 8}
    body = {
        "base": {"kind": "stability", "spec": base},
        "grid": {"pipe.tension": [-2.0, 0.0, 3.0], "flow.pressure": [0.0, 1.0]},
    }
    study = COMPUTATIONS["study"].execute(StudySpec.model_validate(body))
    names = [c["name"] for c in study["columns"]]
    assert study["counts"]["ok"] == 6
    for row in study["rows"]:
        case = dict(zip(names, row, strict=True))
        u = case["critical_velocity"] * math.sqrt(0.5)
        exact = math.sqrt(math.pi**2 - case["flow.pressure"] + case["pipe.tension"])
        assert case["critical_kind"] == "divergence"
        assert u == pytest.approx(exact, rel=1e-10)


def test_a_pressure_profile_over_http(api: TestClient) -> None:
    """flow.pressure takes a profile in a simulation (a new key; the constant profile is the
    number's request), and a profile out of bounds or in a frozen analysis is a 422 naming
    flow.pressure (tests/pipeflow/test_pressure_profile.py checks the numbers)."""
    pipe = {**UNIT, "supports": {"x0": "pinned", "xL": "pinned"}, "flow_area": 1.0}
    body: dict[str, Any] = {
        "pipe": pipe,
        "flow": {"velocity": {"kind": "constant", "value": 1.0}, "pressure": 2.0},
        "modes": 4,
        "time": {"t_end": 0.5, "samples": 11},
    }
    number = api.post("/v1/simulations", json=body).json()
    body["flow"]["pressure"] = {"kind": "constant", "value": 2.0}
    assert api.post("/v1/simulations", json=body).json()["key"] == number["key"]
    body["flow"]["pressure"] = {"kind": "polynomial", "coefficients": [2.0, 4.0]}
    r = api.post("/v1/simulations", json=body)
    assert r.status_code == 200, r.text
    assert r.json()["key"] != number["key"] and r.json()["method_used"] == "magnus"
    body["flow"]["pressure"] = {"kind": "table", "t": [0.0, 1.0], "values": [0.0, 2e10]}
    assert any(
        f.startswith("flow.pressure")
        for f in _fields(_problem(api.post("/v1/simulations", json=body), 422))
    )
    frozen = {**SPOOL, "pipe": pipe, "flow": {"pressure": {"kind": "constant", "value": 1.0}}}
    assert any(
        f.startswith("flow.pressure")
        for f in _fields(_problem(api.post("/v1/stability", json=frozen), 422))
    )


def test_a_bad_member_of_a_pressure_profile_names_its_field(api: TestClient) -> None:
    """A number-or-profile field's error locations carry pydantic's union labels
    ('constrained-float', 'tagged-union[...]'), which are no fields of the body: mapping them
    raised a KeyError, a 500 (schemathesis found it); now a 422 naming the members."""
    body = {
        "pipe": {**UNIT, "flow_area": 1.0},
        "flow": {"pressure": {"kind": "half_sine", "peak": 0.0, "duration": {"unit": "0"}}},
        "time": {"t_end": 0.1, "samples": 11},
    }
    fields = _fields(_problem(api.post("/v1/simulations", json=body), 422))
    assert "flow.pressure.duration" in fields and "flow.pressure" in fields
