"""POST /v1/frequency-responses (and its job form) over HTTP, the clients and the command line.

The numbers are pipeflow.frequency's (tests/pipeflow/test_frequency.py checks them against
closed forms, collocation and direct solves); these tests check that the service carries
them through unchanged from another process, with the cache, job and error machinery shared
with the other computations.  Modes and grids are small: seconds in all.
"""

from __future__ import annotations

import asyncio
import copy
import csv
import io
import json
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import httpx
import numpy as np
import pytest
from fastapi.testclient import TestClient

from pipeflow.computations.registry import COMPUTATIONS
from pipeflow.frequency import PointForce, frequency_grid, frequency_response, resonances
from pipeflow.paper import PAPER_PIPE
from pipeflow.schema.frequency import HAMMER_EXAMPLE, FrequencyResponseSpec
from pipeflow.statics import static_deflection
from pipeflow_cli.cli import main as cli_main
from pipeflow_client import AsyncClient, Client, ServiceError
from service.keys import keyed
from tests.service.conftest import make_client, wait_job, wait_ready

L = PAPER_PIPE.L
#: the README's hammer test, 6 modes and 400 log points (the endpoint's example, smaller)
HAMMER: dict[str, Any] = {
    **copy.deepcopy(HAMMER_EXAMPLE),
    "modes": 6,
    "frequencies": {"min": 10.0, "max": 8000.0, "count": 400, "spacing": "log"},
}
FRF = COMPUTATIONS["frequency_response"]


@pytest.fixture(scope="module")
def api(tmp_path_factory: pytest.TempPathFactory) -> Iterator[TestClient]:
    with make_client(tmp_path_factory.mktemp("frf"), workers=1, queue_size=8) as c:
        wait_ready(c)
        yield c


def _body(**changes: Any) -> dict[str, Any]:
    body = copy.deepcopy(HAMMER)
    body.update(changes)
    return body


def _library(v: float, w0: float, frequencies: Any, *, modes: int = 6) -> Any:
    return frequency_response(
        PAPER_PIPE,
        v,
        w0,
        load=PointForce(L),
        positions=[L],
        frequencies=frequencies,
        modes=modes,
    )


def _same(answer: list[float | None], expected: np.ndarray) -> None:
    """Equal to 1e-12 relative to the curve's scale (the worker is another process)."""
    got = np.array([np.nan if a is None else a for a in answer])
    scale = float(np.max(np.abs(expected)))
    assert np.allclose(got, expected, rtol=1e-12, atol=1e-12 * scale, equal_nan=True)


def _problem_fields(resp: httpx.Response) -> list[str | None]:
    assert resp.status_code == 422, resp.text
    assert resp.headers["content-type"] == "application/problem+json"
    return [e["field"] for e in resp.json()["errors"]]


# -- the answer is the library's -----------------------------------------------------------


def test_answer_equals_the_library_call_then_a_cache_hit(api: TestClient) -> None:
    # refresh: computed here whichever test of the module stored this case first
    r = api.post("/v1/frequency-responses", params={"refresh": "true"}, json=HAMMER)
    assert r.status_code == 200, r.text
    assert r.headers["x-cache"] == "MISS"
    doc = r.json()
    model = FRF.response
    model.model_validate(doc)
    assert set(doc) == set(model.model_fields)  # exactly the documented fields
    assert doc["kind"] == "frequency_response" and doc["unit"] == "m/N"
    assert doc["plots"] == ["bode", "nyquist"]

    found = resonances(PAPER_PIPE, 5.0, 100.0, modes=6)
    W = frequency_grid(10.0, 8000.0, 400, "log", resonances=found)
    ref = _library(5.0, 100.0, W)
    _same(doc["frequencies"], W)
    (point,) = doc["operating_points"]
    (curve,) = point["responses"]
    assert curve["position"] == L
    for part, value in (
        ("real", ref.H[0].real),
        ("imag", ref.H[0].imag),
        ("magnitude", ref.magnitude[0]),
        ("phase", ref.phase[0]),
    ):
        _same(curve[part], value)
    assert [p["mode"] for p in point["peaks"]] == [p.mode for p in ref.peaks]
    for got, want in zip(point["peaks"], ref.peaks, strict=True):
        assert got["frequency"] == pytest.approx(want.frequency, rel=1e-12)
        assert got["damping_ratio"] == pytest.approx(want.damping_ratio, rel=1e-12)
        assert got["magnitude"][0] == pytest.approx(want.magnitude[0], rel=1e-12)
    assert point["stable"] is True and doc["stable"] is True
    assert point["max_growth_rate"] == pytest.approx(ref.max_growth_rate, rel=1e-12)
    assert point["diagnostics"]["method"] == "modal"
    assert point["diagnostics"]["max_relative_difference"] < 1e-9

    # the same physics spelled differently: one operating point as a list, defaults given
    same = _body(
        operating_points=[{"velocity": 5, "omega0": 100}],
        rotation={"hub_radius": 0.0},
        plane="in-plane",
    )
    del same["flow"]
    same["response"] = {"positions": [L], "quantity": "displacement"}
    again = api.post("/v1/frequency-responses", json=same)
    assert again.status_code == 200, again.text
    assert again.headers["x-cache"] == "HIT" and again.json()["cached"] is True
    key = keyed(FRF, FrequencyResponseSpec.model_validate(HAMMER)).key
    assert doc["key"] == again.json()["key"] == key
    assert again.json()["operating_points"] == doc["operating_points"]
    # a different number that matters is a different key
    other = api.post("/v1/frequency-responses", json=_body(modes=5))
    assert other.headers["x-cache"] == "MISS" and other.json()["key"] != key


