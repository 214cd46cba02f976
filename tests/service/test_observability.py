"""Metrics, request ids and structured logs (issue 12).

The log tests run the real server (``uvicorn service.main:app`` in a subprocess,
:func:`tests.live.uvicorn_server`) and read its captured stdout: the request line of the
middleware and the worker's lines for the computation must carry the request id.
"""

from __future__ import annotations

import io
import json
import logging
import re
from pathlib import Path
from typing import Any

import httpx
import pytest
from fastapi.testclient import TestClient

from service import observability
from tests.live import uvicorn_server
from tests.service.conftest import SMALL, make_client, wait_ready

KEY_0 = "0" * 64


def sample(metrics: str, name: str, **labels: str) -> float:
    """The value of the sample ``name{labels}`` in a Prometheus text exposition (0 if absent)."""
    for line in metrics.splitlines():
        m = re.fullmatch(r"([a-zA-Z_:][a-zA-Z0-9_:]*)(\{(.*)\})? (\S+)", line)
        if m is None or m.group(1) != name:
            continue
        found = dict(re.findall(r'(\w+)="((?:[^"\\]|\\.)*)"', m.group(3) or ""))
        if found == labels:
            return float(m.group(4))
    return 0.0


def log_lines(path: Path) -> list[dict[str, Any]]:
    """The JSON log records of a server's captured stdout (every line must be JSON)."""
    records = []
    for line in path.read_text().splitlines():
        if not line.startswith("{"):
            continue  # a Python warning printed before logging was configured
        records.append(json.loads(line))
    return records


@pytest.fixture(scope="module")
def app_client(tmp_path_factory: pytest.TempPathFactory) -> Any:
    with make_client(tmp_path_factory.mktemp("obs")) as c:
        wait_ready(c)
        yield c


def test_request_id_is_taken_or_generated_and_echoed(app_client: TestClient) -> None:
    r = app_client.get("/healthz", headers={"X-Request-ID": "req-42.a:b"})
    assert r.headers["X-Request-ID"] == "req-42.a:b"
    generated = app_client.get("/healthz").headers["X-Request-ID"]
    assert re.fullmatch(r"[0-9a-f]{32}", generated)
    # a header that is not a sane token (spaces, too long) is replaced, not echoed
    bad = app_client.get("/healthz", headers={"X-Request-ID": "a b" + "x" * 200})
    assert re.fullmatch(r"[0-9a-f]{32}", bad.headers["X-Request-ID"])
    # error answers carry it too (problem+json from the handler, 413 from the body limit)
    missing = app_client.get(f"/v1/results/{KEY_0}", headers={"X-Request-ID": "e1"})
    assert missing.status_code == 404 and missing.headers["X-Request-ID"] == "e1"
    big = app_client.post(
        "/v1/simulations", content=b"x" * 2_000_001, headers={"X-Request-ID": "e2"}
    )
    assert big.status_code == 413 and big.headers["X-Request-ID"] == "e2"


def test_requests_counted_by_route_template(app_client: TestClient) -> None:
    before = app_client.get("/metrics").text
    label = {"route": "/v1/results/{key}", "method": "GET", "status": "404"}
    n0 = sample(before, "pipeflow_http_requests_total", **label)
    h0 = sample(
        before,
        "pipeflow_http_request_duration_seconds_count",
        route="/v1/results/{key}",
        method="GET",
    )
    for digit in "123":
        assert app_client.get(f"/v1/results/{digit * 64}").status_code == 404
    r = app_client.get("/metrics")
    assert r.status_code == 200
    assert r.headers["content-type"].startswith("text/plain")
    after = r.text
    # three raw paths, one label set: the template, never the key
    assert sample(after, "pipeflow_http_requests_total", **label) == n0 + 3
    assert (
        sample(
            after,
            "pipeflow_http_request_duration_seconds_count",
            route="/v1/results/{key}",
            method="GET",
        )
        == h0 + 3
    )
    assert "1" * 64 not in after
    assert sample(after, "pipeflow_workers") == 1
    assert sample(after, "pipeflow_workers_ready") == 1
    assert sample(after, "pipeflow_capacity") == 1 + 16
    for status in ("queued", "running", "succeeded", "failed", "cancelled"):
        assert f'pipeflow_jobs{{status="{status}"}}' in after
    # an unmatched path has its own bounded label
    app_client.get("/no/such/path/9")
    assert (
        sample(
            app_client.get("/metrics").text,
            "pipeflow_http_requests_total",
            route="<unmatched>",
            method="GET",
            status="404",
        )
        >= 1
    )


