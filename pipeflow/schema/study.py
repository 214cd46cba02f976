"""Request model of a design study: a base simulation or stability request and its cases.

``POST /v1/studies`` takes :class:`StudySpec`: a ``base`` (``{"kind": "simulation" |
"stability", "spec": <that computation's request>}``) and either ``cases``, a list of
overrides (``[{"pipe.E": 7e9}, {"pipe.E": 8e9, "pipe.L": 0.03}]``), or ``grid``, a
cartesian product of values per field (``{"pipe.L": [0.02, 0.025], "pipe.M2": [...]}``;
JSON objects are unordered, so the cases follow the fields sorted by path, the last
varying fastest: any order of the fields is the same study, with the same key).  An
override names a numeric field of the base request by its dotted JSON path, list items by
their index (``flow.velocity.coefficients.1``, ``velocity_range.1``); its value is a JSON
number in the field's own unit (SI, as the field's description states).  Nothing is ever
evaluated: a path is looked up in the base request, a value is a number.

Validation happens before any work, so a bad study is one 422 naming its field:

- a path that is not a field of the base request, or not a numeric one, names the
  override (``cases.3.pipe.X``, ``grid.pipe.X``);
- more than :data:`MAX_CASES` cases (list length or grid product) names ``cases`` /
  ``grid``;
- every override value is checked in bulk against its field's own type and bounds in the
  base model (:meth:`StudySpec.check`, a few microseconds per distinct value); an invalid
  value names the case's override (``cases.3.pipe.E``, ``grid.pipe.L.2``: the JSON paths
  of the offending number in the study body), and the message says which field and why.

``samples`` instead draws the cases (uncertainty quantification): independent
distributions of numeric fields (normal, truncated normal, uniform, lognormal, each in the
field's own SI unit), ``count`` points of a design in [0, 1)^D (scrambled Sobol',
Latin hypercube, independent uniform draws, or Saltelli's design of ``count (2 D + 2)``
points for Sobol' indices) drawn from ``seed`` and mapped through each inverse CDF
(:mod:`pipeflow.uq`); the same seed is the same study and key.  A bad distribution names
its parameter (``samples.parameters.pipe.E.sigma``), a design over :data:`MAX_CASES`
cases ``samples.count``, a draw the base model refuses ``samples.parameters.<path>``;
integer fields (counts) cannot be sampled.

Each case is then a standalone request of the base kind, validated by the base model when
the study runs (:meth:`StudySpec.validate_case`): a rule across fields that a case breaks
(``output.positions`` beyond a shortened ``pipe.L``) makes that case a failed row naming
its field, not the study a 422.  :meth:`StudySpec.expand` validates every case at once and
raises on the first invalid one.  A case's cost is bounded by that model's own bounds, so
a study costs at most :data:`MAX_CASES` times the base computation's bound.
"""

from __future__ import annotations

import copy
import functools
import itertools
import math
import re
import typing
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from typing import Annotated, Any, Literal

import numpy as np
from pydantic import (
    BaseModel,
    ConfigDict,
    Field,
    PlainValidator,
    TypeAdapter,
    ValidationError,
    WithJsonSchema,
    model_validator,
)
from pydantic_core import InitErrorDetails, PydanticCustomError

from pipeflow import uq
from pipeflow.errors import InvalidField
from pipeflow.schema.distributions import DISTRIBUTIONS as DISTRIBUTIONS
from pipeflow.schema.distributions import Distribution as Distribution
from pipeflow.schema.distributions import LognormalDistribution as LognormalDistribution
from pipeflow.schema.distributions import NormalDistribution as NormalDistribution
from pipeflow.schema.distributions import (
    TruncatedNormalDistribution as TruncatedNormalDistribution,
)
from pipeflow.schema.distributions import UniformDistribution as UniformDistribution
from pipeflow.schema.simulation import (
    PAPER_EXAMPLE,
    Cost,
    SimulationSpec,
    StrictModel,
    costs_unchecked,
)
from pipeflow.schema.stability import PAPER_PIPE_JSON, StabilitySpec
from pipeflow.schema.supports import with_defaults

