"""POST /v1/stability, POST /v1/stability/jobs and POST /v1/sweeps over HTTP.

The numbers are pipeflow's (tests/pipeflow/stability/ check them against the
literature); these tests check that the service carries them through unchanged, with the
job, cache and error machinery shared with simulations.  Grids are small: seconds in all.
"""

from __future__ import annotations

import json
import math
from collections.abc import Iterator
from typing import Any

import pytest
from fastapi.testclient import TestClient

from pipeflow.computations.registry import COMPUTATIONS, STABILITY, SWEEP_KINDS, parse
from pipeflow.schema.stability import PAPER_PIPE_JSON, StabilitySpec
from service.keys import keyed
from tests.service.conftest import make_client, wait_job, wait_ready

#: the paper's pipe at w0 = 100 rad/s, 0..60 m/s, 10 modes (the endpoint's example)
PAPER: dict[str, Any] = {
    "pipe": PAPER_PIPE_JSON,
    "rotation": {"omega0": {"kind": "constant", "value": 100.0}},
    "modes": 10,
    "velocity_range": [0.0, 60.0],
}
#: non-dimensional pipe with beta = 0.2 (E = I = L = 1, M1 + M2 = 1): u = v sqrt(beta)
BETA_02: dict[str, Any] = {
    "pipe": {"E": 1.0, "I": 1.0, "L": 1.0, "M1": 0.8, "M2": 0.2},
    "modes": 10,
    "velocity_range": [0.0, 12.0 / math.sqrt(0.2)],
    "points": 121,
}
#: one small spec of every sweep kind, and the plots its result must offer
SWEEPS: dict[str, tuple[dict[str, Any], list[str]]] = {
    "argand": (
        {"pipe": PAPER_PIPE_JSON, "modes": 4, "tracked_modes": 2, "points": 21}
        | {"velocity_range": [0.0, 40.0], "rotation": {"omega0": {"value": 100.0}}},
        ["argand", "sweep_frequency", "sweep_damping"],
    ),
    "campbell": (
        {"pipe": PAPER_PIPE_JSON, "modes": 4, "tracked_modes": 2, "points": 21}
        | {"spin_range": [0.0, 1000.0], "flow": {"velocity": {"value": 10.0}}},
        ["argand", "campbell", "sweep_frequency", "sweep_damping"],
    ),
    "spin_map": (
        {"pipe": PAPER_PIPE_JSON, "modes": 4, "velocity_points": 12, "spin_points": 4}
        | {"velocity_range": [0.0, 60.0], "spin_range": [0.0, 1000.0]},
        ["spin_map"],
    ),
    "beta_map": ({"modes": 6, "beta_points": 3, "u_points": 31}, ["beta_map"]),
    "resonance_chart": (
        # beta = 0.2, u = 4: omega_2 = 17.13 rad/s lightly damped; principal region near 34
        {"pipe": BETA_02["pipe"], "modes": 3, "mean_velocity": 4.0 / math.sqrt(0.2)}
        | {"amplitude_range": [0.0, 0.8 * 4.0 / math.sqrt(0.2)], "frequency_range": [25.0, 43.0]}
        | {"amplitude_points": 4, "frequency_points": 7},
        ["resonance_chart"],
    ),
    "floquet": (
        {"pipe": PAPER_PIPE_JSON, "modes": 2}
        | {"flow": {"velocity": {"kind": "harmonic", "mean": 10.0, "amplitude": 5.0}}}
        | {"rotation": {"omega0": {"kind": "constant", "value": 100.0}}},
        ["floquet_multipliers"],
    ),
}
SWEEPS["floquet"][0]["flow"]["velocity"]["frequency"] = 1000.0


@pytest.fixture(scope="module")
def api(tmp_path_factory: pytest.TempPathFactory) -> Iterator[TestClient]:
    """Two workers that record progress every 10 ms (so a 1 s job shows intermediate values)."""
    with make_client(
        tmp_path_factory.mktemp("stability"), workers=2, queue_size=8, progress_interval_s=0.01
    ) as c:
        wait_ready(c)
        yield c