def test_computation_and_cache_metrics(app_client: TestClient) -> None:
    spec = dict(SMALL, modes=2)
    before = app_client.get("/metrics").text
    route = "/v1/simulations"
    miss0 = sample(before, "pipeflow_cache_lookups_total", route=route, result="miss")
    hit0 = sample(before, "pipeflow_cache_lookups_total", route=route, result="hit")
    miss = app_client.post(route, json=spec)
    assert miss.headers["X-Cache"] == "MISS"
    used = miss.json()["method_used"]  # "auto" picks magnus for v = 0.4 t
    comp = {"kind": "simulation", "method_used": used, "outcome": "ok"}
    c0 = sample(before, "pipeflow_computations_total", **comp)
    assert app_client.post(route, json=spec).headers["X-Cache"] == "HIT"
    after = app_client.get("/metrics").text
    assert sample(after, "pipeflow_cache_lookups_total", route=route, result="miss") == miss0 + 1
    assert sample(after, "pipeflow_cache_lookups_total", route=route, result="hit") == hit0 + 1
    assert sample(after, "pipeflow_computations_total", **comp) == c0 + 1
    assert (
        sample(
            after,
            "pipeflow_computation_duration_seconds_count",
            kind="simulation",
            method_used=used,
        )
        >= 1
    )
    assert sample(after, "pipeflow_jobs", status="succeeded") >= 1


def test_method_used_read_from_the_bytes() -> None:
    assert observability.method_used(b'{"method":"auto","method_used":"magnus","t":[1]}') == (
        "magnus"
    )
    assert observability.method_used(b'{"status":"ok","method":"rk4"}') == "rk4"
    assert observability.method_used(b'{"critical_velocity":27.7}') == "none"


def test_log_formats_and_level() -> None:
    """JSON lines carry the request id and the extra fields; text is one readable line;
    the level filters; the handler is installed once."""
    root = logging.getLogger()
    saved = root.level
    try:
        observability.configure_logging("INFO", "json")
        observability.configure_logging("INFO", "json")
        ours = [h for h in root.handlers if isinstance(h, observability._PipeflowHandler)]
        assert len(ours) == 1
        handler = ours[0]
        buf = io.StringIO()
        stream = handler.setStream(buf)
        try:
            token = observability.REQUEST_ID.set("rid-7")
            logging.getLogger("pipeflow.test").info("hello %s", "world", extra={"key": "k1"})
            observability.REQUEST_ID.reset(token)
            doc = json.loads(buf.getvalue().splitlines()[-1])
            assert doc["message"] == "hello world"
            assert doc["request_id"] == "rid-7"
            assert doc["key"] == "k1"
            assert doc["level"] == "INFO" and doc["logger"] == "pipeflow.test"

            observability.configure_logging("WARNING", "text")
            logging.getLogger("pipeflow.test").info("dropped")
            logging.getLogger("pipeflow.test").warning("kept", extra={"status": 503})
            text = buf.getvalue().splitlines()[-1]
            assert "dropped" not in buf.getvalue()
            assert re.fullmatch(r"\S+ WARNING +pipeflow\.test \[-\] kept status=503", text), text
        finally:
            handler.setStream(stream)
        with pytest.raises(ValueError, match="log format"):
            observability.configure_logging("INFO", "xml")
    finally:
        observability.configure_logging("INFO", "json")
        root.setLevel(saved)


def test_bad_log_settings_are_refused_naming_the_variable(tmp_path: Path) -> None:
    from pydantic import ValidationError

    from service.settings import Settings

    with pytest.raises(ValidationError, match="log_format"):
        Settings(data_dir=tmp_path, log_format="xml")  # type: ignore[arg-type]
    with pytest.raises(ValidationError, match="log_level"):
        Settings(data_dir=tmp_path, log_level="LOUD")  # type: ignore[arg-type]


