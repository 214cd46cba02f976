"""Metrics, structured logs, request ids and optional tracing: the service's one home for them.

* Request ids: :data:`REQUEST_ID` (a contextvar) holds the id of the request being served;
  the middleware (:class:`service.http.middleware.RequestContext`) sets it from ``X-Request-ID``
  or generates one.  Tasks the request starts copy the context, so the runner reads it
  (:func:`request_id`) and passes it with the job; the worker sets it again around the
  computation, and :class:`RequestIdFilter` stamps it on every log record.
* Logs: :func:`configure_logging` sends every logger (uvicorn's included) to stdout, one
  line per record, JSON (``PIPEFLOW_LOG_FORMAT=json``, the default) or plain text for a
  terminal (``text``), at ``PIPEFLOW_LOG_LEVEL`` (default INFO).  The middleware writes one
  ``request`` line per request (method, route, path, status, duration_ms, cache, key,
  request_id), which replaces uvicorn's access log.
* Metrics (Prometheus, ``GET /metrics``): requests by route template, method and status
  with a latency histogram; computations by kind, method_used and outcome with a duration
  histogram; cache hits and misses; and, read at scrape time through :func:`engine_stats`
  (the one function to re-point when the engine changes), jobs by status, queue depth,
  computations in flight and the worker count.  With ``PROMETHEUS_MULTIPROC_DIR`` set
  (several API processes) the counters and histograms of all processes are aggregated
  from that directory (prometheus-client's multiprocess mode); the engine gauges are those
  of the process answering the scrape, jobs by status come from the shared store.
* Tracing: :func:`tracer` is an OpenTelemetry tracer when the SDK is installed and an
  ``OTEL_*`` exporter is configured (``OTEL_TRACES_EXPORTER`` or
  ``OTEL_EXPORTER_OTLP_ENDPOINT``), else ``None`` and nothing is traced.

Imports only the standard library and prometheus-client: worker processes import this
before numpy (their BLAS threads are pinned first).
"""

from __future__ import annotations

import contextvars
import json
import logging
import os
import re
import sys
import time
import uuid
from collections.abc import Iterable
from contextlib import AbstractContextManager
from dataclasses import dataclass, field
from functools import lru_cache
from typing import Any

from prometheus_client import (
    CONTENT_TYPE_LATEST,
    REGISTRY,
    CollectorRegistry,
    Counter,
    Histogram,
    generate_latest,
)
from prometheus_client.core import GaugeMetricFamily, Metric
from prometheus_client.registry import Collector

#: the id of the request being served (or of the request that started a computation)
REQUEST_ID: contextvars.ContextVar[str | None] = contextvars.ContextVar(
    "pipeflow_request_id", default=None
)
#: a client-supplied X-Request-ID is used as is when it matches this (else one is generated)
REQUEST_ID_PATTERN = re.compile(r"[A-Za-z0-9._:\-]{1,128}")
METRICS_CONTENT_TYPE = CONTENT_TYPE_LATEST

LOG_FORMATS = ("json", "text")


def request_id() -> str | None:
    """The current request id (None outside a request)."""
    return REQUEST_ID.get()


def accept_request_id(header: str | None) -> str:
    """The client's ``X-Request-ID`` if it is a sane token, else a fresh UUID4 hex."""
    if header is not None and REQUEST_ID_PATTERN.fullmatch(header):
        return header
    return uuid.uuid4().hex


# -- logs --------------------------------------------------------------------------------

#: attributes every LogRecord has; anything else on a record came from ``extra=``
_STANDARD = set(logging.LogRecord("", 0, "", 0, "", None, None).__dict__) | {
    "message",
    "asctime",
    "request_id",
    "color_message",  # uvicorn's coloured duplicate of the message
}


class RequestIdFilter(logging.Filter):
    """Stamp ``record.request_id`` from :data:`REQUEST_ID` (unless the record carries one)."""

    def filter(self, record: logging.LogRecord) -> bool:
        if getattr(record, "request_id", None) is None:
            record.request_id = REQUEST_ID.get()
        return True


