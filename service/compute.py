"""What every computing endpoint does, for any computation: cache, single flight, jobs.

Routes stay thin: they validate the body once (FastAPI + the computation's request model),
key it once (:func:`service.keys.keyed`) and call :func:`run_sync` (answer with the
result) or :func:`accept_job` (answer 202 with a job); the OpenAPI pieces they share
(:data:`Refresh`, :data:`CACHE_HEADERS`, :data:`JOB_ACCEPTED`) are here too.
"""

from __future__ import annotations

import asyncio
import gzip
import re
import threading
from collections import OrderedDict
from dataclasses import dataclass
from datetime import UTC, datetime
from typing import Annotated, Any

from fastapi import Query, Response
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse
from pydantic import ValidationError

from service.engine import ComputationCancelled, ComputationFailed, QueueFull, Runner
from service.keys import Keyed
from service.problems import ProblemError
from service.schemas import JobStatus
from service.store import Job, Store

Refresh = Annotated[
    bool, Query(description="Recompute even if the result is cached (and replace it).")
]

#: OpenAPI headers of a result answered by :func:`result_response`
CACHE_HEADERS: dict[str, Any] = {
    "X-Cache": {
        "description": "HIT when served from the cache, MISS when computed for this request.",
        "schema": {"type": "string", "enum": ["HIT", "MISS"]},
    },
    "ETag": {
        "description": 'Strong validator of the representation sent: the key in quotes, `"<key>"`, '
        'for the JSON bytes, `"<key>-gzip"` for their gzip (Content-Encoding: gzip).',
        "schema": {"type": "string"},
    },
}

#: OpenAPI entry of the 202 answered by :func:`accept_job`
JOB_ACCEPTED: dict[int | str, dict[str, Any]] = {
    202: {"headers": {"Location": {"description": "/v1/jobs/{key}", "schema": {"type": "string"}}}}
}


def envelope(key: str, cached: bool, body: bytes) -> bytes:
    """``{"key": ..., "cached": ..., **result}`` without re-encoding the stored result."""
    head = b'{"key":"%s","cached":%s' % (key.encode(), b"true" if cached else b"false")
    rest = body.strip()[1:]  # the stored body is a JSON object: drop its '{'
    return head + (b"," + rest if rest.strip() != b"}" else b"}")


#: answers shorter than this are sent uncompressed [bytes] (gzip's header costs ~20)
GZIP_MIN_BYTES = 1024
#: zlib level of the pre-compressed hit answers (compressed once per key, sent many times)
GZIP_LEVEL = 6


@dataclass(frozen=True)
class Encoded:
    """One answer body as sent: ``identity`` bytes and, when worth it, their ``gzip``."""

    identity: bytes
    gzip: bytes | None = None

    @property
    def size(self) -> int:
        return len(self.identity) + len(self.gzip or b"")


def encode(body: bytes) -> Encoded:
    """``body`` with its gzip (deterministic: mtime 0) when at least GZIP_MIN_BYTES long."""
    if len(body) < GZIP_MIN_BYTES:
        return Encoded(body)
    return Encoded(body, gzip.compress(body, GZIP_LEVEL, mtime=0))


class HitCache:
    """The cache-hit answers (envelope bytes and their gzip) by key, least recently used
    evicted beyond ``max_bytes`` in total: a hit is answered on the event loop, with no
    store read, no thread hop, no parse and no re-encode.  Results are immutable per key
    (the key hashes the normalised request and the version); a recomputation
    (``refresh``) drops the entry."""

    def __init__(self, max_bytes: int) -> None:
        self.max_bytes = max_bytes
        self._items: OrderedDict[str, Encoded] = OrderedDict()
        self._size = 0
        self._lock = threading.Lock()  # put() runs in worker threads too

    def get(self, key: str) -> Encoded | None:
        with self._lock:
            value = self._items.get(key)
            if value is not None:
                self._items.move_to_end(key)
            return value

    def put(self, key: str, value: Encoded) -> None:
        with self._lock:
            self._pop(key)
            if value.size > self.max_bytes:
                return
            self._items[key] = value
            self._size += value.size
            while self._size > self.max_bytes:
                _, old = self._items.popitem(last=False)
                self._size -= old.size

    def pop(self, key: str) -> None:
        with self._lock:
            self._pop(key)

    def _pop(self, key: str) -> None:
        old = self._items.pop(key, None)
        if old is not None:
            self._size -= old.size

    def __len__(self) -> int:
        return len(self._items)


