"""CSV and Parquet of stored results (Accept / ?format=) and plot endpoints (PNG/SVG)."""

from __future__ import annotations

import csv
import io
import sys
from collections.abc import Iterator
from typing import Any, get_args

import pytest

from pipeflow.io.export import TABLES
from service.http.security import API_CSP, SVG_CSP
from service.routes import exports
from service.routes.exports import Table, TableAnswer, TableCache, wanted_format
from tests.service.conftest import SMALL, make_client, wait_ready


@pytest.fixture(scope="module")
def tc(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Any]:
    with make_client(tmp_path_factory.mktemp("export")) as c:
        wait_ready(c)
        yield c


@pytest.fixture
def fresh_tables(tc: Any) -> Iterator[TableCache]:
    """A new, empty table cache on the module's app for one test, the app's own put back
    after it.  Not ``monkeypatch.setattr(app.state, ...)``: starlette's ``State`` keeps its
    attributes in ``_state``, not in ``__dict__``, and pytest 9.2's undo restores from
    ``__dict__``, so it deleted ``app.state.tables`` for every later test of the module."""
    state = tc.app.state
    kept = state.tables
    state.tables = TableCache(1 << 20)
    try:
        yield state.tables
    finally:
        state.tables = kept


@pytest.fixture(scope="module")
def stored(tc: Any) -> dict[str, Any]:
    spec = dict(SMALL, output={"positions": [0.0125], "eigen_modes": 2})
    response = tc.post("/v1/simulations", json=spec)
    assert response.status_code == 200
    result: dict[str, Any] = response.json()
    return result


def _rows(text: str) -> list[list[str]]:
    return list(csv.reader(io.StringIO(text)))


def test_result_lists_its_plots(stored: dict[str, Any]) -> None:
    assert stored["plots"] == [
        "tip_displacement",
        "damping",
        "frequency",
        "argand",
        "displacements",
    ]


def test_csv_by_accept_header(tc: Any, stored: dict[str, Any]) -> None:
    r = tc.get(f"/v1/results/{stored['key']}", headers={"Accept": "text/csv"})
    assert r.status_code == 200
    assert r.headers["content-type"].startswith("text/csv")
    assert "Accept" in r.headers["vary"]
    rows = _rows(r.text)
    assert rows[0] == ["t [s]", "tip_displacement [m]", "u(x=0.0125) [m]"]
    assert [float(x[1]) for x in rows[1:]] == stored["tip_displacement"]


def test_csv_by_query_for_clients_without_headers(tc: Any, stored: dict[str, Any]) -> None:
    r = tc.get(f"/v1/results/{stored['key']}?format=csv&table=eigenvalues")
    rows = _rows(r.text)
    assert rows[0][:3] == ["t [s]", "sigma_1 [1/s]", "omega_1 [rad/s]"]
    assert [float(x[2]) for x in rows[1:]] == stored["eigenvalues"]["modes"][0]["omega"]
    # ?format=json wins over the header; a browser's Accept gets JSON
    r = tc.get(f"/v1/results/{stored['key']}?format=json", headers={"Accept": "text/csv"})
    assert r.headers["content-type"].startswith("application/json")
    browser = "text/html,application/xhtml+xml,application/xml;q=0.9,*/*;q=0.8"
    r = tc.get(f"/v1/results/{stored['key']}", headers={"Accept": browser})
    assert r.json()["key"] == stored["key"]


def test_csv_errors_name_the_field(tc: Any, stored: dict[str, Any]) -> None:
    r = tc.get(f"/v1/results/{stored['key']}?format=csv&table=bode")
    assert r.status_code == 422
    assert r.headers["content-type"] == "application/problem+json"
    assert r.json()["errors"][0]["field"] == "table"
    r = tc.get(f"/v1/results/{'0' * 64}?format=csv")
    assert r.status_code == 404


