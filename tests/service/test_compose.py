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
import json
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


# -- monitoring: Prometheus scrapes each replica and the scheduler, Grafana shows them -------

MONITORING = ("prometheus", "grafana")
#: PromQL keywords (operators and modifiers), which are not metric names
_PROMQL_WORDS = {"bool", "and", "or", "unless", "offset", "on", "ignoring"}
_PROMQL_WORDS |= {"by", "without", "group_left", "group_right"}


def _mounts(service: dict[str, Any]) -> dict[str, tuple[str, str]]:
    """``{container path: (host source, mode)}`` of a service's short-syntax volumes."""
    out = {}
    for volume in service.get("volumes", []):
        source, target, *mode = volume.split(":")
        out[target] = (source, mode[0] if mode else "rw")
    return out


def _prometheus_config(compose: dict[str, Any]) -> dict[str, Any]:
    source, mode = _mounts(compose["services"]["prometheus"])["/etc/prometheus/prometheus.yml"]
    assert mode == "ro"
    doc: dict[str, Any] = yaml.safe_load((ROOT / source).read_text())
    return doc


def _jobs(config: dict[str, Any]) -> dict[str, dict[str, Any]]:
    return {job["job_name"]: job for job in config["scrape_configs"]}


def _targets(job: dict[str, Any]) -> set[str]:
    return {t for static in job["static_configs"] for t in static["targets"]}


def test_prometheus_scrapes_each_replica_and_the_scheduler(compose: dict[str, Any]) -> None:
    """Each API service by name (the proxy's /metrics would alternate between replicas),
    with the bearer key compose gives Prometheus as a secret (auth stays on for /metrics),
    and the scheduler's HTTP server on the port its command binds."""
    services = compose["services"]
    jobs = _jobs(_prometheus_config(compose))
    assert set(jobs) == {"pipeflow-api", "dask-scheduler"}

    apis = {
        f"{name}:{_parse(s['command']).params['port']}"
        for name, s in services.items()
        if s.get("command", [None])[0] == "uvicorn"
    }
    assert apis == {"api1:8000", "api2:8000"}
    api_job = jobs["pipeflow-api"]
    assert _targets(api_job) == apis
    assert not any(t.startswith("proxy:") for job in jobs.values() for t in _targets(job))
    assert api_job.get("metrics_path", "/metrics") == "/metrics"

    # /metrics needs a key in compose: Prometheus reads one from its secret file
    for name in ("api1", "api2"):
        env = services[name]["environment"]
        assert env["PIPEFLOW_AUTH_REQUIRED"] == "true"
        assert str(env.get("PIPEFLOW_METRICS_AUTH", "true")).lower() == "true"
    auth = api_job["authorization"]
    assert auth.get("type", "Bearer") == "Bearer" and "credentials" not in auth
    (secret,) = services["prometheus"]["secrets"]
    assert auth["credentials_file"] == f"/run/secrets/{secret}"
    assert compose["secrets"][secret] == {"environment": "PIPEFLOW_METRICS_KEY"}

    dashboard = _parse(services["scheduler"]["command"]).params
    port = dashboard["dashboard_address"].rpartition(":")[2]
    assert _targets(jobs["dask-scheduler"]) == {f"scheduler:{port}"}
    assert "authorization" not in jobs["dask-scheduler"]


def test_scheduler_dashboard_is_on_and_internal(compose: dict[str, Any]) -> None:
    scheduler = compose["services"]["scheduler"]
    assert "--no-dashboard" not in scheduler["command"]
    params = _parse(scheduler["command"]).params
    assert params["dashboard"] is True
    host, _, port = params["dashboard_address"].rpartition(":")
    assert host in ("", "0.0.0.0") and port.isdigit()  # every interface of the container
    assert "ports" not in scheduler  # reachable on the compose network, not from the host


def test_monitoring_services(compose: dict[str, Any]) -> None:
    """Official images pinned by tag, configuration mounted read-only, the UIs published on
    the host's loopback interface only; Grafana's provisioning points at the files."""
    services = compose["services"]
    for name in MONITORING:
        service = services[name]
        image, _, tag = service["image"].partition(":")
        assert image in ("prom/prometheus", "grafana/grafana") and tag and tag != "latest"
        assert "build" not in service
        for port in service.get("ports", []):
            assert port.startswith("127.0.0.1:"), (name, port)
        assert "test" in service["healthcheck"], name

    mounts = _mounts(services["grafana"])
    provisioning, mode = mounts["/etc/grafana/provisioning"]
    assert mode == "ro"
    datasources = yaml.safe_load(
        (ROOT / provisioning / "datasources" / "prometheus.yml").read_text()
    )["datasources"]
    (ds,) = datasources
    assert ds["type"] == "prometheus" and ds["url"] == "http://prometheus:9090"
    (provider,) = yaml.safe_load((ROOT / provisioning / "dashboards" / "pipeflow.yml").read_text())[
        "providers"
    ]
    path = provider["options"]["path"]
    source, mode = mounts[path]
    assert mode == "ro"
    files = sorted((ROOT / source).glob("*.json"))
    assert files
    for file in files:
        dashboard = json.loads(file.read_text())
        for panel in dashboard["panels"]:
            assert panel["datasource"]["uid"] == ds["uid"], panel["title"]


