"""docker-compose.yml, checked without a Docker engine (none runs here).

The file is parsed, and everything it names that comes from this repo is checked against
the repo: the image builds from the repo's Dockerfile, each command line is parsed by the
real command-line parser of the program it runs (``dask scheduler``, ``dask worker``,
``uvicorn``: an unknown option fails), the modules they load import, the service's
environment variables are settings the service reads, the proxy's configuration file
exists and points at the API services.  The same topology runs as local processes in
``tests/service/engine/test_topology.py``.
"""

from __future__ import annotations

import importlib
import re
from pathlib import Path
from typing import Any

import click
import pytest
import yaml
from sqlalchemy.engine import make_url

from service.settings import Settings

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def compose() -> dict[str, Any]:
    doc: dict[str, Any] = yaml.safe_load((ROOT / "docker-compose.yml").read_text())
    return doc


def _parse(program: list[str]) -> click.Context:
    """Parse ``program`` with the real CLI it names (raises click.UsageError if invalid)."""
    if program[:2] == ["dask", "scheduler"]:
        from distributed.cli.dask_scheduler import main as command
    elif program[:2] == ["dask", "worker"]:
        from distributed.cli.dask_worker import main as command
    elif program[0] == "uvicorn":
        command = importlib.import_module("uvicorn.main").main
    elif program[:3] == ["python", "-m", "service.tls"]:
        return click.Context(click.Command("tls"), info_name="tls")  # parsed in the TLS test
    else:
        raise AssertionError(f"unknown program {program}")
    skip = 1 if program[0] == "uvicorn" else 2
    return command.make_context(" ".join(program[:skip]), list(program[skip:]))


def test_services_and_topology(compose: dict[str, Any]) -> None:
    services = compose["services"]
    assert {"db", "tls", "scheduler", "worker", "api1", "api2", "proxy"} <= set(services)
    assert services["db"]["image"].startswith("postgres:")
    assert services["worker"]["deploy"]["replicas"] >= 2
    assert "pgdata" in compose["volumes"]
    assert any(v.startswith("pgdata:") for v in services["db"]["volumes"])
    for name, service in services.items():
        for dep in service.get("depends_on", {}):
            assert dep in services, (name, dep)
        if name not in ("worker", "tls"):
            assert "test" in service["healthcheck"], name


def test_repo_images_and_commands(compose: dict[str, Any]) -> None:
    ours = {n: s for n, s in compose["services"].items() if "build" in s}
    assert set(ours) == {"tls", "scheduler", "worker", "api1", "api2"}
    for name, service in ours.items():
        assert (ROOT / service["build"] / "Dockerfile").is_file(), name
        ctx = _parse(service["command"])
        if name == "worker":
            assert ctx.params["nthreads"] == 1  # one thread per worker (and one BLAS thread)
            assert ctx.params["scheduler"] == "tls://scheduler:8786"
            # the one preload, in the nanny (the worker's environment before it starts)
            assert list(ctx.params["preload_nanny"]) == ["service.engine.preload"]
            for module in ctx.params["preload_nanny"]:
                assert callable(importlib.import_module(module).dask_setup)
        if name.startswith("api"):
            module, _, attr = ctx.params["app"].partition(":")
            assert module == "service.main" and attr == "app"
            assert ctx.params["port"] == 8000
    with pytest.raises(click.UsageError):
        _parse(["dask", "worker", "tcp://x:1", "--no-such-option"])  # the check can fail


