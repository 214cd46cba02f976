"""RFC 9457 ``application/problem+json`` for every error, in one place.

Handlers map request-validation errors (with the offending field), :class:`PipeflowError`
(with its ``field``), HTTP errors (404, 405, 413) and :class:`ProblemError` raised by the
service to problem documents.  Unexpected exceptions become a 500 problem; bad input never
reaches that path because it is validated first.
"""

from __future__ import annotations

import logging
from typing import Any

from fastapi import FastAPI, Request
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse
from pydantic import BaseModel, ConfigDict, Field
from starlette.exceptions import HTTPException as StarletteHTTPException

from pipeflow.errors import ErrorRecord, PipeflowError, StorageError, classify
from pipeflow.schema import messages
from service import observability

log = logging.getLogger("service")

PROBLEM_MEDIA_TYPE = "application/problem+json"
TYPE_BASE = "https://pipeflow.dev/problems/"

_TITLES = {
    400: "Bad request",
    401: "Unauthorized",
    403: "Forbidden",
    404: "Not found",
    405: "Method not allowed",
    406: "Not acceptable",
    409: "Conflict",
    413: "Request body too large",
    415: "Unsupported media type",
    422: "Invalid input",
    429: "Too many requests",
    500: "Internal server error",
    503: "Service unavailable",
    507: "Insufficient storage",
}


class FieldError(BaseModel):
    """One offending input."""

    field: str | None = Field(
        description="Dotted path of the offending field, e.g. 'pipe.E' (null: the whole body)."
    )
    pointer: str | None = Field(
        None, description="JSON Pointer (RFC 6901) into the request body, e.g. '#/pipe/E'."
    )
    location: str = Field("body", description="Where the input is: body, query or path.")
    message: str = Field(description="What is wrong with it.")
    type: str = Field("value_error", description="Machine-readable error type.")
    offset: int | None = Field(
        None,
        description="Byte offset into the request body where it stops being valid UTF-8 "
        "or JSON (malformed bodies only) [bytes].",
    )


class Problem(BaseModel):
    """An RFC 9457 problem document (``application/problem+json``)."""

    model_config = ConfigDict(extra="allow")

    type: str = Field("about:blank", description="URI identifying the problem type.")
    title: str = Field(description="Short summary of the problem type.")
    status: int = Field(description="HTTP status code.")
    detail: str | None = Field(None, description="Explanation of this occurrence.")
    instance: str | None = Field(None, description="The request path.")
    errors: list[FieldError] | None = Field(
        None, description="Offending inputs (validation errors)."
    )
    request_id: str | None = Field(
        None,
        description="A 500's request id (also the X-Request-ID header): the server's log has "
        "the error's description under it; the body never carries internal exception text.",
    )


class ProblemError(Exception):
    """Raise from a handler to answer with a problem document."""

    def __init__(
        self,
        status: int,
        detail: str,
        *,
        slug: str | None = None,
        title: str | None = None,
        headers: dict[str, str] | None = None,
        errors: list[dict[str, Any]] | None = None,
    ) -> None:
        super().__init__(detail)
        self.status = status
        self.detail = detail
        self.slug = slug
        self.title = title
        self.headers = headers
        self.errors = errors

    @classmethod
    def from_document(cls, doc: dict[str, Any]) -> ProblemError:
        """Re-raise a problem document produced elsewhere (e.g. in a worker)."""
        err = cls(int(doc.get("status", 500)), str(doc.get("detail", "")))
        err.doc = dict(doc)
        return err

    doc: dict[str, Any] | None = None

    def document(self, instance: str | None = None) -> dict[str, Any]:
        if self.doc is not None:
            return {**self.doc, "instance": instance} if instance else dict(self.doc)
        return problem(
            self.status,
            self.detail,
            slug=self.slug,
            title=self.title,
            errors=self.errors,
            instance=instance,
        )


