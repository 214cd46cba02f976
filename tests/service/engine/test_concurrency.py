"""Single flight: 20 concurrent identical requests compute once and all get the answer."""

from __future__ import annotations

import asyncio
from pathlib import Path

import httpx

from service.main import create_app
from service.settings import Settings
from tests.service.conftest import SMALL


def test_twenty_identical_requests_compute_once(tmp_path: Path) -> None:
    app = create_app(Settings(data_dir=tmp_path, workers=2, queue_size=2))
    body = {**SMALL, "time": {"t_end": 0.5, "samples": 151}}

    async def scenario() -> None:
        async with app.router.lifespan_context(app):
            runner = app.state.runner
            transport = httpx.ASGITransport(app=app)
            async with httpx.AsyncClient(transport=transport, base_url="http://test") as client:
                responses = await asyncio.gather(
                    *(client.post("/v1/simulations", json=body) for _ in range(20))
                )
                assert [r.status_code for r in responses] == [200] * 20
                assert runner.computations == 1
                docs = [r.json() for r in responses]
                assert len({d["key"] for d in docs}) == 1
                assert all(d["tip_displacement"] == docs[0]["tip_displacement"] for d in docs)
                # 20 requests shared one slot: capacity (4) was never exceeded
                assert sum(r.headers["x-cache"] == "MISS" for r in responses) >= 1
                hit = await client.post("/v1/simulations", json=body)
                assert hit.headers["x-cache"] == "HIT" and runner.computations == 1

    asyncio.run(scenario())