def test_environment_is_what_the_service_reads(compose: dict[str, Any]) -> None:
    api = compose["services"]["api1"]
    env = {k: str(v) for k, v in api["environment"].items()}
    fields = {f"PIPEFLOW_{name.upper()}" for name in Settings.model_fields}
    assert {k for k in env if k.startswith("PIPEFLOW_")} <= fields
    settings = Settings(
        **{k.removeprefix("PIPEFLOW_").lower(): v for k, v in env.items() if k in fields}
    )
    assert settings.scheduler_address == "tls://scheduler:8786"
    url = make_url(settings.db_url)
    assert url.get_backend_name() == "postgresql" and url.get_driver_name() == "psycopg"
    url.get_dialect()  # the driver's dialect loads (psycopg is installed)
    scheduler_port = _parse(compose["services"]["scheduler"]["command"]).params["port"]
    assert settings.scheduler_address.endswith(f":{scheduler_port}")


def test_proxy_points_at_the_replicas(compose: dict[str, Any]) -> None:
    proxy = compose["services"]["proxy"]
    source = proxy["volumes"][0].split(":")[0]
    conf = (ROOT / source).read_text()
    upstreams = set(re.findall(r"server\s+(\w+):(\d+)", conf))
    assert upstreams == {("api1", "8000"), ("api2", "8000")}
    assert "8000:8000" in proxy["ports"]


def test_dask_speaks_tls_only(compose: dict[str, Any], tmp_path: Path) -> None:
    """Every Dask peer (scheduler, workers, API replicas) reads the TLS configuration that
    the one-shot ``tls`` service writes (its command, run here into a temporary directory),
    which requires encryption; the scheduler's port is not published."""
    services = compose["services"]
    tls = services["tls"]
    command = tls["command"]
    assert command[:3] == ["python", "-m", "service.tls"]
    volume, _, target = tls["volumes"][0].partition(":")
    assert volume in compose["volumes"] and target == command[3]
    assert services["scheduler"]["depends_on"]["tls"]["condition"] == (
        "service_completed_successfully"
    )
    for name in ("scheduler", "worker", "api1", "api2"):
        service = services[name]
        assert service["environment"]["DASK_CONFIG"] == target, name
        assert f"{volume}:{target}:ro" in service["volumes"], name
        assert "ports" not in service, name  # only the proxy is reachable from outside

    from service.tls import main

    main([str(tmp_path), *command[4:]])  # the service's own command, here
    config = yaml.safe_load((tmp_path / "dask.yaml").read_text())["distributed"]["comm"]
    assert config["require-encryption"] is True and config["default-scheme"] == "tls"
    for role in ("scheduler", "worker", "client"):
        assert Path(config["tls"][role]["cert"]).is_file()
        assert Path(config["tls"][role]["key"]).stat().st_mode & 0o077 == 0  # owner only
    before = (tmp_path / "peer.pem").read_bytes()
    main([str(tmp_path), *command[4:]])  # compose runs it at every `up`: kept
    assert (tmp_path / "peer.pem").read_bytes() == before


def test_postgresql_driver_needs_no_system_libpq() -> None:
    """The image (python:3.11-slim) has no libpq: psycopg must load the one of its binary
    wheel (psycopg[binary]). ``PSYCOPG_IMPL=binary`` makes psycopg refuse any other, and
    the libpq mapped into the process must be the wheel's (this host has a system libpq
    that would hide the problem).  .ci/run does the same in the image's clean virtualenv."""
    import subprocess
    import sys

    code = (
        "import psycopg, sqlalchemy\n"
        "sqlalchemy.create_engine('postgresql+psycopg://u@db/pipeflow').dialect\n"
        "psycopg.pq.version()\n"
        "libs = [l.split()[-1] for l in open('/proc/self/maps') if 'libpq' in l]\n"
        "print(psycopg.pq.__impl__, sorted(set(libs)))\n"
    )
    out = subprocess.run(
        [sys.executable, "-c", code],
        env={"PSYCOPG_IMPL": "binary", "PATH": "/usr/bin:/bin"},
        capture_output=True,
        text=True,
        check=False,
    )
    assert out.returncode == 0, out.stderr
    impl, _, libs = out.stdout.partition(" ")
    assert impl == "binary"
    assert "psycopg_binary" in libs and "/lib/x86_64-linux-gnu/libpq" not in libs, libs