#: bound on the cases of one study (list length or grid product) [-]
MAX_CASES = 10_000
#: bound on a study's estimated cost, in requests at its base's bound: the cases times the
#: estimate of a case (:meth:`StudySpec.cost`) is at most this many times the bound of one
#: base request (simulation: 500 x 2,000,000 output values, about 20 minutes of one core
#: at the measured 1.4 us a value; stability: 500 x the spectrum budget)
MAX_STUDY_REQUESTS = 500
#: bound on the fields one case overrides, and on the axes of a grid [-]
MAX_OVERRIDES = 16
#: the base computations a study can vary, by their request model
BASE_MODELS: dict[str, type[StrictModel]] = {
    "simulation": SimulationSpec,
    "stability": StabilitySpec,
}

_PATH = r"^[A-Za-z_][A-Za-z0-9_]*(\.([A-Za-z_][A-Za-z0-9_]*|[0-9]+))*$"
Path = Annotated[
    str,
    Field(
        pattern=_PATH,
        max_length=200,
        description="Dotted JSON path of a numeric field of the base request, list items by "
        "index: 'pipe.E' [Pa], 'rotation.omega0.value' [rad/s], "
        "'flow.velocity.coefficients.1' [m/s^2].",
    ),
]


def _number(value: Any) -> int | float:
    # JSON numbers only: a string is never evaluated, a boolean is not 1
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise InvalidField("an override is a JSON number (in the field's SI unit)")
    if isinstance(value, float) and not math.isfinite(value):
        raise InvalidField("an override must be finite")
    return value


Number = Annotated[
    int | float,
    PlainValidator(_number),
    WithJsonSchema({"type": "number", "description": "Value in the field's own SI unit."}),
]


class SimulationBase(StrictModel):
    kind: Literal["simulation"] = Field(description="The base computation: a simulation.")
    spec: SimulationSpec = Field(description="The simulation every case starts from.")


class StabilityBase(StrictModel):
    kind: Literal["stability"] = Field(
        description="The base computation: a critical-velocity analysis."
    )
    spec: StabilitySpec = Field(description="The analysis every case starts from.")


BaseRequest = Annotated[SimulationBase | StabilityBase, Field(discriminator="kind")]


class Samples(StrictModel):
    """Sampling mode of a study: its cases are drawn from independent distributions of
    numeric fields of the base request (uncertainty quantification)."""

    count: int = Field(
        ge=1,
        le=MAX_CASES,
        description="Design points [-]: the cases for sobol, latin_hypercube and random; "
        "the base points N of saltelli, which gives N (2 D + 2) cases for D parameters. "
        f"The cases are at most {MAX_CASES}. Sobol' designs balance best at a power of 2.",
    )
    method: Literal["sobol", "latin_hypercube", "random", "saltelli"] = Field(
        "sobol",
        description="How the points of the unit hypercube are drawn before each parameter's "
        "inverse CDF maps them: sobol (scrambled Sobol' sequence, scipy.stats.qmc), "
        "latin_hypercube (scipy.stats.qmc.LatinHypercube), random (independent uniform "
        "draws, numpy's default generator), saltelli (Saltelli's design of SALib for "
        "Sobol' sensitivity indices; the result then has `sensitivity`).",
    )
    seed: int = Field(
        0,
        ge=0,
        le=2**32 - 1,
        description="Seed of the design [-]: the same seed gives the same cases (and key).",
    )
    parameters: dict[Path, Distribution] = Field(
        min_length=1,
        max_length=MAX_OVERRIDES,
        description="Field path -> its distribution, in that field's own SI unit (e.g. "
        "{'pipe.E': {'distribution': 'lognormal', 'median': 7.8e9, 'sigma': 0.1}} [Pa]). "
        "The parameters are independent; the design's dimensions follow the paths sorted.",
    )


@dataclass(frozen=True)
class Case:
    """One case of a study: its position, what it overrides, and its own request."""

    index: int
    overrides: dict[str, int | float]
    request: StrictModel


