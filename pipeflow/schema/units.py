"""Quantities with their unit on input, converted to SI at validation (pint).

Wherever a request field takes a number in an SI unit, it also takes that number with its
own unit, as the one documented form ``{"value": 3000, "unit": "rpm"}`` (a JSON object,
never a string to evaluate): ``{"value": 25, "unit": "mm"}`` for a length in metres,
``{"value": 5, "unit": "bar"}`` for a pressure, ``{"value": 50, "unit": "Hz"}`` for an
angular frequency in rad/s.  The field's SI unit is the one its description states in
brackets (``"Pipe length ... [m]."``): that one statement documents the field and drives
the conversion.  Profiles (``flow.velocity``, ``rotation.omega0``, load histories) take
their unit from the field that holds them: their ``value``, ``mean``, ``amplitude`` and
table ``values`` in it, polynomial ``coefficients[k]`` in it per s^k.

The conversion happens before any other check, so the bounds apply in SI, the request's
canonical form (and so the service's cache key) holds the SI number only, and the same
physics asked in rpm or rad/s is one key.  A unit of the wrong dimension, or one pint does
not know, is refused naming the field (``rotation.omega0.value: 3 m is a length, not an
angular velocity [rad/s]``).

Hz means cycles per second here (1 Hz = 2 pi rad/s), and rpm revolutions per minute
(1 rpm = 2 pi / 60 rad/s): pint's default registry takes the radian as dimensionless and
would read 1 Hz as 1 rad/s.

A unit string is checked against a unit grammar (:func:`unit_grammar`: names joined by
``*``, ``/`` or spaces, integer powers of at most two digits, parentheses; no other number
than ``1``) before pint sees it: pint's parser evaluates number expressions before it
refuses them (``"9**9**7 mm"`` cost seconds of a core, ``"9**9**9 mm"`` an hour), and a
string of the grammar never holds one.  Parsed units and conversion factors are cached, so
a request of 10,000 quantities converts each by one multiplication.
"""

from __future__ import annotations

import functools
import math
import re
from collections.abc import Callable, Iterable
from collections.abc import Set as AbstractSet
from contextvars import ContextVar
from typing import TYPE_CHECKING, Any

from pydantic import BaseModel, ConfigDict

from pipeflow.errors import InvalidField

if TYPE_CHECKING:
    import pint

#: the longest unit string accepted [characters]
MAX_UNIT_CHARS = 64
#: the deepest nesting of parentheses in a unit string
MAX_UNIT_DEPTH = 3
#: the most different unit strings one request may use (each new one costs pint a parse
#: of up to ~1 ms; the same one again costs a cache look-up)
MAX_UNITS_PER_REQUEST = 32

#: the JSON form of a quantity (a member of the request schema wherever a unit applies)
QUANTITY_SCHEMA: dict[str, Any] = {
    "type": "object",
    "title": "Quantity",
    "description": "A number with its unit, converted to the field's SI unit at validation: "
    '{"value": 3000, "unit": "rpm"}, {"value": 25, "unit": "mm"} (pint unit names; Hz is '
    "cycles per second, 1 Hz = 2 pi rad/s).",
    "properties": {
        "value": {"type": "number", "description": "The number, in `unit`."},
        "unit": {
            "type": "string",
            "minLength": 1,
            "maxLength": MAX_UNIT_CHARS,
            "description": "Its unit: pint's unit names (mm, bar, rpm, Hz, ...) joined by "
            "'*', '/' or spaces, with integer powers ('m**2', 'm^2', 'm²') and parentheses "
            "(g/cm, kg*m^2, (m/s)**2); no other number than 1 (1/s).",
        },
    },
    "required": ["value", "unit"],
    "additionalProperties": False,
}

