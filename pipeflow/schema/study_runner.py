"""Running a design study: many cases of one simulation or stability analysis, as one table.

:func:`run_study` takes a validated :class:`~pipeflow.schema.study.StudySpec` and its base
computation (the registry's entry for ``spec.base_kind``: passed in, so this module never
imports the registry, which registers the study computation that runs it), expands the
spec into its cases (each a standalone request of the base kind, keyed by
:func:`~pipeflow.schema.keys.canonical_key` exactly as that request would be on its own),
and runs the cases the current memo (:func:`pipeflow.parallel.current_memo`) does not
already hold, in chunks of at most :data:`CHUNK_CASES` cases fanned out on the current
host (:func:`pipeflow.parallel.fan_out`); cases with the same key are computed once.
Each case is run by its base computation's ``execute`` (the same call as a standalone
request) and reduced on the spot to a summary by the base computation's own
``summarize`` (a few numbers, not its time histories, under its ``summary_columns``),
which is what the memo stores.  One failing case does not fail the study: its row says
``failed`` with the problem's type, field and detail.

Progress is exact: the fraction of cases done (served by the memo or computed), reported
after the memo look-up and after each chunk.

The result is a table (``columns`` with their units, one ``row`` per case in case order),
``counts``, ``statistics`` of the numeric summary columns over the ok cases (with the
probability that a case is unstable, :func:`statistics`) and, for a ``saltelli`` sampled
study, the Sobol' indices of each column (:func:`sensitivity`); :mod:`pipeflow.io.export`
writes the table as the ``study`` CSV table.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from typing import Any, Protocol

from pydantic import BaseModel

from pipeflow import parallel, uq
from pipeflow._types import Progress
from pipeflow.errors import classify
from pipeflow.schema import results as r
from pipeflow.schema.keys import canonical_key
from pipeflow.schema.study import StudySpec, field_unit

#: most cases in one fanned-out piece (amortises a dispatch of ~10 ms over several cases,
#: and bounds the cases between two progress reports) [-]
CHUNK_CASES = 16
#: most keys in one memo look-up [-]
MEMO_BATCH = 500
#: the memo's name for per-case summaries: memo key = "study_case:<case key>"
MEMO_KIND = "study_case"


def memo_key(case_key: str) -> str:
    """The memo key of a case's summary (not the case's own key: the full result of the
    standalone request lives under that one)."""
    return f"{MEMO_KIND}:{case_key}"


@dataclass(frozen=True)
class Column:
    """A column of the study table: name, SI unit (``-``: a count or ratio; ``""``: text
    or a flag) and what it holds."""

    name: str
    unit: str
    description: str

    def to_dict(self) -> dict[str, str]:
        """JSON form: :class:`pipeflow.schema.results.StudyColumn`."""
        return r.document(
            r.StudyColumn, name=self.name, unit=self.unit, description=self.description
        )


LEADING = (
    Column(
        "index",
        "-",
        "Position of the case in the study (list order; grid: the fields sorted by "
        "path, the last varying fastest).",
    ),
    Column("key", "", "The case's own cache key: the key of the standalone request."),
    Column("status", "", "ok, or failed (the error_* columns say why)."),
    Column("cached", "", "True when the summary came from the cache, not computed now."),
)
TRAILING = (
    Column(
        "error_type",
        "",
        "Failed cases: the problem type (e.g. budget-exceeded, invalid-input, numerical-range).",
    ),
    Column("error_field", "", "Failed cases: the field of the case's own request at fault."),
    Column("error_detail", "", "Failed cases: what went wrong."),
)


class BaseComputation(Protocol):
    """What a study needs of its base computation (a registry entry, see
    :class:`~pipeflow.schema.registry.Computation`): its name (the cases' key kind), how
    to run one case, and how to reduce a case's result to its summary columns."""

    @property
    def name(self) -> str: ...

    @property
    def summary_columns(self) -> tuple[Column, ...]: ...

    @property
    def summarize(self) -> Callable[[dict[str, Any]], dict[str, Any]] | None: ...

    def execute(self, request: BaseModel, progress: Progress | None = None) -> dict[str, Any]: ...


def _summarize(base: BaseComputation, result: dict[str, Any]) -> dict[str, Any]:
    if base.summarize is None:
        raise TypeError(f"the {base.name} computation has no study summary")
    return base.summarize(result)


#: failures of a case that say nothing lasting about its request (a bug, or the case
#: stopped or could not be stored): reported in the row, never memoised
UNLASTING = ("internal", "cancelled", "runtime-limit", "storage")


def _failure(error_type: str, field: str | None, detail: str) -> dict[str, Any]:
    return {"error_type": error_type, "error_field": field, "error_detail": detail}


def run_case(base: BaseComputation, request: BaseModel) -> dict[str, Any]:
    """Run one case through its base computation and summarise it: ``{"status": "ok",
    **summary}`` or ``{"status": "failed", error_type, error_field, error_detail}``."""
    try:
        result = base.execute(request)
    except Exception as exc:  # an internal one is a bug: in the row, not memoised (run_study)
        record = classify(exc)  # the failure as the service's jobs record it
        return {"status": "failed", **_failure(record.type, record.field, record.message)}
    return {"status": "ok", **_summarize(base, result)}


def run_cases(piece: tuple[BaseComputation, Sequence[BaseModel]]) -> list[dict[str, Any]]:
    """The fanned-out piece: ``(base computation, requests)`` -> their summaries
    (:func:`run_case`)."""
    base, requests = piece
    return [run_case(base, r) for r in requests]


def _memoised(memo: parallel.Memo | None, keys: Sequence[str]) -> dict[str, dict[str, Any]]:
    if memo is None:
        return {}
    found: dict[str, dict[str, Any]] = {}
    for start in range(0, len(keys), MEMO_BATCH):
        batch = keys[start : start + MEMO_BATCH]
        stored = memo.get_many([memo_key(k) for k in batch])
        found.update({k: stored[memo_key(k)] for k in batch if memo_key(k) in stored})
    return found


def _closing(it: Iterator[Any]) -> Iterator[Any]:
    try:
        yield from it
    finally:
        close = getattr(it, "close", None)
        if callable(close):
            close()  # abandon the pieces not yet finished (cancel, runtime limit)


def run_study(
    spec: StudySpec, base: BaseComputation, progress: Progress | None = None
) -> dict[str, Any]:
    """Every case of ``spec`` summarised, as a table (see the module docstring); ``base``
    is the computation named by ``spec.base_kind`` (the registry's entry)."""
    if base.name != spec.base_kind or base.summarize is None:
        raise ValueError(f"a {spec.base_kind} study cannot run cases of {base.name!r}")
    kind = base.name
    cases = spec.expand()
    total = len(cases)
    keys = [canonical_key(kind, case.request.canonical()) for case in cases]
    # one computation per distinct key (cases that normalise alike share it)
    first: dict[str, int] = {}
    multiplicity: dict[str, int] = {}
    for i, key in enumerate(keys):
        first.setdefault(key, i)
        multiplicity[key] = multiplicity.get(key, 0) + 1

    memo = parallel.current_memo()
    summaries = _memoised(memo, list(first))
    cached = set(summaries)
    done = sum(multiplicity[k] for k in cached)
    if progress is not None:
        progress(done / total)

    todo = [k for k in first if k not in cached]
    chunks = parallel.split(len(todo), max_size=CHUNK_CASES)
    pieces = [(base, [cases[first[todo[j]]].request for j in chunk]) for chunk in chunks]
    for c, results in _closing(parallel.fan_out(run_cases, pieces)):
        chunk_keys = [todo[j] for j in chunks[c]]
        summaries.update(zip(chunk_keys, results, strict=True))
        if memo is not None:
            keep = {
                memo_key(k): s
                for k, s in zip(chunk_keys, results, strict=True)
                if s.get("error_type") not in UNLASTING
            }
            if keep:
                memo.put_many(keep)
        done += sum(multiplicity[k] for k in chunk_keys)
        if progress is not None:
            progress(done / total)
    return _table(spec, base, cases, keys, summaries, cached, computed=len(todo))


def columns(spec: StudySpec, base: BaseComputation) -> list[Column]:
    """The columns of ``spec``'s table: leading, one per overridden field, the summary
    columns of the base computation, then the error columns."""
    model = type(spec.base.spec)
    overrides = [
        Column(path, field_unit(model, path), f"The case's {path} (null: the base's).")
        for path in spec.paths()
    ]
    return [*LEADING, *overrides, *base.summary_columns, *TRAILING]


def _table(
    spec: StudySpec,
    base: BaseComputation,
    cases: Sequence[Any],
    keys: Sequence[str],
    summaries: dict[str, dict[str, Any]],
    cached: set[str],
    computed: int,
) -> dict[str, Any]:
    cols = columns(spec, base)
    paths = spec.paths()
    metrics = [c.name for c in (*base.summary_columns, *TRAILING)]
    rows = []
    for case, key in zip(cases, keys, strict=True):
        s = summaries[key]
        rows.append(
            [
                case.index,
                key,
                s["status"],
                key in cached,
                *(case.overrides.get(p) for p in paths),
                *(s.get(m) for m in metrics),
            ]
        )
    failed = sum(1 for r in rows if r[2] == "failed")
    warnings = [f"{failed} of {len(rows)} cases failed (see error_detail)"] if failed else []
    records = [summaries[key] for key in keys]
    sens = sensitivity(spec, base, records)
    if sens is not None:
        warnings += [
            f"no Sobol' indices of {name}: {c['reason']}"
            for name, c in sens["columns"].items()
            if not c["available"]
        ]
    return r.document(
        r.StudyResponse,
        base_kind=spec.base_kind,
        overrides=paths,
        columns=[c.to_dict() for c in cols],
        rows=rows,
        counts=r.document(
            r.StudyCounts,
            total=len(rows),
            ok=len(rows) - failed,
            failed=failed,
            cached=sum(1 for k in keys if k in cached),
            computed=computed,
        ),
        statistics=statistics(spec, base, cases, records),
        sensitivity=sens,
        warnings=warnings,
    )


def numeric_columns(base: BaseComputation) -> list[Column]:
    """The summary columns statistics are taken of: those with a unit (numbers)."""
    return [c for c in base.summary_columns if c.unit != ""]


def _unstable(spec: StudySpec, case: Any, record: dict[str, Any]) -> bool | None:
    """Whether a case is unstable (see :class:`~pipeflow.schema.results.StudyInstability`),
    None when undecided."""
    if record["status"] != "ok":
        return None
    if spec.base_kind == "simulation":
        return bool(record.get("result_status") != "ok")
    v_op = spec.operating_velocity
    assert v_op is not None
    if record.get("stable_at_start") is False:
        return True
    critical = record.get("critical_velocity")
    if critical is not None and critical <= v_op:
        return True
    if float(case.request.velocity_range[1]) < v_op:
        return None  # its range ends before the operating velocity
    return False


#: how a case counts as unstable, by base kind (the result's instability.criterion)
CRITERIA = {
    "simulation": "result_status is diverging or overflow (a growing branch of the frozen "
    "spectrum at t_end, the tip past its divergence bound, or overflow)",
    "stability": "stable_at_start is false, or critical_velocity <= operating_velocity",
}


def statistics(
    spec: StudySpec,
    base: BaseComputation,
    cases: Sequence[Any],
    records: Sequence[dict[str, Any]],
) -> dict[str, Any]:
    """:class:`~pipeflow.schema.results.StudyStatistics` of the cases' summaries
    (``records``, in case order)."""
    ok = [rec for rec in records if rec["status"] == "ok"]
    cols = {
        c.name: r.document(
            r.ColumnStatistics, unit=c.unit, **uq.column_statistics([rec.get(c.name) for rec in ok])
        )
        for c in numeric_columns(base)
    }
    instability = None
    if spec.base_kind == "simulation" or spec.operating_velocity is not None:
        flags = [_unstable(spec, case, rec) for case, rec in zip(cases, records, strict=True)]
        instability = r.document(
            r.StudyInstability,
            criterion=CRITERIA[spec.base_kind],
            **uq.instability_probability([f for f in flags if f is not None]),
        )
    return r.document(
        r.StudyStatistics,
        ok=len(ok),
        failed=len(records) - len(ok),
        columns=cols,
        instability=instability,
    )


def sensitivity(
    spec: StudySpec, base: BaseComputation, records: Sequence[dict[str, Any]]
) -> dict[str, Any] | None:
    """:class:`~pipeflow.schema.results.StudySensitivity` of a saltelli study, else None."""
    samples = spec.samples
    if samples is None or samples.method != "saltelli":
        return None
    paths = spec.paths()
    out: dict[str, Any] = {}
    for c in numeric_columns(base):
        given = [rec.get(c.name) if rec["status"] == "ok" else None for rec in records]
        values = [float(v) for v in given if v is not None and math.isfinite(v)]
        reason = None
        if len(values) < len(given):
            reason = (
                f"{len(given) - len(values)} of {len(given)} cases have no value (failed, or "
                "null): the estimators need every case of the design"
            )
        elif min(values) == max(values):
            reason = "the column does not vary over the design (its variance is 0)"
        if reason is not None:
            out[c.name] = r.document(
                r.ColumnSensitivity, available=False, reason=reason, parameters=None
            )
            continue
        indices = uq.sobol_indices(paths, values, seed=samples.seed)
        out[c.name] = r.document(
            r.ColumnSensitivity,
            available=True,
            reason=None,
            parameters={p: r.document(r.SobolIndices, **indices[p]) for p in paths},
        )
    return r.document(
        r.StudySensitivity,
        method="saltelli",
        base_points=samples.count,
        conf_level=uq.CONF_LEVEL,
        columns=out,
    )
