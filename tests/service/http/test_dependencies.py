"""The request dependencies of the app's routes run on the event loop.

FastAPI sends a plain ``def`` dependency to its thread pool: a thread hop (two context
switches, and a wait for a pool thread on a loaded machine) on every request for what is
an attribute read.  The client identity (:func:`service.http.identity.principal`) was one,
on every computing route; this test walks every route's dependency tree, so a new plain
``def`` dependency fails here rather than quietly adding a hop to the cold path.
"""

from __future__ import annotations

import inspect
from typing import Any

from fastapi.routing import APIRoute

from service.main import create_app
from service.settings import Settings


def _calls(dependant: Any) -> list[Any]:
    out = []
    for sub in dependant.dependencies:
        if sub.call is not None:
            out.append(sub.call)
        out.extend(_calls(sub))
    return out


def _routes(routes: list[Any]) -> list[APIRoute]:
    """The API routes, through included routers (FastAPI keeps them as their router)."""
    out: list[APIRoute] = []
    for route in routes:
        if isinstance(route, APIRoute):
            out.append(route)
        inner = getattr(getattr(route, "original_router", route), "routes", None)
        if inner is not None and inner is not routes:
            out.extend(_routes(list(inner)))
    return out


def test_every_route_dependency_runs_on_the_event_loop(tmp_path: Any) -> None:
    app = create_app(Settings(data_dir=tmp_path))
    routes = _routes(list(app.routes))
    assert any(r.path == "/v1/simulations" for r in routes)  # the walk sees the cold path
    plain = {
        f"{sorted(route.methods)} {route.path}: {getattr(call, '__qualname__', call)}"
        for route in routes
        for call in _calls(route.dependant)
        if not inspect.iscoroutinefunction(call)
    }
    assert plain == set(), "plain def dependencies (run in FastAPI's thread pool)"
