"""The hit path: stored bytes served as they are, gzip when accepted, from memory."""

from __future__ import annotations

import gzip
import json
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from fastapi.testclient import TestClient

from service.engine import preload
from service.http.negotiation import accepts_gzip
from service.http.responses import Encoded, HitCache, encode, envelope
from tests.service.conftest import SMALL, make_client, wait_ready


@pytest.fixture(scope="module")
def app_client(tmp_path_factory: pytest.TempPathFactory) -> Iterator[TestClient]:
    with make_client(tmp_path_factory.mktemp("hits")) as c:
        wait_ready(c)
        yield c


def raw(client: TestClient, method: str, url: str, **kw: Any) -> tuple[dict[str, str], bytes]:
    """Headers and the body bytes exactly as sent (no content decoding)."""
    with client.stream(method, url, **kw) as r:
        return dict(r.headers), b"".join(r.iter_raw())


@pytest.mark.parametrize(
    ("header", "ok"),
    [
        (None, False),
        ("", False),
        ("identity", False),
        ("gzip", True),
        ("GZIP", True),
        ("br, gzip;q=0.5", True),
        ("gzip;q=0", False),
        ("gzip; q=0.000", False),
        ("*", True),
        ("*;q=0", False),
        ("gzip;q=0, *", False),  # the explicit gzip entry wins over the wildcard
        ("deflate, x-gzip", True),
        ("gzip;q=abc", False),
    ],
)
def test_accepts_gzip(header: str | None, ok: bool) -> None:
    assert accepts_gzip(header) is ok


def test_hit_is_the_stored_bytes_and_gzip_decodes_to_them(app_client: TestClient) -> None:
    spec = dict(SMALL, modes=2, time={"t_end": 0.2, "samples": 201})
    miss = app_client.post("/v1/simulations", json=spec, headers={"Accept-Encoding": "gzip"})
    assert miss.headers["X-Cache"] == "MISS"
    key = miss.json()["key"]
    stored = app_client.app.state.store.get_result(key)  # type: ignore[attr-defined]
    # identity: the envelope around the stored bytes, byte for byte
    headers, plain = raw(
        app_client, "POST", "/v1/simulations", json=spec, headers={"Accept-Encoding": "identity"}
    )
    assert headers["x-cache"] == "HIT" and "content-encoding" not in headers
    assert plain == envelope(key, True, stored)
    assert headers["vary"] == "Accept-Encoding" and headers["etag"] == f'"{key}"'

    # gzip: compressed, and it decompresses to exactly those bytes
    headers, packed = raw(
        app_client, "POST", "/v1/simulations", json=spec, headers={"Accept-Encoding": "gzip"}
    )
    assert headers["content-encoding"] == "gzip" and headers["x-cache"] == "HIT"
    assert headers["etag"] == f'"{key}-gzip"'  # another representation, another strong tag
    assert gzip.decompress(packed) == plain
    assert len(packed) < len(plain) / 2  # measured ~4x smaller on this 201-sample result
    assert int(headers["content-length"]) == len(packed)
    # GET /v1/results/{key} answers the same bytes
    headers, got = raw(app_client, "GET", f"/v1/results/{key}", headers={"Accept-Encoding": "gzip"})
    assert headers["content-encoding"] == "gzip" and gzip.decompress(got) == plain
    # the MISS answer is the same document but for "cached"
    assert json.loads(plain) == {**miss.json(), "cached": True}


def test_a_hit_is_answered_from_memory(app_client: TestClient, monkeypatch: Any) -> None:
    """Once encoded, a hit touches neither the store nor the JSON of the result."""
    spec = dict(SMALL, modes=2, time={"t_end": 0.1, "samples": 51})
    app_client.post("/v1/simulations", json=spec)  # MISS: computed and stored
    first = app_client.post("/v1/simulations", json=spec)  # HIT: read once, encoded, kept
    store = app_client.app.state.store  # type: ignore[attr-defined]

    def no_store(key: str) -> bytes | None:
        raise AssertionError("the store was read on a hit")

    monkeypatch.setattr(store, "get_result", no_store)
    monkeypatch.setattr(store, "has_result", no_store)
    again = app_client.post("/v1/simulations", json=spec)
    assert again.status_code == 200 and again.headers["X-Cache"] == "HIT"
    assert again.content == first.content
    key = again.json()["key"]
    assert app_client.get(f"/v1/results/{key}").content == first.content
    for coding, tag in (("identity", f'"{key}"'), ("gzip", f'"{key}-gzip"')):
        etag = {"If-None-Match": tag, "Accept-Encoding": coding}
        assert app_client.get(f"/v1/results/{key}", headers=etag).status_code == 304