def _fields(record: logging.LogRecord) -> dict[str, Any]:
    return {k: v for k, v in record.__dict__.items() if k not in _STANDARD}


class JsonFormatter(logging.Formatter):
    """One JSON object per line: ts (UTC ISO 8601), level, logger, message, request_id,
    pid, the record's ``extra`` fields, and ``exc`` for an exception."""

    def format(self, record: logging.LogRecord) -> str:
        doc: dict[str, Any] = {
            "ts": time.strftime("%Y-%m-%dT%H:%M:%S", time.gmtime(record.created))
            + f".{int(record.msecs):03d}Z",
            "level": record.levelname,
            "logger": record.name,
            "message": record.getMessage(),
            "request_id": getattr(record, "request_id", None),
            "pid": record.process,
        }
        doc.update(_fields(record))
        if record.exc_info:
            doc["exc"] = self.formatException(record.exc_info)
        return json.dumps(doc, default=str, separators=(",", ":"))


class TextFormatter(logging.Formatter):
    """``ts LEVEL logger [request id] message k=v ...`` for a terminal."""

    def format(self, record: logging.LogRecord) -> str:
        ts = time.strftime("%H:%M:%S", time.localtime(record.created)) + f".{int(record.msecs):03d}"
        rid = getattr(record, "request_id", None)
        extra = " ".join(f"{k}={v}" for k, v in _fields(record).items())
        line = f"{ts} {record.levelname:<7} {record.name} [{rid or '-'}] {record.getMessage()}"
        if extra:
            line += " " + extra
        if record.exc_info:
            line += "\n" + self.formatException(record.exc_info)
        return line


class _PipeflowHandler(logging.StreamHandler):  # type: ignore[type-arg,unused-ignore]
    """The handler :func:`configure_logging` installs (recognised so it is installed once)."""


def configure_logging(level: str = "INFO", fmt: str = "json") -> None:
    """Route every log record to stdout in ``fmt`` ("json" | "text") at ``level``.

    Idempotent: a second call replaces the level and format of the handler the first one
    installed.  Other handlers on the root logger (pytest's, say) are left alone.
    uvicorn's loggers propagate to the root (one format for all lines); its access log is
    silenced because the request middleware writes a richer line per request.
    """
    if fmt not in LOG_FORMATS:
        raise ValueError(f"log format {fmt!r}: expected one of {LOG_FORMATS}")
    root = logging.getLogger()
    handler = next((h for h in root.handlers if isinstance(h, _PipeflowHandler)), None)
    if handler is None:
        handler = _PipeflowHandler(sys.stdout)
        handler.addFilter(RequestIdFilter())
        root.addHandler(handler)
    handler.setFormatter(JsonFormatter() if fmt == "json" else TextFormatter())
    root.setLevel(level.upper())
    for name in ("uvicorn", "uvicorn.error"):
        lg = logging.getLogger(name)
        lg.handlers.clear()
        lg.propagate = True
    access = logging.getLogger("uvicorn.access")
    access.handlers.clear()
    access.propagate = False
    access.disabled = True


# -- metrics -----------------------------------------------------------------------------

#: latency buckets [s]: sub-millisecond cache hits up to minute-long computations
_HTTP_BUCKETS = (0.0005, 0.001, 0.002, 0.005, 0.01, 0.02, 0.05, 0.1, 0.25, 0.5, 1, 2.5, 5, 10)
_COMPUTE_BUCKETS = (0.001, 0.005, 0.01, 0.025, 0.05, 0.1, 0.25, 0.5, 1, 2.5, 5, 10, 30, 60, 300)

