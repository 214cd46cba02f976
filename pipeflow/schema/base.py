"""The base of every request model and its two shared rules (split from
:mod:`pipeflow.schema.simulation`, which re-exports these names):

- :class:`StrictModel`: unknown fields, non-finite numbers and loose types refused,
  quantities with units converted to SI, :meth:`~StrictModel.canonical` (the cache key's
  form) and the one cost check (:class:`Cost`, :func:`costs_unchecked`);
- :func:`request_field` / :func:`request_fields` / :func:`library_check`: a library error
  named by the request field it came from.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Iterator, Mapping
from contextlib import contextmanager
from contextvars import ContextVar
from typing import Any, Self

from pydantic import (
    BaseModel,
    ConfigDict,
    GetJsonSchemaHandler,
    ValidatorFunctionWrapHandler,
    model_validator,
)
from pydantic.json_schema import JsonSchemaValue
from pydantic_core import CoreSchema

from pipeflow.errors import InvalidField, PipeflowError
from pipeflow.schema import units


def request_field(exc: PipeflowError, fields: Mapping[str, str], prefix: str = "") -> PipeflowError:
    """Set ``exc.field`` to the request field of its library ``parameter`` (``fields``,
    then ``prefix`` for a nested request), unless a caller already did; returns ``exc``."""
    if exc.field is None and exc.parameter is not None:
        exc.at(prefix + fields.get(exc.parameter, exc.parameter))
    return exc


@contextmanager
def request_fields(fields: Mapping[str, str], prefix: str = "") -> Iterator[None]:
    """Library errors raised inside name request fields (:func:`request_field`)."""
    try:
        yield
    except PipeflowError as exc:
        request_field(exc, fields, prefix)
        raise


def library_check(check: Callable[..., object], fields: Mapping[str, str], *args: Any) -> None:
    """Run a library check (budget, common period...) at validation time, so a request the
    library would refuse is a 422 naming the field at submission, not a job that fails later
    (a pydantic validator must raise ValueError: :class:`InvalidField` carries the field)."""
    try:
        check(*args)
    except PipeflowError as exc:
        field = request_field(exc, fields).field
        raise InvalidField(f"{field}: {exc.message}", field) from None


class StrictModel(BaseModel):
    """Base of every request model: unknown fields, non-finite numbers and loose types are
    refused (``strict``: no bool or string where a number belongs, no 3.0 for an integer).

    :meth:`canonical` is the normalised JSON form the cache key is computed from; models
    that normalise further (:class:`SimulationSpec`) override it.  Subclasses setting
    ``model_config`` (e.g. for schema examples) inherit these settings (pydantic merges it).
    """

    model_config = ConfigDict(extra="forbid", allow_inf_nan=False, strict=True)

    @model_validator(mode="wrap")
    @classmethod
    def _quantities(cls, data: Any, handler: ValidatorFunctionWrapHandler) -> Any:
        """A field in an SI unit also takes ``{"value": 3000, "unit": "rpm"}``, converted
        here to the unit its description states (:mod:`pipeflow.schema.units`; an input
        without a quantity anywhere is scanned once and passes through)."""
        return units.validate(cls, data, handler)

    @classmethod
    def __get_pydantic_json_schema__(
        cls, core_schema: CoreSchema, handler: GetJsonSchemaHandler
    ) -> JsonSchemaValue:
        schema = super().__get_pydantic_json_schema__(core_schema, handler)
        # the generator itself (not this model's handler) files Quantity under $defs and
        # answers a reference to it: one schema for every field taking a unit.  In both
        # modes: a request model echoed in an answer (a simulation's loads) keeps one
        # schema (and one model in generated clients); its numbers are SI numbers there
        generator = handler.generate_json_schema  # type: ignore[attr-defined]
        quantity = generator.generate_inner(units.Quantity.__pydantic_core_schema__)
        units.quantity_json_schema(handler.resolve_ref_schema(schema), cls, quantity)
        return schema

    def canonical(self) -> dict[str, Any]:
        """Normalised JSON form (every default filled in) that the cache key is computed from."""
        return self.model_dump(mode="json")

    def cost(self) -> Cost | None:
        """The request's estimated cost against its bound (None: a part of a request).
        Every request model ends its validation with :meth:`within_budget`, which refuses
        it when the estimate exceeds the bound; the registry gives it as each entry's
        :attr:`~pipeflow.computations.registry.Computation.estimate`."""
        return None

    def within_budget(self) -> Self:
        """The one cost check of every request kind, run last by its model's validator
        (after the model's own rules, so :meth:`cost` reads a consistent request): a
        request whose :meth:`cost` exceeds its bound is refused naming the field and the
        largest value that fits, before anything runs (the library call, the command line
        and the service validate alike).  Skipped inside :func:`costs_unchecked`."""
        if _SKIP_COST.get():
            return self
        cost = self.cost()
        if cost is not None and cost.units > cost.bound:
            raise InvalidField(cost.message(), cost.fields[0])
        return self


_SKIP_COST: ContextVar[bool] = ContextVar("pipeflow_skip_cost", default=False)


@contextmanager
def costs_unchecked() -> Iterator[None]:
    """Validate without the cost check inside (an estimate of a worst case, not a request
    to run: :meth:`pipeflow.schema.study.StudySpec.cost`)."""
    token = _SKIP_COST.set(True)
    try:
        yield
    finally:
        _SKIP_COST.reset(token)


@dataclasses.dataclass(frozen=True)
class Cost:
    """A request's estimated cost: ``units`` (counted as ``terms`` says) against ``bound``.

    ``fields``: the request fields that set it, the first being the one a refusal names;
    ``budget``: the bound's name; ``advice``: what fits (the largest value of the first
    field with the others as given)."""

    units: int
    bound: int
    unit: str
    fields: tuple[str, ...]
    terms: str
    budget: str
    advice: str

    def message(self) -> str:
        """The refusal: the fields, the count, the bound and what fits."""
        return (
            f"{self.fields[0]}: {self.terms} = {self.units:,} {self.unit} exceeds the "
            f"{self.budget} of {self.bound:,} {self.unit}; {self.advice}"
        )
