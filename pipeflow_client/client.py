"""``Client`` and ``AsyncClient``: simulate, submit and wait for jobs, fetch results, CSV,
Parquet and plots.

Results come back as :class:`SimulationResult` (numpy arrays, SI units; ``to_xarray()``,
``to_dataframe()`` and ``plot()`` for notebooks), the other computations' as their JSON;
every result is first validated with its computation's response model
(:mod:`pipeflow.schema.results`, the definition the service writes its documents with:
:func:`parse`), so a document off the contract fails here, naming the field, rather than
later as a missing key.  The service's RFC 9457 problem documents
come back as :class:`ServiceError` carrying the document, the HTTP status and the offending
field.

Every operation is written once, as a generator that yields the HTTP requests (and pauses)
it needs and receives the responses (:mod:`pipeflow_client.client` "sans-IO" style); the
sync :class:`Client` drives it with :class:`httpx.Client` and ``time.sleep``, the
:class:`AsyncClient` with :class:`httpx.AsyncClient` and ``asyncio.sleep``.  Both retry a
``503 Service Unavailable`` (all computation slots busy) with tenacity, waiting what the
answer's ``Retry-After`` says (seconds or an HTTP date; exponential back-off without it).

A server that requires API keys (README "Access") gets the client's key on every request as
``Authorization: Bearer <key>``: the ``api_key`` argument, else the environment variable
``PIPEFLOW_API_KEY`` (:data:`API_KEY_ENV`); an explicit argument beats the variable, and
``api_key=""`` sends none.  The key is kept out of the client's ``headers`` and its repr,
and no message of the client carries it.
"""

from __future__ import annotations

import asyncio
import email.utils
import functools
import os
import time
from collections.abc import Callable, Generator, Mapping
from dataclasses import dataclass, field
from datetime import UTC, datetime
from enum import StrEnum
from typing import Any, TypeVar

import httpx
import numpy as np
import tenacity
from numpy.typing import NDArray
from pydantic import BaseModel

from pipeflow.errors import PipeflowError
from pipeflow.io.notebook import NotebookViews
from pipeflow.schema.results import SimulationResponse

FloatArray = NDArray[np.float64]
Progress = Callable[[float], None]
T = TypeVar("T")


class JobStatus(StrEnum):
    """A job's ``status`` in the service's job document (the service's own states; a test
    keeps the two lists one)."""

    QUEUED = "queued"
    RUNNING = "running"
    SUCCEEDED = "succeeded"
    FAILED = "failed"
    CANCELLED = "cancelled"


#: the states in which a job has ended without a result
ENDED_WITHOUT_RESULT = (JobStatus.FAILED, JobStatus.CANCELLED)


class ServiceError(PipeflowError):
    """The service answered with an error.

    status : HTTP status code.
    problem : the RFC 9457 problem document (``title``, ``detail``, ``errors``, ...).
    field : dotted path of the first offending input (e.g. ``"pipe.E"``), or None.
    errors : every offending input as ``{"field", "message", ...}`` dicts.
    retry_after : the answer's ``Retry-After`` [s] (503), or None.
    """

    def __init__(
        self, status: int, problem: dict[str, Any], retry_after: float | None = None
    ) -> None:
        errors = list(problem.get("errors") or [])
        first = errors[0] if errors else {}
        detail = problem.get("detail") or problem.get("title") or f"HTTP {status}"
        if errors:
            detail = "; ".join(
                f"{e.get('field') or 'body'}: {e.get('message', '')}" for e in errors
            )
        super().__init__(f"{status} {problem.get('title', '')}: {detail}".strip())
        self.at(first.get("field"))  # the request field the service named
        self.status = status
        self.problem = problem
        self.errors = errors
        self.retry_after = retry_after


class JobFailed(ServiceError):
    """A job ended ``failed`` or ``cancelled``; ``problem`` is the job's error document."""