def problem(
    status: int,
    detail: str | None,
    *,
    slug: str | None = None,
    title: str | None = None,
    errors: list[dict[str, Any]] | None = None,
    instance: str | None = None,
) -> dict[str, Any]:
    """A problem document as a dict (``slug`` names the type under :data:`TYPE_BASE`)."""
    doc: dict[str, Any] = {
        "type": TYPE_BASE + slug if slug else "about:blank",
        "title": title or _TITLES.get(status, "Error"),
        "status": status,
    }
    if detail:
        doc["detail"] = detail
    if instance:
        doc["instance"] = instance
    if errors:
        doc["errors"] = errors
    return doc


#: the one table from an engine's (or the library's) :class:`ErrorRecord` to a problem:
#: per record kind, ``(status, slug, title)``; a slug of None is the record's own type (a
#: refusal's, e.g. ``budget-exceeded``), a title of None the status's
RECORD_PROBLEMS: dict[str, tuple[int, str | None, str | None]] = {
    "refused": (422, None, None),
    "numerical-range": (422, "numerical-range", "Inputs out of numerical range"),
    "runtime-limit": (422, "runtime-limit", "Runtime limit exceeded"),
    "storage": (503, "storage", None),  # 507 when the disk is full
    "cancelled": (409, "cancelled", None),
    "internal": (500, "internal", None),
}

#: what the detail of a numerical-range problem adds: the inputs whose magnitudes set the
#: scales (no single field can be blamed)
NUMERICAL_RANGE_ADVICE = (
    "check the magnitudes of pipe (E, I, L, M1, M2, damping, tip_mass, tip_inertia), "
    "rotation.omega0, rotation.hub_radius and flow.velocity"
)


def record_problem(record: ErrorRecord) -> dict[str, Any]:
    """The problem document of ``record`` (see :data:`RECORD_PROBLEMS`).

    A refusal points at the request field (``record.field``, set by the schema layer; the
    library's parameter if it set none) and carries the step bounds the library gave."""
    status, slug, title = RECORD_PROBLEMS.get(record.kind, RECORD_PROBLEMS["internal"])
    slug = slug or record.type
    data = record.data
    if record.kind == "storage":
        log.warning("storage failure answered without its text: %s", record.message)
        full = bool(data.get("full"))
        return problem(
            507 if full else 503,
            _storage_detail("the result could not be stored: " + STORAGE_CAUSES[full]),
            slug=slug,
            title=title,
        )
    if status >= 500:  # a bug: its text goes to the log, never to the client
        log.error("internal error answered without its text: %s", record.message)
        return internal_problem()
    detail = record.message
    if record.kind == "numerical-range":
        detail = f"{detail}; {NUMERICAL_RANGE_ADVICE}"
    if record.kind != "refused":
        return problem(status, detail, slug=slug, title=title)
    field = record.field if record.field is not None else data.get("parameter")
    err: dict[str, Any] = {
        "field": field,
        "pointer": _pointer(field.split(".")) if field else None,
        "location": "body",
        "message": record.message,
        "type": slug,
    }
    doc = problem(status, detail, slug=slug, title=title, errors=[err])
    if "largest_stable_step" in data:
        doc["largest_stable_step"] = data["largest_stable_step"]
    if data.get("smallest_step") is not None:
        doc["smallest_step"] = data["smallest_step"]
    return doc


def stored_problem(error: dict[str, Any]) -> dict[str, Any]:
    """The problem document of a job record's stored ``error``: the record's mapping, or
    the stored document itself when it is not a record (a cancellation's note, or a record
    written before the engine stored records)."""
    record = ErrorRecord.from_dict(error)
    return record_problem(record) if record is not None else error


def response(doc: dict[str, Any], headers: dict[str, str] | None = None) -> JSONResponse:
    return JSONResponse(
        doc, status_code=int(doc["status"]), media_type=PROBLEM_MEDIA_TYPE, headers=headers
    )