def _problem(resp: Any, status: int) -> dict[str, Any]:
    assert resp.status_code == status, resp.text
    assert resp.headers["content-type"] == "application/problem+json"
    doc: dict[str, Any] = resp.json()
    assert doc["status"] == status
    return doc


def _fields(doc: dict[str, Any]) -> list[str | None]:
    return [e["field"] for e in doc.get("errors", [])]


def _matches_model(doc: dict[str, Any]) -> None:
    """The result has exactly the fields its response model documents (both ways)."""
    model = COMPUTATIONS[doc["kind"]].response
    model.model_validate(doc)
    assert set(doc) == set(model.model_fields), doc["kind"]


def _sweep(kind: str) -> dict[str, Any]:
    spec, _ = SWEEPS[kind]
    return {"kind": kind, **json.loads(json.dumps(spec))}


# -- POST /v1/stability ----------------------------------------------------------------------


def test_paper_pipe_critical_velocity_and_cache(api: TestClient) -> None:
    """The paper's pipe at w0 = 100 rad/s loses stability by flutter of mode 3 at 27.69 m/s
    (u_cr = 9.15, the library's value, see the README); the second request is a cache hit
    under the documented key."""
    r = api.post("/v1/stability", json=PAPER)
    assert r.status_code == 200, r.text
    doc = r.json()
    assert r.headers["x-cache"] == "MISS" and doc["cached"] is False
    key = keyed(STABILITY, StabilitySpec.model_validate(PAPER)).key
    assert doc["key"] == key and r.headers["etag"] == f'"{key}"'
    assert doc["critical_velocity"] == pytest.approx(27.692, abs=1e-3)  # [m/s]
    first = doc["crossings"][0]
    assert {"velocity", "frequency", "mode", "kind", "direction"} <= set(first)
    assert (first["mode"], first["kind"], first["direction"]) == (3, "flutter", "loss")
    assert first["frequency"] == pytest.approx(2195.7, rel=1e-3)  # [rad/s]
    assert doc["dimensionless"]["u_cr"] == pytest.approx(9.1495, rel=1e-4)
    assert doc["dimensionless"]["beta"] == pytest.approx(0.46667, rel=1e-4)
    assert doc["reverse_flow"] is None and doc["plots"] == []
    _matches_model(doc)

    again = api.post("/v1/stability", json={**PAPER, "points": 401})  # default spelled out
    assert again.headers["x-cache"] == "HIT" and again.json()["cached"] is True
    assert again.json()["key"] == key
    assert again.json()["crossings"] == doc["crossings"]
    fresh = api.post("/v1/stability", params={"refresh": "true"}, json=PAPER)
    assert fresh.headers["x-cache"] == "MISS"
    stored = api.get(f"/v1/results/{key}")
    assert (
        stored.status_code == 200 and stored.json()["critical_velocity"] == doc["critical_velocity"]
    )


def test_beta_02_critical_flow_number_through_http(api: TestClient) -> None:
    """Gregory & Paidoussis (1966); Paidoussis, Fluid-Structure Interactions vol. 1 (1998)
    sec. 3.5: beta = 0.2, gamma = 0: flutter of the second mode at u_cr ~ 5.6 (read from a
    graph, hence 0.1).  Our 10-mode value is 5.5917 (tests/pipeflow/stability/test_critical.py); the
    service must return it unchanged, so 1e-4 relative here."""
    doc = api.post("/v1/stability", json=BETA_02).json()
    assert doc["dimensionless"]["u_cr"] == pytest.approx(5.6, abs=0.1)
    assert doc["dimensionless"]["u_cr"] == pytest.approx(5.5917, rel=1e-4)
    assert doc["dimensionless"]["beta"] == pytest.approx(0.2)
    # E = I = L = 1, M2 = 0.2: v = u / sqrt(beta) [m/s]
    assert doc["critical_velocity"] == pytest.approx(5.5917 / math.sqrt(0.2), rel=1e-4)
    first = doc["crossings"][0]
    assert (first["mode"], first["kind"], first["direction"]) == (2, "flutter", "loss")
    assert first["flow_number"] == pytest.approx(doc["dimensionless"]["u_cr"], rel=1e-12)
    assert doc["stable_at_start"] is True and doc["stable_throughout"] is False