def test_refresh_drops_the_encoded_hit(app_client: TestClient) -> None:
    spec = dict(SMALL, modes=2, time={"t_end": 0.1, "samples": 41})
    key = app_client.post("/v1/simulations", json=spec).json()["key"]
    app_client.post("/v1/simulations", json=spec)
    hits: HitCache = app_client.app.state.hits  # type: ignore[attr-defined]
    assert hits.get(key) is not None
    r = app_client.post("/v1/simulations", params={"refresh": "true"}, json=spec)
    assert r.headers["X-Cache"] == "MISS"
    assert hits.get(key) is None  # the next hit encodes the new stored bytes


def test_hit_cache_is_bounded_lru() -> None:
    cache = HitCache(max_bytes=100)
    for k in "abc":
        cache.put(k, Encoded(b"x" * 40))
    assert cache.get("a") is None and len(cache) == 2  # 120 > 100: the oldest went
    cache.get("b")  # b is now the most recent
    cache.put("d", Encoded(b"y" * 40))
    assert cache.get("c") is None and cache.get("b") is not None
    cache.put("big", Encoded(b"z" * 101))  # larger than the bound: not kept
    assert cache.get("big") is None
    small = encode(b"{}")
    assert small.gzip is None  # below GZIP_MIN_BYTES: identity only
    big = encode(b'{"a":' + b"1" * 5000 + b"}")
    assert big.gzip is not None and gzip.decompress(big.gzip) == big.identity


#: packages whose first import in a worker would make its first job slow (seconds)
HEAVY = ("pipeflow", "service", "fastapi", "starlette", "pydantic", "numpy", "scipy", "matplotlib")


@pytest.mark.slow  # a server's start-up with its workers' warm-up, 5-30 s
def test_workers_are_warm_before_ready(tmp_path: Path) -> None:
    """Ready means warmed up: a tiny run of each solver and of the default request's mode
    count went through the job function and the encoder, a warm-up task opened the
    worker's store, glibc's malloc trims as by default, and a first real job (here a
    simulation, a stability analysis and a failing run answered with a problem) imports no
    module of the heavy packages that the worker had not imported before it
    (service.http.problems, i.e. FastAPI, once cost ~1 s)."""
    stab = {"pipe": SMALL["pipe"], "modes": 4, "velocity_range": [0, 40], "points": 41}
    bad_step = dict(SMALL, method="rk4", options={"step": 0.01})  # unstable: 422 problem
    with make_client(tmp_path, workers=1) as c:
        wait_ready(c)
        call = c.app.state.runner.call  # type: ignore[attr-defined]
        before = c.portal.call(call, preload.ping)
        assert before["registry_loaded"] and before["warmed_up"]
        # the warm-up task opened the worker's store of the service's database
        assert before["stores"] == [c.app.state.settings.db_url]  # type: ignore[attr-defined]
        # glibc's adaptive trim threshold, not Dask's 65536 (1.3-1.7x slower paper example)
        assert before["malloc_trim_threshold"] is None
        assert c.post("/v1/simulations", json=SMALL).status_code == 200
        assert c.post("/v1/stability", json=stab).status_code == 200
        assert c.post("/v1/simulations", json=bad_step).status_code == 422
        after = c.portal.call(call, preload.ping)
    assert after["pid"] == before["pid"]
    new = set(after["modules"]) - set(before["modules"])
    assert not {m for m in new if m.split(".")[0] in HEAVY}


def test_request_key_memo_equals_the_key() -> None:
    """The memoised key is the salted RFC 8785 hash of the request's normal form for every
    spec, first call and memo hit alike."""
    from pipeflow.computations.registry import COMPUTATIONS
    from pipeflow.schema.simulation import SimulationSpec
    from service.keys import canonical_key, keyed

    simulation = COMPUTATIONS["simulation"]

    variants = [
        SMALL,
        dict(SMALL, modes=4),
        dict(SMALL, method="rk4", options={"step": 1e-5}),
        dict(SMALL, method="rk4", options={"step": 2e-5}),
        dict(SMALL, method="magnus", options={"tolerance": 1e-6}),
        dict(SMALL, initial={"u0": 0.002}),
    ]
    keys = []
    for data in variants:
        spec = SimulationSpec.model_validate(data)
        expected = canonical_key("simulation", spec.canonical())
        for _ in range(2):
            assert keyed(simulation, spec).key == expected
        keys.append(keyed(simulation, spec).key)
    assert len(set(keys)) == len(keys)