@pytest.mark.parametrize(
    ("accept", "wanted"),
    [
        ("text/csv", "csv"),
        ("application/json", "json"),
        ("application/json;q=0.5, text/csv", "csv"),
        ("text/csv;q=0.2, application/json", "json"),
        ("text/csv;q=0", "json"),
        ("*/*", "json"),
        (None, "json"),
        ("application/vnd.apache.parquet", "parquet"),
        ("text/csv;q=0.5, application/vnd.apache.parquet", "parquet"),
        ("application/vnd.apache.parquet;q=0.1, text/csv", "csv"),
    ],
)
def test_accept_negotiation(accept: str | None, wanted: str) -> None:
    assert wanted_format(None, accept) == wanted
    assert wanted_format("csv", accept) == "csv"  # ?format= overrides Accept


@pytest.mark.parametrize(
    ("name", "fmt", "media", "magic"),
    [
        ("tip_displacement", "png", "image/png", b"\x89PNG"),
        ("damping", "svg", "image/svg+xml", b"<?xml"),
        ("frequency", "png", "image/png", b"\x89PNG"),
        ("displacements", "svg", "image/svg+xml", b"<?xml"),
    ],
)
def test_plot_endpoints(
    tc: Any, stored: dict[str, Any], name: str, fmt: str, media: str, magic: bytes
) -> None:
    url = f"/v1/results/{stored['key']}/plots/{name}.{fmt}"
    r = tc.get(url)
    assert r.status_code == 200
    assert r.headers["content-type"] == media
    assert r.content.startswith(magic)
    etag = r.headers["etag"]
    assert tc.get(url, headers={"If-None-Match": etag}).status_code == 304
    # an SVG opened on its own is a document: its inline styles may apply, no script runs
    assert r.headers["content-security-policy"] == (SVG_CSP if fmt == "svg" else API_CSP)


def test_plot_errors(tc: Any, stored: dict[str, Any]) -> None:
    r = tc.get(f"/v1/results/{stored['key']}/plots/bode.png")
    assert r.status_code == 404
    assert r.json()["errors"][0]["field"] == "name"
    assert "tip_displacement" in r.json()["detail"]
    assert tc.get(f"/v1/results/{stored['key']}/plots/damping.gif").status_code == 422
    assert tc.get(f"/v1/results/{'0' * 64}/plots/damping.png").status_code == 404


def test_table_parameter_lists_every_export_table() -> None:
    """The ``table`` query Literal repeats :data:`pipeflow.io.export.TABLES` (a Literal cannot
    be built from a dict for the type checker): keep them equal, so no table is refused
    with 422 and none is advertised that the exporter lacks."""
    assert list(get_args(Table)) == list(TABLES)


@pytest.mark.parametrize("how", ["query", "accept"])
def test_parquet_round_trip_through_the_service(tc: Any, stored: dict[str, Any], how: str) -> None:
    """The Parquet table holds the identical float64 values of the JSON result, with each
    column's SI unit in its field metadata."""
    pq = pytest.importorskip("pyarrow.parquet")  # in the dev extra: CI runs this
    url = f"/v1/results/{stored['key']}"
    if how == "query":
        r = tc.get(url, params={"format": "parquet", "table": "eigenvalues"})
    else:
        r = tc.get(
            url,
            params={"table": "eigenvalues"},
            headers={"Accept": "application/vnd.apache.parquet"},
        )
    assert r.status_code == 200, r.text
    assert r.headers["content-type"] == "application/vnd.apache.parquet"
    assert r.headers["etag"] == f'"{stored["key"]}-eigenvalues.parquet"'
    table = pq.read_table(io.BytesIO(r.content))
    assert table.column_names[:4] == ["t", "sigma_1", "omega_1", "confidence_1"]
    units = {f.name: f.metadata[b"unit"].decode() for f in table.schema}
    assert units["t"] == "s" and units["sigma_2"] == "1/s" and units["omega_2"] == "rad/s"
    assert table.column("t").to_pylist() == stored["eigenvalues"]["t"]
    assert table.column("omega_2").to_pylist() == stored["eigenvalues"]["modes"][1]["omega"]


def test_parquet_of_a_missing_table_names_the_field(tc: Any, stored: dict[str, Any]) -> None:
    r = tc.get(f"/v1/results/{stored['key']}", params={"format": "parquet", "table": "mode_shapes"})
    assert r.status_code == 404
    assert r.headers["content-type"] == "application/problem+json"
    assert r.json()["errors"][0]["field"] == "table"


