"""Fuzz the whole contract with schemathesis: every operation, every check, positive and
negative data, a fixed seed, 0 failures.

A real uvicorn serves the real app with its numerics replaced by a fast fake through the
dependency seam (:mod:`tests.service.fuzz_app`); the schemathesis command line runs against
its ``/openapi.json`` with ``--checks all --mode all`` and the settings in
``tests/service/schemathesis.toml`` (seed; a 422 accepted for schema-valid requests that break
a documented rule across fields).  About 5000 cases, about a minute here.
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
import time
from pathlib import Path

import httpx
import pytest

from service.launch import free_port

#: slow (a fuzz run of the whole API, about 100 s): run by .ci/run's second pytest step
pytestmark = pytest.mark.slow

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent.parent
#: examples per operation and phase (schemathesis' -n); with every phase ~5000 cases
MAX_EXAMPLES = 20


@pytest.mark.skipif(shutil.which("schemathesis") is None, reason="pip install -e '.[dev]'")
def test_schemathesis_finds_nothing(tmp_path: Path) -> None:
    port = free_port()
    env = {**os.environ, "PYTHONPATH": str(ROOT), "PIPEFLOW_DATA_DIR": str(tmp_path)}
    app = "tests.service.fuzz_app:create_fuzz_app"
    server = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "uvicorn",
            "--factory",
            app,
            "--port",
            str(port),
            "--log-level",
            "warning",
        ],
        cwd=ROOT,
        env=env,
    )
    try:
        deadline = time.monotonic() + 120
        while True:
            try:
                if httpx.get(f"http://127.0.0.1:{port}/healthz").status_code == 200:
                    break
            except httpx.TransportError:
                pass
            assert server.poll() is None, "the fuzz server exited"
            assert time.monotonic() < deadline, "the fuzz server did not start"
            time.sleep(0.2)
        config = str(HERE / "schemathesis.toml")
        url = f"http://127.0.0.1:{port}/openapi.json"
        run = subprocess.run(
            [
                "schemathesis",
                "--config-file",
                config,
                "--no-color",
                "run",
                url,
                "--checks",
                "all",
                "--mode",
                "all",
                "-n",
                str(MAX_EXAMPLES),
                "--workers",
                "1",
            ],
            cwd=tmp_path,
            env=env,
            capture_output=True,
            text=True,
            timeout=600,
        )
    finally:
        server.terminate()
        server.wait(timeout=30)
    out = run.stdout + run.stderr
    summary = [
        line for line in out.splitlines() if re.search(r"generated|Seed:|passed|failures", line)
    ]
    print("\n".join(summary))  # the case count and time, for the record (pytest -s)
    assert run.returncode == 0, out[-6000:]
    cases = re.search(r"(\d+) generated", out)
    assert cases is not None and int(cases.group(1)) >= 2000, out[-3000:]
    # every operation of the document was exercised
    tested = re.search(r"Tested:\s+(\d+)", out)
    selected = re.search(r"Selected:\s+(\d+)/(\d+)", out)
    assert tested and selected and tested.group(1) == selected.group(2), out[-3000:]