def test_residual_flexibility_switch(api: TestClient) -> None:
    """No flow: the default adds the truncated modes' static response (the library's
    ``residual=None``); ``residual_flexibility: false`` is the plain modal sum, another key."""
    values = [0.0, 100.0, 900.0]
    base = _body(flow={"velocity": {"kind": "constant", "value": 0.0}})
    base["frequencies"] = {"values": values}
    docs = {}
    for flag in (None, False):
        body = base if flag is None else {**base, "residual_flexibility": flag}
        r = api.post("/v1/frequency-responses", json=body)
        assert r.status_code == 200, r.text
        docs[flag] = r.json()
    for flag, applied in ((None, True), (False, False)):
        (point,) = docs[flag]["operating_points"]
        assert point["diagnostics"]["residual_flexibility"] is applied
        ref = frequency_response(
            PAPER_PIPE,
            0.0,
            100.0,
            load=PointForce(L),
            positions=[L],
            frequencies=values,
            modes=6,
            residual=flag,
        )
        _same(point["responses"][0]["real"], ref.H[0].real)
    assert docs[None]["key"] != docs[False]["key"]
    # W = 0: exactly the static solution of the continuous pipe (tests/pipeflow/test_statics)
    exact = static_deflection(PAPER_PIPE, 0.0, 100.0, [L], force_at=L)[0]
    tip0 = docs[None]["operating_points"][0]["responses"][0]["real"][0]
    assert tip0 == pytest.approx(exact, rel=1e-12)


def test_load_vectors_over_http(api: TestClient) -> None:
    """``load_vectors`` reaches the library (the same H as its call, to the document's
    rounding), is reported in the diagnostics, and is part of the key; left out (0) the
    request keeps the key it had before the field."""
    values = [0.0, 100.0, 900.0]
    base = _body()
    base["frequencies"] = {"values": values}
    plain = api.post("/v1/frequency-responses", json=base)
    enriched = api.post("/v1/frequency-responses", json={**base, "load_vectors": 2})
    zero = api.post("/v1/frequency-responses", json={**base, "load_vectors": 0})
    assert plain.status_code == enriched.status_code == zero.status_code == 200, enriched.text
    assert zero.json()["key"] == plain.json()["key"] != enriched.json()["key"]
    (point,) = enriched.json()["operating_points"]
    assert point["diagnostics"]["load_vectors"] == 2
    assert plain.json()["operating_points"][0]["diagnostics"]["load_vectors"] == 0
    v, w0 = HAMMER["flow"]["velocity"]["value"], HAMMER["rotation"]["omega0"]["value"]
    ref = frequency_response(
        PAPER_PIPE, v, w0, load=PointForce(L), positions=[L], frequencies=values, modes=6,
        load_vectors=2,
    )  # fmt: skip
    _same(point["responses"][0]["real"], ref.H[0].real)


def test_explicit_values_are_answered_at_exactly_those_frequencies(api: TestClient) -> None:
    values = [2000.0, 50.0, 244.0, 0.0]
    doc = api.post("/v1/frequency-responses", json=_body(frequencies={"values": values})).json()
    assert doc["frequencies"] == values
    ref = _library(5.0, 100.0, values)
    _same(doc["operating_points"][0]["responses"][0]["real"], ref.H[0].real)