HTTP_REQUESTS = Counter(
    "pipeflow_http_requests",
    "HTTP requests answered, by route template, method and status code.",
    ["route", "method", "status"],
)
HTTP_DURATION = Histogram(
    "pipeflow_http_request_duration_seconds",
    "Time from receiving a request to sending its last byte [s], by route template and method.",
    ["route", "method"],
    buckets=_HTTP_BUCKETS,
)
CACHE = Counter(
    "pipeflow_cache_lookups",
    "Results answered from the cache (result=hit) or computed for the request (miss).",
    ["route", "result"],
)
COMPUTATIONS = Counter(
    "pipeflow_computations",
    "Computations run by a worker, by job kind, method_used and outcome (ok|error|cancelled).",
    ["kind", "method_used", "outcome"],
)
COMPUTATION_DURATION = Histogram(
    "pipeflow_computation_duration_seconds",
    "Wall time of one computation, handed to a worker until its outcome is back [s].",
    ["kind", "method_used"],
    buckets=_COMPUTE_BUCKETS,
)

_METHOD_USED = re.compile(rb'"method_used":"([A-Za-z0-9_\-]{1,32})"')
_METHOD = re.compile(rb'"method":"([A-Za-z0-9_\-]{1,32})"')


def method_used(body: bytes) -> str:
    """The ``method_used`` of a result's JSON bytes (else its ``method``, else "none").

    Read by a bounded pattern search instead of parsing the result (which can be MBs):
    the first occurrence is the top-level key for the simulation kind.
    """
    for pattern in (_METHOD_USED, _METHOD):
        m = pattern.search(body)
        if m is not None:
            return m.group(1).decode()
    return "none"


def record_computation(kind: str, outcome: str, seconds: float, body: bytes | None) -> None:
    """Count one computation (``outcome`` "ok" | "error" | "cancelled") lasting ``seconds``."""
    used = method_used(body) if body is not None else "none"
    COMPUTATIONS.labels(kind, used, outcome).inc()
    COMPUTATION_DURATION.labels(kind, used).observe(seconds)


def record_request(route: str, method: str, status: int, seconds: float, cache: str | None) -> None:
    HTTP_REQUESTS.labels(route, method, str(status)).inc()
    HTTP_DURATION.labels(route, method).observe(seconds)
    if cache is not None:
        CACHE.labels(route, cache.lower()).inc()


@dataclass(frozen=True)
class EngineStats:
    """What the engine looks like now: ``workers`` processes (``ready`` once started),
    ``in_flight`` computations accepted and unfinished, ``queue_depth`` of them waiting
    for a worker, ``capacity`` (in flight beyond it: 503), job records by status, and
    ``waiting``: jobs in the store's durable queue (accepted, not yet taken by a replica;
    over every replica sharing the store)."""

    workers: int
    ready: bool
    in_flight: int
    queue_depth: int
    capacity: int
    jobs: dict[str, int] = field(default_factory=dict)
    waiting: int = 0


def engine_stats(runner: Any, store: Any) -> EngineStats:
    """Read :class:`EngineStats` from the engine (:class:`service.engine.Runner`) and the
    store: ``workers`` are the Dask workers connected to the scheduler now (the embedded
    cluster's, or the external scheduler's); the queue depth is this replica's flights
    beyond its ``PIPEFLOW_WORKERS`` slots."""
    slots = int(runner.settings.workers)
    in_flight = int(runner.in_flight)
    return EngineStats(
        workers=int(runner.workers),
        ready=bool(runner.ready),
        in_flight=in_flight,
        queue_depth=max(0, in_flight - slots),
        capacity=int(runner.capacity),
        jobs=store.job_counts(),
        waiting=store.waiting_jobs(),
    )