def test_reverse_flow_gets_the_caveat_not_a_threshold(api: TestClient) -> None:
    """Physics notes sec. 4 (Paidoussis & Luu 1985): in the undamped model every v < 0 grows,
    which experiments do not show, so the v < 0 part of a range gets the aspirating-pipe
    caveat and never a critical velocity; the v >= 0 part is unaffected."""
    doc = api.post("/v1/stability", json={**PAPER, "velocity_range": [-10.0, -1.0]}).json()
    assert doc["critical_velocity"] is None and doc["crossings"] == []
    assert doc["stable_at_start"] is None
    caveat = doc["reverse_flow"]
    assert caveat["velocity_range"] == [-10.0, -1.0]
    assert caveat["predicted_unstable"] is True and caveat["growth_rate_at_v_min"] > 0  # [1/s]
    assert "aspirating" in caveat["caveat"] and "Paidoussis & Luu" in caveat["caveat"]
    assert any("reverse flow" in w for w in doc["warnings"])
    _matches_model(doc)

    both = api.post("/v1/stability", json={**PAPER, "velocity_range": [-10.0, 60.0]}).json()
    assert both["critical_velocity"] == pytest.approx(27.692, abs=1e-3)
    assert both["reverse_flow"]["velocity_range"] == [-10.0, 0.0]


@pytest.mark.parametrize(
    ("change", "field"),
    [
        ({"velocity_range": [60.0, 0.0]}, "velocity_range"),
        ({"velocity_range": [0.0, "fast"]}, "velocity_range.1"),
        ({"modes": 0}, "modes"),
        ({"modes": 41}, "modes"),
        ({"points": 5}, "points"),
        ({"pipe": {**PAPER_PIPE_JSON, "E": -1.0}}, "pipe.E"),
        ({"pipe": {**PAPER_PIPE_JSON, "M1": 0.0, "M2": 0.0}}, "pipe.M1"),
        ({"rotation": {"omega0": {"kind": "harmonic", "mean": 1.0}}}, "rotation.omega0.kind"),
        ({"rotation": {"omega0": {"value": 1e8}}}, "rotation.omega0.value"),
        ({"velocity": 3.0}, "velocity"),
    ],
)
def test_stability_422_names_the_field(api: TestClient, change: dict[str, Any], field: str) -> None:
    doc = _problem(api.post("/v1/stability", json={**PAPER, **change}), 422)
    assert field in _fields(doc), doc


def test_stability_422_for_missing_fields_and_bad_json(api: TestClient) -> None:
    doc = _problem(api.post("/v1/stability", json={"modes": 4}), 422)
    assert set(_fields(doc)) == {"pipe", "velocity_range"}
    bad = b'{"pipe": {"E": NaN}}'
    headers = {"content-type": "application/json"}
    _problem(api.post("/v1/stability", content=bad, headers=headers), 422)
    _problem(api.post("/v1/stability/jobs", json={}), 422)


def test_oversize_body_413(api: TestClient) -> None:
    limit = api.app.state.settings.max_body_bytes  # type: ignore[attr-defined]
    big = {**PAPER, "padding": "x" * (limit + 1)}
    _problem(api.post("/v1/stability", json=big), 413)
    _problem(api.post("/v1/stability/jobs", json=big), 413)
    _problem(api.post("/v1/sweeps", json=big), 413)