def _resolve(tree: Any, path: str) -> tuple[bool, Any]:
    """``(found, value)`` of ``path`` (dotted, list items by index) in a JSON tree."""
    node = tree
    for part in path.split("."):
        if isinstance(node, dict) and part in node:
            node = node[part]
        elif isinstance(node, list) and part.isdigit() and int(part) < len(node):
            node = node[int(part)]
        else:
            return False, None
    return True, node


def _assign_copy(sparse: Any, full: Any, parts: Sequence[str], value: Any) -> Any:
    """``sparse`` (the request as given) with ``parts`` (a dotted path) set to ``value``,
    the parts left to their defaults (e.g. a profile's kind) copied from ``full`` (the
    request with its defaults).  ``sparse`` is not touched: the containers along the path
    are copied, every other part is shared (validation never mutates its input)."""
    key: Any = int(parts[0]) if isinstance(full, list) else parts[0]
    if len(parts) == 1:
        node = copy.copy(sparse)
        node[key] = value
        return node
    node = copy.copy(sparse)
    inside = isinstance(node, list) or key in node
    child = node[key] if inside else full[key]  # a default: shared too, copied along the path
    node[key] = _assign_copy(child, full[key], parts[1:], value)
    return node


def get_path(model: Any, path: str) -> Any:
    """The value at the dotted ``path`` of a validated request (attributes, list items)."""
    node = model
    for part in path.split("."):
        node = node[int(part)] if isinstance(node, list) else getattr(node, part)
    return node


def set_path(model: Any, path: str, value: Any) -> None:
    """Set the value at ``path`` of a request model in place, without validation (for
    templates: see :class:`pipeflow.computations.study_runner.CaseKeys`)."""
    parts = path.split(".")
    node = get_path(model, ".".join(parts[:-1])) if len(parts) > 1 else model
    if isinstance(node, list):
        node[int(parts[-1])] = value
    else:
        setattr(node, parts[-1], value)


#: how a leaf value is checked in bulk: strict, finite, as every request model
_LEAF_CONFIG = ConfigDict(strict=True, allow_inf_nan=False)


def _leaf_adapter(model: BaseModel, path: str) -> TypeAdapter[Any] | None:
    """A validator of the value at ``path`` of the validated request ``model`` by its
    field's own type and constraints (None when the field cannot be found)."""
    parts = path.split(".")
    node: Any = model
    annotation: Any = None
    for part in parts:
        if isinstance(node, BaseModel):
            info = type(node).model_fields.get(part)
            if info is None:
                return None
            annotation = (
                Annotated[(info.annotation, *info.metadata)] if info.metadata else info.annotation
            )
            node = getattr(node, part)
        elif isinstance(node, list) and part.isdigit():
            item = [a for a in typing.get_args(_strip(annotation))]
            annotation = item[0] if item else Any
            node = node[int(part)]
        else:
            return None
    return TypeAdapter(annotation, config=_LEAF_CONFIG)


def _strip(annotation: Any) -> Any:
    """``list[X]`` from ``Annotated[list[X], ...]`` or ``list[X] | None``."""
    if typing.get_origin(annotation) is Annotated:
        annotation = typing.get_args(annotation)[0]
    args = [a for a in typing.get_args(annotation) if a is not type(None)]
    if typing.get_origin(annotation) is not list and len(args) == 1:
        return _strip(args[0])
    return annotation


def _error(kind: str, loc: tuple[Any, ...], message: str, value: Any) -> InitErrorDetails:
    return InitErrorDetails(
        type=PydanticCustomError(kind, message),
        loc=loc,
        input=value,
    )


def _case_error(exc: ValidationError) -> tuple[str, str]:
    """The first error of a case's own validation: ``(field of the case, message)``."""
    err = exc.errors()[0]
    loc = [p for p in err["loc"] if not (isinstance(p, str) and p in _UNION_TAGS)]
    named = (err.get("ctx") or {}).get("error")
    if isinstance(named, InvalidField):  # a model's rule names its field as data
        loc += list(named.loc)
    return ".".join(str(p) for p in loc), str(err["msg"]).removeprefix("Value error, ")