def test_repeated_hit_bytes_skip_the_route(app_client: TestClient, monkeypatch: Any) -> None:
    """The same body bytes again are answered by the fast path (the route, which would key
    the body, is not called) with the route's own answer, byte for byte, in both codings;
    counted under the route's template with its cache result; a query string, other
    bytes of the same request, or failed negotiation go to the route as before."""
    from service.routes import computations
    from tests.service.test_observability import sample

    spec = dict(SMALL, modes=2, time={"t_end": 0.1, "samples": 61})
    body = json.dumps(spec).encode()
    post = {"content": body, "headers": {"Content-Type": "application/json"}}
    miss = app_client.post("/v1/simulations", **post)
    assert miss.status_code == 200 and miss.headers["X-Cache"] == "MISS"
    key = miss.json()["key"]
    _, route_plain = raw(
        app_client,
        "POST",
        "/v1/simulations",
        content=body,
        headers={"Content-Type": "application/json", "Accept-Encoding": "identity"},
    )
    calls: list[Any] = []
    real_keyed = computations.keyed_in_thread

    def counted(*args: Any) -> Any:
        calls.append(args)
        return real_keyed(*args)

    monkeypatch.setattr(computations, "keyed_in_thread", counted)
    before = app_client.get("/metrics").text
    for coding in ("identity", "gzip"):
        headers, sent = raw(
            app_client,
            "POST",
            "/v1/simulations",
            content=body,
            headers={"Content-Type": "application/json", "Accept-Encoding": coding},
        )
        assert headers["x-cache"] == "HIT" and headers["vary"] == "Accept-Encoding"
        assert headers["content-location"] == f"/v1/results/{key}"
        if coding == "gzip":
            assert headers["content-encoding"] == "gzip" and headers["etag"] == f'"{key}-gzip"'
            sent = gzip.decompress(sent)
        else:
            assert "content-encoding" not in headers and headers["etag"] == f'"{key}"'
        assert sent == route_plain
        assert headers["x-request-id"]
    assert calls == []  # neither parsed nor keyed again
    after = app_client.get("/metrics").text
    label = {"route": "/v1/simulations", "method": "POST", "status": "200"}
    n = sample(after, "pipeflow_http_requests_total", **label)
    assert n == sample(before, "pipeflow_http_requests_total", **label) + 2
    hits = {"route": "/v1/simulations", "result": "hit"}
    assert sample(after, "pipeflow_cache_lookups_total", **hits) == (
        sample(before, "pipeflow_cache_lookups_total", **hits) + 2
    )
    # the route still runs for: a query string, other bytes of the same request
    again = app_client.post("/v1/simulations", params={"refresh": "false"}, **post)
    assert again.headers["X-Cache"] == "HIT" and len(calls) == 1
    reordered = json.dumps(dict(reversed(list(spec.items())))).encode()
    same = app_client.post(
        "/v1/simulations", content=reordered, headers={"Content-Type": "application/json"}
    )
    assert same.json()["key"] == key and len(calls) == 2
    # negotiation is not skipped: the same bytes as text, or asking for CSV, are refused
    as_text = app_client.post(
        "/v1/simulations", content=body, headers={"Content-Type": "text/plain"}
    )
    assert as_text.status_code == 415
    as_csv = app_client.post(
        "/v1/simulations",
        content=body,
        headers={"Content-Type": "application/json", "Accept": "text/csv"},
    )
    assert as_csv.status_code == 406
    # a refresh drops the hit answer: the same bytes then take the route (and recompute)
    fresh = app_client.post("/v1/simulations", params={"refresh": "true"}, **post)
    assert fresh.headers["X-Cache"] == "MISS"
    n_calls = len(calls)
    assert app_client.post("/v1/simulations", **post).headers["X-Cache"] == "HIT"
    assert len(calls) == n_calls + 1