def responses(*codes: int) -> dict[int | str, dict[str, Any]]:
    """OpenAPI ``responses`` entries declaring the problem documents a route can return."""
    descriptions = {
        400: "Malformed request: the body is not valid JSON (or, sent as gzip, not valid gzip).",
        415: "The body is not application/json, or its Content-Encoding is neither gzip nor "
        "identity.",
        304: "Not modified: the client's copy (If-None-Match) is current.",
        404: "Unknown key.",
        406: "Not acceptable: the Accept header admits none of the operation's media types, "
        "or the requested format needs an optional extra the server lacks (e.g. pyarrow).",
        401: "An API key is required (the server's auth_required) and none, or an unknown "
        "one, was sent.",
        409: "The job is in a state that does not allow this.",
        413: "Request body larger than the configured limit.",
        422: "Invalid input; `errors` names each offending field.  Besides the schema, the "
        "rules across fields that JSON Schema cannot state: M1 + M2 >= 1e-15 kg/m, [lo, hi] "
        "ranges increasing, table times strictly increasing, starting at t <= 0 and covering "
        "time.t_end, stations within [0, L], tracked_modes <= modes, max_points >= points, "
        "a common period of harmonic flow and spin, and the work budgets of maps and charts.",
        429: "Over one of the client's quotas (concurrent jobs, queued jobs, cost per "
        "minute); retry after the Retry-After header [s].",
        503: "Saturated or not ready; retry after the Retry-After header [s].",
    }
    out: dict[int | str, dict[str, Any]] = {}
    for code in codes:
        entry: dict[str, Any] = {"description": descriptions.get(code, _TITLES.get(code, ""))}
        if code >= 400:
            entry["model"] = Problem
        if code in (429, 503):
            entry["headers"] = {
                "Retry-After": {"description": "Seconds to wait", "schema": {"type": "integer"}}
            }
        out[code] = entry
    return out


# -- mapping validation errors to fields -------------------------------------------------


def _pointer(parts: list[Any]) -> str:
    escaped = [str(p).replace("~", "~0").replace("/", "~1") for p in parts]
    return "#/" + "/".join(escaped) if escaped else "#"


#: pydantic's labels of a union's members in an error's location (no field has them)
_UNION_LABELS = frozenset({"float", "int", "str", "bool", "list", "dict", "none"})


def _union_member(part: Any) -> bool:
    """Whether a location part is pydantic's label of a union member (``constrained-float``,
    ``tagged-union[...]``, ``function-wrap[...]``, ``float``...): field names have neither
    ``-`` nor ``[``."""
    return isinstance(part, str) and ("[" in part or "-" in part or part in _UNION_LABELS)


def _walk(body: Any, loc: tuple[Any, ...]) -> list[Any]:
    """Follow ``loc`` through the submitted body, dropping the union tags pydantic inserts."""
    path: list[Any] = []
    node = body
    for part in loc:
        if isinstance(node, dict) and part in node:
            node = node[part]
            path.append(part)
        elif isinstance(node, dict) and part in (node.get("kind"), node.get("distribution")):
            # discriminated-union tag, e.g. ('velocity', 'polynomial', 'coefficients'), or a
            # study's ('samples', 'parameters', 'pipe.E', 'lognormal', 'sigma')
            continue
        elif node is not None and _union_member(part):
            # the member of a plain union pydantic tried, e.g. ('flow', 'pressure',
            # 'constrained-float') or 'tagged-union[...]': no field of the body
            continue
        elif isinstance(node, list) and isinstance(part, int) and 0 <= part < len(node):
            node = node[part]
            path.append(part)
        else:  # a missing field, or below one
            path.append(part)
            node = None
    return path