class _EngineCollector(Collector):
    def __init__(self, stats: EngineStats) -> None:
        self.stats = stats

    def collect(self) -> Iterable[Metric]:
        s = self.stats
        yield GaugeMetricFamily("pipeflow_workers", "Worker processes of the engine.", s.workers)
        yield GaugeMetricFamily(
            "pipeflow_workers_ready", "1 once the worker processes have started.", int(s.ready)
        )
        yield GaugeMetricFamily(
            "pipeflow_in_flight", "Computations accepted and not finished.", s.in_flight
        )
        yield GaugeMetricFamily(
            "pipeflow_queue_depth", "Computations waiting for a free worker.", s.queue_depth
        )
        yield GaugeMetricFamily(
            "pipeflow_capacity", "Computations that may be in flight (beyond: 503).", s.capacity
        )
        yield GaugeMetricFamily(
            "pipeflow_jobs_waiting",
            "Jobs in the durable queue, accepted and not yet taken by a replica (all "
            "replicas sharing the store).",
            s.waiting,
        )
        jobs = GaugeMetricFamily("pipeflow_jobs", "Job records by status.", labels=["status"])
        for status, n in sorted(s.jobs.items()):
            jobs.add_metric([status], n)
        yield jobs


def _registry() -> CollectorRegistry:
    directory = os.environ.get("PROMETHEUS_MULTIPROC_DIR")
    if not directory:
        return REGISTRY
    from prometheus_client import multiprocess

    registry = CollectorRegistry()
    multiprocess.MultiProcessCollector(registry, path=directory)
    return registry


def exposition(stats: EngineStats) -> bytes:
    """The Prometheus text exposition: this process's (or all processes') metrics + engine."""
    engine = CollectorRegistry(auto_describe=False)
    engine.register(_EngineCollector(stats))
    return generate_latest(_registry()) + generate_latest(engine)


def process_exited() -> None:
    """Tell multiprocess mode this process is gone (its live gauges stop counting)."""
    if os.environ.get("PROMETHEUS_MULTIPROC_DIR"):
        from prometheus_client import multiprocess

        multiprocess.mark_process_dead(os.getpid())


# -- tracing -----------------------------------------------------------------------------


@lru_cache(maxsize=1)
def tracer() -> Any:
    """An OpenTelemetry tracer, or None when the SDK is absent or no exporter is configured.

    Configured by the standard variables: ``OTEL_TRACES_EXPORTER`` ("otlp" | "console"),
    ``OTEL_EXPORTER_OTLP_ENDPOINT`` (implies otlp), ``OTEL_SERVICE_NAME`` (default pipeflow).
    """
    exporter_name = os.environ.get("OTEL_TRACES_EXPORTER", "").strip().lower()
    if not exporter_name and os.environ.get("OTEL_EXPORTER_OTLP_ENDPOINT"):
        exporter_name = "otlp"
    if exporter_name in ("", "none"):
        return None
    try:
        from opentelemetry import trace
        from opentelemetry.sdk.resources import Resource
        from opentelemetry.sdk.trace import TracerProvider
        from opentelemetry.sdk.trace.export import BatchSpanProcessor, ConsoleSpanExporter
    except ImportError:
        logging.getLogger(__name__).warning(
            "OTEL_* is set but opentelemetry-sdk is not installed: tracing is off"
        )
        return None
    exporter: Any
    if exporter_name == "console":
        exporter = ConsoleSpanExporter()
    else:
        try:
            from opentelemetry.exporter.otlp.proto.http.trace_exporter import OTLPSpanExporter
        except ImportError:
            logging.getLogger(__name__).warning(
                "OTEL exporter %r needs opentelemetry-exporter-otlp: tracing is off", exporter_name
            )
            return None
        exporter = OTLPSpanExporter()
    name = os.environ.get("OTEL_SERVICE_NAME", "pipeflow")
    provider = TracerProvider(resource=Resource.create({"service.name": name}))
    provider.add_span_processor(BatchSpanProcessor(exporter))
    trace.set_tracer_provider(provider)
    return trace.get_tracer("pipeflow.service")


def span(name: str, attributes: dict[str, Any]) -> AbstractContextManager[Any] | None:
    """A started span context manager for ``name`` (None when tracing is off)."""
    t = tracer()
    return None if t is None else t.start_as_current_span(name, attributes=attributes)