def test_mode_shapes_in_the_result_csv_and_plot(tc: Any) -> None:
    spec = dict(SMALL, output={"mode_shapes": {"times": [0.0, 0.1], "points": 21}})
    r = tc.post("/v1/simulations", json=spec)
    assert r.status_code == 200, r.text
    doc = r.json()
    block = doc["mode_shapes"]
    assert block["t"] == [0.0, 0.1] and len(block["x"]) == 21
    assert block["x"][-1] == spec["pipe"]["L"]
    assert [m["mode"] for m in block["modes"]] == [1, 2, 3]
    assert "mode_shapes" in doc["plots"]
    text = tc.get(f"/v1/results/{doc['key']}", params={"format": "csv", "table": "mode_shapes"})
    header = _rows(text.text)[0]
    assert header[:3] == ["x [m]", "real_1(t=0.0) [-]", "imag_1(t=0.0) [-]"]
    assert len(header) == 1 + 2 * 3 * 2
    png = tc.get(f"/v1/results/{doc['key']}/plots/mode_shapes.png")
    assert png.status_code == 200 and png.content.startswith(b"\x89PNG")


def test_mode_shape_times_outside_the_run_name_the_field(tc: Any) -> None:
    spec = dict(SMALL, output={"mode_shapes": {"times": [0.1, 5.0]}})
    r = tc.post("/v1/simulations", json=spec)
    assert r.status_code == 422
    assert r.json()["errors"][0]["field"] == "output.mode_shapes.times.1"
    bad_points = {"mode_shapes": {"times": [0.1], "points": 1}}
    r = tc.post("/v1/simulations", json=dict(SMALL, output=bad_points))
    assert r.status_code == 422
    assert r.json()["errors"][0]["field"] == "output.mode_shapes.points"


def test_openapi_declares_the_table_formats(tc: Any) -> None:
    """Each operation declares the media types it answers: the tables have their own
    operation (CSV and Parquet, as bytes), the stored result's is JSON (a generated client
    parses every 200 of an operation one way: getResult with ?format=csv crashed it)."""
    paths = tc.get("/openapi.json").json()["paths"]
    op = paths["/v1/results/{key}/tables/{table}.{fmt}"]["get"]
    content = op["responses"]["200"]["content"]
    binary = {"type": "string", "format": "binary"}
    media = ("text/csv", "application/vnd.apache.parquet")
    assert content == {m: {"schema": binary} for m in media}
    params = {p["name"]: p for p in op["parameters"]}
    assert params["table"]["schema"]["enum"] == list(TABLES)
    assert params["fmt"]["schema"]["enum"] == ["csv", "parquet"]
    result = paths["/v1/results/{key}"]["get"]
    assert list(result["responses"]["200"]["content"]) == ["application/json"]
    assert {p["name"] for p in result["parameters"]} == {"key", "if-none-match"}


def test_table_operation_answers_what_format_answers(tc: Any, stored: dict[str, Any]) -> None:
    key = stored["key"]
    for fmt in ("csv", "parquet"):
        path = tc.get(f"/v1/results/{key}/tables/eigenvalues.{fmt}")
        query = tc.get(f"/v1/results/{key}", params={"format": fmt, "table": "eigenvalues"})
        assert path.status_code == 200 and query.status_code == 200
        assert path.content == query.content  # one writer (table_response)
        assert path.headers["content-type"] == query.headers["content-type"]
    assert tc.get(f"/v1/results/{'0' * 64}/tables/history.csv").status_code == 404
    bad = tc.get(f"/v1/results/{key}/tables/nope.csv")
    assert bad.status_code == 422 and bad.headers["content-type"] == "application/problem+json"
    wrong = tc.get(f"/v1/results/{key}/tables/history.csv", headers={"Accept": "image/png"})
    assert wrong.status_code == 406


def test_parquet_without_pyarrow_on_the_server_is_406_naming_format(
    tc: Any, stored: dict[str, Any], monkeypatch: pytest.MonkeyPatch, fresh_tables: TableCache
) -> None:
    """pyarrow is an optional extra of the server too: without it the answer says so (and
    that CSV works) instead of failing with 500."""
    monkeypatch.setitem(sys.modules, "pyarrow", None)  # the server's import now fails
    # ... and such a server never encoded a Parquet table: none in its cache (fresh_tables)
    r = tc.get(f"/v1/results/{stored['key']}", params={"format": "parquet"})
    assert r.status_code == 406
    assert r.headers["content-type"] == "application/problem+json"
    assert r.json()["errors"][0]["field"] == "format"
    assert "pip install 'pipeflow[parquet]'" in r.json()["detail"]