#: discriminator values pydantic inserts into error locations of tagged unions
_UNION_TAGS = ("constant", "polynomial", "harmonic", "table")
_UNIT = re.compile(r"\[([^\],]+)\]")


class StudySpec(StrictModel):
    """A design study: a base request and a list (``cases``) or cartesian grid (``grid``) of
    overrides of its numeric fields; every case runs as the base computation would."""

    model_config = ConfigDict(
        json_schema_extra={
            "examples": [
                {
                    "base": {
                        "kind": "simulation",
                        "spec": {
                            **PAPER_EXAMPLE,
                            "modes": 4,
                            "time": {"t_end": 0.2, "samples": 101},
                        },
                    },
                    "grid": {
                        "pipe.M2": [1.0e-5, 1.6485e-5],
                        "rotation.omega0.value": [50.0, 100.0, 150.0],
                    },
                }
            ]
        },
    )

    base: BaseRequest = Field(description="The request every case starts from, with its kind.")
    cases: list[Annotated[dict[Path, Number], Field(max_length=MAX_OVERRIDES)]] | None = Field(
        None,
        min_length=1,
        max_length=MAX_CASES,
        description="List mode: one object per case, field path -> value in that field's SI "
        f"unit (e.g. {{'pipe.E': 7e9}} [Pa]); an empty object is the base itself. At most "
        f"{MAX_CASES} cases.",
    )
    grid: dict[Path, Annotated[list[Number], Field(min_length=1, max_length=MAX_CASES)]] | None = (
        Field(
            None,
            min_length=1,
            max_length=MAX_OVERRIDES,
            description="Grid mode: field path -> the values it takes, each in that field's SI "
            "unit (e.g. {'pipe.L': [0.02, 0.025]} [m]); the cases are every combination, "
            "in the order of the fields sorted by path, the last varying fastest. The "
            f"product of the lengths is at most {MAX_CASES}.",
        )
    )
    samples: Samples | None = Field(
        None,
        description="Sampling mode: the cases are drawn from distributions of numeric fields "
        "(Monte Carlo or quasi-Monte Carlo), and the result's `statistics` estimate the "
        "distribution of each summary column.",
    )
    operating_velocity: float | None = Field(
        None,
        ge=0,
        description="Stability bases: the flow velocity [m/s] at which "
        "statistics.instability counts a case unstable (its critical velocity at or below "
        "it, or unstable at the start of its range). Simulation bases have their own flow.",
    )

    @property
    def base_kind(self) -> str:
        """The base computation's name (``simulation`` or ``stability``)."""
        return self.base.kind

    def paths(self) -> list[str]:
        """The overridden fields, in order of first appearance (the table's columns; grid
        and samples: sorted by path)."""
        if self.grid is not None:
            return sorted(self.grid)
        if self.samples is not None:
            return sorted(self.samples.parameters)
        return list(dict.fromkeys(p for case in self.cases or [] for p in case))

    def count(self) -> int:
        """Number of cases [-]."""
        if self.grid is not None:
            return math.prod(len(v) for v in self.grid.values())
        if self.samples is not None:
            s = self.samples
            return uq.rows(s.method, s.count, len(s.parameters))
        return len(self.cases or [])

    def overrides(self) -> Iterator[dict[str, int | float]]:
        """Each case's overrides, in case order."""
        if self.grid is not None:
            axes = sorted(self.grid.items())
            for values in itertools.product(*(v for _, v in axes)):
                yield {path: value for (path, _), value in zip(axes, values, strict=True)}
        elif self.samples is not None:
            paths = self.paths()
            for row in self._drawn:
                yield dict(zip(paths, row, strict=True))
        else:
            yield from (dict(c) for c in self.cases or [])

    @functools.cached_property
    def _base_json(self) -> tuple[dict[str, Any], dict[str, Any]]:
        """The base request as given (sparse) and with its defaults (full)."""
        spec = self.base.spec
        full = with_defaults(spec, spec.model_dump(mode="json"))  # supports.py's fields
        return spec.model_dump(mode="json", exclude_unset=True), full

    def case_data(self, overrides: dict[str, int | float]) -> dict[str, Any]:
        """The JSON request of the case with ``overrides`` (the base's own parts shared)."""
        sparse, full = self._base_json
        data: Any = sparse
        for path, value in overrides.items():
            data = _assign_copy(data, full, path.split("."), value)
        return dict(data)

    def validate_case(
        self, overrides: dict[str, int | float]
    ) -> tuple[StrictModel | None, tuple[str, str] | None]:
        """The case's request validated by the base model: ``(request, None)``, or
        ``(None, (field of the case, message))`` when the case is invalid."""
        model = BASE_MODELS[self.base_kind]
        try:
            return model.model_validate(self.case_data(overrides)), None
        except ValidationError as exc:
            return None, _case_error(exc)

    def unit_design(self) -> uq.FloatArray:
        """Sampling mode: the design's points in [0, 1)^D, one row per case, a column per
        parameter in :meth:`paths` order (:func:`pipeflow.uq.unit_design`)."""
        s = self.samples
        if s is None:
            raise ValueError("a study of cases or a grid has no sampling design")
        return uq.unit_design(s.method, s.count, len(s.parameters), s.seed)

    def sample_values(self) -> uq.FloatArray:
        """Sampling mode: each case's values (rows) of the parameters (columns, in
        :meth:`paths` order), in their SI units: the design through each inverse CDF."""
        return np.array(self._drawn, dtype=float).reshape(len(self._drawn), -1)

    @functools.cached_property
    def _drawn(self) -> tuple[tuple[float, ...], ...]:
        """:meth:`sample_values`' rows, drawn once per study: the check before a study is
        accepted (:meth:`check`) and its run (:meth:`overrides`) read the same draws (kept
        as tuples: a study compares equal to another by its fields, with or without its
        draws).  Not pickled (:meth:`__getstate__`): the pieces shipped to workers carry
        their own overrides."""
        s = self.samples
        u = self.unit_design()
        assert s is not None
        columns = [
            uq.ppf(s.parameters[path].to_distribution(), u[:, j])
            for j, path in enumerate(self.paths())
        ]
        return tuple(map(tuple, np.column_stack(columns).tolist()))

    def __getstate__(self) -> dict[Any, Any]:
        state = super().__getstate__()
        state["__dict__"] = {k: v for k, v in state["__dict__"].items() if k != "_drawn"}
        return state

    def expand(self) -> list[Case]:
        """Every case as a validated request of the base kind (raises ValidationError naming
        the study's field, as :class:`StudySpec` validation does)."""
        model = BASE_MODELS[self.base_kind]
        out = []
        for i, overrides in enumerate(self.overrides()):
            try:
                request = model.model_validate(self.case_data(overrides))
            except ValidationError as exc:
                raise self._invalid_case(i, overrides, exc) from None
            out.append(Case(i, overrides, request))
        return out

    def _invalid_case(
        self, i: int, overrides: dict[str, int | float], exc: ValidationError
    ) -> ValidationError:
        field, message = _case_error(exc)
        where = ", ".join(f"{p} = {v!r}" for p, v in overrides.items()) or "no overrides"
        text = f"case {i} ({where}): {field or 'the request'}: {message}"
        loc: tuple[Any, ...]
        if self.grid is not None:
            loc = ("grid",)
            if field in overrides:
                loc = ("grid", field, self._grid_index(i)[field])
        elif self.samples is not None:
            loc = ("samples", "parameters", field) if field in overrides else ("samples",)
        else:
            loc = ("cases", i, field) if field in overrides else ("cases", i)
        value = overrides.get(field)
        return ValidationError.from_exception_data(
            "StudySpec", [_error("case_invalid", loc, text, value)]
        )

    def _grid_index(self, i: int) -> dict[str, int]:
        """Case ``i`` of the grid: the index of its value along each field."""
        out: dict[str, int] = {}
        for path, values in reversed(sorted((self.grid or {}).items())):
            i, out[path] = divmod(i, len(values))
        return out

    @model_validator(mode="after")
    def _valid(self) -> StudySpec:
        given = [m for m in ("cases", "grid", "samples") if getattr(self, m) is not None]
        if len(given) != 1:
            field = "samples" if "samples" in given else "cases"
            raise InvalidField(
                f"{field}: give exactly one of cases (a list of overrides), grid (values per "
                "field, combined as a cartesian product) and samples (distributions per field)"
                + (f"; this study gives {' and '.join(given)}" if given else ""),
                field,
            )
        if self.operating_velocity is not None and self.base_kind != "stability":
            raise InvalidField(
                "operating_velocity: only for stability bases (a simulation's own flow "
                "decides its cases' growth)",
                "operating_velocity",
            )
        if self.samples is not None:
            _check_samples(self.samples)
        if self.grid is not None and self.count() > MAX_CASES:
            sizes = " x ".join(str(len(v)) for _, v in sorted(self.grid.items()))
            raise InvalidField(
                f"grid: {sizes} = {self.count()} cases, more than {MAX_CASES}", "grid"
            )
        self._check_paths()
        return self.within_budget()

    def case_cost(self) -> tuple[Cost | None, dict[str, int | float]]:
        """The estimate of the costliest case: the base's :meth:`~StrictModel.cost` with every
        overridden count (a field that is an integer in the base) at the largest value a
        case gives it (each estimate grows with the counts); and those values.  When that
        combination is not a valid request, the base's own estimate."""
        _, full = self._base_json
        # samples draw real numbers: only cases and grids override counts
        paths = self.paths() if self.samples is None else []
        counts = {p for p in paths if isinstance(_resolve(full, p)[1], int)}
        largest: dict[str, int | float] = {}
        if counts:
            for overrides in self.overrides():
                for path, value in overrides.items():
                    if path in counts and isinstance(value, int):
                        largest[path] = max(largest.get(path, value), value)
        request: StrictModel = self.base.spec
        if largest:
            try:
                with costs_unchecked():
                    request = BASE_MODELS[self.base_kind].model_validate(
                        self.case_data(dict(largest))
                    )
            except ValidationError:
                largest = {}
        return request.cost(), largest

    def cost(self) -> Cost | None:
        """The cases times the estimate of the costliest case (:meth:`case_cost`, at most
        its own bound: a case over it is refused without running) against
        :data:`MAX_STUDY_REQUESTS` times the base's bound."""
        per_case, largest = self.case_cost()
        if per_case is None:
            return None
        cases = self.count()
        units = min(per_case.units, per_case.bound)
        where = "grid" if self.grid is not None else "samples.count" if self.samples else "cases"
        at = ", ".join(f"{p} = {v}" for p, v in largest.items())
        bound = MAX_STUDY_REQUESTS * per_case.bound
        return Cost(
            units=cases * units,
            bound=bound,
            unit=per_case.unit,
            fields=(where, "base"),
            terms=f"{cases} cases x {units:,} {per_case.unit} per case ({per_case.terms}"
            + (f", at {at}" if at else "")
            + ")",
            budget=f"study budget ({MAX_STUDY_REQUESTS} times the {self.base_kind} bound)",
            advice=f"at most {bound // max(1, units)} cases of this base",
        )

    def check(self) -> None:
        """Check every override value against its field's type and bounds in the base
        model, in bulk: each distinct value of a path once, by that field's own validator
        (raises ValidationError naming the first bad value's override, as :meth:`expand`
        does).  Rules across fields are the case's own validation's, when the study runs
        (:meth:`validate_case`: a failed row).  :attr:`~pipeflow.computations.registry.
        Computation.check` runs this before a study is accepted (~1 us per distinct value:
        a few milliseconds for 10,000 cases)."""
        adapters = {p: _leaf_adapter(self.base.spec, p) for p in self.paths()}
        verdicts: dict[tuple[str, type, float], str | None] = {}

        def bad(path: str, value: int | float) -> str | None:
            memo = (path, type(value), value)
            if memo not in verdicts:
                adapter = adapters[path]
                message = None
                if adapter is not None:
                    try:
                        adapter.validate_python(value)
                    except ValidationError as exc:
                        message = _case_error(exc)[1]
                verdicts[memo] = message
            return verdicts[memo]

        if self.grid is not None:
            for path, values in sorted(self.grid.items()):
                for j, value in enumerate(values):
                    message = bad(path, value)
                    if message is not None:
                        i = self._first_case(path, j)
                        text = f"case {i} ({path} = {value!r}): {path}: {message}"
                        raise ValidationError.from_exception_data(
                            "StudySpec",
                            [_error("case_invalid", ("grid", path, j), text, value)],
                        )
            return
        if self.samples is not None:  # draws: a value the field refuses names its parameter
            for i, overrides in enumerate(self.overrides()):
                for path, value in overrides.items():
                    message = bad(path, value)
                    if message is not None:
                        text = f"case {i} ({path} = {value!r}): {path}: {message}"
                        raise ValidationError.from_exception_data(
                            "StudySpec",
                            [_error("case_invalid", ("samples", "parameters", path), text, value)],
                        )
            return
        for i, overrides in enumerate(self.cases or []):
            for path, value in overrides.items():
                message = bad(path, value)
                if message is not None:
                    where = ", ".join(f"{p} = {v!r}" for p, v in overrides.items())
                    text = f"case {i} ({where}): {path}: {message}"
                    raise ValidationError.from_exception_data(
                        "StudySpec", [_error("case_invalid", ("cases", i, path), text, value)]
                    )

    def _first_case(self, path: str, j: int) -> int:
        """The first case of the grid taking value ``j`` of ``path``."""
        i = 0
        for p, values in sorted((self.grid or {}).items()):
            i = i * len(values) + (j if p == path else 0)
        return i

    def _check_paths(self) -> None:
        full = with_defaults(self.base.spec, self.base.spec.model_dump(mode="json"))
        where: dict[str, tuple[Any, ...]] = {}
        if self.grid is not None:
            where = {p: ("grid", p) for p in self.grid}
        elif self.samples is not None:
            where = {p: ("samples", "parameters", p) for p in self.samples.parameters}
        else:
            for i, case in enumerate(self.cases or []):
                for p in case:
                    where.setdefault(p, ("cases", i, p))
        errors = []
        for path, loc in where.items():
            found, value = _resolve(full, path)
            if not found:
                message = f"{path} is not a field of the base {self.base_kind} request"
            elif isinstance(value, bool) or not isinstance(value, int | float | None):
                what = type(value).__name__.replace("dict", "object").replace("list", "array")
                message = f"{path} is not a numeric field (it is {what} in the base request)"
            elif self.samples is not None and isinstance(value, int):
                message = (
                    f"{path} is an integer field (a count): samples draw real numbers; vary "
                    "it by cases or grid"
                )
            else:
                continue
            errors.append(_error("override_path", loc, message, path))
        if errors:
            raise ValidationError.from_exception_data("StudySpec", errors)

    def canonical(self) -> dict[str, Any]:
        """Normalised form for the study's key (and a valid request again: a job is
        recovered from it): the base's own normal form, then the cases or the grid."""
        out: dict[str, Any] = {
            "base": {"kind": self.base_kind, "spec": self.base.spec.canonical()},
        }
        if self.grid is not None:
            out["grid"] = {path: list(values) for path, values in self.grid.items()}
        elif self.samples is not None:
            out["samples"] = self.samples.model_dump(mode="json")
        else:
            out["cases"] = [dict(c) for c in self.cases or []]
        if self.operating_velocity is not None:
            out["operating_velocity"] = self.operating_velocity
        return out


