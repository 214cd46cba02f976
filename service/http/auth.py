"""Optional authentication by API key: ``Authorization: Bearer <key>`` or ``X-API-Key: <key>``.

Off by default (the embedded single-user set-up); ``PIPEFLOW_AUTH_REQUIRED=true`` turns it
on.  Then every request to the API (``/v1/...``) and, unless ``PIPEFLOW_METRICS_AUTH=false``,
to ``/metrics`` must carry a key of the key ring; the health probes (``/healthz``,
``/readyz``), the pages, their static assets and the API documentation stay open (they
carry no results and start no computation).  A missing or unknown key is answered 401
(``WWW-Authenticate: Bearer``), a known key outside ``PIPEFLOW_METRICS_KEY_IDS`` on
``/metrics`` 403, both ``application/problem+json``.

The server stores no key, only its SHA-256 with a key id: entries ``<id>:sha256:<hex>``,
separated by commas or new lines, in ``PIPEFLOW_API_KEYS`` and/or the file
``PIPEFLOW_API_KEYS_FILE`` (one per line, ``#`` comments).  A key is 32 random bytes
(``pf_`` + 43 URL-safe characters), so a fast hash is enough: nobody can guess a key from
its hash by trying candidates, and no slow hash (scrypt) is needed to protect it.  Make
one with ``python -m service.http.auth new <id>``: it prints the key once (give it to the
client) and the entry for the server.  Keys are never logged: the log line of a request
names its key id (``principal``), and the key never appears in a URL.

The credentials are read by FastAPI's security utilities (:class:`~fastapi.security.HTTPBearer`,
:class:`~fastapi.security.APIKeyHeader`, which also describe the schemes in the OpenAPI
document when authentication is on), in an ASGI middleware rather than a route dependency,
so that the hit fast path (:class:`service.http.middleware.HitFastPath`) is behind it too.
The key id of an authenticated request is ``request.state.principal`` (None when
authentication is off or the path is open).  Keys whose ids are in
``PIPEFLOW_ADMIN_KEY_IDS`` read and cancel any client's job; every other key only its own
(:mod:`service.http.access`).
"""

from __future__ import annotations

import argparse
import hashlib
import hmac
import re
import secrets
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from fastapi.security import APIKeyHeader, HTTPBearer
from starlette.requests import HTTPConnection
from starlette.types import ASGIApp, Receive, Scope, Send

from service.http.middleware import HttpMiddleware
from service.http.problems import problem, response
from service.settings import Settings

#: a key id: what the log and the quotas name a client by
KEY_ID = re.compile(r"[A-Za-z0-9._-]{1,64}")
#: one entry of the key ring
_ENTRY = re.compile(r"(?P<id>[^:\s]+):sha256:(?P<hex>[0-9a-fA-F]{64})")

bearer = HTTPBearer(
    auto_error=False,
    scheme_name="bearer",
    description="`Authorization: Bearer <key>` with an API key (when the server requires keys).",
)
api_key_header = APIKeyHeader(
    name="X-API-Key",
    auto_error=False,
    scheme_name="apiKey",
    description="`X-API-Key: <key>`, the same keys as the bearer scheme.",
)


class KeyRingError(ValueError):
    """The key ring's settings cannot be used: the server refuses to start."""


