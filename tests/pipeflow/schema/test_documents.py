"""The response models are the one definition of the result documents' keys.

:mod:`pipeflow.computations.documents` writes every document of the library's results with
:func:`pipeflow.schema.results.document`, which refuses a name its model lacks and a
required field left out; and every field of every response model (nested ones included)
is written by some real result below.  A key added on one side only fails here: in
``documents`` only, ``document`` raises; in a model only, no real result writes it.
"""

from __future__ import annotations

import copy
import functools
import typing
from typing import Any

import pytest
from pydantic import BaseModel

from pipeflow.computations.registry import COMPUTATIONS
from pipeflow.schema import results as r
from tests.pipeflow.cases import TINY

SIM = TINY["simulation"]
#: real requests that between them write every field of every response model
REQUESTS: list[tuple[str, dict[str, Any]]] = [
    *((name, body) for name, body in TINY.items()),
    (
        "simulation",
        {
            **SIM,
            "output": {"modal": True, "positions": [0.01], "mode_shapes": {"times": [0.0]}},
        },
    ),
    (  # every load kind, each with another profile kind (the echo of the inputs)
        "simulation",
        {
            **SIM,
            "loads": [
                {
                    "kind": "point_force",
                    "position": 0.02,
                    "force": {"kind": "constant", "value": 1e-6},
                },
                {
                    "kind": "distributed_force",
                    "intensity": {
                        "kind": "harmonic",
                        "mean": 0.0,
                        "amplitude": 1e-5,
                        "frequency": 300.0,
                    },
                    "start": 0.005,
                },
                {
                    "kind": "base_acceleration",
                    "acceleration": {"kind": "polynomial", "coefficients": [0.0, 1.0]},
                },
                {
                    "kind": "point_force",
                    "position": 0.025,
                    "force": {"kind": "table", "t": [0.0, 1.0], "values": [0.0, 1e-6]},
                },
                {
                    "kind": "point_force",
                    "position": 0.025,
                    "force": {
                        "kind": "table",
                        "t": [0.0, 0.001],
                        "values": [0.0, 1e-6],
                        "after": "hold",
                    },
                },
                {
                    "kind": "point_force",
                    "position": 0.015,
                    "force": {
                        "kind": "half_sine",
                        "peak": 1e-6,
                        "start": 0.001,
                        "duration": 0.0005,
                    },
                },
                {"kind": "impulse", "position": 0.025, "impulse": 1e-9, "time": 0.002},
            ],
        },
    ),
    # each method's own diagnostics (pipeflow.schema.results.SimulationDiagnostics)
    *(("simulation", {**SIM, "method": m}) for m in ("rk4", "magnus", "reference")),
    ("stability", {**TINY["stability"], "velocity_range": [-10.0, 40.0]}),
    (  # a sampled study with Sobol' indices (2 x (2 x 1 + 2) = 8 cases)
        "study",
        {
            "base": TINY["study"]["base"],
            "samples": {
                "count": 2,
                "method": "saltelli",
                "parameters": {
                    "pipe.E": {"distribution": "lognormal", "median": 7.8e9, "sigma": 0.1}
                },
            },
        },
    ),
    ("argand", {**TINY["argand"], "points": 21}),
    ("campbell", {**TINY["campbell"], "spin_range": [0.0, 3000.0], "points": 21}),
    (  # one unstable region (a parametric resonance near 190 rad/s)
        "resonance_chart",
        {**TINY["resonance_chart"], "mean_velocity": 20.0, "amplitude_range": [0.0, 20.0]}
        | {"frequency_range": [187.0, 207.0], "amplitude_points": 3, "frequency_points": 7},
    ),
]


def _models(annotation: Any) -> list[type[BaseModel]]:
    """The response models inside a field's annotation (lists and optionals unwrapped)."""
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return [annotation]
    return [m for arg in typing.get_args(annotation) for m in _models(arg)]


def _walk(model: type[BaseModel], doc: Any, seen: dict[type[BaseModel], set[str]]) -> None:
    """Record the fields of ``model`` written in ``doc`` (and in its nested documents); an
    unknown key fails at once."""
    if isinstance(doc, list):
        for item in doc:
            _walk(model, item, seen)
        return
    if doc is None:
        return
    assert isinstance(doc, dict), (model.__name__, doc)
    assert set(doc) <= set(model.model_fields), (model.__name__, set(doc) - set(model.model_fields))
    seen.setdefault(model, set()).update(doc)
    for name, value in doc.items():
        annotation = model.model_fields[name].annotation
        if _is_mapping(annotation) and isinstance(value, dict):
            items = list(value.values())  # dict[str, Model]: a document per key
        else:
            items = value if isinstance(value, list) else [value]
        for item in items:
            for sub in _models(annotation):
                if _matches(sub, item):
                    _walk(sub, item, seen)