@dataclass(frozen=True)
class SimulationResult(NotebookViews):
    """One simulation result from the service (SI units).

    key : parameter hash of the result (share it: ``GET /v1/results/{key}``).
    cached : True when the service answered from its cache.
    status : "ok", "diverging", "diverged" (stopped at the divergence bound) or "overflow".
    t : output times [s]; tip_displacement : u(L, t) [m].
    eigen_t : times of the eigenvalues [s].
    sigma, omega : tracked frozen eigenvalues xi = sigma + i omega of S(t), shape
        (len(eigen_t), branches): damping [1/s] (negative: decaying), frequency [rad/s].
    displacements : {x [m]: u(x, t) [m]} at the requested stations.
    warnings : what the service says about this result.
    raw : the full JSON document.

    ``to_xarray()``, ``to_dataframe(table)`` and ``plot(name)`` give the same objects as a
    local :class:`pipeflow.simulation.Result` (:mod:`pipeflow.io.notebook`).
    """

    key: str
    cached: bool
    status: str
    t: FloatArray
    tip_displacement: FloatArray
    eigen_t: FloatArray
    sigma: FloatArray
    omega: FloatArray
    displacements: dict[float, FloatArray]
    warnings: list[str]
    raw: dict[str, Any] = field(repr=False)
    #: the validated document (:class:`pipeflow.schema.results.SimulationResponse`)
    model: SimulationResponse | None = field(default=None, repr=False, compare=False)

    @classmethod
    def from_json(cls, doc: dict[str, Any]) -> SimulationResult:
        """Validate ``doc`` with :class:`~pipeflow.schema.results.SimulationResponse` (a
        pydantic ValidationError names the field off the contract) and take the arrays from
        the validated model."""
        model = SimulationResponse.model_validate(doc)
        modes = model.eigenvalues.modes
        return cls(
            key=model.key,
            cached=model.cached,
            status=model.status,
            t=np.asarray(model.t, dtype=float),
            tip_displacement=np.asarray(model.tip_displacement, dtype=float),
            eigen_t=np.asarray(model.eigenvalues.t, dtype=float),
            sigma=np.asarray([m.sigma for m in modes], dtype=float).T,
            omega=np.asarray([m.omega for m in modes], dtype=float).T,
            displacements={s.x: np.asarray(s.u, dtype=float) for s in model.displacements},
            warnings=list(model.warnings),
            raw=doc,
            model=model,
        )

    @property
    def plots(self) -> list[str]:
        """Names of the plots the service can draw of this result."""
        return list(self.model.plots if self.model is not None else self.raw.get("plots", []))

    def _document(self) -> dict[str, Any]:
        return self.raw


# ---- the operations, once, independent of the transport ----------------------------------


@dataclass(frozen=True)
class Call:
    """One HTTP request an operation needs (path relative to the client's base URL)."""

    method: str
    path: str
    params: dict[str, str] | None = None
    json: Any = None
    headers: dict[str, str] = field(default_factory=dict)
    #: this request's own timeout [s] (a long poll's, longer than its wait); None: the client's
    timeout: float | None = None


#: how long one request of :meth:`_Operations.wait_raw` asks the service to hold it [s]
#: (``GET /v1/jobs/{key}?wait=``, at most 60 s there)
LONG_POLL_S = 30.0
#: a long poll's own timeout is its wait plus this [s]
LONG_POLL_MARGIN_S = 15.0


@dataclass(frozen=True)
class Pause:
    """Wait ``seconds`` [s] before the next request (polling a job)."""

    seconds: float


Steps = Generator[Call | Pause, httpx.Response | None, T]


def parse(kind: str, doc: Any) -> BaseModel:
    """``doc``, a result of the computation named ``kind``, validated with its response
    model (:func:`pipeflow.computations.registry.response_type`: the models the service writes
    its documents with); raises pydantic's ValidationError naming the field."""
    from pipeflow.computations.registry import (
        response_type,
    )  # the computations' table, on first use

    model: type[BaseModel] = response_type(kind)
    return model.model_validate(doc)


def _parsed(kind: str, doc: dict[str, Any]) -> dict[str, Any]:
    """``doc`` once it validates as a result of ``kind`` (:func:`parse`)."""
    if kind == "simulation":  # SimulationResult validates it itself
        return doc
    parse(kind, doc)
    return doc


def _json(call: Call) -> Steps[Any]:
    response = yield call
    assert response is not None
    return response.json()


def _spec_json(spec: Any) -> Any:
    dump = getattr(spec, "model_dump", None)
    return dump(mode="json", exclude_unset=True) if callable(dump) else spec


def _refresh(refresh: bool) -> dict[str, str] | None:
    return {"refresh": "true"} if refresh else None


#: the sweeps, maps and Floquet analyses: one path, their request bodies told apart by ``kind``
SWEEP_KINDS = ("argand", "campbell", "spin_map", "beta_map", "resonance_chart", "floquet")

