"""``Client(base_url)``: simulate, submit and wait for jobs, fetch results, CSV and plots.

Results come back as :class:`SimulationResult` (numpy arrays, SI units); the service's
RFC 9457 problem documents come back as :class:`ServiceError` carrying the document, the
HTTP status and the offending field.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

import httpx
import numpy as np
from numpy.typing import NDArray

from pipeflow.errors import PipeflowError

FloatArray = NDArray[np.float64]
Progress = Callable[[float], None]


class ServiceError(PipeflowError):
    """The service answered with an error.

    status : HTTP status code.
    problem : the RFC 9457 problem document (``title``, ``detail``, ``errors``, ...).
    field : dotted path of the first offending input (e.g. ``"pipe.E"``), or None.
    errors : every offending input as ``{"field", "message", ...}`` dicts.
    """

    def __init__(self, status: int, problem: dict[str, Any]) -> None:
        errors = list(problem.get("errors") or [])
        first = errors[0] if errors else {}
        detail = problem.get("detail") or problem.get("title") or f"HTTP {status}"
        if errors:
            detail = "; ".join(
                f"{e.get('field') or 'body'}: {e.get('message', '')}" for e in errors
            )
        super().__init__(
            f"{status} {problem.get('title', '')}: {detail}".strip(), first.get("field")
        )
        self.status = status
        self.problem = problem
        self.errors = errors


class JobFailed(ServiceError):
    """A job ended ``failed`` or ``cancelled``; ``problem`` is the job's error document."""