def _check_samples(samples: Samples) -> None:
    """Each distribution's parameters, and the case count of a Saltelli design."""
    errors = []
    for path, d in samples.parameters.items():
        loc = ("samples", "parameters", path)
        checks: list[tuple[str, bool, str]] = []
        if isinstance(d, NormalDistribution | TruncatedNormalDistribution):
            checks.append(("std", d.std > 0, f"std must be > 0 (got {d.std!r})"))
        if isinstance(d, LognormalDistribution):
            checks.append(("median", d.median > 0, f"median must be > 0 (got {d.median!r})"))
            checks.append(("sigma", d.sigma > 0, f"sigma must be > 0 (got {d.sigma!r})"))
        if isinstance(d, UniformDistribution | TruncatedNormalDistribution):
            checks.append(
                ("low", d.low < d.high, f"low ({d.low!r}) must be below high ({d.high!r})")
            )
        for name, ok, text in checks:
            if not ok:
                message = f"{path}: {d.distribution} {text}"
                errors.append(_error("distribution_invalid", (*loc, name), message, path))
    dims = len(samples.parameters)
    cases = uq.rows(samples.method, samples.count, dims)
    if cases > MAX_CASES:
        largest = MAX_CASES // (2 * dims + 2)
        message = (
            f"saltelli: {samples.count} base points x (2 x {dims} + 2) = {cases} cases, "
            f"more than {MAX_CASES}: count is at most {largest} for {dims} parameters"
        )
        errors.append(_error("too_many_cases", ("samples", "count"), message, cases))
    if errors:
        raise ValidationError.from_exception_data("StudySpec", errors)