def test_too_many_mode_shape_values_is_a_422_naming_the_field(tc: Any) -> None:
    """32 times x 2001 points x 41 branches (modes = eigen_modes = 40) made 114 MB of JSON;
    now a 422 problem naming output.mode_shapes.points, with the cap in the message."""
    from pipeflow.modeshapes import MAX_SHAPE_VALUES

    times = [0.1 * k / 31 for k in range(32)]
    spec = dict(
        SMALL,
        modes=40,
        output={"eigen_modes": 40, "mode_shapes": {"times": times, "points": 2001}},
    )
    r = tc.post("/v1/simulations", json=spec)
    assert r.status_code == 422, r.text
    assert r.headers["content-type"] == "application/problem+json"
    assert "output.mode_shapes.points" in [e["field"] for e in r.json()["errors"]]
    assert str(MAX_SHAPE_VALUES) in r.text


# -- conditional requests and the encoded tables (issue 22, defect 6) --------------------------


@pytest.mark.parametrize(
    ("params", "tag"),
    [
        ({"format": "csv"}, "history.csv"),  # the default table: its name is in the tag
        ({"format": "csv", "table": "eigenvalues"}, "eigenvalues.csv"),
        ({"format": "parquet", "table": "history"}, "history.parquet"),
    ],
)
def test_tables_answer_304_to_their_etag(
    tc: Any, stored: dict[str, Any], params: dict[str, str], tag: str
) -> None:
    if params["format"] == "parquet":
        pytest.importorskip("pyarrow")
    url = f"/v1/results/{stored['key']}"
    r = tc.get(url, params=params)
    assert r.status_code == 200 and r.content
    etag = r.headers["etag"]
    assert etag == f'"{stored["key"]}-{tag}"'
    for header in (etag, f"W/{etag}", f'"other", {etag}', "*"):
        again = tc.get(url, params=params, headers={"If-None-Match": header})
        assert again.status_code == 304, header
        assert again.content == b"" and again.headers["etag"] == etag
        assert again.headers["cache-control"] == r.headers["cache-control"]
    # another representation's tag (the JSON's, another table's) does not match
    for other in (f'"{stored["key"]}"', f'"{stored["key"]}-modes.csv"'):
        assert tc.get(url, params=params, headers={"If-None-Match": other}).status_code == 200


def test_a_table_is_encoded_once_then_served_from_memory(
    tc: Any, stored: dict[str, Any], monkeypatch: pytest.MonkeyPatch, fresh_tables: TableCache
) -> None:
    """Before, every CSV/Parquet GET read the store, parsed the result and wrote the table."""
    encodes: list[tuple[str | None, str]] = []
    real_encode = exports.encode_table

    def counting(key: str, body: bytes, table: str | None, fmt: str) -> TableAnswer:
        encodes.append((table, fmt))
        return real_encode(key, body, table, fmt)

    monkeypatch.setattr(exports, "encode_table", counting)
    store = tc.app.state.store
    reads: list[str] = []
    real_get = store.get_result
    monkeypatch.setattr(store, "get_result", lambda key: reads.append(key) or real_get(key))
    url = f"/v1/results/{stored['key']}"
    first = tc.get(url, headers={"Accept": "text/csv"})
    etag = first.headers["etag"]
    for _ in range(3):
        again = tc.get(url, headers={"Accept": "text/csv"})
        assert again.content == first.content and again.headers["etag"] == etag
    assert tc.get(url, headers={"Accept": "text/csv", "If-None-Match": etag}).status_code == 304
    assert encodes == [(None, "csv")] and reads == [stored["key"]]
    # what is kept is what a fresh encoding writes (same process, same bytes)
    fresh = real_encode(stored["key"], real_get(stored["key"]), None, "csv")
    assert fresh.content == first.content and fresh.etag == etag


