"""Fan-out of the independent pieces of one computation (chunks of a map, cases of a study).

Library code that can split its work calls :func:`fan_out` with a module-level function
and the pieces, and gets ``(index, result)`` pairs back in completion order; it reports
progress and merges as they arrive.  Where the pieces run is the host's choice, installed
for the duration of a computation with :func:`hosting` (a context variable, like joblib's
``parallel_backend``): by default they run here, one after another, so a library call
without a host behaves exactly as a serial loop.  The service's Dask task installs a host
that submits the pieces to every worker of the cluster.

A computation whose pieces are worth keeping on their own (the cases of a study) may also
consult a :class:`Memo`: results of pieces already computed, by their key, looked up and
stored in batches by the computation (the host's memo, e.g. the service's result store).

Pieces and their function must be picklable (module-level functions, plain data, numpy
arrays, pydantic models): a host may run them in other processes or on other machines.
"""

from __future__ import annotations

import contextlib
import math
from collections.abc import Callable, Iterator, Mapping, Sequence
from contextvars import ContextVar
from dataclasses import dataclass
from typing import Any, Protocol, TypeVar

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