#: the kinds of profile (pipeflow.schema.simulation's ProfileSpec)
PROFILE_KINDS = ("constant", "polynomial", "harmonic", "table")
#: the members of a profile (pipeflow.schema.simulation's profile kinds) in the holder's unit
PROFILE_MEMBERS = ("value", "mean", "amplitude", "values")
_BRACKET = re.compile(r"\[([^\[\]]+)\]")
#: names of dimensions in messages
_DIMENSIONS = {
    "[length]": "a length",
    "[time]": "a time",
    "[mass]": "a mass",
    "1 / [time]": "an angular velocity or rate",
    "[length] / [time]": "a velocity",
    "[mass] / [length] / [time] ** 2": "a pressure or modulus",
    "[length] ** 4": "a second moment of area",
    "[mass] / [length]": "a mass per length",
    "[mass] * [length] ** 2": "a moment of inertia",
    "[mass] * [length] / [time] ** 2": "a force",
    "[mass] / [time] ** 2": "a force per length",
    "[length] / [time] ** 2": "an acceleration",
    "[mass] / [length] / [time]": "a viscous damping coefficient",
    "dimensionless": "a number without dimension",
}


@functools.cache
def registry() -> pint.UnitRegistry:
    """The unit registry (pint is imported on the first quantity)."""
    import pint

    ureg: pint.UnitRegistry = pint.UnitRegistry(on_redefinition="ignore")
    ureg.define("hertz = cycle / second = Hz")  # cycles, not radians, per second
    return ureg


@functools.cache
def si_unit(description: str | None) -> str | None:
    """The SI unit a field's description states in brackets (the first bracket that
    pint reads as a unit with a dimension), or None (no such bracket, or ``[-]`` first:
    a number without dimension).  Brackets that are no unit (``[v_min, v_max]``) are
    skipped."""
    for text in _BRACKET.findall(description or ""):
        if text.strip() == "-":
            return None
        try:
            unit = registry().parse_units(text.strip())
        except Exception:
            continue
        if not unit.dimensionless or "radian" in str(unit):
            return text.strip()
    return None


def is_quantity(value: Any) -> bool:
    return isinstance(value, dict) and set(value) == {"value", "unit"}


def _dimension(unit: Any) -> str:
    dim = str(unit.dimensionality)
    return _DIMENSIONS.get(dim, dim)


def to_si(value: Any, unit: str, loc: str) -> Any:
    """``value`` in ``unit`` [SI]: a quantity object converted, anything else unchanged
    (the field's own validation refuses it if it is not a number).  Refuses naming
    ``loc`` a quantity that is malformed or of the wrong dimension."""
    # only an object with a "unit" is a quantity: {"value": 100} may be a constant profile
    # whose kind is left to its default (ConstantRotation.omega0)
    if not isinstance(value, dict) or "unit" not in value:
        return value
    if not is_quantity(value):
        raise InvalidField(f"{loc}: a quantity is {{'value': number, 'unit': string}}", loc)
    number, given = value["value"], value["unit"]
    if isinstance(number, bool) or not isinstance(number, int | float) or not math.isfinite(number):
        raise InvalidField(f"{loc}.value: a finite number is required", f"{loc}.value")
    if not isinstance(given, str) or not 0 < len(given) <= MAX_UNIT_CHARS:
        raise InvalidField(
            f"{loc}.unit: a unit name (1 to {MAX_UNIT_CHARS} characters)", f"{loc}.unit"
        )
    if not unit_grammar(given):
        raise InvalidField(
            f"{loc}.unit: {given!r} is not a unit: unit names (mm, rpm, Hz) joined by '*', "
            "'/' or spaces, integer powers ('m**2', 'm^2') and parentheses; no number but 1",
            f"{loc}.unit",
        )
    seen = _UNITS_SEEN.get()
    if seen is not None and given not in seen:
        if len(seen) >= MAX_UNITS_PER_REQUEST:
            raise InvalidField(
                f"{loc}.unit: a request may use at most {MAX_UNITS_PER_REQUEST} different units",
                f"{loc}.unit",
            )
        seen.add(given)
    source = parsed_unit(given)
    if source is None:
        raise InvalidField(
            f"{loc}.unit: unknown unit {given!r}{unit_suggestion(given, unit)}", f"{loc}.unit"
        )
    scale = conversion(given, unit)
    if isinstance(scale, str):
        raise InvalidField(f"{loc}: {number} {given} {scale} [{unit}]", loc)
    converted = number * scale
    if not math.isfinite(converted):
        raise InvalidField(f"{loc}: {number} {given} is not finite in {unit}", loc)
    return converted