def test_stability_job_flow_shares_the_cache(api: TestClient) -> None:
    spec = {**PAPER, "modes": 8, "velocity_range": [0.0, 50.0]}
    r = api.post("/v1/stability/jobs", json=spec)
    assert r.status_code == 202, r.text
    key = r.json()["key"]
    assert r.headers["location"] == f"/v1/jobs/{key}"
    assert r.json()["kind"] == "stability"
    job = wait_job(api, key)
    assert job["status"] == "succeeded" and job["progress"] == 1.0
    assert job["result"] == f"/v1/results/{key}"
    result = api.get(job["result"]).json()
    assert result["key"] == key and result["critical_velocity"] > 0
    # the sync form of the same spec is a cache hit, and a resubmission is idempotent
    sync = api.post("/v1/stability", json=spec)
    assert sync.headers["x-cache"] == "HIT" and sync.json()["key"] == key
    again = api.post("/v1/stability/jobs", json=spec)
    assert again.status_code == 202 and again.json()["status"] == "succeeded"


def test_saturated_503(tight: TestClient) -> None:
    """All slots taken (one worker, no queue): 503 with Retry-After on the synchronous
    endpoint; the job endpoints accept into the durable queue (202, issue 22 defect 4)."""
    busy = tight.post("/test/sleep-jobs", json={"seconds": 30, "tag": "stability-busy"})
    key = busy.json()["key"]
    queued: list[str] = []
    try:
        wait_job(tight, key, until=lambda j: j["status"] == "running")
        resp = tight.post("/v1/stability", json=PAPER)
        _problem(resp, 503)
        assert resp.headers["retry-after"] == "3"
        for path, body in (("/v1/stability/jobs", PAPER), ("/v1/sweeps", _sweep("argand"))):
            resp = tight.post(path, json=body)
            assert resp.status_code == 202, resp.text
            assert resp.json()["status"] == "queued"
            queued.append(resp.json()["key"])
    finally:
        for k in (key, *queued):
            tight.delete(f"/v1/jobs/{k}")


# -- POST /v1/sweeps -------------------------------------------------------------------------


@pytest.mark.parametrize("kind", list(SWEEPS))
def test_every_sweep_kind_runs_as_a_job_with_plots(api: TestClient, kind: str) -> None:
    body = _sweep(kind)
    r = api.post("/v1/sweeps", json=body)
    assert r.status_code == 202, r.text
    job = r.json()
    key = job["key"]
    assert r.headers["location"] == f"/v1/jobs/{key}"
    assert job["kind"] == kind and job["status"] in ("queued", "running", "succeeded")
    assert key == keyed(COMPUTATIONS[kind], parse(SWEEP_KINDS, body)).key
    done = wait_job(api, key)
    assert done["status"] == "succeeded", done
    result = api.get(f"/v1/results/{key}", headers={"Accept-Encoding": "identity"})
    assert result.status_code == 200 and result.headers["etag"] == f'"{key}"'  # the JSON bytes
    doc = result.json()
    assert doc["kind"] == kind and doc["cached"] is True
    _matches_model(doc)
    expected = SWEEPS[kind][1]
    assert doc["plots"] == expected
    for name in expected:
        png = api.get(f"/v1/results/{key}/plots/{name}.png")
        assert png.status_code == 200 and png.content.startswith(b"\x89PNG"), name
    assert b"<svg" in api.get(f"/v1/results/{key}/plots/{expected[0]}.svg").content
    # resubmitting is idempotent: the finished job at once, same key
    again = api.post("/v1/sweeps", json=body)
    assert again.status_code == 202 and again.json()["status"] == "succeeded"
    assert again.json()["key"] == key


def test_beta_map_takes_the_former_name_of_viscous_ratio(api: TestClient) -> None:
    """The viscous group was 'sigma' before it was renamed viscous_ratio (sigma is the growth
    rate): a request with the old name is the same computation (same key), and the result
    reports viscous_ratio only."""
    new = _sweep("beta_map") | {"viscous_ratio": 0.05}
    r_old = api.post("/v1/sweeps", json=_sweep("beta_map") | {"sigma": 0.05})
    r_new = api.post("/v1/sweeps", json=new)
    assert r_old.status_code == r_new.status_code == 202, (r_old.text, r_new.text)
    key = r_new.json()["key"]
    assert r_old.json()["key"] == key
    assert wait_job(api, key)["status"] == "succeeded"
    groups = api.get(f"/v1/results/{key}").json()["groups"]
    assert groups["viscous_ratio"] == 0.05 and "sigma" not in groups


