"""Fan-out of the independent pieces of one computation (chunks of a map, cases of a study).

Library code that can split its work calls :func:`fan_out` with a module-level function
and the pieces, and gets ``(index, result)`` pairs back in completion order; it reports
progress and merges as they arrive (:func:`gather` does both: results in index order,
progress after each piece).  Where the pieces run is the host's choice, installed
for the duration of a computation with :func:`hosting` (a context variable, like joblib's
``parallel_backend``): by default they run here, one after another, so a library call
without a host behaves exactly as a serial loop.  The service's Dask task installs a host
that submits the pieces to every worker of the cluster.

A computation whose pieces are worth keeping on their own (the cases of a study) may also
consult a :class:`Memo`: results of pieces already computed, by their key, looked up and
stored in batches by the computation (the host's memo, e.g. the service's result store).

Work whose cost is known only as it is planned (a solver's step control) can be metered:
the solver calls :func:`charge` with its estimate before doing each part, and a caller that
installed an allowance with :func:`metered` gets :class:`~pipeflow.errors.OverAllowance`
raised before the part that would pass it (the service runs small computations in a thread
of its API process this way and hands one that would pass its bound to a worker).  Without
an allowance :func:`charge` does nothing.

Pieces and their function must be picklable (module-level functions, plain data, numpy
arrays, pydantic models): a host may run them in other processes or on other machines.
"""

from __future__ import annotations

import contextlib
import math
from collections.abc import Callable, Iterator, Mapping, Sequence
from contextvars import ContextVar
from dataclasses import dataclass, field
from typing import Any, Protocol, TypeVar

from pipeflow.errors import OverAllowance

T = TypeVar("T")
R = TypeVar("R")


class Host(Protocol):
    """Where the pieces of a fan-out run."""

    @property
    def width(self) -> int:
        """How many pieces run at once (e.g. the cluster's worker threads); >= 1."""
        ...

    def map(self, fn: Callable[[Any], Any], items: Sequence[Any]) -> Iterator[tuple[int, Any]]:
        """``(i, fn(items[i]))`` for every i, in any order; an exception from a piece leaves
        the iteration (closing the iterator abandons the pieces not yet finished)."""
        ...


class Memo(Protocol):
    """Results of pieces computed before, by key (JSON-ready dicts)."""

    def get_many(self, keys: Sequence[str]) -> dict[str, dict[str, Any]]:
        """The stored results among ``keys`` (missing keys are absent)."""
        ...

    def put_many(self, results: Mapping[str, dict[str, Any]]) -> None:
        """Store ``results`` (key -> result); failures to store are the memo's to report."""
        ...


@dataclass(frozen=True)
class Serial:
    """The default host: every piece here, in order."""

    width: int = 1

    def map(self, fn: Callable[[Any], Any], items: Sequence[Any]) -> Iterator[tuple[int, Any]]:
        for i, item in enumerate(items):
            yield i, fn(item)


SERIAL = Serial()
_HOST: ContextVar[Host | None] = ContextVar("pipeflow_host", default=None)
_MEMO: ContextVar[Memo | None] = ContextVar("pipeflow_memo", default=None)


@contextlib.contextmanager
def hosting(host: Host | None = None, memo: Memo | None = None) -> Iterator[None]:
    """Run the fan-outs (and memo look-ups) of the computations in this block on ``host``
    (and ``memo``); ``None`` keeps the default (serial, no memo)."""
    tokens = (_HOST.set(host), _MEMO.set(memo))
    try:
        yield
    finally:
        _HOST.reset(tokens[0])
        _MEMO.reset(tokens[1])


def current_host() -> Host:
    """The host installed by :func:`hosting`, else :data:`SERIAL`."""
    return _HOST.get() or SERIAL


def current_memo() -> Memo | None:
    """The memo installed by :func:`hosting`, if any."""
    return _MEMO.get()


