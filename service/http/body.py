"""Request bodies parsed and validated in a worker thread, not on the event loop.

A computing route declares its body as ``thread_validated(<request type>)`` and uses
:class:`ThreadValidatedRoute` (FastAPI's extension point for custom request handling).
FastAPI parses a JSON body and validates it on the event loop; here the body is read on
the loop (I/O), then ``json.loads`` and the validation run in a worker thread, and
FastAPI's own handler gets the outcome: the validated model, or the validation's error,
which the body type's validator hands back (:class:`ThreadValidated`), so nothing is
validated twice.  What a client sees is unchanged:

- the route's OpenAPI document (the body's JSON schema is the request type's);
- a body that is not JSON: FastAPI's ``json_invalid`` error (400 ``malformed-json`` with
  its byte offset); not UTF-8: the same 400 as before;
- an invalid body: FastAPI's 422, after the route's dependencies (406, 415 first) and
  merged with its query parameters' errors, as FastAPI orders them;
- a body not declared JSON (415), or an empty one: FastAPI's own handling.

Bounded cost is what keeps a body from stalling the service (a long C call holds the GIL
in any thread): the body's size (``max_body_bytes``), the unit grammar of quantities
(:mod:`pipeflow.schema.units`).  The thread lets the loop run between the Python parts of a
large validation (unit conversions, model validators).
"""

from __future__ import annotations

import functools
import json
import typing
from collections.abc import Callable, Coroutine
from dataclasses import dataclass
from typing import Annotated, Any

import anyio.to_thread
from fastapi import HTTPException, Request, Response
from fastapi.exceptions import RequestValidationError
from fastapi.routing import APIRoute
from pydantic import GetCoreSchemaHandler, TypeAdapter, ValidationError
from pydantic_core import CoreSchema, core_schema
from starlette.exceptions import HTTPException as StarletteHTTPException

from service.http.negotiation import json_declared

__all__ = ["ThreadValidated", "ThreadValidatedRoute", "thread_validated"]

#: FastAPI's detail when a body cannot be read or decoded (a 400)
PARSE_ERROR = "There was an error parsing the body"


@dataclass(frozen=True)
class _Outcome:
    """A body validated in a worker thread: its value, or the error of its validation; and
    the parsed JSON document (for the error's report)."""

    doc: Any
    value: Any = None
    error: ValidationError | None = None


class ThreadValidated:
    """Annotation of a body type ``tp`` validated in a worker thread: ``Annotated[Any,
    ThreadValidated(tp)]`` (:func:`thread_validated`).  Its JSON schema is ``tp``'s; its
    validator returns the outcome of :meth:`validate` (the value, or raises the error
    unchanged), and validates anything else as ``tp`` does."""

    def __init__(self, tp: Any) -> None:
        self.tp = tp

    @functools.cached_property
    def adapter(self) -> TypeAdapter[Any]:
        return TypeAdapter(self.tp)

    def validate(self, doc: Any) -> _Outcome:
        """``doc`` validated as ``tp`` (FastAPI's call: attributes read from objects)."""
        try:
            return _Outcome(doc, self.adapter.validate_python(doc, from_attributes=True))
        except ValidationError as exc:
            return _Outcome(doc, error=exc)

    def _unwrap(self, value: Any) -> Any:
        if isinstance(value, _Outcome):
            if value.error is not None:
                raise value.error  # pydantic passes it on: FastAPI's errors, loc from body
            return value.value
        return self.adapter.validate_python(value, from_attributes=True)

    def __get_pydantic_core_schema__(
        self, source: Any, handler: GetCoreSchemaHandler
    ) -> CoreSchema:
        # the schema of tp itself (``source`` is Any: a discriminated union's Field would
        # otherwise be applied to this function's schema)
        return core_schema.no_info_plain_validator_function(
            self._unwrap, json_schema_input_schema=handler.generate_schema(self.tp)
        )


def thread_validated(tp: Any) -> Any:
    """The body type ``tp`` validated in a worker thread by :class:`ThreadValidatedRoute`."""
    return Annotated[Any, ThreadValidated(tp)]


def _validator(field: Any) -> ThreadValidated | None:
    """The :class:`ThreadValidated` of a route's body field, if it has one."""
    info = getattr(field, "field_info", None)
    found = [*getattr(info, "metadata", ()), *typing.get_args(getattr(info, "annotation", None))]
    return next((m for m in found if isinstance(m, ThreadValidated)), None)


class _ReadRequest(Request):
    """The request with its body read: ``json()`` is the body's validation outcome."""

    def __init__(self, request: Request, raw: bytes, outcome: _Outcome) -> None:
        super().__init__(request.scope, request.receive)
        self._raw, self._outcome = raw, outcome

    async def body(self) -> bytes:
        return self._raw

    async def json(self) -> Any:
        return self._outcome


def _parse_and_validate(validator: ThreadValidated, raw: bytes) -> _Outcome | Exception:
    """``raw`` parsed and validated (in a worker thread): the outcome, or the exception
    FastAPI raises for a body it cannot parse."""
    try:
        doc = json.loads(raw)
    except json.JSONDecodeError as e:
        # FastAPI's own error for a body that is not JSON (fastapi.routing)
        return RequestValidationError(
            [
                {
                    "type": "json_invalid",
                    "loc": ("body", e.pos),
                    "msg": "JSON decode error",
                    "input": {},
                    "ctx": {"error": e.msg},
                }
            ],
            body=e.doc,
        )
    except Exception as e:  # not UTF-8, nested too deep: FastAPI's 400
        error = HTTPException(status_code=400, detail=PARSE_ERROR)
        error.__cause__ = e
        return error
    return validator.validate(doc)


class ThreadValidatedRoute(APIRoute):
    """An :class:`~fastapi.routing.APIRoute` whose body, declared
    :func:`thread_validated`, is parsed and validated in a worker thread (see the module
    docstring); other routes are FastAPI's."""

    def get_route_handler(self) -> Callable[[Request], Coroutine[Any, Any, Response]]:
        handler = super().get_route_handler()
        validator = _validator(self.body_field)
        if validator is None:
            return handler

        async def validated_in_thread(request: Request) -> Response:
            if not json_declared(request.headers.get("content-type")):
                return await handler(request)  # a 415 (service.http.negotiation)
            try:
                raw = await request.body()
            except StarletteHTTPException:
                raise  # the body limit's 413
            except Exception as e:
                raise HTTPException(status_code=400, detail=PARSE_ERROR) from e
            if not raw:
                return await handler(request)  # FastAPI's "missing"
            outcome = await anyio.to_thread.run_sync(_parse_and_validate, validator, raw)
            if isinstance(outcome, Exception):
                raise outcome
            try:
                return await handler(_ReadRequest(request, raw, outcome))
            except RequestValidationError as exc:
                if exc.body is outcome:  # FastAPI reports the body it validated: the JSON
                    exc.body = outcome.doc
                exc.body_type = validator.tp  # type: ignore[attr-defined]  # its messages
                raise

        return validated_in_thread
