"""Start the service as it is deployed, in a child process: the one launcher of the tests, the
benchmarks and any tool that embeds pipeflow's server.

:func:`serve` runs ``python -m uvicorn service.main:app --http
service.http.deadline:HTTPProtocol --port P`` (the README's command) on a
free port of 127.0.0.1, in a process group of its own, with this source tree first on the
child's path (a checkout or worktree serves its own code), and waits until it answers
``/readyz`` (or ``/healthz``).  On exit the group is stopped: ``SIGTERM`` to the server and,
after ``grace_s`` [s], ``SIGKILL`` to whatever of the group is left (the embedded cluster's
workers included), so no process outlives the block.
"""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import time
import urllib.error
import urllib.request
from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

#: the directory holding the ``service`` and ``pipeflow`` packages
ROOT = Path(__file__).resolve().parents[1]
#: uvicorn's arguments for the service's HTTP protocol (:mod:`service.http.deadline`: a
#: request not received within PIPEFLOW_READ_TIMEOUT_S is answered 408 and closed)
HTTP_ARGS = ("--http", "service.http.deadline:HTTPProtocol")


def free_port() -> int:
    """A TCP port of 127.0.0.1 free at the time of asking."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port: int = s.getsockname()[1]
        return port


def child_environment(**overrides: str) -> dict[str, str]:
    """This process's environment with :data:`ROOT` first on ``PYTHONPATH``, plus
    ``overrides`` (e.g. ``PIPEFLOW_WORKERS="1"``)."""
    path = os.pathsep.join(p for p in (str(ROOT), os.environ.get("PYTHONPATH", "")) if p)
    return {**os.environ, "PYTHONPATH": path, **overrides}


def answers(url: str, timeout: float = 2.0) -> bool:
    """Whether ``GET url`` answers 200 (False on any transport error or other status)."""
    try:
        with urllib.request.urlopen(url, timeout=timeout) as resp:
            return bool(resp.status == 200)
    except (OSError, urllib.error.URLError):
        return False


def stop_group(
    proc: subprocess.Popen[bytes], sig: int = signal.SIGKILL, grace_s: float = 20.0
) -> None:
    """Send ``sig`` to ``proc``'s process group, wait up to ``grace_s`` [s] for the leader
    to end, then ``SIGKILL`` whatever is left of the group."""
    for s, wait_s in ((sig, grace_s), (signal.SIGKILL, None)):
        try:
            os.killpg(proc.pid, s)
        except ProcessLookupError:
            pass  # the whole group has ended
        try:
            proc.wait(timeout=wait_s)
        except subprocess.TimeoutExpired:
            pass


@dataclass(frozen=True)
class Server:
    """A running server: its process (the group leader) and base URL."""

    proc: subprocess.Popen[bytes]
    url: str

    @property
    def pid(self) -> int:
        return self.proc.pid


@contextmanager
def serve(
    log: Path,
    *,
    env: Mapping[str, str] | None = None,
    ready: bool = True,
    timeout_s: float = 120.0,
    stop: int = signal.SIGTERM,
    grace_s: float = 20.0,
) -> Iterator[Server]:
    """Run the service until the block ends (see the module docstring).

    ``log``: the server's stdout and stderr (appended).  ``env``: settings for the child
    (``PIPEFLOW_DATA_DIR``, ``PIPEFLOW_WORKERS``...).  ``ready``: wait for ``/readyz``
    (True) or only ``/healthz``.  ``timeout_s`` [s]: how long to wait before raising
    :class:`RuntimeError` with the log.  ``stop``: the signal that ends the server.
    """
    port = free_port()
    with open(log, "ab") as out:
        proc = subprocess.Popen(
            [sys.executable, "-m", "uvicorn", "service.main:app", *HTTP_ARGS, "--port", str(port)],
            cwd=ROOT,
            env=child_environment(**dict(env or {})),
            stdout=out,
            stderr=subprocess.STDOUT,
            start_new_session=True,  # its own group: the server and its workers
        )
    server = Server(proc, f"http://127.0.0.1:{port}")
    probe = f"{server.url}/readyz" if ready else f"{server.url}/healthz"
    try:
        deadline = time.monotonic() + timeout_s
        while not answers(probe):
            if proc.poll() is not None or time.monotonic() > deadline:
                text = Path(log).read_text(errors="replace")
                raise RuntimeError(f"the server did not answer {probe}:\n{text}")
            time.sleep(0.1)
        yield server
    finally:
        stop_group(proc, stop, grace_s)