def _dashboard_metrics() -> dict[str, set[str]]:
    """The metric names of every panel expression of the dashboards, by panel title."""
    out: dict[str, set[str]] = {}
    for file in sorted((ROOT / "deploy" / "grafana" / "dashboards").glob("*.json")):
        for panel in json.loads(file.read_text())["panels"]:
            names: set[str] = set()
            for target in panel["targets"]:
                names |= _metric_names(target["expr"])
            assert names, panel["title"]
            out[panel["title"]] = names
    return out


def _metric_names(expr: str) -> set[str]:
    """Metric names of a PromQL expression: identifiers that are not functions, not in
    label matchers, grouping clauses, ranges or strings, and not keywords."""
    expr = re.sub(r'"[^"]*"', "", expr)
    expr = re.sub(r"\{[^}]*\}|\[[^\]]*\]", "", expr)
    expr = re.sub(r"\b(by|without|on|ignoring|group_left|group_right)\s*\([^)]*\)", "", expr)
    names = set(re.findall(r"(?<![\w:.])([A-Za-z_:][\w:]*)\b(?!\s*\()", expr))
    return names - _PROMQL_WORDS


def test_metric_names_of_an_expression() -> None:
    expr = (
        'histogram_quantile(0.95, sum by (route, le) (rate(x_bucket{job="a", le=~"1"}'
        "[$__rate_interval]))) / on (route) group_left y offset 5m"
    )
    assert _metric_names(expr) == {"x_bucket", "y"}


def _exported(text: str) -> set[str]:
    """Every sample name the exposition ``text`` can have, from its families' types (a
    labelled metric with no child yet has a family and no sample)."""
    from prometheus_client.parser import text_string_to_metric_families

    suffixes = {
        "counter": ("_total", "_created"),
        "histogram": ("_bucket", "_count", "_sum", "_created"),
        "summary": ("", "_count", "_sum", "_created"),
    }
    out: set[str] = set()
    for family in text_string_to_metric_families(text):
        out |= {family.name + s for s in suffixes.get(family.type, ("",))}
        out |= {sample.name for sample in family.samples}
    return out


def test_dashboard_queries_what_the_service_exports(tmp_path: Path) -> None:
    """Every ``pipeflow_*`` name of a panel is in a live app's GET /metrics; the other
    names are the scheduler's (next test) or Prometheus' own ``up``."""
    from tests.service.conftest import make_client

    with make_client(tmp_path) as client:  # /metrics answers before the workers are warm
        assert client.get("/healthz").status_code == 200
        response = client.get("/metrics")
    assert response.status_code == 200
    exported = _exported(response.text)
    used = _dashboard_metrics()
    for title, names in used.items():
        ours = {n for n in names if n.startswith("pipeflow_")}
        assert ours <= exported, (title, ours - exported)
        assert names - ours <= {"up"} | {n for n in names if n.startswith("dask_")}, title
    everything = set().union(*used.values())
    for family in ("http_requests_total", "http_request_duration_seconds_bucket"):
        assert f"pipeflow_{family}" in everything
    for gauge in ("in_flight", "queue_depth", "jobs", "jobs_waiting", "workers"):
        assert f"pipeflow_{gauge}" in everything
    assert {"pipeflow_cache_lookups_total", "pipeflow_computations_total"} <= everything


