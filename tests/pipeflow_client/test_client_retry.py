"""pipeflow_client against a real uvicorn server: the async client, and retries of 503
honouring Retry-After.

The server runs as deployed (``uvicorn service.main:app`` in a subprocess, see
:mod:`tests.live`) with one worker and no queue (``PIPEFLOW_QUEUE_SIZE=0``), so one long
job takes the only computation slot and every other computation is answered 503 with
``Retry-After: 1`` by the server itself: no mocks anywhere in the proving tests.
"""

from __future__ import annotations

import asyncio
import io
import itertools
import threading
import time
from collections.abc import Iterator
from datetime import UTC, datetime
from typing import Any

import httpx
import numpy as np
import pytest

from pipeflow.schema.simulation import PAPER_EXAMPLE
from pipeflow_client import AsyncClient, Client, RetryPolicy, ServiceError, SimulationResult
from pipeflow_client.client import retry_after_seconds
from tests.live import uvicorn_server
from tests.service.conftest import SMALL

#: slow (CI's second step): a server of its own kept saturated: ~13 s
pytestmark = pytest.mark.slow


def _blocker(tag: float) -> dict[str, Any]:
    """Seconds of RK4 (10 modes, 15 s simulated): holds the only slot until cancelled;
    ``tag`` [s] makes distinct keys."""
    return {
        "pipe": PAPER_EXAMPLE["pipe"],
        "modes": 10,
        "method": "rk4",
        "time": {"t_end": 15.0 + tag, "samples": 101},
    }


@pytest.fixture(scope="module")
def url(tmp_path_factory: pytest.TempPathFactory) -> Iterator[str]:
    tmp = tmp_path_factory.mktemp("retry")
    with uvicorn_server(
        tmp / "data",
        tmp / "uvicorn.log",
        PIPEFLOW_QUEUE_SIZE="0",
        PIPEFLOW_RETRY_AFTER_S="1",
        PIPEFLOW_PROGRESS_INTERVAL_S="0.05",
    ) as base:
        yield base


def _occupy(url: str, tag: float) -> str:
    """Submit a blocker job and wait until the server refuses other work with 503."""
    r = httpx.post(f"{url}/v1/jobs", json=_blocker(tag), timeout=30)
    assert r.status_code == 202, r.text
    return str(r.json()["key"])


def _release(url: str, key: str) -> None:
    r = httpx.delete(f"{url}/v1/jobs/{key}", timeout=30)
    assert r.status_code == 200, r.text


def test_retry_after_header_forms() -> None:
    """RFC 9110 section 10.2.3: delay-seconds or an HTTP date."""
    now = datetime(2026, 1, 1, 12, 0, 0, tzinfo=UTC)
    assert retry_after_seconds("3") == 3.0
    assert retry_after_seconds("Thu, 01 Jan 2026 12:00:07 GMT", now) == 7.0
    assert retry_after_seconds("Thu, 01 Jan 2026 11:00:00 GMT", now) == 0.0  # in the past
    assert retry_after_seconds("soon") is None and retry_after_seconds(None) is None


def test_sync_client_retries_503_honouring_retry_after(url: str) -> None:
    key = _occupy(url, 0.0)
    # the server itself says it is full: 503 with Retry-After, as a problem document
    busy = httpx.post(f"{url}/v1/simulations", json=SMALL, timeout=30)
    assert busy.status_code == 503, busy.text
    assert busy.headers["retry-after"] == "1"
    assert busy.headers["content-type"] == "application/problem+json"

    with Client(url, retry=RetryPolicy(attempts=1)) as once, pytest.raises(ServiceError) as err:
        once.simulate(SMALL)
    assert err.value.status == 503 and err.value.retry_after == 1.0

    waits: list[float] = []
    stamps: list[float] = []

    def on_retry(error: ServiceError, wait: float) -> None:
        assert error.status == 503
        waits.append(wait)
        stamps.append(time.monotonic())
        if len(waits) == 2:  # free the slot while the client is waiting
            threading.Thread(target=_release, args=(url, key)).start()

    with Client(url, retry=RetryPolicy(attempts=60, on_retry=on_retry)) as client:
        result = client.simulate(SMALL)
    assert isinstance(result, SimulationResult) and result.status == "ok"
    assert len(waits) >= 2
    assert all(w == 1.0 for w in waits)  # exactly what Retry-After said
    # and the client did wait that long between attempts (a lower bound: cannot flake)
    assert all(b - a >= 0.99 for a, b in itertools.pairwise(stamps))


def test_async_client_retries_and_runs_every_kind_of_call(url: str) -> None:
    async def scenario() -> None:
        key = _occupy(url, 0.5)
        waits: list[float] = []

        def on_retry(error: ServiceError, wait: float) -> None:
            waits.append(wait)
            if len(waits) == 1:
                threading.Thread(target=_release, args=(url, key)).start()

        policy = RetryPolicy(attempts=60, on_retry=on_retry)
        async with AsyncClient(url, retry=policy) as client:
            spec = dict(SMALL, initial={"u0": 0.002})
            r = await client.simulate(spec)
            assert waits and all(w == 1.0 for w in waits)
            assert r.status == "ok" and r.t.shape == (101,)
            assert r.tip_displacement[0] == pytest.approx(2 * 2.7244e-3, rel=1e-3)  # [m]

            # concurrent awaits on one AsyncClient: cached now, both answered
            again, health = await asyncio.gather(client.simulate(spec), client.health())
            assert again.cached and again.key == r.key and health["status"] == "ok"
            np.testing.assert_array_equal(again.tip_displacement, r.tip_displacement)

            seen: list[float] = []
            job = await client.submit(dict(SMALL, time={"t_end": 0.3, "samples": 61}))
            waited = await client.wait(job["key"], progress=seen.append, poll=0.02, timeout=120)
            assert waited.t.size == 61 and seen[-1] == 1.0

            csv = await client.result_csv(r.key, "eigenvalues")
            assert csv.startswith("t [s],sigma_1 [1/s],omega_1 [rad/s]")
            assert (await client.plot(r.key, "damping")).startswith(b"\x89PNG")
            pq = pytest.importorskip("pyarrow.parquet")
            table = pq.read_table(io.BytesIO(await client.result_parquet(r.key)))
            assert table.column("tip_displacement").to_pylist() == r.raw["tip_displacement"]

            bad = dict(SMALL, modes=0)
            with pytest.raises(ServiceError) as err:
                await client.simulate(bad)
            assert err.value.status == 422 and err.value.field == "modes"

    asyncio.run(scenario())


def test_client_result_offers_the_notebook_views(url: str) -> None:
    """The client's result gives the same DataFrame and Dataset as the library's functions
    on the same JSON (one implementation: pipeflow.io.notebook)."""
    pytest.importorskip("xarray")
    from pipeflow.io.notebook import to_dataframe

    with Client(url) as client:
        r = client.simulate(dict(SMALL, output={"mode_shapes": {"times": [0.1], "points": 11}}))
    frame = r.to_dataframe("eigenvalues")
    assert frame.equals(to_dataframe(r.raw, "eigenvalues"))
    assert frame.attrs["units"]["omega_1"] == "rad/s"
    ds = r.to_xarray()
    np.testing.assert_array_equal(ds["omega"].values, r.omega)
    assert ds["tip_displacement"].attrs["units"] == "m" and ds.attrs["key"] == r.key
    assert ds["mode_shape"].shape == (1, 3, 11)
    assert r.plot("mode_shapes").axes[0].get_xlabel() == "position along the pipe x [m]"