@pytest.mark.slow  # a live server with two workers and their logs, 10-30 s
def test_live_server_logs_and_metrics_carry_the_request_id(tmp_path: Path) -> None:
    """A real uvicorn server: its stdout has one JSON request line per request with the
    request id, and the worker's lines for that computation carry the same id; /metrics
    counts it.  PROMETHEUS_MULTIPROC_DIR is set, and a second server process on the same
    directory reports the first one's counts too (aggregation across processes)."""
    prom = tmp_path / "prom"
    prom.mkdir()
    log = tmp_path / "server.log"
    spec = dict(SMALL, modes=2)
    # the time-variant run on a Dask worker (not metered in the API process's fast lane):
    # the worker's lines must carry the request id across the process boundary
    env = {
        "PROMETHEUS_MULTIPROC_DIR": str(prom),
        "PIPEFLOW_LOG_FORMAT": "json",
        "PIPEFLOW_FAST_LANE_MAX_METERED_S": "0",
    }
    with uvicorn_server(tmp_path / "data", log, **env) as url:
        r = httpx.post(
            url + "/v1/simulations", json=spec, headers={"X-Request-ID": "live-1"}, timeout=60
        )
        assert r.status_code == 200 and r.headers["X-Cache"] == "MISS"
        key, used = r.json()["key"], r.json()["method_used"]
        assert r.headers["X-Request-ID"] == "live-1"
        hit = httpx.post(url + "/v1/simulations", json=spec, timeout=60)
        assert hit.headers["X-Cache"] == "HIT"
        hit_id = hit.headers["X-Request-ID"]
        metrics = httpx.get(url + "/metrics", timeout=10).text
    records = log_lines(log)
    requests = [r for r in records if r["logger"] == "service.access"]
    miss_line = next(r for r in requests if r["request_id"] == "live-1")
    assert miss_line | {"duration_ms": 0, "ts": "", "pid": 0} == {
        "ts": "",
        "level": "INFO",
        "logger": "service.access",
        "message": "request",
        "request_id": "live-1",
        "pid": 0,
        "method": "POST",
        "route": "/v1/simulations",
        "path": "/v1/simulations",
        "status": 200,
        "duration_ms": 0,
        "cache": "MISS",
        "key": key,
        "principal": None,  # authentication is off: no key id (service.http.auth)
    }
    assert miss_line["duration_ms"] > 0
    hit_line = next(r for r in requests if r["request_id"] == hit_id)
    assert hit_line["cache"] == "HIT" and hit_line["key"] == key
    worker = [r for r in records if r["logger"] == "service.worker" and r.get("key") == key]
    assert {r["message"] for r in worker} == {"computation started", "computation finished"}
    assert all(r["request_id"] == "live-1" for r in worker)
    assert all(r["pid"] != miss_line["pid"] for r in worker)  # written by the worker process
    # application INFO logs reach the output (uvicorn's own, through the same handler)
    assert any(r["logger"] == "uvicorn.error" and r["level"] == "INFO" for r in records)

    route = {"route": "/v1/simulations", "method": "POST", "status": "200"}
    assert sample(metrics, "pipeflow_http_requests_total", **route) == 2
    assert sample(metrics, "pipeflow_cache_lookups_total", route=route["route"], result="hit") == 1
    comp = {"kind": "simulation", "method_used": used, "outcome": "ok"}
    assert sample(metrics, "pipeflow_computations_total", **comp) == 1

    with uvicorn_server(tmp_path / "data", tmp_path / "second.log", **env) as url:
        again = httpx.get(url + "/metrics", timeout=10).text
    assert sample(again, "pipeflow_http_requests_total", **route) == 2
    assert sample(again, "pipeflow_computations_total", **comp) == 1


def test_waiting_jobs_gauge_counts_the_durable_queue(tmp_path: Path) -> None:
    """``pipeflow_jobs_waiting``: jobs accepted into the store's durable queue and not yet
    taken by a replica (issue 22); a job a replica took, or one driven at once, is not
    waiting.  The engine is a stand-in (a unit seam); the store is real."""
    from types import SimpleNamespace

    from service.store import Store

    store = Store(tmp_path / "db.sqlite3", cache_max_bytes=10_000, memory_cache_bytes=0)
    for key in ("a", "b", "c"):
        assert store.queue_job(key, "simulation", {"k": key}, bound=10)[1]
    store.enqueue_job("d", "simulation", {"k": "d"})  # driven at once: not waiting
    assert [job.key for job in store.claim_waiting("replica-1", 1)] == ["a"]
    runner = SimpleNamespace(
        settings=SimpleNamespace(workers=1), in_flight=0, workers=1, ready=True, capacity=17
    )
    text = observability.exposition(observability.engine_stats(runner, store)).decode()
    assert sample(text, "pipeflow_jobs_waiting") == 2
    assert sample(text, "pipeflow_jobs", status="queued") == 4
    store.close()
