"""Real processes for the service's fault and topology tests: uvicorn servers on free
ports, process groups killed by signal, polling a job over HTTP."""

from __future__ import annotations

import os
import signal
import subprocess
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import httpx

from service.launch import ROOT, answers, child_environment, serve
from service.settings import Settings
from service.store import Job, Store

TERMINAL = ("succeeded", "failed", "cancelled")
#: heartbeat every 0.1 s, a lease without one for 2 s is dead: a recovery takes seconds
FAST_RECOVERY = {"PIPEFLOW_PROGRESS_INTERVAL_S": "0.1", "PIPEFLOW_STALE_AFTER_S": "2"}


def spawn(args: list[str], log: Path, **overrides: str) -> subprocess.Popen[bytes]:
    """Start ``args`` in its own process group, output to ``log``."""
    with open(log, "ab") as out:
        return subprocess.Popen(
            args,
            cwd=ROOT,
            env=child_environment(**overrides),
            stdout=out,
            stderr=subprocess.STDOUT,
            start_new_session=True,  # its own group: the process and its children
        )


def wait_http(url: str, proc: subprocess.Popen[bytes] | None = None, timeout: float = 90) -> None:
    end = time.monotonic() + timeout
    while not answers(url):
        assert proc is None or proc.poll() is None, f"{proc.args} exited"
        assert time.monotonic() < end, f"{url} did not answer 200"
        time.sleep(0.1)


def kill_group(proc: subprocess.Popen[bytes], sig: int = signal.SIGKILL) -> None:
    """``sig`` to the process group of ``proc`` (the fault tests' kill), waiting for the
    leader; a group whose leader is gone already gets SIGKILL (children left behind)."""
    if proc.poll() is None:
        os.killpg(proc.pid, sig)
        proc.wait(timeout=30)
    else:
        try:
            os.killpg(proc.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass


def live_group_members(pgid: int) -> list[int]:
    """Pids of processes in group ``pgid`` that are not zombies (from /proc)."""
    members = []
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            stat = (entry / "stat").read_text()
        except OSError:
            continue
        fields = stat.rpartition(")")[2].split()
        state, pgrp = fields[0], int(fields[2])
        if pgrp == pgid and state != "Z":
            members.append(int(entry.name))
    return members


@contextmanager
def server(
    log: Path, ready: bool = True, **overrides: str
) -> Iterator[tuple[subprocess.Popen[bytes], str]]:
    """``uvicorn service.main:app`` on a free port with ``PIPEFLOW_*`` ``overrides``
    (:func:`service.launch.serve`), its whole group SIGKILLed at the end."""
    with serve(log, env=overrides, ready=ready, timeout_s=90, stop=signal.SIGKILL) as s:
        yield s.proc, s.url


def wait_job(
    url: str,
    key: str,
    until: Callable[[dict[str, Any]], bool] | None = None,
    timeout: float = 120,
) -> dict[str, Any]:
    """Poll ``GET url/v1/jobs/key`` until ``until(job)`` (default: a terminal status)."""
    until = until or (lambda job: job["status"] in TERMINAL)
    end = time.monotonic() + timeout
    while True:
        resp = httpx.get(f"{url}/v1/jobs/{key}", timeout=10)
        if resp.status_code == 200 and until(job := resp.json()):
            return job
        assert time.monotonic() < end, f"job {key} stuck: {resp.text}"
        time.sleep(0.1)


def job_record(data_dir: Path, key: str) -> Job:
    """The job record as the store in ``data_dir`` holds it (the HTTP document has no
    worker: where it ran, ``host:pid`` of the API process in the fast lane or a Dask
    worker's ``tcp://`` address)."""
    store = Store(Settings(data_dir=data_dir).db_url, 10**9, 0, migrate=False)
    try:
        job = store.get_job(key)
    finally:
        store.close()
    assert job is not None
    return job
