"""The fast lane's metered runs at the task seam (:func:`service.engine.runner._run_in_lane`
with the real store): a time-variant simulation whose next magnus propagation would pass
the lane's allowance stops before computing it, gives its lease back with the reason and
leaves the record active for a worker, which computes it once.  The real server's side
(admission, hand-off to a Dask worker, a SIGKILL) is in ``test_lane_metered_server.py``."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from pipeflow.computations.registry import COMPUTATIONS, metered_run_time_simulation
from service.engine.runner import _run_in_lane
from service.engine.task import Accept, TaskConfig, run_job
from service.keys import keyed
from service.store import Claim, StorageError, Store
from tests.service.conftest import SMALL

SIMULATION = COMPUTATIONS["simulation"]


def _cfg(store: Store) -> TaskConfig:
    return TaskConfig(
        db_url=store.url,
        cache_max_bytes=store.cache_max_bytes,
        timeout_s=30.0,
        progress_interval_s=0.05,
        stale_after_s=10.0,
        grace_s=5.0,
    )


def test_which_simulations_are_metered() -> None:
    """Time-variant ``auto``/``magnus`` runs without loads meter their propagations; the
    estimate of the rest is the output work plus two eigenvalue stacks; other solvers and
    forced runs are not metered (their cost is not charged as it is planned)."""
    request = SIMULATION.request
    paper = request.model_validate({**SMALL, "modes": 10, "time": {"t_end": 1, "samples": 2001}})
    rest = metered_run_time_simulation(paper)
    # 2 ms + 1e-8 x (2001 + 201) x 10^2 + 2 x 201 x (5 us + 5 ns x 20^3) = 22.3 ms
    assert rest is not None and abs(rest - 0.022292) < 1e-9
    assert metered_run_time_simulation(request.model_validate({**SMALL, "method": "magnus"}))
    for other in ({"method": "rk4"}, {"method": "cma"}, {"method": "reference"}):
        assert metered_run_time_simulation(request.model_validate({**SMALL, **other})) is None
    forced = {
        **SMALL,
        "loads": [
            {"kind": "point_force", "position": 0.025, "force": {"kind": "constant", "value": 1e-3}}
        ],
    }
    assert metered_run_time_simulation(request.model_validate(forced)) is None


def test_a_metered_run_over_its_allowance_gives_its_lease_back_for_a_worker(
    tmp_path: Path,
) -> None:
    store = Store(tmp_path / "db.sqlite3", cache_max_bytes=10**7, memory_cache_bytes=0)
    job = keyed(SIMULATION, SIMULATION.request.model_validate(SMALL))
    got: list[Claim | StorageError] = []
    accept = Accept(job.canonical, False, got.append)
    # the lane's first attempt writes the record leased to itself, then the allowance
    # (1 ns) refuses the first propagation
    args: tuple[Any, ...] = (SIMULATION, job.request, job.key, _cfg(store), None, store)
    outcome = _run_in_lane(1e-9, *args, accept)
    assert outcome.status == "handoff" and not outcome.finished and outcome.body is None
    assert outcome.note is not None and "would pass the allowance of 1e-06 ms" in outcome.note
    assert len(got) == 1 and isinstance(got[0], Claim) and got[0].outcome == "claimed"
    record = store.get_job(job.key)
    assert record is not None
    # active, unowned, the lane's attempt given back (a hand-off must not use up one of
    # the starts a dying worker may take: MAX_ATTEMPTS), the reason on the record; nothing
    # stored
    assert (record.status, record.owner, record.attempts) == ("running", None, 0)
    assert (record.last_retry_reason or "").startswith(
        "handed off to a worker by the fast lane: a magnus propagation of"
    )
    assert not store.has_result(job.key)

    # the worker's attempt (no allowance) takes the record over and computes it once
    outcome = run_job(*args)
    assert outcome.status == "succeeded" and outcome.finished
    record = store.get_job(job.key)
    assert record is not None and (record.status, record.attempts) == ("succeeded", 1)
    body = store.get_result(job.key)
    assert body is not None
    # the same computation in this process: the same numbers to the last bit
    direct = SIMULATION.execute(job.request)
    assert np.array_equal(
        json.loads(body)["tip_displacement"], np.asarray(direct["tip_displacement"])
    )


def test_a_metered_run_within_its_allowance_finishes_in_the_lane(tmp_path: Path) -> None:
    store = Store(tmp_path / "db.sqlite3", cache_max_bytes=10**7, memory_cache_bytes=0)
    job = keyed(SIMULATION, SIMULATION.request.model_validate(SMALL))
    accept = Accept(job.canonical, False, lambda claim: None)
    outcome = _run_in_lane(1.0, SIMULATION, job.request, job.key, _cfg(store), None, store, accept)
    assert outcome.status == "succeeded" and outcome.finished and outcome.body is not None
    record = store.get_job(job.key)
    assert record is not None and (record.status, record.attempts) == ("succeeded", 1)
