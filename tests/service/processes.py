"""Real processes for the service's fault and topology tests: uvicorn servers on free
ports, process groups killed by signal, polling a job over HTTP."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import httpx

from tests.live import free_port

ROOT = Path(__file__).resolve().parents[2]
TERMINAL = ("succeeded", "failed", "cancelled")


def env(**overrides: str) -> dict[str, str]:
    """This environment with this tree first on the path, plus ``overrides``."""
    path = os.pathsep.join(p for p in (str(ROOT), os.environ.get("PYTHONPATH", "")) if p)
    return {**os.environ, "PYTHONPATH": path, **overrides}


def spawn(args: list[str], log: Path, **overrides: str) -> subprocess.Popen[bytes]:
    """Start ``args`` in its own process group, output to ``log``."""
    with open(log, "ab") as out:
        return subprocess.Popen(
            args,
            cwd=ROOT,
            env=env(**overrides),
            stdout=out,
            stderr=subprocess.STDOUT,
            start_new_session=True,  # its own group: the process and its children
        )


def wait_http(url: str, proc: subprocess.Popen[bytes] | None = None, timeout: float = 90) -> None:
    end = time.monotonic() + timeout
    while True:
        assert proc is None or proc.poll() is None, f"{proc.args} exited"
        try:
            if httpx.get(url, timeout=2).status_code == 200:
                return
        except httpx.TransportError:
            pass
        assert time.monotonic() < end, f"{url} did not answer 200"
        time.sleep(0.1)


def kill_group(proc: subprocess.Popen[bytes], sig: int = signal.SIGKILL) -> None:
    if proc.poll() is None:
        os.killpg(proc.pid, sig)
        proc.wait(timeout=30)
    else:  # the leader is gone: its group may still hold children
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
    """``uvicorn service.main:app`` on a free port with ``PIPEFLOW_*`` ``overrides``."""
    port = free_port()
    proc = spawn(
        [sys.executable, "-m", "uvicorn", "service.main:app", "--port", str(port)],
        log,
        **overrides,
    )
    url = f"http://127.0.0.1:{port}"
    try:
        wait_http(f"{url}/readyz" if ready else f"{url}/healthz", proc)
        yield proc, url
    finally:
        kill_group(proc)


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