_CODING = re.compile(r"\s*([A-Za-z0-9*_-]+)\s*(?:;\s*q\s*=\s*([0-9.]+))?\s*")


def accepts_gzip(accept_encoding: str | None) -> bool:
    """RFC 9110 section 12.5.3: gzip (or ``*``) listed with a q-value above 0."""
    if not accept_encoding:
        return False
    q_of: dict[str, float] = {}
    for part in accept_encoding.split(","):
        m = _CODING.fullmatch(part)
        if m is None:
            continue
        try:
            q = float(m.group(2)) if m.group(2) is not None else 1.0
        except ValueError:
            continue
        q_of[m.group(1).lower()] = q
    q = q_of.get("gzip", q_of.get("x-gzip", q_of.get("*", 0.0)))
    return q > 0


@dataclass(frozen=True)
class Hit:
    """The per-request part of the hit path: the app's :class:`HitCache` and whether the
    client accepts gzip (see :func:`service.deps.get_hit`)."""

    cache: HitCache | None = None
    gzip: bool = False


def entity_tag(key: str, gzip: bool = False) -> str:
    """The strong ETag of a result answer: ``"<key>"`` for its JSON bytes, a distinct
    ``"<key>-gzip"`` for their gzip (another representation, other bytes: RFC 9110 section
    8.8.3 says the two must not share a strong tag).  The gzip bytes are a function of the
    JSON bytes (fixed level, mtime 0)."""
    return f'"{key}-gzip"' if gzip else f'"{key}"'


def sends_gzip(encoded: Encoded, gzip_ok: bool) -> bool:
    """Whether the answer of ``encoded`` is its gzip: accepted and worth compressing."""
    return gzip_ok and encoded.gzip is not None


def result_response(
    key: str, cached: bool, body: bytes | Encoded, gzip_ok: bool = False
) -> Response:
    """A result answer: the envelope (or ``Encoded`` envelope), gzip when accepted and
    available, with X-Cache, the ETag of the representation sent (:func:`entity_tag`),
    Content-Location and ``Vary: Accept-Encoding``."""
    encoded = body if isinstance(body, Encoded) else Encoded(envelope(key, cached, body))
    packed = sends_gzip(encoded, gzip_ok)
    headers = {
        "X-Cache": "HIT" if cached else "MISS",
        "ETag": entity_tag(key, packed),
        "Content-Location": f"/v1/results/{key}",
        "Vary": "Accept-Encoding",
    }
    content = encoded.identity
    if packed:
        assert encoded.gzip is not None
        content = encoded.gzip
        headers["Content-Encoding"] = "gzip"
    return Response(content, media_type="application/json", headers=headers)


async def encoded_hit(key: str, body: bytes, hit: Hit | None) -> Encoded:
    """The HIT answer for the stored ``body``, encoded (and compressed, off the event loop)
    once, then kept in the hit cache."""
    if hit is None or hit.cache is None:
        return Encoded(envelope(key, True, body))
    encoded = await asyncio.to_thread(encode, envelope(key, True, body))
    hit.cache.put(key, encoded)
    return encoded


async def hit_response(key: str, body: bytes, hit: Hit | None) -> Response:
    """The HIT answer for the stored ``body`` (see :func:`encoded_hit`)."""
    encoded = await encoded_hit(key, body, hit)
    return result_response(key, True, encoded, hit is not None and hit.gzip)


def _saturated(runner: Runner, exc: QueueFull) -> ProblemError:
    return ProblemError(
        503,
        f"all {runner.capacity} computation slots are taken ({exc}); retry later",
        slug="saturated",
        headers={"Retry-After": str(runner.settings.retry_after_s)},
    )