#: computation name (the registry's, the job's ``kind``) -> ``(path, sync)``: with ``sync``
#: ``POST path`` answers with the result and ``POST path/jobs`` with a job; without it
#: ``POST path`` always answers with a job.  The one place the client spells URL paths of
#: computations.
PATHS: dict[str, tuple[str, bool]] = {
    "simulation": ("/v1/simulations", True),
    "compare": ("/v1/compare", True),
    "stability": ("/v1/stability", True),
    **{kind: ("/v1/sweeps", False) for kind in SWEEP_KINDS},
    "study": ("/v1/studies", False),
    "frequency_response": ("/v1/frequency-responses", True),
    "state_space": ("/v1/state-space", True),
}


def _path(kind: str) -> tuple[str, bool]:
    try:
        return PATHS[kind]
    except KeyError:
        raise ValueError(
            f"unknown computation {kind!r}; choose one of: {', '.join(PATHS)}"
        ) from None


def _job_path(kind: str) -> str:
    path, sync = _path(kind)
    return f"{path}/jobs" if sync else path


def _body(kind: str, spec: Any) -> Any:
    """The JSON body of ``spec`` for ``kind``: where several computations share a path, it
    carries ``kind`` (added when missing; a different one is refused)."""
    body = _spec_json(spec)
    shared = sum(1 for path, _ in PATHS.values() if path == _path(kind)[0]) > 1
    if shared and isinstance(body, dict):
        given = body.get("kind", getattr(spec, "kind", kind))  # a model's default tag is unset
        if given != kind:
            raise ValueError(f"the spec's kind is {given!r}, not {kind!r}")
        body = {"kind": kind, **{k: v for k, v in body.items() if k != "kind"}}
    return body