#: a token of the unit grammar (:func:`unit_grammar`), after optional white space
_UNIT_TOKEN = re.compile(
    r"\s*(?:"
    r"(?P<name>°|[^\W\d]\w*)"  # a unit name (pint's, with its prefixes and plurals)
    r"|(?P<one>1)(?![\w.])"  # the only number outside a power: 1/s
    r"|(?P<power>(?:\*\*|\^)\s*[+-]?[0-9]{1,2}(?![\w.])|⁻?[⁰¹²³⁴⁵⁶⁷⁸⁹]{1,2})"
    r"|(?P<op>[*/·])"
    r"|(?P<open>\()"
    r"|(?P<close>\))"
    r")"
)


def unit_grammar(text: str) -> bool:
    """Whether ``text`` is a unit of the grammar pint may read: unit names (and ``1``)
    joined by ``*``, ``/``, ``·`` or spaces, each name or parenthesised group raised at
    most once to an integer power of at most two digits (``**2``, ``^-1``, ``²``),
    parentheses nested at most :data:`MAX_UNIT_DEPTH` deep.  No other number: nothing
    for pint to evaluate.  One pass over ``text`` (time linear in its length)."""
    pos, end = 0, len(text.rstrip())
    depth = 0
    operand = powered = False  # the last token ends an operand; it is a power
    while pos < end:
        m = _UNIT_TOKEN.match(text, pos)
        if m is None:
            return False
        pos, kind = m.end(), m.lastgroup
        if kind == "name":  # after an operand too: "N m" is N*m
            operand, powered = True, False
        elif kind in ("one", "open"):
            if operand:  # "m 1", "m(s)": pint would read a call or a factor
                return False
            if kind == "open":
                depth += 1
                if depth > MAX_UNIT_DEPTH:
                    return False
            operand = kind == "one"
        elif kind == "power":
            if not operand or powered:  # "**2" first, "m**2**3"
                return False
            powered = True
        elif kind == "op":
            if not operand:
                return False
            operand = powered = False
        else:  # close
            if not operand or depth == 0:
                return False
            depth -= 1
            powered = False
    return operand and depth == 0


#: the units a misspelt one is matched against, by SI unit (a field's), and for any field
USUAL_UNITS: dict[str, tuple[str, ...]] = {
    "m": ("m", "mm", "cm", "km", "um", "inch", "ft"),
    "rad/s": ("rad/s", "rpm", "Hz", "deg/s"),
    "m/s": ("m/s", "mm/s", "cm/s", "km/h", "ft/s"),
    "Pa": ("Pa", "kPa", "MPa", "GPa", "bar", "psi"),
    "s": ("s", "ms", "min", "h"),
    "kg": ("kg", "g", "lb"),
    "N": ("N", "kN", "mN", "lbf"),
}


def unit_suggestion(given: str, unit: str) -> str:
    """``"; did you mean 'rpm'?"`` for a misspelt unit (``"rmp"``): the closest of the
    usual units of the field's SI ``unit`` (:data:`USUAL_UNITS`), else of every usual
    unit; ``""`` if none is close."""
    import difflib

    usual = USUAL_UNITS.get(unit, ())
    everything = tuple(u for units in USUAL_UNITS.values() for u in units)
    for names in (usual, everything):
        lowered = {name.lower(): name for name in names}
        close = difflib.get_close_matches(given.lower(), list(lowered), n=1, cutoff=0.6)
        if close:
            return f"; did you mean {lowered[close[0]]!r}?"
    return ""


@functools.lru_cache(maxsize=1024)
def parsed_unit(text: str) -> Any:
    """The pint unit of ``text`` (a unit of :func:`unit_grammar`, or a field's SI unit),
    None if pint does not know it; cached."""
    try:
        return registry().parse_units(text)
    except Exception:
        return None


