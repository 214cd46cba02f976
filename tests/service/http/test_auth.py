"""Optional API-key authentication: the key ring, the key command, the middleware's answers
and the OpenAPI document of a server that requires keys.

The app runs without its lifespan: every answer here is the middleware's (401, 403) or
comes from a route that needs no engine (``/healthz``, the pages, the test route reading
``request.state.principal``).  ``test_auth_server.py`` checks the same against a real
uvicorn with workers (slow).
"""

from __future__ import annotations

import hashlib
from collections.abc import Iterator
from pathlib import Path

import pytest
from fastapi import APIRouter, Request
from fastapi.testclient import TestClient

from service.http import auth
from service.http.auth import KeyRing, KeyRingError, new_key
from service.main import create_app
from service.settings import Settings

ALICE, ALICE_ENTRY = new_key("alice")
BOB, BOB_ENTRY = new_key("bob")
SCRAPER, SCRAPER_ENTRY = new_key("prometheus")


def _whoami() -> APIRouter:
    router = APIRouter()

    @router.get("/v1/test/whoami")
    async def whoami(request: Request) -> dict[str, str | None]:
        return {"principal": request.state.principal}

    @router.get("/test/open-whoami")
    async def open_whoami(request: Request) -> dict[str, str | None]:
        return {"principal": request.state.principal}

    return router


def _client(tmp: Path, **overrides: object) -> TestClient:
    app = create_app(Settings(data_dir=tmp, **overrides))  # type: ignore[arg-type]
    app.include_router(_whoami())
    return TestClient(app, raise_server_exceptions=False)  # no lifespan: no workers


@pytest.fixture(scope="module")
def tc(tmp_path_factory: pytest.TempPathFactory) -> Iterator[TestClient]:
    tmp = tmp_path_factory.mktemp("auth")
    keys_file = tmp / "keys"
    keys_file.write_text(f"# the scraper's key\n{SCRAPER_ENTRY}\n")
    yield _client(
        tmp,
        auth_required=True,
        api_keys=f"{ALICE_ENTRY},{BOB_ENTRY}",
        api_keys_file=keys_file,
        metrics_key_ids="prometheus",
    )


def test_new_key_and_its_entry() -> None:
    key, entry = new_key("ci-runner.1")
    key_id, algorithm, digest = entry.split(":")
    assert (key_id, algorithm) == ("ci-runner.1", "sha256")
    assert digest == hashlib.sha256(key.encode()).hexdigest()  # the entry holds no key
    assert key not in entry and key.startswith("pf_") and len(key) == 3 + 43  # 32 bytes
    assert new_key("ci-runner.1")[0] != key
    with pytest.raises(KeyRingError):
        new_key("no spaces")


def test_key_command_prints_a_key_and_its_entry(capsys: pytest.CaptureFixture[str]) -> None:
    assert auth.main(["new", "alice"]) == 0
    out = capsys.readouterr().out
    key, entry = (line.rsplit(" ", 1)[1] for line in out.splitlines())
    assert KeyRing.parse(entry).identify(key) == "alice"


def test_key_ring_parses_entries_and_identifies_keys() -> None:
    ring = KeyRing.parse(f"{ALICE_ENTRY}, {BOB_ENTRY}\n# a comment\n\n{SCRAPER_ENTRY}  # trailing")
    assert ring.identify(ALICE) == "alice" and ring.identify(BOB) == "bob"
    assert ring.identify(SCRAPER) == "prometheus"
    assert ring.identify(ALICE + "x") is None and ring.identify("") is None
    assert ring.identify(ALICE_ENTRY) is None  # the entry is not a key


@pytest.mark.parametrize(
    "text",
    [
        "alice",
        "alice:sha256:abc",
        f"alice:md5:{'0' * 64}",
        f"al ice:sha256:{'0' * 64}",
        f"{'a' * 65}:sha256:{'0' * 64}",
    ],
)
def test_bad_entries_are_refused_without_echoing_them(text: str) -> None:
    with pytest.raises(KeyRingError) as info:
        KeyRing.parse(f"{ALICE_ENTRY}\n{text}")
    assert "entry 2" in str(info.value) and text not in str(info.value)


def test_a_server_requiring_keys_refuses_to_start_without_one(tmp_path: Path) -> None:
    with pytest.raises(KeyRingError, match="no key"):
        create_app(Settings(data_dir=tmp_path, auth_required=True))
    with pytest.raises(KeyRingError, match="cannot be read"):
        create_app(Settings(data_dir=tmp_path, api_keys_file=tmp_path / "missing"))
    create_app(Settings(data_dir=tmp_path, auth_required=False))  # off: no key needed


def test_admin_key_ids_must_be_keys_of_the_ring(tmp_path: Path) -> None:
    """A misspelt admin id would leave the operator without the admin key they meant:
    the server refuses to start and names the id (ids are not secrets)."""
    with pytest.raises(KeyRingError, match="PIPEFLOW_ADMIN_KEY_IDS names 'ops'"):
        create_app(
            Settings(
                data_dir=tmp_path, auth_required=True, api_keys=ALICE_ENTRY, admin_key_ids="ops"
            )
        )
    create_app(
        Settings(data_dir=tmp_path, auth_required=True, api_keys=ALICE_ENTRY, admin_key_ids="alice")
    )