class _Operations:
    """Every operation of the service as a generator of :class:`Call`/:class:`Pause`; the
    public methods of :class:`Client` and :class:`AsyncClient` are made from these by
    :func:`_operation`."""

    @staticmethod
    def compute(
        kind: str,
        spec: Any,
        *,
        refresh: bool = False,
        progress: Progress | None = None,
        poll: float = 0.2,
        timeout: float | None = None,
    ) -> Steps[dict[str, Any]]:
        """Run the computation named ``kind`` (``simulation``, ``compare``, ``stability``,
        a sweep kind, ``study``, ``frequency_response``: :data:`PATHS`) on ``spec`` and
        return the result JSON.

        One ``POST`` where the service answers with the result and no ``progress`` is
        given; otherwise submitted as a job (:meth:`submit_job`) and waited for
        (``progress(fraction)`` while running, see :meth:`wait_raw`).  The result is
        validated with the computation's response model (:func:`parse`).
        """
        path, sync = _path(kind)
        if sync and progress is None:
            doc: dict[str, Any] = yield from _json(
                Call("POST", path, _refresh(refresh), _body(kind, spec))
            )
            return _parsed(kind, doc)
        job = yield from _Operations.submit_job(kind, spec, refresh=refresh)
        done = yield from _Operations.wait_raw(
            job["key"], progress=progress, poll=poll, timeout=timeout
        )
        return _parsed(kind, done)

    @staticmethod
    def submit_job(kind: str, spec: Any, *, refresh: bool = False) -> Steps[dict[str, Any]]:
        """Submit the computation named ``kind`` on ``spec`` as a job; returns the job
        document (``key``, ``kind``, ``status``, ``progress``)."""
        doc: dict[str, Any] = yield from _json(
            Call("POST", _job_path(kind), _refresh(refresh), _body(kind, spec))
        )
        return doc

    @staticmethod
    def simulate_raw(
        spec: Any, *, refresh: bool = False, progress: Progress | None = None
    ) -> Steps[dict[str, Any]]:
        """Run ``spec`` (dict or :class:`~pipeflow.schema.simulation.SimulationSpec`); the JSON.

        With ``progress`` the run goes through a job, and ``progress(fraction)`` is called
        while waiting; otherwise it is one ``POST /v1/simulations``.
        """
        return (
            yield from _Operations.compute("simulation", spec, refresh=refresh, progress=progress)
        )

    @staticmethod
    def simulate(
        spec: Any, *, refresh: bool = False, progress: Progress | None = None
    ) -> Steps[SimulationResult]:
        """Run ``spec`` (or serve it from the cache) and return the result as numpy arrays."""
        raw = yield from _Operations.simulate_raw(spec, refresh=refresh, progress=progress)
        return SimulationResult.from_json(raw)

    @staticmethod
    def submit(spec: Any, *, refresh: bool = False) -> Steps[dict[str, Any]]:
        """Submit ``spec`` as a job; returns the job document (``key``, ``status``, ...)."""
        return (yield from _Operations.submit_job("simulation", spec, refresh=refresh))

    @staticmethod
    def job(key: str, *, wait: float = 0.0) -> Steps[dict[str, Any]]:
        """The job document: status, progress [0..1], timestamps, error.  ``wait`` > 0 [s,
        at most 60]: a long poll, answered once the job has ended or after ``wait``."""
        if wait <= 0:
            doc: dict[str, Any] = yield from _json(Call("GET", f"/v1/jobs/{key}"))
            return doc
        call = Call(
            "GET", f"/v1/jobs/{key}", {"wait": f"{wait:g}"}, timeout=wait + LONG_POLL_MARGIN_S
        )
        doc = yield from _json(call)
        return doc

    @staticmethod
    def cancel(key: str) -> Steps[dict[str, Any]]:
        """Cancel a queued or running job."""
        doc: dict[str, Any] = yield from _json(Call("DELETE", f"/v1/jobs/{key}"))
        return doc

    @staticmethod
    def wait_raw(
        key: str,
        *,
        progress: Progress | None = None,
        poll: float = 0.2,
        timeout: float | None = None,
    ) -> Steps[dict[str, Any]]:
        """Wait for job ``key`` to end; return the result JSON.

        Each request is a long poll (``GET /v1/jobs/{key}?wait=``): the service answers as
        soon as the job ends, or after :data:`LONG_POLL_S` [s] (``poll`` [s] when
        ``progress`` is given, so ``progress(fraction)`` is called that often), with no
        sleeping here in between.  A service that answers a running job at once (an older
        one, or one holding its limit of long polls) is asked again after ``poll`` [s].
        Raises :class:`JobFailed` for a failed or cancelled job and :class:`TimeoutError`
        after ``timeout`` [s].
        """
        deadline = None if timeout is None else time.monotonic() + timeout
        while True:
            wait = LONG_POLL_S if progress is None else max(poll, 0.0)
            if deadline is not None:
                wait = max(0.0, min(wait, deadline - time.monotonic()))
            asked = time.monotonic()
            job = yield from _Operations.job(key, wait=wait)
            if progress is not None:
                progress(float(job.get("progress", 0.0)))
            status = job["status"]
            if status == JobStatus.SUCCEEDED:
                if progress is not None:
                    progress(1.0)
                return (yield from _Operations.result_raw(key))
            if status in ENDED_WITHOUT_RESULT:
                raise JobFailed(409, job.get("error") or {"title": f"job {status}"})
            if deadline is not None and time.monotonic() > deadline:
                raise TimeoutError(f"job {key} still {status} after {timeout} s")
            if time.monotonic() - asked < wait / 2:
                yield Pause(poll)  # not held: do not ask again at once

    @staticmethod
    def wait(
        key: str,
        *,
        progress: Progress | None = None,
        poll: float = 0.2,
        timeout: float | None = None,
    ) -> Steps[SimulationResult]:
        """Wait for job ``key`` (see :meth:`wait_raw`) and return its result."""
        raw = yield from _Operations.wait_raw(key, progress=progress, poll=poll, timeout=timeout)
        return SimulationResult.from_json(raw)

    @staticmethod
    def result_raw(key: str) -> Steps[dict[str, Any]]:
        """The stored result JSON of ``key``."""
        doc: dict[str, Any] = yield from _json(Call("GET", f"/v1/results/{key}"))
        return doc

    @staticmethod
    def result(key: str) -> Steps[SimulationResult]:
        """The stored result of ``key`` as numpy arrays."""
        return SimulationResult.from_json((yield from _Operations.result_raw(key)))

    @staticmethod
    def result_csv(key: str, table: str = "history") -> Steps[str]:
        """CSV of a stored result: ``history`` (t [s], u(L,t) [m], ...), ``eigenvalues``
        or ``cma_exponents`` (sigma [1/s], omega [rad/s]), ``mode_shapes``; header row
        with units."""
        call = Call("GET", f"/v1/results/{key}", {"table": table}, headers={"Accept": "text/csv"})
        response = yield call
        assert response is not None
        return response.text

    @staticmethod
    def result_parquet(key: str, table: str = "history") -> Steps[bytes]:
        """Parquet bytes of a stored result's ``table`` (bare column names, each unit in
        the field metadata ``unit``); read with ``pyarrow.parquet.read_table(io.BytesIO(b))``."""
        call = Call(
            "GET",
            f"/v1/results/{key}",
            {"table": table},
            headers={"Accept": "application/vnd.apache.parquet"},
        )
        response = yield call
        assert response is not None
        return response.content

    @staticmethod
    def result_file(key: str, fmt: str = "uff") -> Steps[bytes]:
        """A stored result as a file: ``fmt="uff"`` (universal file: dataset 58 per
        operating point and position of a frequency response, abscissa in Hz; dataset 55
        for mode shapes; read with ``pyuff``) or ``"netcdf"`` (netCDF-3, the xarray layout
        with units; ``xarray.open_dataset(io.BytesIO(b))``) or ``"mat"`` (a state-space
        result as a MATLAB file; ``scipy.io.loadmat(io.BytesIO(b))``)."""
        if fmt not in ("uff", "netcdf", "mat"):
            raise ValueError(f"fmt must be 'uff', 'netcdf' or 'mat', got {fmt!r}")
        response = yield Call("GET", f"/v1/results/{key}", {"format": fmt})
        assert response is not None
        return response.content

    @staticmethod
    def plot(key: str, name: str = "tip_displacement", fmt: str = "png") -> Steps[bytes]:
        """PNG or SVG bytes of plot ``name`` of the stored result ``key``."""
        response = yield Call("GET", f"/v1/results/{key}/plots/{name}.{fmt}")
        assert response is not None
        return response.content

    @staticmethod
    def compare(
        simulation: Any, methods: list[str] | None = None, *, refresh: bool = False
    ) -> Steps[dict[str, Any]]:
        """Run one case with several methods (``POST /v1/compare``): per method the solve and
        wall time [s], estimated error [-] and relative difference from the most accurate
        (``baseline``) on the modal state and the tip [-]."""
        body: dict[str, Any] = {"simulation": _spec_json(simulation)}
        if methods is not None:
            body["methods"] = list(methods)
        return (yield from _Operations.compute("compare", body, refresh=refresh))

    @staticmethod
    def stability(
        spec: Any, *, refresh: bool = False, progress: Progress | None = None
    ) -> Steps[dict[str, Any]]:
        """Critical flow velocities [m/s] at constant spin: ``critical_velocity``,
        ``crossings``, ``dimensionless`` (spec: dict or
        :class:`~pipeflow.schema.stability.StabilitySpec`).

        One ``POST /v1/stability``; with ``progress`` it runs as a job instead
        (``POST /v1/stability/jobs``) and ``progress(fraction)`` is called while waiting.
        """
        return (
            yield from _Operations.compute("stability", spec, refresh=refresh, progress=progress)
        )

    @staticmethod
    def frequency_response(
        spec: Any, *, refresh: bool = False, progress: Progress | None = None
    ) -> Steps[dict[str, Any]]:
        """Frequency response functions H(W) at one or several frozen operating points
        (spec: dict or :class:`~pipeflow.schema.frequency.FrequencyResponseSpec`): the result
        JSON with ``frequencies`` [rad/s], ``unit`` and one block per operating point
        (``responses`` per position: real, imag, magnitude, phase [rad]; ``peaks``;
        ``stable``; ``diagnostics``).  Plots ``bode``, ``nyquist``, ``waterfall``,
        ``deflection_shape`` (:meth:`plot`); tables ``frequency_response`` and ``peaks``
        (:meth:`result_csv`).

        One ``POST /v1/frequency-responses``; with ``progress`` it runs as a job instead.
        """
        return (
            yield from _Operations.compute(
                "frequency_response", spec, refresh=refresh, progress=progress
            )
        )

    @staticmethod
    def state_space(spec: Any, *, refresh: bool = False) -> Steps[dict[str, Any]]:
        """A state-space model at a frozen operating point (spec: the body of a frequency
        response without ``frequencies``, dict or
        :class:`~pipeflow.schema.state_space.StateSpaceSpec`): ``A``, ``B``, ``C``, ``D``
        (nested lists), ``states``, ``inputs``, ``outputs`` and ``units``.  One
        ``POST /v1/state-space``; :meth:`result_file` with ``fmt="mat"`` saves it as a
        MATLAB file."""
        return (yield from _Operations.compute("state_space", spec, refresh=refresh))

    @staticmethod
    def submit_frequency_response(spec: Any, *, refresh: bool = False) -> Steps[dict[str, Any]]:
        """Submit a frequency response as a job; returns the job document."""
        return (yield from _Operations.submit_job("frequency_response", spec, refresh=refresh))

    @staticmethod
    def submit_stability(spec: Any, *, refresh: bool = False) -> Steps[dict[str, Any]]:
        """Submit a critical-velocity analysis as a job; returns the job document."""
        return (yield from _Operations.submit_job("stability", spec, refresh=refresh))

    @staticmethod
    def submit_sweep(spec: Any, *, refresh: bool = False) -> Steps[dict[str, Any]]:
        """Submit a sweep, map or Floquet analysis (``POST /v1/sweeps``, spec ``kind``) as a
        job; returns the job document (``key``, ``kind``, ``status``, ``progress``)."""
        kind = spec.get("kind") if isinstance(spec, dict) else getattr(spec, "kind", None)
        if kind in SWEEP_KINDS:
            return (yield from _Operations.submit_job(kind, spec, refresh=refresh))
        # no or an unknown kind: the service's 422 names the field
        path = _job_path(SWEEP_KINDS[0])
        doc: dict[str, Any] = yield from _json(
            Call("POST", path, _refresh(refresh), _spec_json(spec))
        )
        return doc

    @staticmethod
    def sweep(
        spec: Any,
        *,
        refresh: bool = False,
        progress: Progress | None = None,
        poll: float = 0.2,
        timeout: float | None = None,
    ) -> Steps[dict[str, Any]]:
        """An Argand/Campbell sweep, stability map, resonance chart or Floquet analysis
        (spec ``kind``; dict or a :mod:`pipeflow.schema.stability` model): submitted as a job,
        waited for (``progress(fraction)`` while running, see :meth:`wait_raw`), and returned
        as the result JSON (SI units, ``plots`` for :meth:`plot`), validated with the
        response model of its ``kind`` (:func:`parse`)."""
        job = yield from _Operations.submit_sweep(spec, refresh=refresh)
        doc = yield from _Operations.wait_raw(
            job["key"], progress=progress, poll=poll, timeout=timeout
        )
        return _parsed(str(job.get("kind") or doc["kind"]), doc)

    @staticmethod
    def submit_study(spec: Any, *, refresh: bool = False) -> Steps[dict[str, Any]]:
        """Submit a design study (``POST /v1/studies``: a base simulation or stability
        request and its ``cases`` or ``grid`` of overrides) as a job; returns the job."""
        return (yield from _Operations.submit_job("study", spec, refresh=refresh))

    @staticmethod
    def study(
        spec: Any,
        *,
        refresh: bool = False,
        progress: Progress | None = None,
        poll: float = 0.2,
        timeout: float | None = None,
    ) -> Steps[dict[str, Any]]:
        """A design study (dict or :class:`pipeflow.schema.study.StudySpec`): submitted,
        waited for (``progress(fraction of cases done)``) and returned as the result JSON:
        ``columns`` (with SI units), one of ``rows`` per case, ``counts``; the same table
        as CSV: :meth:`result_csv` with ``table="study"`` (validated: :func:`parse`)."""
        job = yield from _Operations.submit_study(spec, refresh=refresh)
        doc = yield from _Operations.wait_raw(
            job["key"], progress=progress, poll=poll, timeout=timeout
        )
        return _parsed("study", doc)

    @staticmethod
    def post(path: str, body: Any, **params: Any) -> Steps[Any]:
        """``POST path`` with a JSON body; returns the JSON answer (any endpoint)."""
        return (yield from _json(Call("POST", path, params or None, _spec_json(body))))

    @staticmethod
    def health() -> Steps[dict[str, Any]]:
        """``GET /healthz``: ``{"status": "ok", "version": ...}``."""
        doc: dict[str, Any] = yield from _json(Call("GET", "/healthz"))
        return doc