@functools.lru_cache(maxsize=1024)
def conversion(given: str, unit: str) -> float | str:
    """The factor from ``given`` to ``unit`` (both units pint knows: a value in ``given``
    times it is the value in ``unit``), or why there is none (the end of a message after
    the quantity: ``is a length, not an angular velocity or rate``); cached."""
    source, target = parsed_unit(given), parsed_unit(unit)
    if source.dimensionality != target.dimensionality:
        return f"is {_dimension(source)}, not {_dimension(target)}"
    ureg = registry()
    try:
        scale = float(ureg.Quantity(1.0, source).to(target).magnitude)
        zero = float(ureg.Quantity(0.0, source).to(target).magnitude)
    except Exception:
        return f"cannot be converted to {unit}"
    if zero != 0.0:  # an offset or logarithmic unit: no factor
        return f"is not a unit that scales to {unit}"
    if not math.isfinite(scale) or scale == 0.0:  # (km**99)**9, (nm**99)**9
        return f"cannot be represented in {unit}"
    return scale


#: the ids of the dicts of the inputs being validated that hold no quantity anywhere in
#: them (their nested models skip the conversion); set for the duration of a validation
_QUANTITY_FREE: ContextVar[AbstractSet[int]] = ContextVar(
    "pipeflow_quantity_free", default=frozenset()
)
#: the unit strings of the input being validated (:data:`MAX_UNITS_PER_REQUEST`); set by
#: the outermost model whose input holds a quantity, for the duration of its validation
_UNITS_SEEN: ContextVar[set[str] | None] = ContextVar("pipeflow_units_seen", default=None)


def validate(model: type[Any], data: Any, handler: Callable[[Any], Any]) -> Any:
    """The request models' unit hook (a wrap validator): ``data`` with its quantities
    converted (:func:`convert_fields`), validated by ``handler``.

    An input with no quantity anywhere (no object with a ``"unit"``: every request of plain
    SI numbers) is scanned once, by its outermost model: the ids of its dicts are marked
    quantity-free for the duration of its validation, and the nested models that receive
    them skip the conversion at the cost of a set look-up.  A dict a validator builds
    (not in the input) is scanned when a model receives it.  The outermost model whose
    input holds a quantity counts its different units (:data:`MAX_UNITS_PER_REQUEST`)."""
    if not isinstance(data, dict):
        return handler(data)
    free = _QUANTITY_FREE.get()
    if id(data) in free:
        return handler(data)
    ids = _quantity_free_ids(data)
    if ids is None:
        if _UNITS_SEEN.get() is not None:
            return handler(convert_fields(model, data))
        units = _UNITS_SEEN.set(set())
        try:
            return handler(convert_fields(model, data))
        finally:
            _UNITS_SEEN.reset(units)
    if len(ids) == 1:  # no dict inside (e.g. a default {}): no nested model to tell
        return handler(data)
    token = _QUANTITY_FREE.set(free | ids if free else ids)  # never changed once set
    try:
        return handler(data)
    finally:
        _QUANTITY_FREE.reset(token)


def _quantity_free_ids(data: dict[str, Any]) -> set[int] | None:
    """The ids of ``data`` and of every dict in it, or None if one of them has a
    ``"unit"`` (a quantity, or a malformed one :func:`to_si` refuses)."""
    ids: set[int] = set()
    return ids if _scan(data, ids) else None


def _scan(node: dict[str, Any], ids: set[int]) -> bool:
    """Whether no dict in ``node`` has a ``"unit"``; adds their ids to ``ids``."""
    if "unit" in node:
        return False
    ids.add(id(node))
    return _scan_values(node.values(), ids)


def _scan_values(values: Iterable[Any], ids: set[int]) -> bool:
    """:func:`_scan` of the dicts in ``values`` and in its lists.  Written for speed: it
    runs on every request of plain numbers."""
    for value in values:
        kind = type(value)
        if kind is dict:
            if not _scan(value, ids):
                return False
        elif kind is list and not _scan_values(value, ids):
            return False
    return True