def _assert_401(r: object, message: str) -> None:
    assert r.status_code == 401, r.text  # type: ignore[attr-defined]
    assert r.headers["content-type"] == "application/problem+json"  # type: ignore[attr-defined]
    assert r.headers["www-authenticate"].startswith("Bearer")  # type: ignore[attr-defined]
    doc = r.json()  # type: ignore[attr-defined]
    assert doc["type"].endswith("/unauthorized") and doc["title"] == "Unauthorized"
    [err] = doc["errors"]
    assert err["field"] == "Authorization" and err["location"] == "header"
    assert err["message"] == message


def test_the_api_needs_a_known_key(tc: TestClient) -> None:
    _assert_401(tc.get("/v1/test/whoami"), "missing")
    _assert_401(tc.post("/v1/simulations", json={}), "missing")
    _assert_401(tc.get("/v1/test/whoami", headers={"Authorization": "Bearer nope"}), "unknown key")
    _assert_401(tc.get("/v1/test/whoami", headers={"X-API-Key": BOB + "x"}), "unknown key")
    _assert_401(tc.get("/v1/test/whoami", headers={"Authorization": f"Basic {ALICE}"}), "missing")
    # refused before the body is read: no 413, no 422, no computation
    _assert_401(tc.post("/v1/simulations", content=b"x" * 3_000_000), "missing")


@pytest.mark.parametrize(
    ("headers", "principal"),
    [
        ({"Authorization": f"Bearer {ALICE}"}, "alice"),
        ({"Authorization": f"bearer {BOB}"}, "bob"),
        ({"X-API-Key": BOB}, "bob"),
        ({"X-API-Key": SCRAPER}, "prometheus"),  # from the keys file
    ],
)
def test_a_known_key_sets_the_principal(
    tc: TestClient, headers: dict[str, str], principal: str
) -> None:
    r = tc.get("/v1/test/whoami", headers=headers)
    assert r.status_code == 200 and r.json() == {"principal": principal}


def test_probes_pages_and_documentation_stay_open(tc: TestClient) -> None:
    for path in ("/healthz", "/", "/stability", "/static/viewer.js", "/docs", "/openapi.json"):
        assert tc.get(path).status_code == 200, path
    # open paths carry no principal, even when a key is sent
    r = tc.get("/test/open-whoami", headers={"X-API-Key": ALICE})
    assert r.json() == {"principal": None}


def test_metrics_need_a_key_listed_for_them(tc: TestClient) -> None:
    _assert_401(tc.get("/metrics"), "missing")
    r = tc.get("/metrics", headers={"X-API-Key": ALICE})
    assert r.status_code == 403 and r.headers["content-type"] == "application/problem+json"
    assert r.json()["type"].endswith("/forbidden") and "alice" in r.json()["detail"]
    assert ALICE not in r.text


def test_metrics_switch_opens_them(tmp_path: Path) -> None:
    tc = _client(tmp_path, auth_required=True, api_keys=ALICE_ENTRY, metrics_auth=False)
    # open: no 401 (the route itself needs the engine, absent without the lifespan)
    assert tc.get("/metrics").status_code not in (401, 403)
    _assert_401(tc.get("/v1/test/whoami"), "missing")


def test_off_by_default_everything_is_open_and_anonymous(tmp_path: Path) -> None:
    tc = _client(tmp_path, api_keys=ALICE_ENTRY)  # keys listed, auth not required
    r = tc.get("/v1/test/whoami")
    assert r.status_code == 200 and r.json() == {"principal": None}


def test_openapi_of_a_server_requiring_keys_declares_them(tc: TestClient) -> None:
    doc = tc.get("/openapi.json").json()
    schemes = doc["components"]["securitySchemes"]
    assert schemes["bearer"] == {
        "type": "http",
        "scheme": "bearer",
        "description": schemes["bearer"]["description"],
    }
    assert schemes["apiKey"]["in"] == "header" and schemes["apiKey"]["name"] == "X-API-Key"
    post = doc["paths"]["/v1/simulations"]["post"]
    assert post["security"] == [{"bearer": []}, {"apiKey": []}]
    assert "401" in post["responses"]
    assert "403" in doc["paths"]["/metrics"]["get"]["responses"]
    assert "security" not in doc["paths"]["/healthz"]["get"]
    # a key cancels only the runs it started (an admin key: any)
    assert "403" in doc["paths"]["/v1/jobs/{key}"]["delete"]["responses"]
    assert "403" not in doc["paths"]["/v1/jobs/{key}"]["get"]["responses"]


def test_the_compose_replicas_require_keys() -> None:
    """On in the compose file: both API replicas require keys, whose entries the operator
    must export (compose stops with the message of ``${PIPEFLOW_API_KEYS:?...}`` if not)."""
    yaml = pytest.importorskip("yaml")
    root = Path(__file__).resolve().parents[3]
    services = yaml.safe_load((root / "docker-compose.yml").read_text())["services"]
    for name in ("api1", "api2"):
        env = services[name]["environment"]
        assert Settings(data_dir=root, auth_required=env["PIPEFLOW_AUTH_REQUIRED"]).auth_required
        assert env["PIPEFLOW_API_KEYS"].startswith("${PIPEFLOW_API_KEYS:?")
        assert env["PIPEFLOW_DATABASE_URL"].startswith("postgresql")  # the shared entries kept