@dataclass(frozen=True)
class SimulationResult:
    """One simulation result from the service (SI units).

    key : parameter hash of the result (share it: ``GET /v1/results/{key}``).
    cached : True when the service answered from its cache.
    status : "ok", "diverging" or "overflow".
    t : output times [s]; tip_displacement : u(L, t) [m].
    eigen_t : times of the eigenvalues [s].
    sigma, omega : tracked frozen eigenvalues xi = sigma + i omega of S(t), shape
        (len(eigen_t), branches): damping [1/s] (negative: decaying), frequency [rad/s].
    displacements : {x [m]: u(x, t) [m]} at the requested stations.
    warnings : what the service says about this result.
    raw : the full JSON document.
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

    @classmethod
    def from_json(cls, doc: dict[str, Any]) -> SimulationResult:
        modes = doc["eigenvalues"]["modes"]
        return cls(
            key=doc.get("key", ""),
            cached=bool(doc.get("cached", False)),
            status=doc["status"],
            t=np.asarray(doc["t"], dtype=float),
            tip_displacement=np.asarray(doc["tip_displacement"], dtype=float),
            eigen_t=np.asarray(doc["eigenvalues"]["t"], dtype=float),
            sigma=np.asarray([m["sigma"] for m in modes], dtype=float).T,
            omega=np.asarray([m["omega"] for m in modes], dtype=float).T,
            displacements={
                float(s["x"]): np.asarray(s["u"], dtype=float) for s in doc.get("displacements", [])
            },
            warnings=list(doc.get("warnings", [])),
            raw=doc,
        )

    @property
    def plots(self) -> list[str]:
        """Names of the plots the service can draw of this result."""
        return list(self.raw.get("plots", []))


def _spec_json(spec: Any) -> Any:
    dump = getattr(spec, "model_dump", None)
    return dump(mode="json", exclude_unset=True) if callable(dump) else spec


class Client:
    """A pipeflow service at ``base_url`` (e.g. ``"http://localhost:8000"``).

    ``http`` lets a caller pass its own :class:`httpx.Client` (tests pass FastAPI's
    ``TestClient``); otherwise one is created with ``timeout`` [s] and closed by
    :meth:`close` or the ``with`` block.
    """

    def __init__(
        self,
        base_url: str,
        *,
        timeout: float = 600.0,
        http: httpx.Client | None = None,
        headers: Mapping[str, str] | None = None,
    ) -> None:
        self.base_url = base_url.rstrip("/")
        self._own = http is None
        self.http = http if http is not None else httpx.Client(timeout=timeout)
        self.headers = dict(headers or {})

    def __enter__(self) -> Client:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        if self._own:
            self.http.close()

    # ---- transport -------------------------------------------------------------------

    def _request(self, method: str, path: str, **kw: Any) -> httpx.Response:
        headers = {**self.headers, **kw.pop("headers", {})}
        response = self.http.request(method, self.base_url + path, headers=headers, **kw)
        if response.status_code >= 400:
            raise ServiceError(response.status_code, _problem(response))
        return response

    def _json(self, method: str, path: str, **kw: Any) -> Any:
        return self._request(method, path, **kw).json()

    # ---- simulations -----------------------------------------------------------------

    def simulate_raw(
        self, spec: Any, *, refresh: bool = False, progress: Progress | None = None
    ) -> dict[str, Any]:
        """Run ``spec`` (dict or :class:`~pipeflow.schema.simulation.SimulationSpec`); the JSON.

        With ``progress`` the run goes through a job, and ``progress(fraction)`` is called
        while waiting; otherwise it is one ``POST /v1/simulations``.
        """
        if progress is None:
            return self._json(
                "POST", "/v1/simulations", json=_spec_json(spec), params=_refresh(refresh)
            )
        job = self.submit(spec, refresh=refresh)
        return self.wait_raw(job["key"], progress=progress)

    def simulate(
        self, spec: Any, *, refresh: bool = False, progress: Progress | None = None
    ) -> SimulationResult:
        """Run ``spec`` (or serve it from the cache) and return the result as numpy arrays."""
        return SimulationResult.from_json(
            self.simulate_raw(spec, refresh=refresh, progress=progress)
        )

    def submit(self, spec: Any, *, refresh: bool = False) -> dict[str, Any]:
        """Submit ``spec`` as a job; returns the job document (``key``, ``status``, ...)."""
        doc: dict[str, Any] = self._json(
            "POST", "/v1/jobs", json=_spec_json(spec), params=_refresh(refresh)
        )
        return doc

    def job(self, key: str) -> dict[str, Any]:
        """The job document: status, progress [0..1], timestamps, error."""
        doc: dict[str, Any] = self._json("GET", f"/v1/jobs/{key}")
        return doc

    def cancel(self, key: str) -> dict[str, Any]:
        """Cancel a queued or running job."""
        doc: dict[str, Any] = self._json("DELETE", f"/v1/jobs/{key}")
        return doc

    def wait_raw(
        self,
        key: str,
        *,
        progress: Progress | None = None,
        poll: float = 0.2,
        timeout: float | None = None,
    ) -> dict[str, Any]:
        """Poll job ``key`` every ``poll`` [s] until it ends; return the result JSON.

        Raises :class:`JobFailed` for a failed or cancelled job and :class:`TimeoutError`
        after ``timeout`` [s].
        """
        deadline = None if timeout is None else time.monotonic() + timeout
        while True:
            job = self.job(key)
            if progress is not None:
                progress(float(job.get("progress", 0.0)))
            status = job["status"]
            if status == "succeeded":
                if progress is not None:
                    progress(1.0)
                return self.result_raw(key)
            if status in ("failed", "cancelled"):
                raise JobFailed(409, job.get("error") or {"title": f"job {status}"})
            if deadline is not None and time.monotonic() > deadline:
                raise TimeoutError(f"job {key} still {status} after {timeout} s")
            time.sleep(poll)

    def wait(
        self,
        key: str,
        *,
        progress: Progress | None = None,
        poll: float = 0.2,
        timeout: float | None = None,
    ) -> SimulationResult:
        """Wait for job ``key`` (see :meth:`wait_raw`) and return its result."""
        raw = self.wait_raw(key, progress=progress, poll=poll, timeout=timeout)
        return SimulationResult.from_json(raw)

    # ---- stored results ----------------------------------------------------------------

    def result_raw(self, key: str) -> dict[str, Any]:
        """The stored result JSON of ``key``."""
        doc: dict[str, Any] = self._json("GET", f"/v1/results/{key}")
        return doc

    def result(self, key: str) -> SimulationResult:
        """The stored result of ``key`` as numpy arrays."""
        return SimulationResult.from_json(self.result_raw(key))

    def result_csv(self, key: str, table: str = "history") -> str:
        """CSV of a stored result: ``history`` (t [s], u(L,t) [m], ...), ``eigenvalues``
        or ``cma_exponents`` (sigma [1/s], omega [rad/s]); header row with units."""
        response = self._request(
            "GET", f"/v1/results/{key}", params={"table": table}, headers={"Accept": "text/csv"}
        )
        return response.text

    def plot(self, key: str, name: str = "tip_displacement", fmt: str = "png") -> bytes:
        """PNG or SVG bytes of plot ``name`` of the stored result ``key``."""
        return self._request("GET", f"/v1/results/{key}/plots/{name}.{fmt}").content

    # ---- method comparison ---------------------------------------------------------------

    def compare(
        self, simulation: Any, methods: list[str] | None = None, *, refresh: bool = False
    ) -> dict[str, Any]:
        """Run one case with several methods (``POST /v1/compare``): per method the solve and
        wall time [s], estimated error [-] and relative difference from the most accurate
        (``baseline``) on the modal state and the tip [-]."""
        body: dict[str, Any] = {"simulation": _spec_json(simulation)}
        if methods is not None:
            body["methods"] = list(methods)
        doc: dict[str, Any] = self._json("POST", "/v1/compare", json=body, params=_refresh(refresh))
        return doc

    # ---- stability -----------------------------------------------------------------------

    def stability(
        self, spec: Any, *, refresh: bool = False, progress: Progress | None = None
    ) -> dict[str, Any]:
        """Critical flow velocities [m/s] at constant spin: ``critical_velocity``,
        ``crossings``, ``dimensionless`` (spec: dict or
        :class:`~pipeflow.schema.stability.StabilitySpec`).

        One ``POST /v1/stability``; with ``progress`` it runs as a job instead
        (``POST /v1/stability/jobs``) and ``progress(fraction)`` is called while waiting.
        """
        if progress is None:
            doc: dict[str, Any] = self._json(
                "POST", "/v1/stability", json=_spec_json(spec), params=_refresh(refresh)
            )
            return doc
        job = self.submit_stability(spec, refresh=refresh)
        return self.wait_raw(job["key"], progress=progress)

    def submit_stability(self, spec: Any, *, refresh: bool = False) -> dict[str, Any]:
        """Submit a critical-velocity analysis as a job; returns the job document."""
        doc: dict[str, Any] = self._json(
            "POST", "/v1/stability/jobs", json=_spec_json(spec), params=_refresh(refresh)
        )
        return doc

    def submit_sweep(self, spec: Any, *, refresh: bool = False) -> dict[str, Any]:
        """Submit a sweep, map or Floquet analysis (``POST /v1/sweeps``, spec ``kind``) as a
        job; returns the job document (``key``, ``kind``, ``status``, ``progress``)."""
        body = _spec_json(spec)
        if isinstance(body, dict) and "kind" not in body and hasattr(spec, "kind"):
            body = {"kind": spec.kind, **body}  # a model's default tag is not "set"
        doc: dict[str, Any] = self._json("POST", "/v1/sweeps", json=body, params=_refresh(refresh))
        return doc

    def sweep(
        self,
        spec: Any,
        *,
        refresh: bool = False,
        progress: Progress | None = None,
        poll: float = 0.2,
        timeout: float | None = None,
    ) -> dict[str, Any]:
        """An Argand/Campbell sweep, stability map, resonance chart or Floquet analysis
        (spec ``kind``; dict or a :mod:`pipeflow.schema.stability` model): submitted as a job,
        waited for (``progress(fraction)`` while running, see :meth:`wait_raw`), and returned
        as the result JSON (SI units, ``plots`` for :meth:`plot`)."""
        job = self.submit_sweep(spec, refresh=refresh)
        return self.wait_raw(job["key"], progress=progress, poll=poll, timeout=timeout)

    # ---- other computations --------------------------------------------------------------

    def post(self, path: str, body: Any, **params: Any) -> Any:
        """``POST path`` with a JSON body; returns the JSON answer (any endpoint)."""
        return self._json("POST", path, json=_spec_json(body), params=params or None)

    def health(self) -> dict[str, Any]:
        doc: dict[str, Any] = self._json("GET", "/healthz")
        return doc


def _refresh(refresh: bool) -> dict[str, str] | None:
    return {"refresh": "true"} if refresh else None


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
