"""Where the service keeps its data when PIPEFLOW_DATA_DIR is not set."""

from __future__ import annotations

from pathlib import Path

import pytest

from service.settings import Settings


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
