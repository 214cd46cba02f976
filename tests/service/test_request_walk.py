"""One request's walk from the HTTP body to the numerical model: validated once, keyed once.

The service runs the real route, key, engine, job record and task function; only the
Dask cluster is replaced by a thread (``InProcessRunner``), so that one profiler sees the
whole walk.  The request model's validators are counted by the code objects they run
(pydantic calls them on every validation, whoever validates), the normal form by
``canonical`` and the arrival at the numerics by :func:`pipeflow.model.build_model`.
"""

from __future__ import annotations

import asyncio
import threading
import traceback
from collections import Counter
from pathlib import Path
from typing import Any

import httpx
import pytest

from pipeflow import model as model_module
from pipeflow import simulation as simulation_module
from pipeflow.model import Pipe
from pipeflow.schema import simulation as schema
from service.engine import Flight, Runner
from service.engine.task import run_job
from service.main import create_app
from service.settings import Settings
from tests.service.conftest import SMALL

ROOT = Path(__file__).resolve().parents[2]


def package_files(stack: list[traceback.FrameSummary]) -> list[str]:
    """The files of ``pipeflow`` and ``service`` on ``stack`` (outermost first), each
    consecutive run of frames in one file once: a change of file is a hop of the walk."""
    out: list[str] = []
    for frame in stack:
        path = Path(frame.filename).resolve()
        if not any(path.is_relative_to(ROOT / p) for p in ("pipeflow", "service")):
            continue
        name = str(path.relative_to(ROOT))
        if not out or out[-1] != name:
            out.append(name)
    return out


class InProcessRunner(Runner):
    """The engine with its Dask cluster replaced by a thread running the task function."""

    def __init__(self, settings: Settings, store: Any) -> None:
        super().__init__(settings, store)
        self._connected.set()  # no cluster to connect to
        #: the files on the stack where the engine hands the job to its cluster
        self.submitted_from: list[str] = []

    def _execute(self, flight: Flight, job: Any) -> Any:
        if not self.submitted_from:
            self.submitted_from = package_files(traceback.extract_stack()[:-1])
        return asyncio.ensure_future(
            asyncio.to_thread(
                run_job, flight.job.computation, flight.job.request, job.key, self._config()
            )
        )


def test_body_to_pipe_model_validates_once(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    watched = {
        schema.SimulationSpec._consistent.__code__: "SimulationSpec",
        schema.PipeSpec._mass.__code__: "PipeSpec",
    }
    calls: Counter[str] = Counter()

    def profile(frame: Any, event: str, arg: Any) -> None:
        if event == "call" and frame.f_code in watched:
            calls[watched[frame.f_code]] += 1

    canonical = schema.SimulationSpec.canonical
    built: list[tuple[Pipe, int]] = []
    build_model = model_module.build_model

    def counting_canonical(self: schema.SimulationSpec) -> dict[str, Any]:
        calls["canonical"] += 1
        return canonical(self)

    model_reached_from: list[str] = []

    def recording_build_model(pipe: Pipe, modes: int, *args: Any, **kw: Any) -> Any:
        if not built:
            model_reached_from.extend(package_files(traceback.extract_stack()[:-1]))
        built.append((pipe, modes))
        calls[f"validations before the model #{len(built)}"] = calls["SimulationSpec"]
        return build_model(pipe, modes, *args, **kw)

    monkeypatch.setattr(schema.SimulationSpec, "canonical", counting_canonical)
    monkeypatch.setattr(simulation_module, "build_model", recording_build_model)
    body = {**SMALL, "modes": 2, "time": {"t_end": 0.05, "samples": 21}}
    # no fast lane: its warm-up validates and runs requests of its own in this process
    app: Any = create_app(Settings(data_dir=tmp_path, workers=1, fast_lane_threads=0))

    runners: list[InProcessRunner] = []

    async def walk() -> httpx.Response:
        # one thread for the app (so the profiler sees it); the worker thread starts later
        async with app.router.lifespan_context(app):
            app.state.runner = InProcessRunner(app.state.settings, app.state.store)
            runners.append(app.state.runner)
            app.state.runner.ready = True
            transport = httpx.ASGITransport(app=app)
            async with httpx.AsyncClient(transport=transport, base_url="http://walk") as c:
                return await c.post("/v1/simulations", json=body)

    # a thread of its own (with its own event loop: another test may have left one running
    # in this thread), started after the profiler is installed for new threads
    out: list[httpx.Response] = []
    threading.setprofile(profile)
    try:
        thread = threading.Thread(target=lambda: out.append(asyncio.run(walk())))
        thread.start()
        thread.join(timeout=120)
    finally:
        threading.setprofile(None)  # type: ignore[arg-type]
    assert out, "the walk did not finish"
    resp = out[0]
    assert resp.status_code == 200, resp.text
    assert resp.headers["x-cache"] == "MISS"
    # validated once (the route), normalised once (the key), and the pipe reached the model
    assert calls["SimulationSpec"] == 1, calls
    assert calls["PipeSpec"] == 1, calls
    assert calls["canonical"] == 1, calls
    assert built and built[0] == (Pipe(**body["pipe"]), 2)
    assert calls["validations before the model #1"] == 1
    # the walk's engine and worker parts, file by file (issue 33: "the walks shorter"; the
    # part below the registry is tests/pipeflow/schema/test_walk.py's).  The engine's task
    # (Flights.start in service/engine/flight.py) starts the driver, which hands the flight
    # back to the runner's submit callback:
    assert runners[0].submitted_from == ["service/engine/drive.py", "service/engine/runner.py"]
    # the worker's task function (the cluster's submit, Dask, in the real engine) hands the
    # validated request to the registry, which runs the library:
    assert model_reached_from == [
        "service/engine/task.py",  # run_job, _run_job, _compute
        "pipeflow/computations/registry.py",  # Computation.execute
        "pipeflow/computations/simulation.py",  # run_simulation, simulate_spec
        "pipeflow/simulation.py",  # simulate
    ]
