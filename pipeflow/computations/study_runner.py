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
which is what the memo stores.  A base computation with ``summarize_many`` (simulation:
:func:`pipeflow.batch.summaries`, one stacked computation for the constant-coefficient
cases, stacked magnus runs for the time-variant ones) is given a whole piece first; the
cases it leaves (``None``) run one by one as above.  Pieces hold up to
:data:`BATCH_CHUNK_CASES` cases when the base says the study's cases are ``batchable``
(constant coefficients: microseconds a case), else :data:`CHUNK_CASES` (time-variant cases,
tens of milliseconds each: 16 fill one stacked magnus,
:data:`pipeflow.solvers.magnus.stack.MAX_RUNS`, and keep every worker busy).  On a host
that ships its pieces, a large batchable study is cut by :func:`plan` instead (large
pieces first, small ones last; each summarised :data:`BATCH_CASES` cases at a time).  One
failing case does not fail the study: its row says ``failed`` with the problem's type,
field and detail; a case its base model refuses (a rule across fields) is such a row too
(``invalid-input``, no key).

On the serial host (the library's default) cases are validated and keyed here, looked up
in the memo in one batch, and the pieces carry the validated requests.  On any other host
(the service's Dask workers) a piece carries the study's base, a contiguous run of case
overrides (plain JSON, small to ship) and the memo, and does all of a case's work where it
runs (:func:`run_piece`): validation, key, memo look-up (one batch per piece), the
computation of the cases the memo lacks, and their memo write (one batch per piece); this
process only merges the rows.  Pydantic models cost more to pickle (~0.3 ms a case, both
ways) than to validate (~0.17 ms), and validating in this process first serialised half of
a study's work on one core while the workers waited.  Cases with equal keys are computed
once per piece there (equal keys in two pieces may both be computed; ``counts.computed``
counts computations).  A case's key is its standalone request's
:func:`~pipeflow.schema.keys.canonical_key`, computed by :class:`CaseKeys` from a template
of the base where the case's dump shows that only its override fields differ from the base
(else from its own canonical form, as before).

Progress is exact: the fraction of cases done (served by the memo or computed), reported
after the memo look-up and after each chunk (serial host), or after each piece.

The result is a table (``columns`` with their units, one ``row`` per case in case order),
``counts``, ``statistics`` of the numeric summary columns over the ok cases (with the
probability that a case is unstable, :func:`statistics`) and, for a ``saltelli`` sampled
study, the Sobol' indices of each column (:func:`sensitivity`); :mod:`pipeflow.io.export`
writes the table as the ``study`` CSV table.
"""

from __future__ import annotations

import hashlib
import math
import os
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from typing import Any, Protocol

import rfc8785
from pydantic import BaseModel, TypeAdapter

from pipeflow import __version__, parallel, uq
from pipeflow._types import Progress
from pipeflow.errors import InvalidInput, classify
from pipeflow.schema import results as r
from pipeflow.schema.keys import canonical_key
from pipeflow.schema.stability import StabilitySpec
from pipeflow.schema.study import StudySpec, field_unit, get_path, set_path

#: most cases in one fanned-out piece (amortises a dispatch of ~10 ms over several cases,
#: and bounds the cases between two progress reports) [-]
CHUNK_CASES = 16
#: most cases in one piece when the base summarises a chunk at once (one stacked
#: computation: larger pieces amortise it and the dispatch) on the serial host [-]
BATCH_CHUNK_CASES = 256
#: most cases in one stacked computation (``summarize_many``) of a shipped piece: a piece
#: of more cases runs it on consecutive runs of this many (per case, 128 took ~0.22 ms of
#: CPU against ~0.25 for 256 and ~0.27 for 512 on the 10,000-case study: the stack's
#: temporaries stay in cache) [-]
BATCH_CASES = 128
#: most cases in one shipped piece of batchable cases: the first pieces of a study are
#: this large (fewer dispatches, each costing a worker ~5-15 ms idle between two pieces
#: on the 2-core machine), later ones shrink, :func:`plan` [-]
BATCH_PIECE_CASES = 1024
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
    :class:`~pipeflow.computations.registry.Computation`): its name (the cases' key kind), how
    to run one case, and how to reduce a case's result to its summary columns."""

    @property
    def name(self) -> str: ...

    @property
    def summary_columns(self) -> tuple[Column, ...]: ...

    @property
    def summarize(self) -> Callable[[dict[str, Any]], dict[str, Any]] | None: ...

    @property
    def summarize_many(
        self,
    ) -> Callable[[Sequence[BaseModel]], list[dict[str, Any] | None]] | None: ...

    @property
    def batchable(self) -> Callable[[BaseModel], bool] | None: ...

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


def plan(total: int, width: int, many: bool) -> list[range]:
    """``range(total)`` cut into the contiguous pieces a shipping host of ``width`` workers
    runs.  Cases run one by one (not ``many``): pieces of at most :data:`CHUNK_CASES`.
    Up to ``4 width`` x :data:`BATCH_CASES` batchable cases: :func:`parallel.split` (about
    4 pieces a worker, at most :data:`BATCH_CHUNK_CASES` cases each).  More batchable
    cases, guided self-scheduling: each piece a ``2 width``-th of the cases left,
    between :data:`BATCH_CASES` and :data:`BATCH_PIECE_CASES` (the last two share a
    remainder under 2 x :data:`BATCH_CASES`), so the first pieces are large (few
    dispatches, during which a worker idles) and the last ones small (the workers end
    together).  10,000 cases on 2 workers: 17 pieces, sizes never growing, the last three
    of 128 cases (it was 40 pieces of 250)."""
    if total <= 0:
        return []
    if not many:
        return parallel.split(total, max_size=CHUNK_CASES)
    width = max(1, width)
    if total <= 4 * width * BATCH_CASES:
        return parallel.split(total, max_size=BATCH_CHUNK_CASES)
    out: list[range] = []
    start = 0
    while start < total:
        left = total - start
        size = min(left, BATCH_PIECE_CASES, max(BATCH_CASES, math.ceil(left / (2 * width))))
        if 0 < left - size < BATCH_CASES:
            size = math.ceil(left / 2)  # the last two share what is left
        out.append(range(start, start + size))
        start += size
    return out


@dataclass(frozen=True)
class Piece:
    """Cases to compute: their base computation and the validated ``requests``; ``batch``:
    the most cases of one ``summarize_many`` call (None: all at once)."""

    base: BaseComputation
    requests: Sequence[BaseModel]
    batch: int | None = None


@dataclass(frozen=True)
class Chunk:
    """A shipped piece of a study (see the module docstring): the cases ``start``,
    ``start + 1``, ... of ``spec`` with ``overrides``, looked up in and written to
    ``memo``; ``batch``: as :attr:`Piece.batch`."""

    base: BaseComputation
    spec: StudySpec
    start: int
    overrides: Sequence[dict[str, int | float]]
    memo: parallel.Memo | None = None
    batch: int | None = None


@dataclass(frozen=True)
class ChunkRows:
    """What :func:`run_piece` gives back per case of its chunk: the key (None: the case is
    invalid), the summary, whether the memo served it; and the keys it computed.

    ``timing``: where the piece's time went (diagnostics, ``benchmarks/bench_fanout.py
    --timeline``): ``start``/``end`` [s since the epoch, the worker's clock], ``pid``, and
    the seconds of its phases ``validate`` (validation and keys), ``memo_get``,
    ``compute``, ``memo_put``, and the CPU seconds of this thread in the whole piece
    (``cpu``) and in its memo write (``memo_put_cpu``): wall minus CPU is waiting (a lock,
    the GIL, another process on the core)."""

    keys: list[str | None]
    summaries: list[dict[str, Any]]
    cached: list[bool]
    computed: list[str]
    timing: dict[str, float] = field(default_factory=dict)


def run_piece(chunk: Chunk) -> ChunkRows:
    """Every case of ``chunk``, where the piece runs: validated, keyed, served by the memo
    or computed (:func:`run_cases`, each distinct key once) and memoised."""
    start, t0, c0 = time.time(), time.perf_counter(), time.thread_time()
    spec, base = chunk.spec, chunk.base
    keyer = CaseKeys(base.name, spec.base.spec, spec.paths())
    keys: list[str | None] = []
    summaries: list[dict[str, Any] | None] = []
    first: dict[str, BaseModel] = {}
    for j, o in enumerate(chunk.overrides):
        request, problem = spec.validate_case(o)
        if request is None:
            assert problem is not None
            keys.append(None)
            summaries.append(_invalid(chunk.start + j, problem))
            continue
        key = keyer.key(request)
        keys.append(key)
        summaries.append(None)
        first.setdefault(key, request)
    t1 = time.perf_counter()
    found = _memoised(chunk.memo, list(first))
    todo = [k for k in first if k not in found]
    t2 = time.perf_counter()
    computed = run_cases(Piece(base, requests=[first[k] for k in todo], batch=chunk.batch))
    results = dict(zip(todo, computed, strict=True))
    t3, c3 = time.perf_counter(), time.thread_time()
    _remember(chunk.memo, results)
    t4, c4 = time.perf_counter(), time.thread_time()
    found.update(results)
    rows = [s if s is not None else found[str(k)] for s, k in zip(summaries, keys, strict=True)]
    cached = [k is not None and k not in results for k in keys]
    timing = {
        "start": start,
        "end": start + (time.perf_counter() - t0),
        "pid": float(os.getpid()),
        "validate": t1 - t0,
        "memo_get": t2 - t1,
        "compute": t3 - t2,
        "memo_put": t4 - t3,
        "cpu": time.thread_time() - c0,
        "memo_put_cpu": c4 - c3,
    }
    return ChunkRows(keys=keys, summaries=rows, cached=cached, computed=todo, timing=timing)


def _invalid(i: int, problem: tuple[str, str]) -> dict[str, Any]:
    """The row of case ``i``, which its base model refuses (``problem``: field, message)."""
    field, message = problem
    detail = f"case {i}: {field or 'the request'}: {message}"
    return {"status": "failed", **_failure(InvalidInput(detail).slug, field or None, detail)}


def _remember(memo: parallel.Memo | None, results: dict[str, dict[str, Any]]) -> None:
    """Write the lasting ones of ``results`` (case key -> summary) to ``memo``, one batch."""
    if memo is None:
        return
    keep = {memo_key(k): s for k, s in results.items() if s.get("error_type") not in UNLASTING}
    if keep:
        memo.put_many(keep)


def run_cases(piece: Piece | tuple[BaseComputation, Sequence[BaseModel]]) -> list[dict[str, Any]]:
    """The fanned-out piece -> its cases' summaries: the base's ``summarize_many`` first
    where it has one, :func:`run_case` for the cases it leaves."""
    if isinstance(piece, tuple):
        piece = Piece(piece[0], requests=piece[1])
    base, requests = piece.base, list(piece.requests)
    many = getattr(base, "summarize_many", None)
    found: list[dict[str, Any] | None] = [None] * len(requests)
    if many:
        step = piece.batch or len(requests) or 1
        found = [s for i in range(0, len(requests), step) for s in many(requests[i : i + step])]
    return [s if s is not None else run_case(base, r) for s, r in zip(found, requests, strict=True)]


class CaseKeys:
    """The key of each case of a study, as its standalone request's
    (:func:`~pipeflow.schema.keys.canonical_key` of its canonical form), computed fast.

    The RFC 8785 form and its hash are pure Python (~0.1 ms a case); a case differs from
    the base in its override fields only, so its key is a template: the base's canonical
    JSON with a sentinel at each override path, cut there, rejoined with the case's values.
    That holds when the case's own ``model_dump_json`` is the base's dump with the case's
    values at those paths (the canonical form is a function of the model's fields, as the
    service's key memo relies on: equal dumps, equal normal forms); a case whose dump shows
    anything else (a validator normalised another field) is keyed from its own canonical
    form, and so is every case when the template cannot be cut cleanly."""

    def __init__(self, kind: str, base: BaseModel, paths: Sequence[str]) -> None:
        self.kind, self.paths = kind, list(paths)
        self._dump: tuple[list[str], list[int]] | None = None
        self._jcs: tuple[list[bytes], list[int]] | None = None
        self._texts: dict[tuple[type, Any], tuple[str, bytes]] = {}
        try:
            self._template(base)
        except Exception:  # no template: every case keyed from its canonical form
            self._dump = self._jcs = None

    def _template(self, base: BaseModel) -> None:
        model = base.model_copy(deep=True)
        sentinels: list[Any] = []
        for i, path in enumerate(self.paths):
            current = get_path(model, path)
            if isinstance(current, int) and not isinstance(current, bool):
                sentinel: Any = -(7_340_000_001 + i)
            else:
                sentinel = float(f"-1.2345678901{i:02d}e-299")
            set_path(model, path, sentinel)
            sentinels.append(sentinel)
        canonical = getattr(model, "canonical", None)
        canon = canonical() if callable(canonical) else model.model_dump(mode="json")
        payload = {"pipeflow": __version__, "kind": self.kind, "spec": canon}
        dump = _cut(model.model_dump_json(), [self._text(v)[0] for v in sentinels], once=True)
        jcs = _cut(rfc8785.dumps(payload), [self._text(v)[1] for v in sentinels], once=False)
        if dump is not None and jcs is not None:
            self._dump, self._jcs = dump, jcs

    def _text(self, value: Any) -> tuple[str, bytes]:
        """(pydantic's JSON, RFC 8785's) of a number."""
        memo = (type(value), value)
        found = self._texts.get(memo)
        if found is None:
            pyd = _adapter(type(value)).dump_json(value).decode()
            found = self._texts[memo] = (pyd, rfc8785.dumps(value))
        return found

    def key(self, request: BaseModel) -> str:
        """The key of ``request``, a validated case of the study."""
        if self._dump is not None and self._jcs is not None:
            texts = [self._text(get_path(request, p)) for p in self.paths]
            parts, order = self._dump
            predicted = parts[0] + "".join(
                texts[j][0] + part for j, part in zip(order, parts[1:], strict=True)
            )
            if request.model_dump_json() == predicted:
                jparts, jorder = self._jcs
                body = jparts[0] + b"".join(
                    texts[j][1] + part for j, part in zip(jorder, jparts[1:], strict=True)
                )
                return hashlib.sha256(body).hexdigest()
        canonical = getattr(request, "canonical", None)
        canon = canonical() if callable(canonical) else request.model_dump(mode="json")
        return canonical_key(self.kind, canon)


_ADAPTERS: dict[type, TypeAdapter[Any]] = {}


def _adapter(kind: type) -> TypeAdapter[Any]:
    """pydantic's serialiser of a number type, built once per process (building one takes
    ~0.4 ms: per distinct value in every piece of a study, it was a third of a piece's
    bookkeeping)."""
    found = _ADAPTERS.get(kind)
    if found is None:
        found = _ADAPTERS[kind] = TypeAdapter(kind)
    return found


def _cut(text: Any, marks: Sequence[Any], once: bool) -> tuple[list[Any], list[int]] | None:
    """``text`` cut at each of ``marks`` (a number's text, followed by ``,``, ``}`` or
    ``]``): the parts and, per cut, which mark; None when a mark occurs twice (or, with
    ``once``, not at all)."""
    textual = isinstance(text, str)
    ends = (",", "}", "]") if textual else (b",", b"}", b"]")
    starts = (":", ",", "[") if textual else (b":", b",", b"[")
    cuts: list[tuple[int, int, int]] = []
    for j, mark in enumerate(marks):
        hits = []
        start = text.find(mark)
        while start >= 0:
            end = start + len(mark)
            before = text[start - 1 : start]
            if text[end : end + 1] in ends and before in starts:
                hits.append(start)
            start = text.find(mark, start + 1)
        if len(hits) > 1 or (once and not hits):
            return None
        cuts += [(h, h + len(mark), j) for h in hits]
    cuts.sort()
    parts, order, at = [], [], 0
    for s0, s1, j in cuts:
        parts.append(text[at:s0])
        order.append(j)
        at = s1
    parts.append(text[at:])
    return parts, order


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
    overrides = list(spec.overrides())
    batchable = getattr(base, "batchable", None)
    many = batchable is not None and batchable(spec.base.spec)
    if not isinstance(parallel.current_host(), parallel.Serial):
        return _run_shipped(spec, base, overrides, many, progress)
    kind = base.name
    total = len(overrides)
    keyer = CaseKeys(kind, spec.base.spec, spec.paths())
    requests: list[BaseModel | None] = []
    keys: list[str | None] = []
    summaries: dict[str, dict[str, Any]] = {}
    # one computation per distinct key (cases that normalise alike share it)
    first: dict[str, int] = {}
    multiplicity: dict[str, int] = {}
    invalid = 0
    for i, o in enumerate(overrides):
        request, problem = spec.validate_case(o)
        requests.append(request)
        if request is None:
            assert problem is not None
            keys.append(None)
            summaries[f"invalid:{i}"] = _invalid(i, problem)
            invalid += 1
            continue
        key = keyer.key(request)
        keys.append(key)
        first.setdefault(key, i)
        multiplicity[key] = multiplicity.get(key, 0) + 1

    memo = parallel.current_memo()
    summaries.update(_memoised(memo, list(first)))
    cached = {k for k in summaries if k in first}
    done = invalid + sum(multiplicity[k] for k in cached)
    if progress is not None:
        progress(done / total)

    todo = [k for k in first if k not in cached]
    chunks = parallel.split(len(todo), max_size=BATCH_CHUNK_CASES if many else CHUNK_CASES)

    def piece(chunk: range) -> Piece:
        idx = [first[todo[j]] for j in chunk]
        return Piece(base, requests=[r for r in (requests[i] for i in idx) if r is not None])

    pieces = [piece(chunk) for chunk in chunks]
    for c, results in _closing(parallel.fan_out(run_cases, pieces)):
        chunk_keys = [todo[j] for j in chunks[c]]
        summaries.update(zip(chunk_keys, results, strict=True))
        _remember(memo, dict(zip(chunk_keys, results, strict=True)))
        done += sum(multiplicity[k] for k in chunk_keys)
        if progress is not None:
            progress(done / total)
    return _table(spec, base, overrides, keys, summaries, cached, computed=len(todo))


def _run_shipped(
    spec: StudySpec,
    base: BaseComputation,
    overrides: list[dict[str, int | float]],
    many: bool,
    progress: Progress | None,
) -> dict[str, Any]:
    """:func:`run_study` on a host that ships its pieces: every case's work in
    :func:`run_piece` (see the module docstring); here only the rows are merged."""
    total = len(overrides)
    memo = parallel.current_memo()
    chunks = plan(total, parallel.current_host().width, many)
    batch = BATCH_CASES if many else None
    pieces = [Chunk(base, spec, c.start, overrides[c.start : c.stop], memo, batch) for c in chunks]
    keys: list[str | None] = [None] * total
    summaries: dict[str, dict[str, Any]] = {}
    served: set[str] = set()
    computed: set[str] = set()
    runs = 0
    done = 0
    for c, rows in _closing(parallel.fan_out(run_piece, pieces)):
        start = chunks[c].start
        for j, (key, summary, hit) in enumerate(
            zip(rows.keys, rows.summaries, rows.cached, strict=True)
        ):
            keys[start + j] = key
            summaries[key if key is not None else f"invalid:{start + j}"] = summary
            if hit:
                served.add(str(key))
        computed.update(rows.computed)
        runs += len(rows.computed)
        done += len(rows.keys)
        if progress is not None:
            progress(done / total)
    return _table(spec, base, overrides, keys, summaries, served - computed, computed=runs)


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
    overrides: Sequence[dict[str, int | float]],
    keys: Sequence[str | None],
    summaries: dict[str, dict[str, Any]],
    cached: set[str],
    computed: int,
) -> dict[str, Any]:
    cols = columns(spec, base)
    paths = spec.paths()
    metrics = [c.name for c in (*base.summary_columns, *TRAILING)]
    rows = []
    for i, (case, key) in enumerate(zip(overrides, keys, strict=True)):
        s = summaries[key if key is not None else f"invalid:{i}"]
        rows.append(
            [
                i,
                key,
                s["status"],
                key in cached,
                *(case.get(p) for p in paths),
                *(s.get(m) for m in metrics),
            ]
        )
    failed = sum(1 for r in rows if r[2] == "failed")
    warnings = [f"{failed} of {len(rows)} cases failed (see error_detail)"] if failed else []
    records = [summaries[k if k is not None else f"invalid:{i}"] for i, k in enumerate(keys)]
    sens = sensitivity(spec, base, records)
    if sens is not None:
        warnings += [
            f"no Sobol' indices of {name}: {c['reason']}"
            for name, c in sens["columns"].items()
            if not c["available"]
        ]
        warnings += out_of_range(sens)
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
            cached=sum(1 for k in keys if k is not None and k in cached),
            computed=computed,
        ),
        statistics=statistics(spec, base, overrides, records),
        sensitivity=sens,
        request=spec.canonical(),  # the design, for the report and the study page
        warnings=warnings,
    )