@dataclass
class Allowance:
    """A bound on the metered work of the computations in a :func:`metered` block and the
    work they charged so far, both estimated on one core [s]."""

    bound_s: float
    spent_s: float = 0.0
    #: the parts charged, in order: (what, estimated seconds) (diagnostics, tests)
    charges: list[tuple[str, float]] = field(default_factory=list)

    def charge(self, seconds: float, what: str) -> None:
        """Count ``seconds`` of work about to be done; raises
        :class:`~pipeflow.errors.OverAllowance` (counting nothing) if it would pass
        :attr:`bound_s`."""
        if self.spent_s + seconds > self.bound_s:
            raise OverAllowance(self.spent_s, seconds, self.bound_s, what)
        self.spent_s += seconds
        self.charges.append((what, seconds))


_ALLOWANCE: ContextVar[Allowance | None] = ContextVar("pipeflow_allowance", default=None)


@contextlib.contextmanager
def metered(bound_s: float) -> Iterator[Allowance]:
    """Meter the work of the computations in this block against ``bound_s`` [s, estimated
    on one core]: a :func:`charge` that would pass it raises
    :class:`~pipeflow.errors.OverAllowance` before that work starts."""
    allowance = Allowance(float(bound_s))
    token = _ALLOWANCE.set(allowance)
    try:
        yield allowance
    finally:
        _ALLOWANCE.reset(token)


def charge(seconds: float, what: str) -> None:
    """Work of ``seconds`` [s, estimated on one core] is about to be done (``what`` names
    it): counted against the allowance of the enclosing :func:`metered` block, which raises
    :class:`~pipeflow.errors.OverAllowance` if it would pass it; nothing without one."""
    allowance = _ALLOWANCE.get()
    if allowance is not None:
        allowance.charge(seconds, what)


def fan_out(fn: Callable[[T], R], items: Sequence[T]) -> Iterator[tuple[int, R]]:
    """``(i, fn(items[i]))`` for every piece, in completion order, on the current host."""
    items = list(items)
    if not items:
        return iter(())
    host = current_host()
    if len(items) == 1:
        host = SERIAL  # nothing to spread: no dispatch cost
    return host.map(fn, items)


def split(
    n: int, pieces_per_worker: int = 4, min_size: int = 1, max_size: int | None = None
) -> list[range]:
    """``range(n)`` cut into contiguous chunks for the current host: about
    ``pieces_per_worker`` chunks per unit of width (so a slow piece does not leave the
    other workers idle), none smaller than ``min_size``; one chunk on the serial host.
    With ``max_size``, none larger than that either (more chunks, on any host: e.g. to
    report progress between them); ``max_size`` wins over ``min_size``."""
    if n <= 0:
        return []
    width = max(1, int(current_host().width))
    count = 1
    if width > 1:
        count = max(1, min(n // max(1, min_size), width * pieces_per_worker))
    if max_size is not None:
        count = max(count, math.ceil(n / max(1, max_size)))
    size = math.ceil(n / count)
    return [range(i, min(n, i + size)) for i in range(0, n, size)]


def gather(
    fn: Callable[[T], R],
    items: Sequence[T],
    progress: Callable[[float], None] | None = None,
    weights: Sequence[float] | None = None,
) -> list[R]:
    """``[fn(item) for item in items]`` computed by :func:`fan_out` and merged in index
    order, whatever order the pieces finish in.

    After each piece ``progress`` gets the fraction of the work done (by ``weights``, one
    per item, default equal); it may raise (``Cancelled``): the fan-out is then closed,
    which abandons the pieces not yet finished, and the exception propagates.
    """
    items = list(items)
    w = [1.0] * len(items) if weights is None else [float(x) for x in weights]
    if len(w) != len(items):
        raise ValueError("one weight per item")
    total = sum(w) or 1.0
    out: list[Any] = [None] * len(items)
    seen = [False] * len(items)
    done = 0.0
    pieces = fan_out(fn, items)
    try:
        for i, result in pieces:
            if seen[i]:
                raise RuntimeError(f"the host returned piece {i} twice")
            out[i], seen[i] = result, True
            done += w[i]
            if progress is not None:
                progress(min(1.0, done / total))
    finally:
        close = getattr(pieces, "close", None)
        if close is not None:
            close()
    if not all(seen):
        raise RuntimeError(f"the host returned {sum(seen)} of {len(items)} pieces")
    return out