def _operation(steps: Callable[..., Steps[Any]]) -> Callable[..., Any]:
    """A client method from an operation: ``self._run(steps(...))`` (sync: the value;
    async: an awaitable of it)."""

    @functools.wraps(steps)
    def method(self: _Base, *args: Any, **kwargs: Any) -> Any:
        return self._run(steps(*args, **kwargs))

    return method


# ---- retries of 503 --------------------------------------------------------------------


def retry_after_seconds(value: str | None, now: datetime | None = None) -> float | None:
    """``Retry-After`` (RFC 9110 section 10.2.3: delay-seconds or an HTTP date) in [s]."""
    if value is None or not value.strip():
        return None
    value = value.strip()
    if value.isdigit():
        return float(value)
    try:
        when = email.utils.parsedate_to_datetime(value)
    except (TypeError, ValueError):
        return None
    return max(0.0, (when - (now or datetime.now(UTC))).total_seconds())


def _is_busy(exc: BaseException) -> bool:
    return isinstance(exc, ServiceError) and exc.status == 503


@dataclass(frozen=True)
class RetryPolicy:
    """How 503 answers are retried.

    attempts : requests in all, the first included (1: never retry).
    max_wait : longest single wait [s]; a longer ``Retry-After`` is cut to it.
    backoff : first wait [s] when the answer has no ``Retry-After`` (then doubled).
    on_retry : called as ``on_retry(error, wait_seconds)`` before each wait.
    """

    attempts: int = 5
    max_wait: float = 60.0
    backoff: float = 0.5
    on_retry: Callable[[ServiceError, float], None] | None = None

    def _wait(self, state: tenacity.RetryCallState) -> float:
        exc = state.outcome.exception() if state.outcome is not None else None
        after = exc.retry_after if isinstance(exc, ServiceError) else None
        if after is None:
            after = self.backoff * 2 ** (state.attempt_number - 1)
        return min(after, self.max_wait)

    def _before_sleep(self, state: tenacity.RetryCallState) -> None:
        exc = state.outcome.exception() if state.outcome is not None else None
        if self.on_retry is not None and isinstance(exc, ServiceError):
            wait = state.next_action.sleep if state.next_action is not None else 0.0
            self.on_retry(exc, wait)

    def tenacity_kwargs(self) -> dict[str, Any]:
        """Arguments of :class:`tenacity.Retrying` / :class:`tenacity.AsyncRetrying`."""
        return {
            "retry": tenacity.retry_if_exception(_is_busy),
            "wait": self._wait,
            "stop": tenacity.stop_after_attempt(max(1, self.attempts)),
            "before_sleep": self._before_sleep,
            "reraise": True,
        }