def _named_field(body: Any, base: list[Any], err: dict[str, Any]) -> list[Any]:
    """A validator's refusal names its field as data (:class:`pipeflow.errors.InvalidField`,
    ``loc`` below the model or field it checks, the error's ``ctx["error"]``); resolve it.

    ``InvalidField(..., "output.eigen_modes")`` raised on the whole body points at
    ``output.eigen_modes``; ``"M1"`` raised on ``pipe`` at ``pipe.M1`` when the body gives
    ``pipe.M1`` (a one-part location that the body lacks stays at ``base``); ``"methods"``
    raised by the validator of ``methods`` at ``methods`` (its own field, not
    ``methods.methods``).  A refusal without a location stays at ``base``.
    """
    loc = getattr((err.get("ctx") or {}).get("error"), "loc", None)
    if not loc:
        return base
    parts = [str(p) for p in loc]
    node = body
    for part in base:
        if isinstance(node, dict):
            node = node.get(part)
        elif isinstance(node, list) and isinstance(part, int) and 0 <= part < len(node):
            node = node[part]
        else:
            node = None
    if base and parts[0] == str(base[-1]):
        # a field validator naming its own field: ("methods", ...) raised on ``methods``
        return base + parts[1:]
    if len(parts) > 1 or (isinstance(node, dict) and parts[0] in node):
        return base + parts
    return base


def validation_errors(exc: RequestValidationError) -> list[dict[str, Any]]:
    """Each error of ``exc`` as the problem document's entry: the field, its JSON
    pointer, and the message (:func:`pipeflow.schema.messages.message`: no "Value error,"
    prefix, the quantity form for "3000 rpm" sent as text, a "did you mean" for an
    unknown field of the body's type, which :mod:`service.http.body` attaches as
    ``exc.body_type``)."""
    body = getattr(exc, "body", None)
    model = getattr(exc, "body_type", None)
    out: list[dict[str, Any]] = []
    for err in exc.errors():
        offset: int | None = None
        loc = tuple(err.get("loc", ()))
        where = str(loc[0]) if loc else "body"
        rest = loc[1:]
        if where == "body":
            path = _walk(body, rest)
            if err.get("type") == "value_error" or err.get("type") == "assertion_error":
                path = _named_field(body, path, err)
            if err.get("type") == "json_invalid":
                path = []
                offset = _byte_offset(body, rest)
            if not path and err.get("type") in ("union_tag_invalid", "union_tag_not_found"):
                # the body itself is a tagged union (/v1/sweeps): name its tag, e.g. 'kind'
                tag = str((err.get("ctx") or {}).get("discriminator", "")).strip("'\"")
                path = [tag] if tag.isidentifier() else path
        else:
            path = list(rest)
        field = ".".join(str(p) for p in path) or None
        out.append(
            {
                "field": field,
                "pointer": _pointer(path) if where == "body" else None,
                "location": where,
                "message": messages.message(err, model if where == "body" else None),
                "type": str(err.get("type", "value_error")),
            }
        )
        if offset is not None:
            message = f"{out[-1]['message']} at byte offset {offset}"
            detail = (err.get("ctx") or {}).get("error")
            out[-1].update(message=f"{message}: {detail}" if detail else message, offset=offset)
    return out


def _byte_offset(doc: Any, loc: tuple[Any, ...]) -> int | None:
    """The byte offset in the UTF-8 body of a JSON error at character ``loc[0]`` of the
    decoded ``doc`` (FastAPI's json_invalid error carries the character position)."""
    if not (isinstance(doc, str) and loc and isinstance(loc[0], int)):
        return None
    return len(doc[: loc[0]].encode("utf-8", "surrogatepass"))


def allowed_methods(request: Request) -> list[str]:
    """Every method some route of the app serves at the request's path."""
    path = request.url.path
    methods: set[str] = set()

    def walk(routes: list[Any]) -> None:
        for route in routes:
            inner = getattr(route, "original_router", None)  # an included router
            if inner is not None:
                walk(inner.routes)
            regex = getattr(route, "path_regex", None)
            if regex is not None and regex.match(path):
                methods.update(getattr(route, "methods", None) or ())

    walk(request.app.routes)
    return sorted(methods)


# -- handlers ------------------------------------------------------------------------------


#: what a 503/507 of the store says, by whether its disk is full (the driver's text is logged)
STORAGE_CAUSES = {True: "the disk of the store is full", False: "the store could not be written"}