def test_table_cache_keeps_the_recent_tables_within_its_bound() -> None:
    cache = TableCache(max_bytes=250)
    for i in range(4):
        cache.put(f"k{i}", TableAnswer("0" * 64, "history", "csv", b"x" * 100))
        cache.get("k0")  # k0 stays the most recently used
    assert len(cache) == 2 and cache.get("k0") is not None and cache.get("k3") is not None
    assert cache.get("k1") is None and cache.get("k2") is None
    cache.put("huge", TableAnswer("0" * 64, "history", "csv", b"x" * 251))  # over the bound
    assert cache.get("huge") is None and len(cache) == 2


def _supported_spec() -> dict[str, Any]:
    """SMALL on two pins with a spring at midspan, asking for mode shapes."""
    L = SMALL["pipe"]["L"]
    pipe = dict(
        SMALL["pipe"],
        supports={"x0": "pinned", "xL": "pinned"},
        intermediate_supports=[{"position": L / 2, "translational": 10.0}],
    )
    return dict(SMALL, pipe=pipe, output={"mode_shapes": {"times": [0.0], "points": 21}})


def _support_ids(svg: str) -> set[str]:
    return {part.split('"')[0] for part in svg.split('id="support:')[1:]}


def test_stored_figures_along_the_pipe_draw_its_supports(tc: Any) -> None:
    """Issue 31 (Users: "the plots draw the supports"): the service's stored figure of the
    mode shapes draws the supports of the request that made the result (its job record),
    the same symbols as the library's figure (pipeflow.io.support_symbols: an SVG group
    per artist, id "support:<where>:<kind>"); the cantilever draws its clamp only.  Before,
    a stored result's figures drew none."""
    doc = tc.post("/v1/simulations", json=_supported_spec()).json()
    svg = tc.get(f"/v1/results/{doc['key']}/plots/mode_shapes.svg")
    assert svg.status_code == 200
    assert _support_ids(svg.text) == {"x0:pinned", "xL:pinned", "point0:elastic"}
    plain = dict(SMALL, output={"mode_shapes": {"times": [0.0], "points": 21}})
    doc = tc.post("/v1/simulations", json=plain).json()
    svg = tc.get(f"/v1/results/{doc['key']}/plots/mode_shapes.svg")
    assert _support_ids(svg.text) == {"x0:clamped"}
    # figures not along the pipe draw none
    svg = tc.get(f"/v1/results/{doc['key']}/plots/tip_displacement.svg")
    assert _support_ids(svg.text) == set()


def test_a_result_without_its_request_draws_no_supports(tc: Any) -> None:
    """A result stored without a job record (an import, or a record pruned): its figures
    render as before, with no supports, never a 500."""
    doc = tc.post("/v1/simulations", json=_supported_spec()).json()
    body = tc.get(f"/v1/results/{doc['key']}").content
    store = tc.app.state.store
    orphan = "f" * len(doc["key"])
    store.put_result(orphan, "simulation", body)
    svg = tc.get(f"/v1/results/{orphan}/plots/mode_shapes.svg")
    assert svg.status_code == 200 and _support_ids(svg.text) == set()
    gif = tc.get(f"/v1/results/{orphan}/animations/mode_shapes.gif")
    assert gif.status_code == 200 and gif.content[:6] == b"GIF89a"


def test_the_mode_shape_animation_draws_the_supports(tc: Any) -> None:
    """The viewer's GIF (GET .../animations/mode_shapes.gif) is the library's animation with
    the request's pipe, frame for frame (same process, same renderer), and differs from the
    one without supports."""
    from pipeflow.io.animation import mode_shape_gif
    from pipeflow.schema.simulation import pipe_of_request

    spec = _supported_spec()
    doc = tc.post("/v1/simulations", json=spec).json()
    gif = tc.get(f"/v1/results/{doc['key']}/animations/mode_shapes.gif", params={"frames": 4})
    assert gif.status_code == 200
    result = tc.get(f"/v1/results/{doc['key']}").json()
    pipe = pipe_of_request(spec)
    assert pipe is not None and pipe.intermediate_supports
    assert gif.content == mode_shape_gif(result, frames=4, pipe=pipe)
    assert gif.content != mode_shape_gif(result, frames=4)