def _is_mapping(annotation: Any) -> bool:
    """``dict[...]`` (or an optional one)."""
    if typing.get_origin(annotation) is dict:
        return True
    return any(_is_mapping(arg) for arg in typing.get_args(annotation))


def _matches(model: type[BaseModel], doc: Any) -> bool:
    """Whether ``doc`` can be ``model``: a member of a union told apart by ``kind`` (the
    echoed loads and profiles) is only the model whose ``kind`` literal it carries."""
    field = model.model_fields.get("kind")
    if not isinstance(doc, dict) or "kind" not in doc or field is None:
        return True
    if typing.get_origin(field.annotation) is not typing.Literal:
        return True
    return doc["kind"] in typing.get_args(field.annotation)


def _reachable(model: type[BaseModel], out: set[type[BaseModel]]) -> set[type[BaseModel]]:
    if model not in out:
        out.add(model)
        for info in model.model_fields.values():
            for sub in _models(info.annotation):
                _reachable(sub, out)
    return out


@functools.cache
def _documents() -> list[tuple[type[BaseModel], dict[str, Any]]]:
    """Every request of :data:`REQUESTS` run as the service runs it, with the fields the
    service adds (key, cached: execute adds kind and plots)."""
    out = []
    for name, body in REQUESTS:
        c = COMPUTATIONS[name]
        body = copy.deepcopy(body)
        request = c.request.model_validate(
            {"kind": name, **body} if "kind" in c.request.model_fields else body
        )
        out.append((c.response, {"key": "0" * 64, "cached": False, **c.execute(request)}))
    return out


def test_every_real_document_validates_against_its_model() -> None:
    for model, doc in _documents():
        model.model_validate(doc)
        _walk(model, doc, {})


def test_every_field_of_every_response_model_is_written_by_a_real_result() -> None:
    seen: dict[type[BaseModel], set[str]] = {}
    for model, doc in _documents():
        _walk(model, doc, seen)
    served: set[type[BaseModel]] = set()
    for c in COMPUTATIONS.values():
        if c.name in dict(REQUESTS):
            _reachable(c.response, served)
    unwritten = {
        m.__name__: sorted(set(m.model_fields) - seen.get(m, set()))
        for m in served
        if set(m.model_fields) - seen.get(m, set())
    }
    assert not unwritten, f"fields no real result writes (a key on the model only?): {unwritten}"


def test_document_refuses_a_name_the_model_lacks_and_a_missing_required_field() -> None:
    with pytest.raises(TypeError, match=r"Fundamental: not a field: extra"):
        r.document(r.Fundamental, sigma=[], omega=[], extra=1)
    with pytest.raises(TypeError, match=r"Fundamental: missing: omega"):
        r.document(r.Fundamental, sigma=[])
    # optional fields may be left out (absent from the document), the service's never given
    assert r.document(r.Trace, mode=1, sigma=[], omega=[], confidence=[]) == {
        "mode": 1,
        "sigma": [],
        "omega": [],
        "confidence": [],
    }
    assert list(
        r.document(r.CompareResponse, t_end=1.0, baseline="a", methods=[], samples=2, modes=1)
    ) == [
        "t_end",
        "baseline",
        "methods",
        "samples",
        "modes",
    ]  # in the order given: the bytes the service sends keep the library's order


def test_the_documents_are_written_through_document(monkeypatch: pytest.MonkeyPatch) -> None:
    """A key pipeflow.computations.documents writes that its model lacks fails as it is written."""
    monkeypatch.setattr(
        r.Crossing,
        "model_fields",
        {k: v for k, v in r.Crossing.model_fields.items() if k != "frequency_hz"},
    )
    r._names.cache_clear()
    try:
        name, body = "stability", TINY["stability"]
        c = COMPUTATIONS[name]
        with pytest.raises(TypeError, match="Crossing: not a field: frequency_hz"):
            c.execute(c.request.model_validate(body))
    finally:
        monkeypatch.undo()
        r._names.cache_clear()