def test_sweep_numbers_survive_the_trip(api: TestClient) -> None:
    """Spot checks of the JSON against the library's conventions (SI units)."""
    key = api.post("/v1/sweeps", json=_sweep("campbell")).json()["key"]
    wait_job(api, key)
    doc = api.get(f"/v1/results/{key}").json()
    axis = doc["parameter"]
    assert axis["name"] == "spin" and axis["unit"] == "rad/s"
    assert axis["values_rpm"][-1] == pytest.approx(1000.0 * 60 / (2 * math.pi))
    mode = doc["modes"][0]
    assert mode["frequency_hz"][0] == pytest.approx(mode["omega"][0] / (2 * math.pi))
    assert all(0.0 <= c <= 1.0 for c in mode["confidence"])
    assert doc["fixed"] == {"velocity": 10.0}

    chart_key = api.post("/v1/sweeps", json=_sweep("resonance_chart")).json()["key"]
    wait_job(api, chart_key)
    chart = api.get(f"/v1/results/{chart_key}").json()
    assert not any(chart["unstable"][0])  # no pulsation, no resonance
    region = chart["regions"][0]  # principal region of the second mode (test_floquet.py)
    assert region["nearest_resonance"]["condition"] == "2*omega_2"


def test_sweep_job_reports_progress_then_succeeds(api: TestClient) -> None:
    """A 100 x 100 spin map with 10 modes (about a second): progress is seen between 0 and
    1, never decreasing, and the job ends succeeded with progress 1."""
    body = _sweep("spin_map") | {"modes": 10, "velocity_points": 100, "spin_points": 100}
    key = api.post("/v1/sweeps", json=body).json()["key"]
    seen: list[float] = []

    def finished(job: dict[str, Any]) -> bool:
        seen.append(job["progress"])
        return bool(job["status"] in ("succeeded", "failed", "cancelled"))

    job = wait_job(api, key, until=finished)
    assert job["status"] == "succeeded" and job["progress"] == 1.0
    assert seen == sorted(seen) and all(0.0 <= f <= 1.0 for f in seen)
    assert any(0.0 < f < 1.0 for f in seen), seen
    doc = api.get(f"/v1/results/{key}").json()
    assert len(doc["spins"]) == 100 and len(doc["growth_rate"][0]) == 100


def test_sweep_job_can_be_cancelled(api: TestClient) -> None:
    body = _sweep("spin_map") | {"modes": 10, "velocity_points": 150, "spin_points": 150}
    key = api.post("/v1/sweeps", json=body).json()["key"]
    wait_job(api, key, until=lambda j: j["progress"] > 0 or j["status"] == "succeeded")
    r = api.delete(f"/v1/jobs/{key}")
    assert r.status_code == 200 and r.json()["status"] == "cancelled"
    assert wait_job(api, key)["status"] == "cancelled"
    _problem(api.get(f"/v1/results/{key}"), 404)


def test_over_budget_map_is_refused_at_submission(api: TestClient) -> None:
    """A 200 x 200 map with 40 modes passes the per-field bounds but exceeds the library's
    work budget: the request is refused at once (422 naming the field), no job is created."""
    body = _sweep("spin_map") | {"modes": 40, "velocity_points": 200, "spin_points": 200}
    r = api.post("/v1/sweeps", json=body)
    doc = _problem(r, 422)
    assert doc["errors"][0]["field"] == "spin_points"
    assert "fewer points or modes" in doc["detail"]