def _storage_detail(cause: str) -> str:
    return (
        f"{cause}; the request was not done, and the service recovers by itself once the "
        f"store is writable again: retry later (the cause is in the server's log under "
        f"request id {observability.request_id()})"
    )


def storage_problem(exc: StorageError, instance: str | None = None) -> dict[str, Any]:
    """507 when the store's disk is full, else 503: nothing was lost, retry later.  The
    driver's text (logged by the store) is not sent."""
    return problem(
        507 if exc.full else 503,
        _storage_detail(STORAGE_CAUSES[exc.full]),
        slug="storage",
        instance=instance,
    )


def internal_problem(instance: str | None = None) -> dict[str, Any]:
    """The 500 of a bug: no exception text (that is in the log), the request id instead,
    as ``request_id`` and in the detail, to find the log lines."""
    rid = observability.request_id()
    doc = problem(
        500,
        f"an internal error occurred; its description is in the server's log under "
        f"request id {rid}",
        slug="internal",
        instance=instance,
    )
    doc["request_id"] = rid
    return doc


def undecodable_body(exc: UnicodeDecodeError, instance: str | None = None) -> dict[str, Any]:
    """The 400 of a JSON body that is not UTF-8 (RFC 8259 section 8.1), naming the byte
    offset where decoding failed."""
    message = f"the body is not valid UTF-8 at byte offset {exc.start} ({exc.reason})"
    err = {
        "field": None,
        "pointer": "#",
        "location": "body",
        "message": message,
        "type": "utf8_invalid",
        "offset": exc.start,
    }
    return problem(400, message, slug="malformed-json", errors=[err], instance=instance)


def storage_headers(app: FastAPI) -> dict[str, str]:
    return {"Retry-After": str(app.state.settings.retry_after_s)}


def install(app: FastAPI) -> None:
    """Register the problem+json exception handlers on ``app``."""

    @app.exception_handler(RequestValidationError)
    async def _validation(request: Request, exc: RequestValidationError) -> JSONResponse:
        errors = validation_errors(exc)
        detail = "; ".join(f"{e['field'] or 'body'}: {e['message']}" for e in errors[:5])
        if any(e["type"] == "json_invalid" for e in errors):  # not JSON at all: 400
            return response(
                problem(
                    400, detail, slug="malformed-json", errors=errors, instance=request.url.path
                )
            )
        return response(
            problem(422, detail, slug="validation", errors=errors, instance=request.url.path)
        )

    @app.exception_handler(PipeflowError)
    async def _pipeflow(request: Request, exc: PipeflowError) -> JSONResponse:
        doc = record_problem(classify(exc))
        doc["instance"] = request.url.path
        return response(doc)

    @app.exception_handler(ProblemError)
    async def _problem(request: Request, exc: ProblemError) -> JSONResponse:
        return response(exc.document(request.url.path), exc.headers)

    @app.exception_handler(StorageError)
    async def _storage(request: Request, exc: StorageError) -> JSONResponse:
        return response(storage_problem(exc, request.url.path), storage_headers(request.app))

    @app.exception_handler(StarletteHTTPException)
    async def _http(request: Request, exc: StarletteHTTPException) -> JSONResponse:
        if isinstance(exc.__cause__, UnicodeDecodeError):  # FastAPI's "error parsing the body"
            return response(undecodable_body(exc.__cause__, request.url.path))
        detail = exc.detail if isinstance(exc.detail, str) else None
        headers = dict(exc.headers) if exc.headers else {}
        if exc.status_code == 405:
            # Starlette names the methods of the first route matching the path only; a path
            # served by several routes (GET and DELETE /v1/jobs/{key}) allows all of theirs
            headers["Allow"] = ", ".join(allowed_methods(request))
        return response(
            problem(exc.status_code, detail, instance=request.url.path), headers or None
        )

    @app.exception_handler(Exception)
    async def _internal(request: Request, exc: Exception) -> JSONResponse:
        # reached only from outside the middleware (RequestContext answers the rest)
        log.exception("unhandled error on %s", request.url.path)
        return response(internal_problem(request.url.path))