async def check_request(job: Keyed) -> None:
    """The computation's validation too costly for the event loop
    (:attr:`~pipeflow.schema.registry.Computation.check`, e.g. every case of a study), in a
    thread; a failure is answered as the body's own validation errors are (422 naming the
    field)."""
    check = job.computation.check
    if check is None:
        return
    try:
        await asyncio.to_thread(check, job.request)
    except ValidationError as exc:
        errors = [{**e, "loc": ("body", *e["loc"])} for e in exc.errors()]
        body = job.request.model_dump(mode="json", exclude_unset=True)
        raise RequestValidationError(errors, body=body) from None


async def run_sync(
    runner: Runner, store: Store, job: Keyed, refresh: bool, hit: Hit | None = None
) -> Response:
    """Serve the result of ``job``: from the cache, or computed now (once per key).

    With ``hit`` (the app's hit cache, see :class:`Hit`), a hit is answered from memory as
    its pre-encoded bytes, gzip when the client accepts it."""
    key = job.key
    cache = hit.cache if hit is not None else None
    if not refresh:
        encoded = cache.get(key) if cache is not None else None
        if encoded is not None:
            return result_response(key, True, encoded, hit is not None and hit.gzip)
        body = await asyncio.to_thread(store.get_result, key)
        if body is not None:
            return await hit_response(key, body, hit)
    if cache is not None:
        cache.pop(key)  # a recomputation replaces the stored result
    if not runner.is_active(key):
        await check_request(job)
    try:
        task = await runner.submit(job, force=refresh)
        body = await asyncio.shield(task)
    except QueueFull as exc:
        raise _saturated(runner, exc) from None
    except ComputationFailed as exc:
        raise ProblemError.from_document(exc.problem) from None
    except ComputationCancelled as exc:
        raise ProblemError(409, f"the computation was cancelled: {exc}", slug="cancelled") from None
    return result_response(key, False, body)


async def submit_job(runner: Runner, store: Store, job: Keyed, refresh: bool) -> Job:
    """Accept ``job`` (idempotent: the id is the parameter hash) and return its record."""
    key = job.key
    if not refresh and not runner.is_active(key) and await asyncio.to_thread(store.has_result, key):
        await asyncio.to_thread(store.mark_succeeded, key, job.computation.name, job.canonical)
    else:
        if not runner.is_active(key):
            await check_request(job)
        try:
            await runner.submit(job, force=refresh)
        except QueueFull as exc:
            raise _saturated(runner, exc) from None
    record = await asyncio.to_thread(store.get_job, key)
    assert record is not None
    return record


async def accept_job(runner: Runner, store: Store, job: Keyed, refresh: bool) -> JSONResponse:
    """:func:`submit_job`, answered 202 with the job and ``Location: /v1/jobs/{key}``."""
    return job_response(await submit_job(runner, store, job, refresh), 202)


def job_response(job: Job, status: int = 200) -> JSONResponse:
    """The job as :class:`service.schemas.JobStatus` JSON; a 202 carries its ``Location``."""
    body = JobStatus.model_validate(job_document(job)).model_dump(mode="json")
    headers = {"Location": f"/v1/jobs/{job.key}"} if status == 202 else None
    return JSONResponse(body, status, headers)


def _time(t: float | None) -> datetime | None:
    return None if t is None else datetime.fromtimestamp(t, tz=UTC)


def job_document(job: Job) -> dict[str, Any]:
    """The JSON of a job record (see :class:`service.schemas.JobStatus`)."""
    return {
        "key": job.key,
        "kind": job.kind,
        "status": job.status,
        "progress": job.progress,
        "created": _time(job.created),
        "started": _time(job.started),
        "finished": _time(job.finished),
        "updated": _time(job.updated),
        "error": job.error,
        "result": f"/v1/results/{job.key}" if job.status == "succeeded" else None,
        "attempts": job.attempts,
        "last_retry_reason": job.last_retry_reason,
    }
