"""API tests: POST /v1/simulations, results, health, and every error path."""

from __future__ import annotations

import copy
import json
from typing import Any

import pytest
from fastapi.testclient import TestClient

from pipeflow.schema.results import SimulationResponse
from tests.service.conftest import SMALL


def _small(**changes: Any) -> dict[str, Any]:
    body = copy.deepcopy(SMALL)
    body.update(changes)
    return body


def test_simulation_miss_then_hit(client: TestClient) -> None:
    body = _small(initial={"u0": 0.002})
    first = client.post("/v1/simulations", json=body)
    assert first.status_code == 200, first.text
    assert first.headers["x-cache"] == "MISS"
    doc = first.json()
    assert doc["cached"] is False
    assert len(doc["key"]) == 64
    assert first.headers["etag"] == f'"{doc["key"]}"'
    assert len(doc["t"]) == len(doc["tip_displacement"]) == 101
    assert [m["mode"] for m in doc["eigenvalues"]["modes"]] == [1, 2, 3]
    assert set(doc["fundamental"]) == {"sigma", "omega"}
    assert (doc["method"], doc["method_used"]) == ("auto", "magnus")  # the default
    for field in ("dimensionless", "diagnostics"):
        assert isinstance(doc[field], dict)

    second = client.post("/v1/simulations", json=body)
    assert second.status_code == 200
    assert second.headers["x-cache"] == "HIT"
    again = second.json()
    assert again["cached"] is True
    assert {**again, "cached": False} == doc


def test_response_matches_documented_schema(client: TestClient) -> None:
    """Every field the core returns is documented in SimulationResponse (and validates)."""
    doc = client.post("/v1/simulations", json=_small(output={"modal": True})).json()
    SimulationResponse.model_validate(doc)
    assert set(doc) <= set(SimulationResponse.model_fields)
    assert "modal" in doc


def test_refresh_recomputes(client: TestClient) -> None:
    body = _small(initial={"u0": 0.003})
    runner = client.app.state.runner  # type: ignore[attr-defined]
    assert client.post("/v1/simulations", json=body).headers["x-cache"] == "MISS"
    before = runner.computations
    fresh = client.post("/v1/simulations?refresh=true", json=body)
    assert fresh.status_code == 200
    assert fresh.headers["x-cache"] == "MISS" and fresh.json()["cached"] is False
    assert runner.computations == before + 1
    assert client.post("/v1/simulations", json=body).headers["x-cache"] == "HIT"


def test_results_etag_and_304(client: TestClient) -> None:
    """Each representation has its own strong tag: ``"<key>"`` for the JSON bytes,
    ``"<key>-gzip"`` for their gzip; If-None-Match is compared (weakly) with the tag of the
    representation the request selects, and the 304 carries that tag."""
    doc = client.post("/v1/simulations", json=_small(initial={"u0": 0.004})).json()
    key = doc["key"]
    for coding, etag in (("identity", f'"{key}"'), ("gzip", f'"{key}-gzip"')):
        enc = {"Accept-Encoding": coding}
        got = client.get(f"/v1/results/{key}", headers=enc)
        assert got.status_code == 200
        assert got.headers["etag"] == etag, coding
        assert got.headers.get("content-encoding", "identity") == coding
        assert got.headers["vary"] == "Accept-Encoding"
        assert got.json()["tip_displacement"] == doc["tip_displacement"]
        assert got.json()["cached"] is True
        for tag in (etag, f"W/{etag}", f'"other", {etag}', "*"):
            not_modified = client.get(f"/v1/results/{key}", headers={**enc, "If-None-Match": tag})
            assert not_modified.status_code == 304, (coding, tag)
            assert not_modified.headers["etag"] == etag
            assert not_modified.headers["vary"] == "Accept-Encoding"
            assert not_modified.content == b""
        stale = client.get(
            f"/v1/results/{key}", headers={**enc, "If-None-Match": '"something-else"'}
        )
        assert stale.status_code == 200
    # the tag of one representation does not validate the other
    other = client.get(
        f"/v1/results/{key}", headers={"Accept-Encoding": "gzip", "If-None-Match": f'"{key}"'}
    )
    assert other.status_code == 200 and other.headers["etag"] == f'"{key}-gzip"'
    other = client.get(
        f"/v1/results/{key}",
        headers={"Accept-Encoding": "identity", "If-None-Match": f'"{key}-gzip"'},
    )
    assert other.status_code == 200 and other.headers["etag"] == f'"{key}"'