def out_of_range(sens: dict[str, Any]) -> list[str]:
    """A warning per column of a :class:`~pipeflow.schema.results.StudySensitivity` whose
    estimated indices leave [0, 1], where Sobol' indices lie: the sampling error of a
    Saltelli design with too few base points for them."""
    out = []
    for name, column in sens["columns"].items():
        outside = [
            f"{path}: {index} = {value:.3g}"
            for path, indices in (column["parameters"] or {}).items()
            for index in ("S1", "ST")
            if not 0.0 <= (value := indices[index]) <= 1.0
        ]
        if outside:
            out.append(
                f"Sobol' indices of {name} outside [0, 1] ({', '.join(outside)}): the "
                f"sampling error of a design too small for them (N = {sens['base_points']} "
                "base points); a larger samples.count narrows it (see S1_conf, ST_conf)"
            )
    return out


def numeric_columns(base: BaseComputation) -> list[Column]:
    """The summary columns statistics are taken of: those with a unit (numbers)."""
    return [c for c in base.summary_columns if c.unit != ""]


def _unstable(
    spec: StudySpec, overrides: dict[str, int | float], record: dict[str, Any]
) -> bool | None:
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
    base_spec = spec.base.spec
    assert isinstance(base_spec, StabilitySpec)  # operating_velocity: stability bases only
    top = overrides.get("velocity_range.1", base_spec.velocity_range[1])
    if float(top) < v_op:
        return None  # its range ends before the operating velocity
    return False


#: how a case counts as unstable, by base kind (the result's instability.criterion)
CRITERIA = {
    "simulation": "result_status is diverging, diverged or overflow (a growing branch of the "
    "frozen spectrum at t_end, the deflection past its divergence bound, or overflow)",
    "stability": "stable_at_start is false, or critical_velocity <= operating_velocity",
}


def statistics(
    spec: StudySpec,
    base: BaseComputation,
    overrides: Sequence[dict[str, int | float]],
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
        flags = [_unstable(spec, o, rec) for o, rec in zip(overrides, records, strict=True)]
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


#: a column whose values spread over at most this fraction of their magnitude is constant
#: for the Sobol' indices (its differences are rounding errors) [-]
CONSTANT = 1e-12


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
        elif max(values) - min(values) <= CONSTANT * max(map(abs, values)):
            # a spread of rounding errors gives indices of noise (ST = 2.02 of a peak
            # deflection that differed by 1 ulp over the cases)
            reason = (
                "the column does not vary over the design beyond rounding (its spread is at "
                f"most {CONSTANT:g} of its magnitude)"
            )
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
