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

import json
import os
import tempfile
from collections.abc import AsyncIterator
from contextlib import asynccontextmanager
from typing import Any

from fastapi import FastAPI, Request

from pipeflow.model import PAPER_PIPE
from pipeflow.schema.registry import COMPUTATIONS
from service import deps, worker
from service.keys import Keyed
from service.main import create_app
from service.runner import Runner
from service.settings import Settings
from service.store import Store

PIPE = {k: getattr(PAPER_PIPE, k) for k in ("E", "I", "L", "M1", "M2")}
#: a tiny real request of every computation
TINY: dict[str, dict[str, Any]] = {
    "simulation": {"pipe": PIPE, "modes": 2, "time": {"t_end": 0.01, "samples": 11}},
    "compare": {
        "simulation": {"pipe": PIPE, "modes": 2, "time": {"t_end": 0.01, "samples": 11}},
        "methods": ["cma", "rk4"],
    },
    "stability": {"pipe": PIPE, "modes": 3, "velocity_range": [0.0, 40.0], "points": 11},
    "argand": {"pipe": PIPE, "modes": 3, "tracked_modes": 2, "points": 5}
    | {"velocity_range": [0.0, 40.0]},
    "campbell": {"pipe": PIPE, "modes": 3, "tracked_modes": 2, "points": 5}
    | {"spin_range": [0.0, 1000.0]},
    "spin_map": {"pipe": PIPE, "modes": 3, "velocity_points": 5, "spin_points": 2}
    | {"velocity_range": [0.0, 60.0], "spin_range": [0.0, 1000.0]},
    "beta_map": {"modes": 3, "beta_points": 2, "u_points": 11},
    "resonance_chart": {"pipe": PIPE, "modes": 2, "mean_velocity": 10.0}
    | {"amplitude_range": [0.0, 5.0], "frequency_range": [500.0, 1500.0]}
    | {"amplitude_points": 2, "frequency_points": 2},
    "floquet": {"pipe": PIPE, "modes": 2}
    | {"flow": {"velocity": {"kind": "harmonic", "mean": 10.0, "amplitude": 5.0}}},
}
TINY["floquet"]["flow"]["velocity"]["frequency"] = 1000.0


def tiny_results() -> dict[str, bytes]:
    """The JSON bytes of each computation's tiny case (the fake's answers)."""
    out = {}
    for name, body in TINY.items():
        c = COMPUTATIONS[name]
        request = c.request.model_validate(
            {"kind": name, **body} if "kind" in c.request.model_fields else body
        )
        out[name] = json.dumps(c.execute(request), allow_nan=False).encode()
    return out


class FakeRunner(Runner):
    """The real runner with its worker processes replaced by a table of results."""

    def __init__(self, settings: Settings, store: Store, results: dict[str, bytes]) -> None:
        super().__init__(settings, store)
        self.results = results
        self.ready = True

    async def _execute(self, job: Keyed) -> worker.Outcome:
        self.computations += 1
        return ("ok", self.results[job.computation.name])


def create_fuzz_app() -> FastAPI:
    """The service over a fresh data directory, numerics faked (see the module docstring)."""
    data_dir = os.environ.get("PIPEFLOW_DATA_DIR") or tempfile.mkdtemp(prefix="pipeflow-fuzz-")
    settings = Settings(data_dir=data_dir, workers=1, queue_size=64)
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