def test_dashboard_queries_what_the_scheduler_exports(compose: dict[str, Any]) -> None:
    """The ``dask_*`` names of the panels are in the /metrics of a ``dask scheduler`` run
    with the compose file's options (on free local ports, without TLS)."""
    import subprocess
    import sys
    import time
    import urllib.request

    from service.launch import free_port

    command = compose["services"]["scheduler"]["command"]
    port, http = free_port(), free_port()
    args = [a for a in command[2:] if a not in ("--port", "--dashboard-address")]
    args = [a for a in args if not a.startswith(":") and not a.isdigit()]
    program = [sys.executable, "-m", "distributed.cli.dask_scheduler", *args]
    program += ["--host", "127.0.0.1", "--port", str(port)]
    program += ["--dashboard-address", f"127.0.0.1:{http}"]
    proc = subprocess.Popen(program, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        end = time.monotonic() + 30
        while True:
            try:
                with urllib.request.urlopen(f"http://127.0.0.1:{http}/metrics", timeout=2) as r:
                    text = r.read().decode()
                break
            except OSError:
                assert time.monotonic() < end and proc.poll() is None, "no scheduler /metrics"
                time.sleep(0.2)
    finally:
        proc.terminate()
        proc.wait(10)
    exported = _exported(text)
    dask = {n for names in _dashboard_metrics().values() for n in names if n.startswith("dask_")}
    assert dask and dask <= exported, dask - exported


# -- credentials: required, without defaults, handed over as files -------------------------

#: what the operator must export before ``docker compose up``: none has a default
CREDENTIALS = ("PIPEFLOW_API_KEYS", "PIPEFLOW_METRICS_KEY", "GRAFANA_ADMIN_PASSWORD")
#: compose's variable syntax: ``${NAME}``, ``${NAME:-default}``, ``${NAME-default}``,
#: ``${NAME:?message}``, ``${NAME?message}``, ``${NAME:+alt}``, ``${NAME+alt}``; ``$$`` is a $
_VARIABLE = re.compile(r"\$\$|\$\{(?P<name>\w+)(?:(?P<op>:?[-?+])(?P<arg>[^}]*))?\}")


class Unset(KeyError):
    """A required variable is unset or empty (compose stops with its message)."""


def _interpolate(node: Any, env: dict[str, str]) -> Any:
    """``node`` (the parsed file) with compose's variable interpolation applied to every
    string, as ``docker compose`` does before anything runs."""
    if isinstance(node, dict):
        return {k: _interpolate(v, env) for k, v in node.items()}
    if isinstance(node, list):
        return [_interpolate(v, env) for v in node]
    if not isinstance(node, str):
        return node

    def one(m: re.Match[str]) -> str:
        if m[0] == "$$":
            return "$"
        name, op, arg = m["name"], m["op"] or "", m["arg"] or ""
        value = env.get(name)
        present = value is not None and (value != "" or not op.startswith(":"))
        if op.endswith("?") and not present:
            raise Unset(f"{name}: {arg}")
        if op.endswith("-") and not present:
            return arg
        if op.endswith("+"):
            return arg if present else ""
        return value or ""

    return _VARIABLE.sub(one, node)


def test_credentials_are_required_and_have_no_default(compose: dict[str, Any]) -> None:
    """Each credential is required (``${NAME:?message}``) wherever the file names it, and
    none has a default (Grafana's was ``admin``): compose stops, naming the missing one."""
    text = (ROOT / "docker-compose.yml").read_text()
    uses = [m for m in _VARIABLE.finditer(text) if m["name"]]
    for name in CREDENTIALS:
        ops = [m["op"] for m in uses if m["name"] == name]
        assert ops and set(ops) == {":?"}, (name, ops)
        assert all(m["arg"].strip() for m in uses if m["name"] == name)  # a message
    assert "admin}" not in text and ":-admin" not in text

    env = {name: f"value-of-{name}" for name in CREDENTIALS}
    _interpolate(compose, env)  # everything set: compose goes on
    for name in CREDENTIALS:
        for missing in ({k: v for k, v in env.items() if k != name}, {**env, name: ""}):
            with pytest.raises(Unset, match=name):
                _interpolate(compose, missing)


def test_secrets_reach_their_services_as_files_only(compose: dict[str, Any]) -> None:
    """Prometheus' key and Grafana's admin password are compose secrets read from the
    operator's environment, mounted as files and read from there; neither value is in any
    container's environment."""
    env = {name: f"value-of-{name}" for name in CREDENTIALS}
    doc = _interpolate(compose, env)
    services = doc["services"]
    assert doc["secrets"]["metrics_key"] == {"environment": "PIPEFLOW_METRICS_KEY"}
    assert doc["secrets"]["grafana_admin_password"] == {"environment": "GRAFANA_ADMIN_PASSWORD"}
    grafana = services["grafana"]
    assert grafana["secrets"] == ["grafana_admin_password"]
    environment = grafana["environment"]
    assert "GF_SECURITY_ADMIN_PASSWORD" not in environment  # a value would be a default
    assert environment["GF_SECURITY_ADMIN_PASSWORD__FILE"] == "/run/secrets/grafana_admin_password"
    assert services["prometheus"]["secrets"] == ["metrics_key"]
    for name, service in services.items():
        values = json.dumps(service.get("environment", {}))
        for secret in ("PIPEFLOW_METRICS_KEY", "GRAFANA_ADMIN_PASSWORD"):
            assert env[secret] not in values, (name, secret)


def test_the_interpolation_of_this_test_is_composes() -> None:
    env = {"A": "a", "E": ""}
    assert _interpolate("${A}-${B:-b}-${E:-e}-${E-e}-$${A}-${A:+x}-${B:+x}", env) == (
        "a-b-e--${A}-x-"
    )
    with pytest.raises(Unset, match="B: say so"):
        _interpolate({"k": ["${B:?say so}"]}, env)
    with pytest.raises(Unset, match="E"):
        _interpolate("${E:?}", env)
    assert _interpolate("${E?}", env) == ""