def test_job_form_and_several_operating_points(api: TestClient) -> None:
    points = [{"velocity": v, "omega0": 100.0} for v in (0.0, 5.0, 10.0)]
    body = _body(operating_points=points, response={"positions": [L / 2, L]})
    del body["flow"], body["rotation"]
    r = api.post("/v1/frequency-responses/jobs", json=body)
    assert r.status_code == 202, r.text
    job = r.json()
    assert r.headers["location"] == f"/v1/jobs/{job['key']}"
    assert wait_job(api, job["key"])["status"] == "succeeded"
    assert api.get(f"/v1/jobs/{job['key']}").json()["kind"] == "frequency_response"
    doc = api.get(f"/v1/results/{job['key']}").json()
    assert [p["velocity"] for p in doc["operating_points"]] == [0.0, 5.0, 10.0]
    assert doc["plots"] == ["bode", "nyquist", "waterfall"]
    # one common grid with every point's resonances in it; each block is the library's
    for p in doc["operating_points"]:
        ref = frequency_response(
            PAPER_PIPE,
            p["velocity"],
            100.0,
            load=PointForce(L),
            positions=[L / 2, L],
            frequencies=doc["frequencies"],
            modes=6,
        )
        assert [c["position"] for c in p["responses"]] == [L / 2, L]
        _same(p["responses"][1]["imag"], ref.H[1].imag)
    # the sync form of the same body is now a hit on the job's result
    hit = api.post("/v1/frequency-responses", json=body)
    assert hit.headers["x-cache"] == "HIT" and hit.json()["key"] == job["key"]

    # figures and tables of the stored result
    for name in ("bode", "nyquist", "waterfall"):
        png = api.get(f"/v1/results/{job['key']}/plots/{name}.png")
        assert png.status_code == 200 and png.content.startswith(b"\x89PNG")
    svg = api.get(f"/v1/results/{job['key']}/plots/bode.svg")
    assert svg.status_code == 200 and b"rad/s" in svg.content
    text = api.get(f"/v1/results/{job['key']}?format=csv").text  # the first table
    header = next(csv.reader(io.StringIO(text)))
    assert header[0] == "frequency [rad/s]"
    assert header[1] == f"real(v=0.0,w0=100.0,x={L / 2!r}) [m/N]"
    assert header[4] == f"phase(v=0.0,w0=100.0,x={L / 2!r}) [rad]"
    assert len(header) == 1 + 3 * 2 * 4
    peaks = api.get(f"/v1/results/{job['key']}?format=csv&table=peaks").text
    rows = list(csv.reader(io.StringIO(peaks)))
    assert rows[0][:6] == [
        "velocity [m/s]",
        "omega0 [rad/s]",
        "mode [-]",
        "frequency [rad/s]",
        "natural_frequency [rad/s]",
        "damping_ratio [-]",
    ]
    assert len(rows) - 1 == sum(len(p["peaks"]) for p in doc["operating_points"])
    pq = pytest.importorskip("pyarrow.parquet")
    parquet = api.get(f"/v1/results/{job['key']}?format=parquet&table=peaks")
    table = pq.read_table(io.BytesIO(parquet.content))
    assert table.schema.field("frequency").metadata == {b"unit": b"rad/s"}


def test_unstable_point_is_answered_with_stable_false_and_a_warning(api: TestClient) -> None:
    """The paper's pipe at w0 = 100 rad/s flutters beyond v = 27.69 m/s (README): at 40 m/s
    there is no steady state, and the answer says so (200, never an error)."""
    r = api.post(
        "/v1/frequency-responses",
        json=_body(flow={"velocity": {"kind": "constant", "value": 40.0}}),
    )
    assert r.status_code == 200, r.text
    doc = r.json()
    point = doc["operating_points"][0]
    assert doc["stable"] is False and point["stable"] is False
    assert point["max_growth_rate"] > 0 and doc["max_growth_rate"] == point["max_growth_rate"]
    assert any("unstable operating point" in w for w in doc["warnings"])
    assert any("no steady state" in w for w in point["warnings"])


# -- bad input: 422 naming the field -------------------------------------------------------


