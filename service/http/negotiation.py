"""Content negotiation of the API: 415 for a body that is not JSON, 406 for an Accept
header the operation cannot satisfy (both ``application/problem+json``).

Used as route dependencies, which FastAPI runs before it validates the body, so a form or
text body is a 415 rather than a 422 about its shape.  A request without ``Accept`` (or
with ``*/*``) gets the operation's first media type; a body without ``Content-Type`` is
read as JSON.
"""

from __future__ import annotations

import re
from collections.abc import Callable, Coroutine
from typing import Any

from fastapi import Request

from service.http.problems import PROBLEM_MEDIA_TYPE, ProblemError

JSON = "application/json"


def media_ranges(accept: str) -> list[tuple[str, float]]:
    """``(media range, q)`` pairs of an Accept header in its order, q > 0 only (the one
    parser of Accept; :func:`service.routes.exports.wanted_format` ranks them)."""
    out = []
    for part in accept.split(","):
        media, *params = (p.strip() for p in part.split(";"))
        q = 1.0
        for p in params:
            if p.startswith("q="):
                try:
                    q = float(p[2:])
                except ValueError:
                    q = 0.0
        if media and q > 0:
            out.append((media.lower(), q))
    return out


def acceptable(accept: str | None, offered: tuple[str, ...]) -> bool:
    """Whether ``accept`` admits one of ``offered`` (or the problem document)."""
    if not accept or not accept.strip():
        return True
    for media, _ in media_ranges(accept):
        kind, _, sub = media.partition("/")
        for o in (*offered, PROBLEM_MEDIA_TYPE):
            okind, _, osub = o.partition("/")
            if media == "*/*" or (kind == okind and sub in ("*", osub)):
                return True
    return False


def accepts(*offered: str) -> Callable[[Request], Coroutine[Any, Any, None]]:
    """A dependency answering 406 unless ``Accept`` admits one of ``offered``."""

    async def check(request: Request) -> None:
        if "format" in request.query_params:  # ?format= overrides Accept where offered
            return
        accept = request.headers.get("accept")
        if not acceptable(accept, offered):
            raise ProblemError(
                406,
                f"cannot answer with any of Accept: {accept!r}; this operation gives "
                + ", ".join(offered),
                slug="not-acceptable",
                errors=[{"field": "Accept", "location": "header", "message": "not acceptable"}],
            )

    return check


def json_declared(ctype: str | None) -> bool:
    """Whether a body with Content-Type ``ctype`` is read as JSON: ``application/json``,
    any ``application/*+json``, or no Content-Type at all."""
    if ctype is None:
        return True
    media = ctype.split(";")[0].strip().lower()
    main, _, sub = media.partition("/")
    return main == "application" and (sub == "json" or sub.endswith("+json"))


async def json_body(request: Request) -> None:
    """A dependency answering 415 unless the body is declared JSON (or not declared)."""
    ctype = request.headers.get("content-type")
    if not json_declared(ctype):
        raise ProblemError(
            415,
            f"the body must be application/json, not {ctype!r}",
            slug="unsupported-media-type",
            errors=[
                {"field": "Content-Type", "location": "header", "message": "not application/json"}
            ],
        )


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