def convert_fields(model: type[Any], data: Any) -> Any:
    """The fields of ``data`` (a request model's input) that hold quantities, converted to
    the SI unit their description states; lists element by element; a profile member by
    the holder's unit (coefficients[k] per s^k).  Other input is returned unchanged."""
    if not isinstance(data, dict):
        return data
    out: dict[str, Any] | None = None
    for name, description in _candidates(model):  # type: ignore[arg-type]
        value = data.get(name)
        # only an object can be a quantity: plain numbers never reach pint
        if not (isinstance(value, dict) or (isinstance(value, list) and _objects(value))):
            continue
        unit = si_unit(description)
        if unit is None:
            continue
        if out is None:
            out = dict(data)
        if isinstance(value, list):
            out[name] = [to_si(v, unit, f"{name}.{i}") for i, v in enumerate(value)]
        elif isinstance(value, dict) and _is_profile(value):
            out[name] = convert_profile(value, unit, name)
        else:
            out[name] = to_si(value, unit, name)
    return data if out is None else out


@functools.cache
def _candidates(model: type[Any]) -> tuple[tuple[str, str], ...]:
    """The fields of ``model`` whose description has a bracket (a unit, perhaps), with
    it: the only ones :func:`convert_fields` looks at (read once per model)."""
    return tuple(
        (name, field.description)
        for name, field in model.model_fields.items()
        if field.description and "[" in field.description
    )


def _is_profile(value: dict[str, Any]) -> bool:
    """A profile (its kind, or the kind left to its default: a constant's ``value``)."""
    if "unit" in value:
        return False
    return value.get("kind") in PROFILE_KINDS or (
        "kind" not in value and bool(set(value) & {*PROFILE_MEMBERS, "coefficients"})
    )


def _objects(values: list[Any]) -> bool:
    return any(isinstance(v, dict) for v in values)


def convert_profile(profile: dict[str, Any], unit: str, loc: str) -> dict[str, Any]:
    """A profile's members in ``unit`` (the holder's), coefficients[k] in unit/s^k."""
    out = dict(profile)
    for name in PROFILE_MEMBERS:
        if name in out:
            value = out[name]
            where = f"{loc}.{name}"
            out[name] = (
                [to_si(v, unit, f"{where}.{i}") for i, v in enumerate(value)]
                if isinstance(value, list)
                else to_si(value, unit, where)
            )
    if isinstance(out.get("coefficients"), list):
        out["coefficients"] = [
            to_si(c, f"({unit}) / s ** {k}" if k else unit, f"{loc}.coefficients.{k}")
            for k, c in enumerate(out["coefficients"])
        ]
    return out


def quantity_json_schema(
    schema: dict[str, Any], model: type[Any], quantity: dict[str, Any]
) -> dict[str, Any]:
    """``schema`` (a request model's validation JSON schema) with each field that takes a
    quantity offered as either its number or ``quantity`` (the schema, or its reference,
    of :data:`QUANTITY_SCHEMA`)."""
    props = schema.get("properties", {})
    profile = "kind" in model.model_fields  # a profile's members take the holder's unit
    for name, field in model.model_fields.items():
        key = field.alias or name
        member = profile and name in (*PROFILE_MEMBERS, "coefficients")
        if key not in props or not (member or si_unit(field.description) is not None):
            continue
        prop = props[key]
        if prop.get("type") == "number":
            props[key] = _either(prop, quantity)
        elif prop.get("type") == "array" and prop.get("items", {}).get("type") == "number":
            prop["items"] = _either(prop["items"], quantity)
        elif "anyOf" in prop and any(p.get("type") == "number" for p in prop["anyOf"]):
            prop["anyOf"] = [
                _either(p, quantity) if p.get("type") == "number" else p for p in prop["anyOf"]
            ]
    return schema


def _either(number: dict[str, Any], quantity: dict[str, Any]) -> dict[str, Any]:
    """A number schema or a quantity; the field's description and default stay outside."""
    outer: dict[str, Any] = {
        k: number.pop(k) for k in ("title", "description", "default") if k in number
    }
    return {"anyOf": [number, dict(quantity)], **outer}


class Quantity(BaseModel):
    """The JSON form of a quantity (:data:`QUANTITY_SCHEMA`): one named schema that every
    field taking a unit refers to.  Not a validator: :func:`to_si` reads the objects."""

    model_config = ConfigDict(
        title="Quantity", extra="forbid", json_schema_extra=lambda s, _: s.update(QUANTITY_SCHEMA)
    )

    value: float
    unit: str