@dataclass(frozen=True)
class KeyRing:
    """Key ids by the SHA-256 digest of their key."""

    digests: tuple[tuple[bytes, str], ...] = ()

    @classmethod
    def parse(cls, text: str, source: str = "PIPEFLOW_API_KEYS") -> KeyRing:
        """Entries ``<id>:sha256:<hex>`` separated by commas or new lines; ``#`` starts a
        comment.  Raises :class:`KeyRingError` naming the bad entry's number (never its
        text, which may be a key pasted by mistake)."""
        out = []
        entries = [e.split("#", 1)[0].strip() for e in re.split(r"[,\n]", text)]
        for number, entry in enumerate((e for e in entries if e), start=1):
            m = _ENTRY.fullmatch(entry)
            if m is None or not KEY_ID.fullmatch(m["id"]):
                raise KeyRingError(
                    f"{source}: entry {number} is not <id>:sha256:<64 hex digits> with an id "
                    "of letters, digits, '.', '_' or '-' (make one with: python -m "
                    "service.http.auth new <id>)"
                )
            out.append((bytes.fromhex(m["hex"]), m["id"]))
        return cls(tuple(out))

    @classmethod
    def from_settings(cls, settings: Settings) -> KeyRing:
        """The ring of ``settings.api_keys`` and ``settings.api_keys_file``; with
        ``auth_required``, at least one key (else :class:`KeyRingError`)."""
        ring = cls.parse(settings.api_keys or "")
        path = settings.api_keys_file
        if path is not None:
            try:
                text = Path(path).read_text()
            except OSError as exc:
                raise KeyRingError(
                    f"PIPEFLOW_API_KEYS_FILE={path} cannot be read ({exc.strerror})"
                ) from None
            ring = cls(ring.digests + cls.parse(text, f"PIPEFLOW_API_KEYS_FILE={path}").digests)
        if settings.auth_required and not ring.digests:
            raise KeyRingError(
                "PIPEFLOW_AUTH_REQUIRED is on but there is no key: set PIPEFLOW_API_KEYS or "
                "PIPEFLOW_API_KEYS_FILE (make a key with: python -m service.http.auth new <id>)"
            )
        unknown = sorted(admin_ids(settings) - {key_id for _, key_id in ring.digests})
        if settings.auth_required and unknown:
            raise KeyRingError(
                f"PIPEFLOW_ADMIN_KEY_IDS names {', '.join(map(repr, unknown))}, not the id of "
                "any key of PIPEFLOW_API_KEYS or PIPEFLOW_API_KEYS_FILE"
            )
        return ring

    def identify(self, key: str) -> str | None:
        """The id of ``key``, or None; every entry is compared, in constant time each."""
        digest = hashlib.sha256(key.encode("utf-8", "surrogateescape")).digest()
        found = None
        for known, key_id in self.digests:
            if hmac.compare_digest(known, digest):
                found = key_id
        return found


def new_key(key_id: str) -> tuple[str, str]:
    """A fresh key and its key-ring entry ``<id>:sha256:<hex>``."""
    if not KEY_ID.fullmatch(key_id):
        raise KeyRingError("a key id is 1-64 letters, digits, '.', '_' or '-'")
    key = "pf_" + secrets.token_urlsafe(32)
    return key, f"{key_id}:sha256:{hashlib.sha256(key.encode()).hexdigest()}"


def protected(path: str, settings: Settings) -> bool:
    """Whether ``path`` needs a key when authentication is on: the API and (its own
    switch) the metrics; not the probes, pages, assets and documentation."""
    if path == "/metrics":
        return settings.metrics_auth
    return path == "/v1" or path.startswith("/v1/")


def _ids(text: str) -> frozenset[str]:
    return frozenset(i.strip() for i in text.split(",") if i.strip())


def _metrics_ids(settings: Settings) -> frozenset[str]:
    return _ids(settings.metrics_key_ids)


def admin_ids(settings: Settings) -> frozenset[str]:
    """The key ids of ``PIPEFLOW_ADMIN_KEY_IDS``: they may read and cancel any job
    (:mod:`service.http.access`)."""
    return _ids(settings.admin_key_ids)


