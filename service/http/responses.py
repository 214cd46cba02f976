"""The answers of the computing endpoints: a result (cache hit or fresh, JSON or gzip),
the hit cache of pre-encoded answers, and a job record as JSON.

The OpenAPI pieces the routes share (:data:`CACHE_HEADERS`, :data:`JOB_ACCEPTED`) are here
too; what the endpoints do (cache, single flight, jobs) is :mod:`service.orchestration`.
"""

from __future__ import annotations

import asyncio
import gzip
import threading
from collections import OrderedDict
from dataclasses import dataclass
from datetime import UTC, datetime
from typing import Any, Generic, Protocol, TypeVar

from fastapi import Response
from fastapi.responses import JSONResponse

from service.engine.lifecycle import JobState
from service.http.problems import stored_problem
from service.schemas import JobStatus
from service.store import Job

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


class Sized(Protocol):
    """A cached answer: its bytes held in memory."""

    @property
    def size(self) -> int: ...


V = TypeVar("V", bound=Sized)


class AnswerCache(Generic[V]):
    """Encoded answers by name, least recently used evicted beyond ``max_bytes`` in total
    (each value's ``size``); a value larger than the bound is not kept.  Thread-safe:
    put() runs in worker threads too."""

    def __init__(self, max_bytes: int) -> None:
        self.max_bytes = max_bytes
        self._items: OrderedDict[str, V] = OrderedDict()
        self._size = 0
        self._lock = threading.Lock()

    def get(self, key: str) -> V | None:
        with self._lock:
            value = self._items.get(key)
            if value is not None:
                self._items.move_to_end(key)
            return value

    def put(self, key: str, value: V) -> None:
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


class HitCache(AnswerCache[Encoded]):
    """The cache-hit answers (envelope bytes and their gzip) by key: a hit is answered on
    the event loop, with no store read, no thread hop, no parse and no re-encode.  Results
    are immutable per key (the key hashes the normalised request and the version); a
    recomputation (``refresh``) drops the entry."""


def etag_matches(if_none_match: str, etag: str) -> bool:
    """RFC 9110 If-None-Match: weak comparison of each listed tag (or ``*``) against
    ``etag``, the entity tag of the representation the request selects."""
    tags = [t.strip() for t in if_none_match.split(",")]
    return any(t == "*" or t.removeprefix("W/") == etag for t in tags)


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
        "error": stored_problem(job.error) if job.error is not None else None,
        "result": f"/v1/results/{job.key}" if job.status == JobState.SUCCEEDED else None,
        "attempts": job.attempts,
        "last_retry_reason": job.last_retry_reason,
    }
