"""The service with fast fake numerics, for fuzzing the contract (``test_schemathesis.py``).

``uvicorn --factory tests.service.fuzz_app:create_fuzz_app`` serves the real app (routes,
validation, problems, negotiation, store, job records, single flight, cancellation) with
one change made through the app's dependency seam: ``get_runner`` answers a
:class:`FakeRunner`, whose computations return a real result of the same kind computed
once at start-up on a tiny case, instead of running the request's numerics.  So every
response still has the shape of its response model, and a fuzzed request for 40 modes and
200001 samples costs microseconds.
"""

from __future__ import annotations

import asyncio
import json
import os
import tempfile
from collections.abc import AsyncIterator, Awaitable
from contextlib import asynccontextmanager

from fastapi import FastAPI, Request

from pipeflow.computations.registry import COMPUTATIONS
from service import deps
from service.engine import Flight, Runner
from service.engine.task import Outcome
from service.main import create_app
from service.settings import Settings
from service.store import Job, Store
from tests.pipeflow.cases import TINY, tiny_request


def tiny_results() -> dict[str, bytes]:
    """The JSON bytes of each computation's tiny case (the fake's answers)."""
    out = {}
    for name in TINY:
        result = COMPUTATIONS[name].execute(tiny_request(name))
        out[name] = json.dumps(result, allow_nan=False).encode()
    return out


class FakeRunner(Runner):
    """The real engine with its Dask tasks replaced by a table of results: the fake task
    stores the result of its computation's kind and finishes the job record, as the real
    task does."""

    def __init__(self, settings: Settings, store: Store, results: dict[str, bytes]) -> None:
        super().__init__(settings, store)
        self.results = results
        self.ready = True
        self._connected.set()  # no cluster to connect to

    def _execute(self, flight: Flight, job: Job) -> Awaitable[Outcome]:
        name = flight.job.computation.name

        def task() -> Outcome:
            self.store.put_result(job.key, name, self.results[name])
            self.store.finish_job(job.key, "succeeded")
            return Outcome("succeeded", seconds=0.0)

        return asyncio.ensure_future(asyncio.to_thread(task))


def create_fuzz_app() -> FastAPI:
    """The service over a fresh data directory, numerics faked (see the module docstring)."""
    data_dir = os.environ.get("PIPEFLOW_DATA_DIR") or tempfile.mkdtemp(prefix="pipeflow-fuzz-")
    # no fast lane: it runs the real computation before the faked `_execute` would see it
    # long polls held 0.2 s at most: the fuzzer asks for waits of up to 60 s on jobs that stay
    # queued here (held for the whole wait they tripled the fuzz's time, 126 -> 351 s)
    settings = Settings(
        data_dir=data_dir, workers=1, queue_size=64, fast_lane_threads=0, max_job_wait_s=0.2
    )
    app = create_app(settings)
    results = tiny_results()
    real_lifespan = app.router.lifespan_context

    @asynccontextmanager
    async def lifespan(app: FastAPI) -> AsyncIterator[None]:
        async with real_lifespan(app):
            app.state.fake_runner = FakeRunner(settings, app.state.store, results)
            yield

    app.router.lifespan_context = lifespan

    def fake_runner(request: Request) -> Runner:
        runner: Runner = request.app.state.fake_runner
        return runner

    app.dependency_overrides[deps.get_runner] = fake_runner
    return app