@pytest.mark.parametrize(
    ("change", "field"),
    [
        ({"response": {"positions": [0.03]}}, "response.positions"),
        ({"response": {"positions": [0.0]}}, "response.positions.0"),
        ({"response": {"positions": [L], "quantity": "jerk"}}, "response.quantity"),
        ({"response": {"positions": [L] * 65}}, "response.positions"),
        ({"load": {"kind": "point_force", "position": 0.05}}, "load.position"),
        ({"load": {"kind": "hammer"}}, "load"),
        ({"frequencies": {"min": 100.0, "max": 100.0}}, "frequencies.min"),
        ({"frequencies": {"min": 500.0, "max": 100.0}}, "frequencies.min"),
        ({"frequencies": {"min": 0.0, "max": 100.0, "spacing": "log"}}, "frequencies.min"),
        ({"frequencies": {"min": 1.0, "max": 100.0, "count": 20_001}}, "frequencies.count"),
        ({"frequencies": {"values": [1.0], "min": 1.0}}, "frequencies.values"),
        ({"frequencies": {"values": [-1.0]}}, "frequencies.values.0"),
        ({"frequencies": {}}, "frequencies"),
        ({"flow": {"velocity": {"kind": "polynomial", "coefficients": [0, 0.4]}}}, "flow.velocity"),
        ({"rotation": {"omega0": {"kind": "harmonic", "mean": 100.0}}}, "rotation.omega0"),
        (
            {"operating_points": [{"velocity": 1.0, "omega0": 0.0}] * 65},
            "operating_points",
        ),
        ({"operating_points": [{"velocity": 1.0, "omega0": 0.0}]}, "operating_points"),
        (
            {
                "response": {"positions": [L / 64 * (i + 1) for i in range(64)]},
                "frequencies": {"min": 1.0, "max": 9000.0, "count": 20_000},
            },
            "frequencies.count",
        ),
        ({"modes": 41}, "modes"),
        ({"load_vectors": 4}, "load_vectors"),
        ({"load_vectors": 1, "residual_flexibility": True}, "load_vectors"),
    ],
)
def test_bad_input_is_a_422_naming_the_field(
    api: TestClient, change: dict[str, Any], field: str
) -> None:
    fields = _problem_fields(api.post("/v1/frequency-responses", json=_body(**change)))
    assert field in fields, fields


def test_the_bounds_are_stated_in_the_cost_note(api: TestClient) -> None:
    doc = api.get("/openapi.json").json()
    op = doc["paths"]["/v1/frequency-responses"]["post"]
    assert op["operationId"] == "runFrequencyResponse"
    assert "1,000,000 values" in op["description"]
    assert "frequencies.count <= 20000" in op["description"]
    job = doc["paths"]["/v1/frequency-responses/jobs"]["post"]
    assert job["operationId"] == "submitFrequencyResponseJob"


# -- the clients and the command line ------------------------------------------------------


def test_client_round_trip_sync_and_async(api: TestClient) -> None:
    with Client(str(api.base_url), http=api) as client:
        doc = client.frequency_response(HAMMER)
        assert doc["kind"] == "frequency_response"
        again = client.frequency_response(FrequencyResponseSpec.model_validate(HAMMER))
        assert again["key"] == doc["key"] and again["cached"] is True
        seen: list[float] = []
        job = client.frequency_response(_body(modes=4), progress=seen.append)
        assert seen and seen[-1] == 1.0 and job["kind"] == "frequency_response"
        assert client.plot(doc["key"], "bode").startswith(b"\x89PNG")
        assert client.result_csv(doc["key"], "peaks").startswith("velocity [m/s]")
        with pytest.raises(ServiceError) as err:
            client.frequency_response(_body(response={"positions": [1.0]}))
        assert err.value.status == 422 and err.value.field == "response.positions"

    async def scenario() -> dict[str, Any]:
        app = api.app
        transport = httpx.ASGITransport(app=app)  # type: ignore[arg-type]
        async with httpx.AsyncClient(transport=transport, base_url="http://test") as http:
            async with AsyncClient("http://test", http=http) as client:
                out: dict[str, Any] = await client.frequency_response(HAMMER)
                return out

    adoc = asyncio.run(scenario())
    assert adoc["key"] == doc["key"] and adoc["cached"] is True
    assert adoc["operating_points"] == doc["operating_points"]


def _uff_curves(data: bytes, tmp_path: Path) -> list[np.ndarray]:
    pyuff = pytest.importorskip("pyuff")
    path = tmp_path / "frf.uff"
    path.write_bytes(data)
    sets = pyuff.UFF(str(path)).read_sets()
    return [s["data"] for s in (sets if isinstance(sets, list) else [sets])]