def _checked(response: httpx.Response) -> httpx.Response:
    if response.status_code >= 400:
        raise ServiceError(
            response.status_code,
            _problem(response),
            retry_after_seconds(response.headers.get("retry-after")),
        )
    return response


# ---- the two clients -------------------------------------------------------------------

#: the environment variable a client takes its API key from when given none
API_KEY_ENV = "PIPEFLOW_API_KEY"
#: request headers that carry a key (lower case)
_KEY_HEADERS = frozenset({"authorization", "x-api-key"})


def api_key_headers(
    api_key: str | None, headers: Mapping[str, str] | None = None
) -> dict[str, str]:
    """The ``Authorization: Bearer <key>`` header of a client (empty: send no key).

    ``api_key`` given (not None) decides: its key, or none when empty.  Otherwise a key
    header among the caller's own ``headers`` is left to speak for itself, and failing that
    the environment variable :data:`API_KEY_ENV` gives the key (an empty one: none)."""
    if api_key is None:
        if any(name.lower() in _KEY_HEADERS for name in headers or {}):
            return {}
        api_key = os.environ.get(API_KEY_ENV)
    key = (api_key or "").strip()
    return {"Authorization": f"Bearer {key}"} if key else {}


class _Base:
    """What both clients share: base URL, default headers, API key, retry policy, and the
    methods."""

    def __init__(
        self,
        base_url: str,
        headers: Mapping[str, str] | None,
        retry: RetryPolicy | None,
        api_key: str | None = None,
    ) -> None:
        self.base_url = base_url.rstrip("/")
        self.headers = dict(headers or {})
        self.retry = retry if retry is not None else RetryPolicy()
        # kept apart from ``headers`` (which a caller may print); an explicit key replaces
        # a key header of the caller's own
        self._key_headers = api_key_headers(api_key, self.headers)
        if self._key_headers:
            self.headers = {k: v for k, v in self.headers.items() if k.lower() not in _KEY_HEADERS}

    @property
    def sends_api_key(self) -> bool:
        """Whether requests carry an API key (from ``api_key`` or ``PIPEFLOW_API_KEY``)."""
        return bool(self._key_headers)

    def __repr__(self) -> str:
        key = ", api key" if self._key_headers else ""
        return f"{type(self).__name__}({self.base_url!r}{key})"

    def _run(self, steps: Steps[Any]) -> Any:
        raise NotImplementedError

    def _kwargs(self, call: Call) -> dict[str, Any]:
        kwargs = {
            "method": call.method,
            "url": self.base_url + call.path,
            "params": call.params,
            "json": call.json,
            "headers": {**self.headers, **self._key_headers, **call.headers},
        }
        if call.timeout is not None:
            kwargs["timeout"] = call.timeout
        return kwargs

    compute = _operation(_Operations.compute)
    submit_job = _operation(_Operations.submit_job)
    simulate_raw = _operation(_Operations.simulate_raw)
    simulate = _operation(_Operations.simulate)
    submit = _operation(_Operations.submit)
    job = _operation(_Operations.job)
    cancel = _operation(_Operations.cancel)
    wait_raw = _operation(_Operations.wait_raw)
    wait = _operation(_Operations.wait)
    result_raw = _operation(_Operations.result_raw)
    result = _operation(_Operations.result)
    result_csv = _operation(_Operations.result_csv)
    result_parquet = _operation(_Operations.result_parquet)
    result_file = _operation(_Operations.result_file)
    plot = _operation(_Operations.plot)
    compare = _operation(_Operations.compare)
    stability = _operation(_Operations.stability)
    submit_stability = _operation(_Operations.submit_stability)
    frequency_response = _operation(_Operations.frequency_response)
    submit_frequency_response = _operation(_Operations.submit_frequency_response)
    state_space = _operation(_Operations.state_space)
    submit_sweep = _operation(_Operations.submit_sweep)
    sweep = _operation(_Operations.sweep)
    submit_study = _operation(_Operations.submit_study)
    study = _operation(_Operations.study)
    post = _operation(_Operations.post)
    health = _operation(_Operations.health)


