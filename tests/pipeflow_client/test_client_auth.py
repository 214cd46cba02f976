"""The command line and both clients send an API key to a server that requires keys.

One real ``uvicorn service.main:app`` (:func:`tests.live.uvicorn_server`) with
``PIPEFLOW_AUTH_REQUIRED=true`` and one key in its ring, as docker-compose.yml runs the
replicas.  Checked: ``Client``/``AsyncClient`` with ``api_key=`` and with the environment
variable ``PIPEFLOW_API_KEY``, an explicit key beating the variable, no key at all a 401
``ServiceError``; the command line's ``--api-key`` and the variable, for a computation
(``run``) and a figure (``plot``); a refused key said so with a hint, and never echoed, nor
written to the server's log.
"""

from __future__ import annotations

import asyncio
import json
from collections.abc import Iterator
from pathlib import Path

import pytest

from pipeflow_cli.cli import main as cli_main
from pipeflow_client import API_KEY_ENV, AsyncClient, Client, ServiceError
from service.http.auth import new_key
from tests.live import uvicorn_server
from tests.service.conftest import SMALL

KEY, ENTRY = new_key("integrator")
#: a well-formed key the server does not know
STRANGER, _ = new_key("stranger")


@pytest.fixture(scope="module")
def live(tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[str, Path]]:
    """The base URL of a server that requires keys, and its log file."""
    tmp = tmp_path_factory.mktemp("client-auth")
    log = tmp / "uvicorn.log"
    env = {"PIPEFLOW_AUTH_REQUIRED": "true", "PIPEFLOW_API_KEYS": ENTRY}
    with uvicorn_server(tmp / "data", log, **env) as url:
        yield url, log


@pytest.fixture(autouse=True)
def _no_key_in_the_environment(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv(API_KEY_ENV, raising=False)


def _status(client: Client) -> int:
    """The status of one health-of-the-API request (a small simulation): 200 or the error's."""
    try:
        client.simulate(SMALL)
    except ServiceError as exc:
        return exc.status
    return 200


def test_the_client_sends_its_key(live: tuple[str, Path]) -> None:
    url, _ = live
    with Client(url) as c:
        with pytest.raises(ServiceError) as err:
            c.simulate(SMALL)
        assert err.value.status == 401 and err.value.field == "Authorization"
        assert not c.sends_api_key
    with Client(url, api_key=KEY) as c:
        r = c.simulate(SMALL)
        assert len(r.key) == 64
        assert c.result(r.key).key == r.key  # every call carries it, not only the first
        assert KEY not in repr(c) and KEY not in str(c.headers)  # not shown


def test_the_environment_gives_the_key_and_an_argument_beats_it(
    live: tuple[str, Path], monkeypatch: pytest.MonkeyPatch
) -> None:
    url, _ = live
    monkeypatch.setenv(API_KEY_ENV, KEY)
    with Client(url) as c:
        assert _status(c) == 200
    with Client(url, api_key=STRANGER) as c:  # explicit, wrong: the variable is not used
        assert _status(c) == 401
    with Client(url, api_key="") as c:  # explicitly none
        assert _status(c) == 401
    monkeypatch.setenv(API_KEY_ENV, STRANGER)
    with Client(url, api_key=KEY) as c:
        assert _status(c) == 200
    # a caller's own key header speaks for itself: the variable does not replace it
    with Client(url, headers={"X-API-Key": KEY}) as c:
        assert _status(c) == 200


def test_the_async_client_sends_its_key(
    live: tuple[str, Path], monkeypatch: pytest.MonkeyPatch
) -> None:
    url, _ = live

    async def run(api_key: str | None = None) -> int:
        async with AsyncClient(url, api_key=api_key) as c:
            try:
                await c.simulate(SMALL)
            except ServiceError as exc:
                return exc.status
            return 200

    assert asyncio.run(run()) == 401
    assert asyncio.run(run(api_key=KEY)) == 200
    monkeypatch.setenv(API_KEY_ENV, KEY)
    assert asyncio.run(run()) == 200
    assert asyncio.run(run(api_key=STRANGER)) == 401


def test_the_command_line_sends_its_key(
    live: tuple[str, Path],
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
) -> None:
    url, log = live
    spec = tmp_path / "spec.json"
    spec.write_text(json.dumps({**SMALL, "initial": {"u0": 0.0013}}))
    out = tmp_path / "r.json"

    # no key: the server's 401, and what to do about it
    assert cli_main(["run", str(spec), "--server", url, "-o", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "401" in err and "--api-key" in err and API_KEY_ENV in err

    # --api-key
    argv = ["run", str(spec), "--server", url, "-o", str(out), "--quiet"]
    assert cli_main([*argv, "--api-key", KEY]) == 0, capsys.readouterr().err
    assert len(json.loads(out.read_text())["key"]) == 64

    # an unknown key: refused, and not echoed
    assert cli_main([*argv, "--api-key", STRANGER]) == 2
    captured = capsys.readouterr()
    assert "401" in captured.err and STRANGER not in captured.out + captured.err

    # the environment variable; an explicit --api-key beats it
    monkeypatch.setenv(API_KEY_ENV, KEY)
    png = tmp_path / "tip.png"
    plot = ["plot", str(spec), "--server", url, "--out", str(png), "--quiet"]
    assert cli_main(plot) == 0, capsys.readouterr().err
    assert png.read_bytes().startswith(b"\x89PNG")
    assert cli_main([*plot, "--api-key", STRANGER]) == 2
    monkeypatch.setenv(API_KEY_ENV, STRANGER)
    assert cli_main([*argv, "--api-key", KEY]) == 0

    # a key without a server is a usage error (nothing would use it)
    with pytest.raises(SystemExit) as usage:
        cli_main(["run", str(spec), "--api-key", KEY])
    assert usage.value.code == 2
    assert KEY not in capsys.readouterr().err

    text = log.read_text()
    assert KEY not in text and STRANGER not in text  # the server logs key ids only
    principals = {
        rec.get("principal")
        for rec in _records(text)
        if rec.get("message") == "request" and rec.get("path") == "/v1/simulations"
    }
    assert "integrator" in principals


def _records(text: str) -> list[dict[str, object]]:
    """The JSON log records of ``text`` (other lines skipped)."""
    out = []
    for line in text.splitlines():
        try:
            record = json.loads(line)
        except ValueError:
            continue
        if isinstance(record, dict):
            out.append(record)
    return out
