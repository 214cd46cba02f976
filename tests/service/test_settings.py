"""Where the service keeps its data when PIPEFLOW_DATA_DIR is not set."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from service.settings import Settings
from tests.live import ROOT


def test_default_data_dir_is_per_user_not_the_working_directory(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    monkeypatch.delenv("PIPEFLOW_DATA_DIR", raising=False)
    monkeypatch.setenv("XDG_DATA_HOME", str(tmp_path / "xdg"))
    for cwd in (tmp_path, Path("/")):
        monkeypatch.chdir(cwd)
        assert Settings().data_dir == tmp_path / "xdg" / "pipeflow"
    monkeypatch.delenv("XDG_DATA_HOME")
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    assert Settings().data_dir == tmp_path / "home" / ".local" / "share" / "pipeflow"


def test_pipeflow_data_dir_overrides_it(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    monkeypatch.setenv("PIPEFLOW_DATA_DIR", str(tmp_path / "d"))
    assert Settings().data_dir == tmp_path / "d"
    assert Settings().db_path == tmp_path / "d" / "pipeflow.sqlite3"


@pytest.mark.slow  # a real server refusing to start, 5-9 s
def test_an_unwritable_data_dir_stops_the_server_with_a_clear_message(tmp_path: Path) -> None:
    """uvicorn exits at start-up with a message that says what to do, instead of SQLite's
    'unable to open database file'.  (The case of the container, a root-owned bind mount and
    uid 10001, cannot be made here: tests run as root, who may write anywhere, so the
    directory is made impossible instead: its parent is a regular file.)"""
    blocker = tmp_path / "not-a-directory"
    blocker.write_text("")
    data = blocker / "data"
    env = {**os.environ, "PIPEFLOW_DATA_DIR": str(data), "PIPEFLOW_WORKERS": "1"}
    done = subprocess.run(
        [sys.executable, "-m", "uvicorn", "service.main:app", "--port", "0"],
        cwd=ROOT,
        env=env,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode != 0
    uid = os.getuid()
    # the service logs to stdout, uvicorn's start-up failure included (service.observability)
    output = done.stdout + done.stderr
    assert f"PIPEFLOW_DATA_DIR={data} is not a writable directory for uid {uid}" in output
    assert f"(chown {uid} {data})" in output
