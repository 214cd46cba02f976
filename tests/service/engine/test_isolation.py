"""One job's runtime limit costs no other job anything (issue 22, defect 3).

A fanned-out job secedes from its worker's thread while its pieces run, so another job's
task may start in the same process.  Before the fix the parent waited for its pieces
without looking at the clock, and past its limit the watchdog killed the whole process,
the other job with it.  Now the parent stops waiting at its limit (its pieces are
cancelled), and the watchdog of a silent computation kills its process only once no other
job's task runs there.
"""

from __future__ import annotations

import os
import signal
import time
from dataclasses import dataclass
from pathlib import Path
from types import SimpleNamespace

import pytest

from service.engine.task import TaskConfig, _Heartbeat
from service.keys import keyed
from service.orchestration import submit_job
from service.store import Store
from tests.service.conftest import TERMINAL, make_client, wait_job, wait_ready
from tests.service.engine.fan_kinds import FAN, FanSpec

#: runtime limit of the shared-worker test [s]: the innocent job (5 s) starts 2 s after
#: the fanned-out one, so it is still running when that one's limit (+ 0.6 s grace) passes
LIMIT_S = 6.0
GRACE_S = 0.6  # max(watchdog_grace_s, 0.1 x limit): when the old watchdog killed


@pytest.mark.slow  # a 2-worker cluster, jobs overrunning a 6 s limit: 15-45 s
def test_an_overrunning_fan_out_spares_the_job_sharing_its_worker(tmp_path: Path) -> None:
    """Job A fans out 2 pieces: one in A's own process returns at once, the other sleeps
    12 s silently on the other worker.  Job B (5 s, reporting) then starts in the thread
    A's parent freed.  A fails with the runtime-limit problem at its limit, not when its
    slow piece ends, and B, in the same worker process, succeeds in its first attempt
    (before the fix: A's watchdog killed that process at limit + grace, B's attempt with
    it: B needed attempts = 2).

    Where the scheduler puts the pieces and B is its choice, and a loaded machine delays
    B's start: when the run did not make the scenario (B computing in A's process across
    the moment the old watchdog killed), the pair is tried again, up to 3 times, and the
    test is skipped (not passed) with the reason if the scenario never arose: at load
    average 40-50 the scheduler queued B behind A's slow piece on the other worker in all
    3 tries (2 Dec 2026); at load 12 it put B in A's process at the first."""
    with make_client(
        tmp_path, workers=2, queue_size=4, job_timeout_s=LIMIT_S, progress_interval_s=0.05
    ) as c:
        wait_ready(c)
        runner, store = c.app.state.runner, c.app.state.store  # type: ignore[attr-defined]
        runner.watchdog_grace_s = 0.5
        for attempt in range(3):
            fan = keyed(FAN, FanSpec(far_s=2 * LIMIT_S, tag=f"{tmp_path}-{attempt}"))
            c.portal.call(submit_job, runner, store, fan, False)
            wait_job(c, fan.key, lambda j: j["progress"] > 0 or j["status"] in TERMINAL)
            started = store.get_job(fan.key).started
            time.sleep(max(0.0, started + 2.0 - time.time()))
            spec = {"seconds": 5, "tag": f"innocent-{attempt}"}
            b_key = c.post("/test/sleep-jobs", json=spec).json()["key"]
            wait_job(c, b_key, lambda j: j["progress"] > 0 or j["status"] in TERMINAL)
            b_worker = store.get_job(b_key).worker
            a, b = wait_job(c, fan.key), wait_job(c, b_key, timeout=120)
            a_rec, b_rec = store.get_job(fan.key), store.get_job(b_key)
            kill_at = a_rec.started + LIMIT_S + GRACE_S
            if b_worker == a_rec.worker and b_rec.started < kill_at < b_rec.finished:
                break  # the scenario: B computed in A's process when the old watchdog killed
            time.sleep(LIMIT_S)  # A's slow piece ends
        else:
            pytest.skip("the scheduler never put B in A's process across A's limit (3 tries)")

        assert b["status"] == "succeeded" and b["attempts"] == 1, b
        assert b["last_retry_reason"] is None
        assert a["status"] == "failed" and a["error"]["type"].endswith("/runtime-limit"), a
        # ended at its limit (+ one 50 ms tick, a store write), before its 12 s piece
        assert a_rec.finished - a_rec.started < LIMIT_S + 1.5


@dataclass(frozen=True)
class _Task:
    key: str


class _Worker:
    """The part of a Dask worker the watchdog reads: the keys executing in its process."""

    def __init__(self, own: str) -> None:
        self.own = own
        self.state = SimpleNamespace(executing=set(), long_running=set())

    def get_current_task(self) -> str:
        return self.own

    def run(self, *keys: str) -> None:
        self.state.executing = {_Task(k) for k in keys}


def test_the_watchdog_kills_its_process_only_when_no_other_job_runs_there(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The watchdog of a silent computation (real store; the worker's task table and
    ``os.kill`` are the seams): past the limit it fails its job at once; while another
    job's task executes in the process it does not kill it, and kills it once only its own
    task (and its pieces) remain."""
    store = Store(tmp_path / "db.sqlite3", cache_max_bytes=10_000, memory_cache_bytes=0)
    store.enqueue_job("k", "test-sleep", {"seconds": 60})
    assert store.claim("k", "me", "w1", 10.0).outcome == "claimed"
    cfg = TaskConfig(str(tmp_path), 0, 1.0, 0.05, 10.0, 0.5)
    worker = _Worker(own="test-sleep-k-g1-a0")
    beat = _Heartbeat(store, "k", "me", cfg, worker=worker)
    beat.host = SimpleNamespace(keys={"pipeflow-piece-f-t-0"})  # type: ignore[assignment]
    kills: list[tuple[int, int]] = []
    monkeypatch.setattr(os, "kill", lambda pid, sig: kills.append((pid, sig)))

    worker.run("test-sleep-k-g1-a0", "test-sleep-other-g1-a0", "pipeflow-piece-f-t-0")
    beat._kill_overdue()
    job = store.get_job("k")
    assert job is not None and job.status == "failed"
    assert job.error is not None and job.error["data"]["killed"] is True
    assert beat.stop == "runtime limit" and kills == []
    beat._kill_overdue()  # the next interval: the other job still runs
    assert kills == []

    worker.run("test-sleep-k-g1-a0", "pipeflow-piece-f-t-0")  # only its own remain
    beat._kill_overdue()
    assert kills == [(os.getpid(), signal.SIGKILL)]