def field_unit(model: type[BaseModel], path: str) -> str:
    """The SI unit of the numeric field ``path`` of ``model``, read from the descriptions:
    the field's own ``[unit]``; for a profile's value, mean, amplitude or table values the
    profile's (the quantity's) unit; ``(unit) s^-k`` for a polynomial's coefficient k;
    ``-`` when the field states none (counts)."""
    chain = _descriptions(model, path.split("."))
    leaf = path.split(".")
    own = _UNIT.findall(chain[-1]) if chain else []
    if own:
        return own[0]
    if len(leaf) >= 2 and leaf[-2] == "coefficients" and leaf[-1].isdigit():
        unit = _quantity_unit(chain[:-1])
        k = int(leaf[-1])
        return unit if k == 0 or unit == "-" else f"({unit}) s^-{k}"
    if leaf[-1] in ("value", "mean", "amplitude") or (len(leaf) >= 2 and leaf[-2] == "values"):
        return _quantity_unit(chain[:-1])
    return "-"


def _quantity_unit(chain: Sequence[str]) -> str:
    for text in reversed(chain):
        found = _UNIT.findall(text)
        if found:
            return found[0]
    return "-"


def _descriptions(model: type[BaseModel], parts: list[str]) -> list[str]:
    """The descriptions of the fields along ``parts`` (profiles: their variants' fields)."""
    out: list[str] = []
    models: list[type[BaseModel]] = [model]
    for part in parts:
        if part.isdigit():
            continue
        info = next((m.model_fields[part] for m in models if part in m.model_fields), None)
        if info is None:
            break
        out.append(info.description or "")
        models = _model_types(info.annotation)
    return out


def _model_types(annotation: Any) -> list[type[BaseModel]]:
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return [annotation]
    found: list[type[BaseModel]] = []
    for arg in typing.get_args(annotation):
        found += _model_types(arg)
    return found


#: a small study of the paper's example (6 cases, 4 modes, 0.2 s each)
STUDY_EXAMPLE: dict[str, Any] = StudySpec.model_json_schema()["examples"][0]

#: a stability study: critical velocity of the paper's pipe at four spins
STABILITY_STUDY_EXAMPLE: dict[str, Any] = {
    "base": {
        "kind": "stability",
        "spec": {"pipe": PAPER_PIPE_JSON, "modes": 6, "velocity_range": [0.0, 60.0]},
    },
    "grid": {"rotation.omega0.value": [0.0, 100.0, 200.0, 400.0]},
}