@pytest.mark.parametrize(
    ("body", "field"),
    [
        ({"pipe": PAPER_PIPE_JSON, "velocity_range": [0.0, 1.0]}, "kind"),
        ({"kind": "bode", "pipe": PAPER_PIPE_JSON}, "kind"),
        (_sweep("argand") | {"velocity_range": [5.0, 1.0]}, "velocity_range"),
        (_sweep("argand") | {"tracked_modes": 5}, "tracked_modes"),
        (_sweep("argand") | {"points": 1}, "points"),
        (_sweep("campbell") | {"spin_range": [0.0]}, "spin_range.1"),
        (_sweep("spin_map") | {"spin_points": 500}, "spin_points"),
        (_sweep("beta_map") | {"beta_range": [0.0, 0.5]}, "beta_range"),
        (_sweep("beta_map") | {"u_range": [-1.0, 5.0]}, "u_range"),
        (_sweep("beta_map") | {"sigma": 0.1, "viscous_ratio": 0.1}, "sigma"),  # not both
        (_sweep("resonance_chart") | {"frequency_range": [0.0, 10.0]}, "frequency_range"),
        (_sweep("floquet") | {"flow": {"velocity": {"kind": "constant"}}}, "flow.velocity"),
        (_sweep("floquet") | {"flow": {"velocity": {"value": 1.0}}}, "flow.velocity"),
        (_sweep("floquet") | {"modes": 21}, "modes"),
        ({k: v for k, v in _sweep("argand").items() if k != "pipe"}, "pipe"),
        (_sweep("argand") | {"spin_range": [0.0, 1.0]}, "spin_range"),
    ],
)
def test_sweep_422_names_the_field(api: TestClient, body: dict[str, Any], field: str) -> None:
    doc = _problem(api.post("/v1/sweeps", json=body), 422)
    assert field in _fields(doc), doc


def test_unknown_keys_404(api: TestClient) -> None:
    key = "f" * 64
    _problem(api.get(f"/v1/jobs/{key}"), 404)
    _problem(api.get(f"/v1/results/{key}"), 404)
    _problem(api.delete(f"/v1/jobs/{key}"), 404)
    # a stability result has no figure: asking for one is a 404 naming the plot
    stored = api.post("/v1/stability", json=PAPER).json()["key"]
    doc = _problem(api.get(f"/v1/results/{stored}/plots/argand.png"), 404)
    assert _fields(doc) == ["name"]


def test_openapi_documents_the_new_operations(api: TestClient) -> None:
    doc = api.get("/openapi.json").json()
    stab = doc["paths"]["/v1/stability"]["post"]
    assert stab["operationId"] == "runStability"
    assert {"200", "409", "413", "422", "503", "500"} <= set(stab["responses"])
    ok = stab["responses"]["200"]["content"]["application/json"]["schema"]
    assert ok == {"$ref": "#/components/schemas/StabilityResponse"}
    example = stab["requestBody"]["content"]["application/json"]["examples"]["paper"]["value"]
    assert example["pipe"] == PAPER_PIPE_JSON
    assert StabilitySpec.model_validate(example)
    jobs = doc["paths"]["/v1/stability/jobs"]["post"]
    sweeps = doc["paths"]["/v1/sweeps"]["post"]
    for op in (jobs, sweeps):
        assert {"202", "413", "422", "503", "500"} <= set(op["responses"])
        assert "Location" in op["responses"]["202"]["headers"]
    examples = sweeps["requestBody"]["content"]["application/json"]["examples"]
    assert set(examples) == set(SWEEPS)
    for name, ex in examples.items():
        assert getattr(parse(SWEEP_KINDS, ex["value"]), "kind", None) == name
    schemas = doc["components"]["schemas"]
    assert "[m/s]" in schemas["StabilityResponse"]["properties"]["critical_velocity"]["description"]
    result = doc["paths"]["/v1/results/{key}"]["get"]["responses"]["200"]["content"]
    refs = {s["$ref"].rsplit("/", 1)[1] for s in result["application/json"]["schema"]["anyOf"]}
    assert {"SimulationResponse", "StabilityResponse", "SweepResponse", "FloquetResponse"} <= refs