class Client(_Base):
    """A pipeflow service at ``base_url`` (e.g. ``"http://localhost:8000"``), blocking.

    ``http`` lets a caller pass its own :class:`httpx.Client` (tests pass FastAPI's
    ``TestClient``); otherwise one is created with ``timeout`` [s] and closed by
    :meth:`close` or the ``with`` block.  ``retry`` sets how 503 answers are retried
    (:class:`RetryPolicy`; ``RetryPolicy(attempts=1)`` never retries).  ``api_key``: the key
    of a server that requires keys, sent as ``Authorization: Bearer <key>``; None (the
    default) takes ``PIPEFLOW_API_KEY`` from the environment, ``""`` sends none.
    """

    def __init__(
        self,
        base_url: str,
        *,
        timeout: float = 600.0,
        http: httpx.Client | None = None,
        headers: Mapping[str, str] | None = None,
        retry: RetryPolicy | None = None,
        api_key: str | None = None,
    ) -> None:
        super().__init__(base_url, headers, retry, api_key)
        self._own = http is None
        self.http = http if http is not None else httpx.Client(timeout=timeout)

    def __enter__(self) -> Client:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        if self._own:
            self.http.close()

    def _send(self, call: Call) -> httpx.Response:
        for attempt in tenacity.Retrying(**self.retry.tenacity_kwargs()):
            with attempt:
                return _checked(self.http.request(**self._kwargs(call)))
        raise AssertionError("unreachable: tenacity reraises the last error")

    def _run(self, steps: Steps[T]) -> T:
        answer: httpx.Response | None = None
        try:
            while True:
                step = steps.send(answer)
                if isinstance(step, Pause):
                    time.sleep(step.seconds)
                    answer = None
                else:
                    answer = self._send(step)
        except StopIteration as done:
            value: T = done.value
            return value