def test_uff_and_netcdf_by_query_by_clients_and_cli(api: TestClient, tmp_path: Path) -> None:
    """?format=uff: dataset 58 per operating point x position, the JSON's H to the
    format's 12 significant digits (tolerance 1e-11 of the curve's max); ?format=netcdf:
    the exact floats; the sync and async clients' result_file and the CLI's --format save
    the same bytes; a result without curves or shapes is a 422 naming format."""
    xr = pytest.importorskip("xarray")
    doc = api.post("/v1/frequency-responses", json=HAMMER).json()
    key = doc["key"]
    r = api.get(f"/v1/results/{key}", params={"format": "uff"})
    assert r.status_code == 200, r.text
    assert r.headers["content-type"].startswith("application/vnd.uff")
    assert r.headers["content-disposition"].endswith('.uff"')
    (curve,) = doc["operating_points"][0]["responses"]
    h = np.asarray(curve["real"]) + 1j * np.asarray(curve["imag"])
    (got,) = _uff_curves(r.content, tmp_path)
    assert np.max(np.abs(got - h)) <= 1e-11 * np.max(np.abs(h))
    nc = api.get(f"/v1/results/{key}", headers={"Accept": "application/x-netcdf"})
    assert nc.status_code == 200 and nc.headers["content-type"] == "application/x-netcdf"
    ds = xr.open_dataset(io.BytesIO(nc.content), engine="scipy").load()
    np.testing.assert_array_equal(ds["H_real"].values[0, 0], h.real)
    assert ds["H_imag"].attrs["units"] == "m/N"
    with Client(str(api.base_url), http=api) as client:
        assert client.result_file(key, "uff") == r.content
        assert client.result_file(key, "netcdf") == nc.content

    async def scenario() -> bytes:
        transport = httpx.ASGITransport(app=api.app)  # type: ignore[arg-type]
        async with httpx.AsyncClient(transport=transport, base_url="http://test") as http:
            async with AsyncClient("http://test", http=http) as client:
                out: bytes = await client.result_file(key, "uff")
                return out

    assert asyncio.run(scenario()) == r.content
    spec = tmp_path / "frf.json"
    spec.write_text(json.dumps(HAMMER))
    out = tmp_path / "frf.uff"
    assert (
        cli_main(["frequency-response", str(spec), "--format", "uff", "-o", str(out), "--quiet"])
        == 0
    )
    (cli_curve,) = _uff_curves(out.read_bytes(), tmp_path)
    assert np.max(np.abs(cli_curve - h)) <= 1e-11 * np.max(np.abs(h))
    stab = api.post("/v1/stability", json={"pipe": HAMMER["pipe"], "velocity_range": [0, 40]})
    bad = api.get(f"/v1/results/{stab.json()['key']}", params={"format": "uff"})
    assert _problem_fields(bad) == ["format"]


def test_cli_local_run_and_plot(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    spec = tmp_path / "frf.json"
    spec.write_text(json.dumps(HAMMER))
    out = tmp_path / "frf_result.json"
    assert cli_main(["frequency-response", str(spec), "-o", str(out), "--quiet"]) == 0
    err = capsys.readouterr().err
    assert "v = 5 m/s, w0 = 100 rad/s: mode 1 at 243.9" in err
    doc = json.loads(out.read_text())
    local = FRF.execute(FrequencyResponseSpec.model_validate(HAMMER))
    assert doc["operating_points"] == json.loads(json.dumps(local["operating_points"]))
    png = tmp_path / "bode.png"
    assert cli_main(["plot", str(out), "--name", "bode", "--out", str(png)]) == 0
    assert png.read_bytes().startswith(b"\x89PNG")
    # a spec is run first, then drawn
    svg = tmp_path / "nyquist.svg"
    assert cli_main(["plot", str(spec), "--kind", "frequency_response", "--name", "nyquist",
                     "--out", str(svg), "--quiet"]) == 0  # fmt: skip
    assert b"Re H" in svg.read_bytes()
    csv_out = tmp_path / "peaks.csv"
    args = ["frequency-response", str(spec), "--format", "csv", "--table", "peaks"]
    assert cli_main([*args, "-o", str(csv_out), "--quiet"]) == 0
    assert csv_out.read_text().startswith("velocity [m/s],omega0 [rad/s],mode [-]")
    # bad input names the field, exit status 2
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps(_body(frequencies={"min": 10.0, "max": 1.0})))
    capsys.readouterr()
    assert cli_main(["frequency-response", str(bad), "--quiet"]) == 2
    assert "frequencies" in capsys.readouterr().err


def test_cli_with_server(api: TestClient, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """--server goes through the client: the answer is the server's (same key)."""
    import pipeflow_client

    class Bound(Client):
        def __init__(self, base_url: str, **kw: Any) -> None:
            super().__init__(base_url, http=api, **kw)

    monkeypatch.setattr(pipeflow_client, "Client", Bound)
    spec = tmp_path / "frf.json"
    spec.write_text(json.dumps(HAMMER))
    out = tmp_path / "remote.json"
    args = ["frequency-response", str(spec), "--server", str(api.base_url), "-o", str(out)]
    assert cli_main([*args, "--quiet"]) == 0
    doc = json.loads(out.read_text())
    assert doc["key"] == keyed(FRF, FrequencyResponseSpec.model_validate(HAMMER)).key