def _problem(resp: Any, status: int) -> dict[str, Any]:
    assert resp.status_code == status, resp.text
    assert resp.headers["content-type"] == "application/problem+json"
    doc: dict[str, Any] = resp.json()
    assert doc["status"] == status and doc["title"]
    return doc


def test_unknown_result_404(client: TestClient) -> None:
    doc = _problem(client.get("/v1/results/" + "0" * 64), 404)
    assert doc["instance"] == "/v1/results/" + "0" * 64
    assert client.get("/v1/results/" + "0" * 64, headers={"If-None-Match": "*"}).status_code == 404


def test_malformed_key_422(client: TestClient) -> None:
    doc = _problem(client.get("/v1/results/not-a-key"), 422)
    assert doc["errors"][0]["field"] == "key"
    assert doc["errors"][0]["location"] == "path"


def test_unknown_route_and_method(client: TestClient) -> None:
    _problem(client.get("/v1/nothing"), 404)
    _problem(client.get("/v1/simulations"), 405)


def _fields(doc: dict[str, Any]) -> list[str | None]:
    return [e["field"] for e in doc["errors"]]


def test_validation_points_at_field(client: TestClient) -> None:
    cases: list[tuple[dict[str, Any], str]] = [
        ({**SMALL, "pipe": {**SMALL["pipe"], "E": -1}}, "pipe.E"),
        ({**SMALL, "pipe": {k: v for k, v in SMALL["pipe"].items() if k != "L"}}, "pipe.L"),
        ({**SMALL, "modes": 41}, "modes"),
        ({**SMALL, "time": {"samples": 10**9}}, "time.samples"),
        ({**SMALL, "method": "euler"}, "method"),
        ({**SMALL, "colour": "red"}, "colour"),
        (
            {**SMALL, "flow": {"velocity": {"kind": "polynomial", "coefficients": [0, "x"]}}},
            "flow.velocity.coefficients.1",
        ),
        ({**SMALL, "flow": {"velocity": {"kind": "sawtooth"}}}, "flow.velocity"),
        (
            {**SMALL, "rotation": {"omega0": {"kind": "table", "t": [0, 1], "values": [1, 2, 3]}}},
            "rotation.omega0.t",
        ),
        ({**SMALL, "pipe": {**SMALL["pipe"], "M1": 0, "M2": 0}}, "pipe.M1"),
        ({**SMALL, "output": {"positions": [1.0]}}, "output.positions"),
    ]
    for body, field in cases:
        doc = _problem(client.post("/v1/simulations", json=body), 422)
        assert field in _fields(doc), (field, doc)
        assert doc["errors"][0]["pointer"].startswith("#")


def test_non_finite_inputs_rejected(client: TestClient) -> None:
    template = json.dumps({**SMALL, "pipe": {**SMALL["pipe"], "E": 12345.0}})
    for literal in ("NaN", "Infinity", "-Infinity", "1e999"):
        raw = template.replace("12345.0", literal)
        resp = client.post(
            "/v1/simulations", content=raw, headers={"content-type": "application/json"}
        )
        doc = _problem(resp, 422)
        assert _fields(doc) == ["pipe.E"], literal


