"""What every response model shares: :func:`document` (the one way the library's results
are written as JSON) and :class:`Result`, the fields every result document has.  Part of
:mod:`pipeflow.schema.results`, which re-exports these names."""

from __future__ import annotations

import functools
from typing import Any

from pydantic import BaseModel, ConfigDict, Field

from pipeflow.model import GROUPS

#: the extended model's group names, for descriptions (definitions: pipeflow.model.GROUPS)
GROUP_NAMES = ", ".join(GROUPS)
PLOTS_DESCRIPTION = "Figures of this result: GET /v1/results/{key}/plots/{name}.png or .svg."
#: the fields of a result document the service adds, never the library
SERVICE_FIELDS = frozenset({"key", "cached", "plots"})


@functools.cache
def _names(model: type[BaseModel]) -> tuple[frozenset[str], frozenset[str]]:
    """``model``'s field names, and the required ones the library must give."""
    fields = model.model_fields
    required = {n for n, f in fields.items() if f.is_required()} - SERVICE_FIELDS - {"kind"}
    return frozenset(fields), frozenset(required)


def document(model: type[BaseModel], /, **values: Any) -> dict[str, Any]:
    """``values`` as a JSON object of ``model`` (a result document or a part of one): the
    one way :mod:`pipeflow.computations.documents` writes the library's results, so a key exists
    only as a field.

    Every name must be a field of ``model``, and every required field must be given but
    :data:`SERVICE_FIELDS` and ``kind`` (the computation's name, which
    :meth:`~pipeflow.computations.registry.Computation.execute` adds); an optional field left out
    is absent from the document.  The values are kept as given (JSON-ready, the caller's
    lists and numbers: nothing is converted or copied), in the order given (the order of
    the bytes the service sends).  Raises TypeError naming the model and the names.  Cost:
    a set difference of the names (about a microsecond), not a validation of the values.
    """
    fields, required = _names(model)
    unknown = values.keys() - fields
    missing = required - values.keys()
    if unknown or missing:
        raise TypeError(
            f"{model.__name__}: "
            + "; ".join(
                f"{what}: {', '.join(sorted(names))}"
                for what, names in (("not a field", unknown), ("missing", missing))
                if names
            )
        )
    return values


class Result(BaseModel):
    model_config = ConfigDict(extra="allow")

    key: str = Field(description="Parameter hash (SHA-256 hex) identifying this result.")
    cached: bool = Field(description="True when served from the cache, not computed now.")
    warnings: list[str] = Field(description="What the caller should know about this result.")
    plots: list[str] = Field(default_factory=list, description=PLOTS_DESCRIPTION)