class AsyncClient(_Base):
    """The same service and methods as :class:`Client`, for asyncio: every method returns
    an awaitable (``r = await client.simulate(spec)``), on an :class:`httpx.AsyncClient`
    (``http``, or one created with ``timeout`` [s] and closed by :meth:`aclose` or
    ``async with``); ``api_key`` as for :class:`Client`."""

    def __init__(
        self,
        base_url: str,
        *,
        timeout: float = 600.0,
        http: httpx.AsyncClient | None = None,
        headers: Mapping[str, str] | None = None,
        retry: RetryPolicy | None = None,
        api_key: str | None = None,
    ) -> None:
        super().__init__(base_url, headers, retry, api_key)
        self._own = http is None
        self.http = http if http is not None else httpx.AsyncClient(timeout=timeout)

    async def __aenter__(self) -> AsyncClient:
        return self

    async def __aexit__(self, *exc: object) -> None:
        await self.aclose()

    async def aclose(self) -> None:
        if self._own:
            await self.http.aclose()

    async def _send(self, call: Call) -> httpx.Response:
        async for attempt in tenacity.AsyncRetrying(**self.retry.tenacity_kwargs()):
            with attempt:
                return _checked(await self.http.request(**self._kwargs(call)))
        raise AssertionError("unreachable: tenacity reraises the last error")

    async def _run(self, steps: Steps[T]) -> T:
        answer: httpx.Response | None = None
        try:
            while True:
                step = steps.send(answer)
                if isinstance(step, Pause):
                    await asyncio.sleep(step.seconds)
                    answer = None
                else:
                    answer = await self._send(step)
        except StopIteration as done:
            value: T = done.value
            return value


def _problem(response: httpx.Response) -> dict[str, Any]:
    try:
        doc = response.json()
    except ValueError:
        doc = None
    if isinstance(doc, dict):
        return doc
    return {
        "title": response.reason_phrase,
        "status": response.status_code,
        "detail": response.text,
    }