def test_extreme_magnitudes_are_422_not_500(client: TestClient) -> None:
    """Finite, positive but extreme inputs take the numerics out of double precision
    (OverflowError, division by zero, singular matrices, Inf/NaN in the result): each
    answer is a 422 problem, never an internal error."""
    pipe = SMALL["pipe"]
    bodies = {
        "L=1e308": _small(pipe={**pipe, "L": 1e308}),
        "L=1e-300": _small(pipe={**pipe, "L": 1e-300}),
        "M1=1e308": _small(pipe={**pipe, "M1": 1e308}),
        "E=1e-300": _small(pipe={**pipe, "E": 1e-300}),
        "omega0=1e308": _small(rotation={"omega0": {"kind": "constant", "value": 1e308}}),
        "v=1e308": _small(flow={"velocity": {"kind": "polynomial", "coefficients": [1e308]}}),
    }
    for name, body in bodies.items():
        resp = client.post("/v1/simulations", json=body)
        assert resp.status_code != 500, (name, resp.text)
        if resp.status_code != 200:  # a result with status "overflow" is a clear answer too
            doc = _problem(resp, 422)
            assert doc["detail"], name


def test_bad_json_and_missing_body(client: TestClient) -> None:
    """Malformed JSON is a 400 problem (documented); a missing body a 422."""
    doc = _problem(
        client.post(
            "/v1/simulations", content=b"{not json", headers={"content-type": "application/json"}
        ),
        400,
    )
    assert doc["errors"][0]["type"] == "json_invalid"
    _problem(client.post("/v1/simulations"), 422)


@pytest.mark.parametrize(
    ("path", "value", "field"),
    [
        ("pipe.E", True, "pipe.E"),
        ("modes", "10", "modes"),
        ("modes", True, "modes"),
        ("rotation.omega0", {"kind": "constant", "value": False}, "rotation.omega0.value"),
        ("time.t_end", "1", "time.t_end"),
        ("output.modal", 1, "output.modal"),
    ],
)
def test_inputs_are_strict(client: TestClient, path: str, value: Any, field: str) -> None:
    """A boolean or a string where a number belongs (or a number for a boolean) is a 422
    naming the field, never coerced (``"E": true`` was taken as 1 Pa)."""
    body = _small()
    node = body
    *parents, leaf = path.split(".")
    for part in parents:
        node = node.setdefault(part, {})
    node[leaf] = value
    doc = _problem(client.post("/v1/simulations", json=body), 422)
    assert _fields(doc) == [field]


def test_content_negotiation(client: TestClient) -> None:
    """415 for a body that is not JSON, 406 for an Accept the operation cannot meet."""
    body = json.dumps(_small()).encode()
    for ctype in ("text/plain", "application/x-www-form-urlencoded", "application/xml"):
        doc = _problem(
            client.post("/v1/simulations", content=body, headers={"content-type": ctype}), 415
        )
        assert doc["errors"][0]["field"] == "Content-Type"
    doc = _problem(
        client.post("/v1/sweeps", content=b"kind=argand", headers={"content-type": "text/plain"}),
        415,
    )
    for accept in ("text/html", "image/png", "application/xml;q=1, text/csv"):
        resp = client.post("/v1/simulations", json=_small(), headers={"accept": accept})
        _problem(resp, 406)
        _problem(client.get(f"/v1/jobs/{'0' * 64}", headers={"accept": accept}), 406)
    key = "0" * 64
    _problem(client.get(f"/v1/results/{key}", headers={"accept": "image/png"}), 406)
    _problem(
        client.get(f"/v1/results/{key}/plots/damping.png", headers={"accept": "text/csv"}), 406
    )
    _problem(client.get("/healthz", headers={"accept": "text/html"}), 406)
    # what each offers is fine (the key is unknown: 404, after negotiation)
    _problem(client.get(f"/v1/results/{key}", headers={"accept": "text/csv"}), 404)
    _problem(client.get(f"/v1/results/{key}/plots/damping.png", headers={"accept": "image/*"}), 404)
    # JSON by any name is fine
    for accept in ("application/json", "*/*", "application/*;q=0.5", "application/problem+json"):
        assert (
            client.post("/v1/simulations", json=_small(), headers={"accept": accept}).status_code
            == 200
        )
    ok = client.post(
        "/v1/simulations", content=body, headers={"content-type": "application/json; charset=utf-8"}
    )
    assert ok.status_code == 200


