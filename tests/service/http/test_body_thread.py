"""Request bodies are validated and keyed off the event loop (issue 34, item 2), with the
answers FastAPI gave when it validated them on the loop.

The app is real (its Dask worker and store); the probe is the validation's own code: the
unit conversion of a quantity (:func:`pipeflow.schema.units.to_si`) and the hash of the
key (:func:`service.keys.canonical_key`) record whether an event loop runs in the thread
that calls them.
"""

from __future__ import annotations

import asyncio
import copy
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from fastapi.testclient import TestClient

from pipeflow.schema import units
from service import keys
from tests.service.conftest import SMALL, make_client, wait_ready


def _on_loop() -> bool:
    try:
        asyncio.get_running_loop()
    except RuntimeError:
        return False
    return True


@pytest.fixture(scope="module")
def app(tmp_path_factory: pytest.TempPathFactory) -> Iterator[TestClient]:
    with make_client(tmp_path_factory.mktemp("body-thread"), workers=1) as c:
        wait_ready(c)
        yield c


@pytest.fixture
def threads(monkeypatch: pytest.MonkeyPatch) -> dict[str, list[bool]]:
    """Whether each call of the unit conversion and of the key hash ran on a loop."""
    seen: dict[str, list[bool]] = {"to_si": [], "canonical_key": []}
    to_si, canonical_key = units.to_si, keys.canonical_key

    def recording_to_si(*args: Any) -> Any:
        seen["to_si"].append(_on_loop())
        return to_si(*args)

    def recording_key(*args: Any) -> Any:
        seen["canonical_key"].append(_on_loop())
        return canonical_key(*args)

    monkeypatch.setattr(units, "to_si", recording_to_si)
    monkeypatch.setattr(keys, "canonical_key", recording_key)
    return seen


def _with_length(unit: str, tag: float) -> dict[str, Any]:
    body = copy.deepcopy(SMALL)
    body["pipe"]["L"] = {"value": 25, "unit": unit}
    body["initial"] = {"u0": tag}  # a key of its own: not memoised by an earlier test
    return body


def test_a_valid_body_is_validated_and_keyed_in_a_worker_thread(
    app: TestClient, threads: dict[str, list[bool]], tmp_path: Path
) -> None:
    resp = app.post("/v1/simulations/jobs", json=_with_length("mm", 0.0011))
    assert resp.status_code == 202, resp.text
    assert threads["to_si"] == [False]
    assert threads["canonical_key"] == [False]
    assert resp.json()["key"] == app.post("/v1/jobs", json=_with_length("mm", 0.0011)).json()["key"]


def test_an_invalid_body_is_validated_in_a_worker_thread_with_fastapis_errors(
    app: TestClient, threads: dict[str, list[bool]]
) -> None:
    """The 422 holds the query parameter's error and the body's, in FastAPI's order."""
    resp = app.post("/v1/simulations?refresh=maybe", json=_with_length("bogon", 0.0012))
    assert resp.status_code == 422, resp.text
    assert threads["to_si"] == [False] and threads["canonical_key"] == []
    fields = [(e["location"], e["field"]) for e in resp.json()["errors"]]
    assert fields == [("query", "refresh"), ("body", "pipe.L.unit")]
    # a union told apart by kind: the fields are named in the body, without the tag
    sweep = app.post("/v1/sweeps", json={"kind": "campbell", "pipe": 1})
    assert [e["field"] for e in sweep.json()["errors"]] == ["pipe", "spin_range"]


def test_negotiation_comes_before_the_body_as_before(app: TestClient) -> None:
    """406 and 415 are answered before the body's errors (FastAPI's dependencies first);
    a body that is not JSON is a 400 with its byte offset, and an empty body a 422."""
    bad = _with_length("bogon", 0.0013)
    assert app.post("/v1/simulations", json=bad, headers={"accept": "text/csv"}).status_code == 406
    text = app.post("/v1/simulations", content=b"{}", headers={"content-type": "text/plain"})
    assert text.status_code == 415
    broken = app.post(
        "/v1/simulations", content=b'{"pipe": ', headers={"content-type": "application/json"}
    )
    assert broken.status_code == 400 and broken.json()["errors"][0]["offset"] == 9
    empty = app.post("/v1/simulations", content=b"", headers={"content-type": "application/json"})
    assert empty.status_code == 422 and empty.json()["errors"][0]["type"] == "missing"
