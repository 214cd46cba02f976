"""Readable validation messages (issue 34, item 8), shared by the service's 422 problem
documents and the command line.

:func:`message` rewrites one of pydantic's errors (an item of ``ValidationError.errors()``):

- a validator's refusal loses pydantic's ``"Value error, "`` prefix (the text is ours);
- a number sent as text with a unit (``"3000 rpm"``) is told the form that takes a unit,
  ``{"value": 3000, "unit": "rpm"}``;
- an unknown field gets a "did you mean" from the fields of the model at its place
  (:func:`field_names`, given the request type).
"""

from __future__ import annotations

import difflib
import json
import re
import typing
from collections.abc import Mapping
from typing import Any

from pydantic import BaseModel

from pipeflow.schema import units

_PREFIXES = ("Value error, ", "Assertion failed, ")
#: a number followed by a unit, as text: "3000 rpm", "25mm", "-1.5e3 N"
_NUMBER_UNIT = re.compile(r"^\s*([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)\s*(\S.*?)\s*$")


def _models(annotation: Any) -> list[type[BaseModel]]:
    """The models in ``annotation`` (unions, lists, Annotated, optionals)."""
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return [annotation]
    found: list[type[BaseModel]] = []
    for arg in typing.get_args(annotation):
        found += _models(arg)
    return found


def field_names(tp: Any, loc: tuple[Any, ...]) -> list[str]:
    """The field names of the models that may sit at ``loc`` in a value of type ``tp``
    (union tags and list indices in ``loc`` are passed over)."""
    models = _models(tp)
    for part in loc:
        fields = [m.model_fields[part] for m in models if part in m.model_fields]
        if fields:
            models = [m for f in fields for m in _models(f.annotation)]
    return sorted({name for m in models for name in m.model_fields})


def did_you_mean(given: str, names: list[str] | tuple[str, ...]) -> str:
    """``"; did you mean 'steel'?"`` for a near miss among ``names``, else ``""``."""
    close = difflib.get_close_matches(given, list(names), n=1, cutoff=0.6)
    if not close:
        lowered = {n.lower(): n for n in names}
        close = [lowered[c] for c in difflib.get_close_matches(given.lower(), list(lowered))]
    return f"; did you mean {close[0]!r}?" if close else ""


def quantity_hint(text: str) -> str:
    """For text that reads as a number with a unit pint knows (``"3000 rpm"``), how to
    send it: ``{"value": 3000, "unit": "rpm"}``; else ``""``."""
    m = _NUMBER_UNIT.match(text)
    if m is None or len(text) > 2 * units.MAX_UNIT_CHARS:
        return ""
    number, unit = m.group(1), m.group(2)
    if not units.unit_grammar(unit) or units.parsed_unit(unit) is None:
        return ""
    value = float(number)
    shown = json.dumps(int(value) if value.is_integer() and abs(value) < 1e15 else value)
    return (
        f"; {text!r} is text: send a number in the field's SI unit, or the number with its "
        f'unit as {{"value": {shown}, "unit": {json.dumps(unit)}}}'
    )


def message(err: Mapping[str, Any], tp: Any = None) -> str:
    """The text of pydantic error ``err``, rewritten as the module docstring says; ``tp``
    (the validated type) lets an unknown field be matched against its neighbours."""
    text = str(err.get("msg", "invalid"))
    for prefix in _PREFIXES:
        text = text.removeprefix(prefix)
    kind = err.get("type")
    given = err.get("input")
    if kind in ("float_type", "float_parsing", "int_type") and isinstance(given, str):
        text += quantity_hint(given)
    elif kind == "extra_forbidden" and tp is not None:
        loc = tuple(err.get("loc", ()))
        if loc and isinstance(loc[-1], str):
            text += did_you_mean(loc[-1], field_names(tp, loc[:-1]))
    return text