def test_405_names_every_allowed_method(client: TestClient) -> None:
    """OPTIONS (or PUT) on /v1/jobs/{key} names GET and DELETE, which both exist."""
    for method in ("OPTIONS", "PUT", "PATCH"):
        resp = client.request(method, f"/v1/jobs/{'0' * 64}")
        _problem(resp, 405)
        assert {m.strip() for m in resp.headers["allow"].split(",")} == {"GET", "DELETE"}
    resp = client.request("PUT", "/v1/simulations")
    _problem(resp, 405)
    assert resp.headers["allow"] == "POST"


def test_library_refusal_is_422_with_field(client: TestClient) -> None:
    """An RK4 step outside the stability region is refused by pipeflow with its field."""
    body = _small(method="rk4", options={"step": 0.5})
    doc = _problem(client.post("/v1/simulations", json=body), 422)
    assert _fields(doc) == ["options.step"]
    assert doc["largest_stable_step"] > 0


def test_oversize_body_413(client: TestClient) -> None:
    limit = client.app.state.settings.max_body_bytes  # type: ignore[attr-defined]
    big = _small(output={"positions": [0.0] * 10}, padding="x" * (limit + 1))
    _problem(client.post("/v1/simulations", json=big), 413)

    def chunks() -> Any:  # no Content-Length: counted while streaming
        for _ in range(limit // 10_000 + 2):
            yield b" " * 10_000

    doc = _problem(
        client.post(
            "/v1/simulations", content=chunks(), headers={"content-type": "application/json"}
        ),
        413,
    )
    assert "limit" in doc["detail"]


def test_health_and_ready(client: TestClient) -> None:
    health = client.get("/healthz")
    assert health.status_code == 200 and health.json()["status"] == "ok"
    ready = client.get("/readyz")
    assert ready.status_code == 200
    assert ready.json()["workers"] == 2 and ready.json()["capacity"] == 10


@pytest.mark.parametrize(
    ("full", "cause"),
    [(True, "the disk of the store is full"), (False, "the store could not be written")],
)
def test_readiness_of_a_failing_store_gives_the_cause_not_the_drivers_text(
    client: TestClient, monkeypatch: pytest.MonkeyPatch, full: bool, cause: str
) -> None:
    """Issue 34, item 4: the 503 carried the driver's exception text ("OperationalError:
    database or disk is full"); it says what is wrong, the log has the driver's words.
    The store's probe is held failing for the test, then run for real again."""
    store = client.app.state.store  # type: ignore[attr-defined]
    driver = (
        "OperationalError: database or disk is full" if full else "OperationalError: disk I/O error"
    )
    monkeypatch.setattr(store, "probe", lambda: False)
    store.mark_failed(driver, full=full)
    try:
        ready = client.get("/readyz")
        assert ready.status_code == 503
        assert ready.headers["content-type"] == "application/problem+json"
        doc = ready.json()
        assert doc["type"].endswith("/storage") and cause in doc["detail"]
        assert "OperationalError" not in ready.text and "disk I/O" not in ready.text
        assert "database or disk" not in ready.text
    finally:
        monkeypatch.undo()
        assert store.probe()  # healthy again for the module's other tests


def test_workers_pin_blas_threads(client: TestClient) -> None:
    from service.engine import preload

    runner = client.app.state.runner  # type: ignore[attr-defined]
    info = client.portal.call(runner.call, preload.ping)  # type: ignore[union-attr]
    assert info["threads"]["OMP_NUM_THREADS"] == "1"
    assert info["threads"]["OPENBLAS_NUM_THREADS"] == "1"
    assert info["numpy_loaded"]


def test_out_of_range_magnitudes_name_the_field(client: TestClient) -> None:
    """Pipe properties and profile values outside the documented ranges (far beyond any
    engineering pipe, where double precision would overflow) are refused by the schema,
    naming the field, before any numerics run."""
    pipe = SMALL["pipe"]
    cases = {
        "pipe.L": _small(pipe={**pipe, "L": 1e308}),
        "pipe.E": _small(pipe={**pipe, "E": 1e14}),
        "pipe.M1": _small(pipe={**pipe, "M1": 1e308}),
        "rotation.omega0.value": _small(rotation={"omega0": {"kind": "constant", "value": 1e308}}),
        "flow.velocity.coefficients.0": _small(
            flow={"velocity": {"kind": "polynomial", "coefficients": [1e308]}}
        ),
    }
    for field, body in cases.items():
        doc = _problem(client.post("/v1/simulations", json=body), 422)
        assert field in _fields(doc), (field, doc)


def test_step_too_small_for_the_budget_is_422_not_cached(client: TestClient) -> None:
    """Defect: rk4 with options.step = 1e-22 s answered 200 'ok' (a wrapped negative step
    count passed the budget) and cached it; magnus answered 500.  Both are now 422 naming
    options.step with the smallest step the budget allows, and a retry is refused again
    (nothing was cached)."""
    for method in ("rk4", "magnus"):
        body = _small(method=method, options={"step": 1e-22})
        for _ in range(2):
            doc = _problem(client.post("/v1/simulations", json=body), 422)
            assert _fields(doc) == ["options.step"], doc
            assert doc["type"].endswith("budget-exceeded")
            assert doc["smallest_step"] > 0
            assert f"{doc['smallest_step']:.3g} s" in doc["detail"]


def test_validation_field_comes_from_the_error_not_its_text() -> None:
    """A validator names its field as data (InvalidField.loc); the message text is shown as
    is and never parsed: a plain ValueError whose text starts with a field name points at
    the model it was raised on."""
    import pickle

    from fastapi.exceptions import RequestValidationError
    from pydantic import BaseModel, ValidationError, model_validator

    from pipeflow.errors import InvalidField
    from service.http.problems import validation_errors

    class Inner(BaseModel):
        a: float = 0.0
        b: float = 0.0

        @model_validator(mode="after")
        def _check(self) -> Inner:
            if self.a > 1:
                raise InvalidField("b must follow a", "b")
            if self.a < 0:
                raise ValueError("b must follow a")
            return self

    class Outer(BaseModel):
        inner: Inner

    def errors(body: dict[str, Any]) -> list[dict[str, Any]]:
        with pytest.raises(ValidationError) as caught:
            Outer.model_validate(body)
        errs = [{**e, "loc": ("body", *e["loc"])} for e in caught.value.errors()]
        return validation_errors(RequestValidationError(errs, body=body))

    [named] = errors({"inner": {"a": 2, "b": 0}})
    assert (named["field"], named["pointer"]) == ("inner.b", "#/inner/b")
    assert named["message"] == "b must follow a"  # no pydantic prefix (issue 34, item 8)
    [plain] = errors({"inner": {"a": -1, "b": 0}})
    assert (plain["field"], plain["message"]) == ("inner", "b must follow a")
    # a location given for a field the body lacks stays at the model (as for one part)
    [absent] = errors({"inner": {"a": 2}})
    assert absent["field"] == "inner"
    again = pickle.loads(pickle.dumps(InvalidField("x: bad", "x.y")))
    assert (str(again), again.loc) == ("x: bad", ("x", "y"))


def test_an_over_budget_output_is_refused_before_it_runs(client: TestClient) -> None:
    """The audit's 1.6 kB request (200,001 samples x 64 positions x the modal state at 40
    modes) ran 40 s and stored a 299 MB row: now a 422 naming time.samples, the bound and
    the most samples that fit, at once (as a job too)."""
    L = SMALL["pipe"]["L"]
    body = _small(
        modes=40,
        time={"t_end": 1.0, "samples": 200_001},
        output={"positions": [L * (i + 1) / 65 for i in range(64)], "modal": True},
    )
    for path in ("/v1/simulations", "/v1/simulations/jobs"):
        doc = _problem(client.post(path, json=body), 422)
        assert _fields(doc) == ["time.samples"], path
        assert "output budget of 2,000,000 values" in doc["detail"]
        assert "samples with these outputs" in doc["detail"]


def test_an_underflowing_bending_stiffness_is_422_for_every_method(client: TestClient) -> None:
    """E = I = 1e-200: E I underflows to 0.  magnus, reference and /v1/compare answered 500
    with the exception's text; every method and endpoint now answers the same 422."""
    pipe = {**SMALL["pipe"], "E": 1e-200, "I": 1e-200}
    for method in ("auto", "cma", "magnus", "reference", "rk4"):
        doc = _problem(client.post("/v1/simulations", json=_small(pipe=pipe, method=method)), 422)
        assert _fields(doc) == ["pipe.E"], method
        assert "pipe.I" in doc["detail"]
    doc = _problem(client.post("/v1/compare", json={"simulation": _small(pipe=pipe)}), 422)
    assert _fields(doc) == ["simulation.pipe.E"]
    stability = {"pipe": pipe, "velocity_range": [0.0, 10.0], "modes": 3, "points": 11}
    doc = _problem(client.post("/v1/stability", json=stability), 422)
    assert _fields(doc) == ["pipe.E"]


@pytest.mark.parametrize("first", ["none", "json"])
def test_a_body_without_content_type_is_json_on_both_paths(client: TestClient, first: str) -> None:
    """The README: a body without Content-Type is read as JSON.  The route refused it (422)
    while the hit fast path answered the same bytes 200 HIT once cached: both read it as
    JSON now, whichever came first."""
    raw = json.dumps(_small(initial={"u0": 0.0041 if first == "none" else 0.0042})).encode()
    declared = {"content-type": "application/json"}
    miss = client.post("/v1/simulations", content=raw, headers=declared if first == "json" else {})
    assert miss.status_code == 200, miss.text
    assert miss.headers["x-cache"] == "MISS"
    for _ in range(2):  # the route's hit, then the fast path's (it learnt the bytes' key)
        hit = client.post("/v1/simulations", content=raw)
        assert hit.status_code == 200, hit.text
        assert hit.headers["x-cache"] == "HIT"
        assert hit.json()["key"] == miss.json()["key"]
    # and bytes that are not JSON are the same 400 as with a JSON Content-Type
    doc = _problem(client.post("/v1/simulations", content=b"{not json"), 400)
    assert doc["errors"][0]["type"] == "json_invalid"


def test_a_diverged_runs_traces_end_at_the_divergence_time(client: TestClient) -> None:
    """v = 20 + 1000 t m/s passes v_cr = 27.69 m/s at 7.7 ms; the tip passes 0.1 L at
    21.2 ms of the 50 ms asked.  The traces (frozen and CMA exponents) end there, with
    their samples evenly spread from 0; before, they ran to 50 ms."""
    body = _small(modes=10)  # the paper's pipe, w0 = 100 rad/s
    body["flow"] = {"velocity": {"kind": "polynomial", "coefficients": [20.0, 1000.0]}}
    body["initial"] = {"u0": 1e-6}
    body["time"] = {"t_end": 0.05, "samples": 501}
    body["output"] = {"eigen_samples": 101}
    r = client.post("/v1/simulations", json=body)
    assert r.status_code == 200, r.text
    doc = r.json()
    assert doc["status"] == "diverged"
    stop = doc["divergence_time"]
    assert 0.01 < stop < 0.05 and doc["t"][-1] == stop
    for block in ("eigenvalues", "cma_exponents"):
        t = doc[block]["t"]
        assert t[0] == 0.0 and t[-1] == stop and len(t) == 101, block
        assert all(len(m["sigma"]) == len(t) for m in doc[block]["modes"])
    got = client.get(f"/v1/results/{doc['key']}")  # the stored document, read back
    assert got.status_code == 200
    assert got.json()["eigenvalues"]["t"] == doc["eigenvalues"]["t"]