class Authenticate(HttpMiddleware):
    """The ASGI middleware: sets ``scope["state"]["principal"]`` (``request.state.principal``)
    to the key id, or answers 401/403 (see the module docstring)."""

    def __init__(self, app: ASGIApp, settings: Settings, ring: KeyRing) -> None:
        super().__init__(app)
        self.settings = settings
        self.ring = ring
        self.metrics_ids = _metrics_ids(settings)

    async def http(self, scope: Scope, receive: Receive, send: Send) -> None:
        state = scope.setdefault("state", {})
        if self.settings.auth_required:
            state["principal"] = None  # only a verified key names one
        else:
            state.setdefault("principal", None)  # an outer layer's identity is kept
        path = scope["path"]
        if not self.settings.auth_required or not protected(path, self.settings):
            await self.app(scope, receive, send)
            return
        connection = HTTPConnection(scope)
        credentials = await bearer(connection)
        key = credentials.credentials if credentials is not None else None
        if key is None:
            key = await api_key_header(connection)
        key_id = self.ring.identify(key) if key is not None else None
        if key_id is None:
            detail = (
                "this server requires an API key: send Authorization: Bearer <key> or "
                "X-API-Key: <key>"
                if key is None
                else "the API key is not known to this server"
            )
            doc = problem(
                401,
                detail,
                slug="unauthorized",
                errors=[
                    {
                        "field": "Authorization",
                        "location": "header",
                        "message": "missing" if key is None else "unknown key",
                        "type": "unauthorized",
                    }
                ],
                instance=path,
            )
            await response(doc, {"WWW-Authenticate": 'Bearer realm="pipeflow"'})(
                scope, receive, send
            )
            return
        if path == "/metrics" and self.metrics_ids and key_id not in self.metrics_ids:
            doc = problem(
                403,
                f"the key {key_id!r} may not read the metrics (PIPEFLOW_METRICS_KEY_IDS)",
                slug="forbidden",
                instance=path,
            )
            await response(doc)(scope, receive, send)
            return
        state["principal"] = key_id
        await self.app(scope, receive, send)


def document(doc: dict[str, Any], settings: Settings) -> dict[str, Any]:
    """Add the security schemes, and to each protected operation its ``security`` and its
    401 (and 403 on /metrics), to the OpenAPI document ``doc`` of a server that requires
    keys (unchanged otherwise)."""
    if not settings.auth_required:
        return doc
    schemes = doc.setdefault("components", {}).setdefault("securitySchemes", {})
    for scheme in (bearer, api_key_header):
        dumped = scheme.model.model_dump(mode="json", by_alias=True, exclude_none=True)
        schemes[scheme.scheme_name] = dumped
    ref = {"schema": {"$ref": "#/components/schemas/Problem"}}
    for path, operations in doc.get("paths", {}).items():
        if not protected(path, settings):
            continue
        for operation in operations.values():
            operation["security"] = [{bearer.scheme_name: []}, {api_key_header.scheme_name: []}]
            answers = operation.setdefault("responses", {})
            answers.setdefault(
                "401",
                {
                    "description": "No API key, or an unknown one.",
                    "content": {"application/problem+json": ref},
                },
            )
            if operation.get("operationId") == "cancelJob":
                answers.setdefault(
                    "403",
                    {
                        "description": "The job is another key's run, which this key joined: "
                        "only the key that started it, or an admin key, cancels it.",
                        "content": {"application/problem+json": ref},
                    },
                )
            if path == "/metrics" and _metrics_ids(settings):
                answers.setdefault(
                    "403",
                    {
                        "description": "The key may not read the metrics.",
                        "content": {"application/problem+json": ref},
                    },
                )
    return doc


def main(argv: list[str] | None = None) -> int:
    """``python -m service.http.auth new <id>``: a key and its entry for the server."""
    parser = argparse.ArgumentParser(
        prog="python -m service.http.auth", description="Make an API key for pipeflow."
    )
    sub = parser.add_subparsers(dest="command", required=True)
    made = sub.add_parser("new", help="a new key: prints the key and the server's entry")
    made.add_argument("id", help="the key id (1-64 letters, digits, '.', '_', '-')")
    args = parser.parse_args(argv)
    try:
        key, entry = new_key(args.id)
    except KeyRingError as exc:
        parser.error(str(exc))
    print(f"key (give it to the client; it is not stored anywhere): {key}")
    print(f"entry (PIPEFLOW_API_KEYS, or a line of PIPEFLOW_API_KEYS_FILE): {entry}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
