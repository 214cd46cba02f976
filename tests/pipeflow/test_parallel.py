"""The fan-out seam (:mod:`pipeflow.parallel`): default serial host, installed hosts, chunking."""

from __future__ import annotations

from collections.abc import Callable, Iterator, Sequence
from typing import Any

from pipeflow import parallel


def _square(x: int) -> int:
    return x * x


class _Reversed:
    """A host that finishes the pieces in reverse order (completion order is not input order)."""

    width = 3

    def map(self, fn: Callable[[Any], Any], items: Sequence[Any]) -> Iterator[tuple[int, Any]]:
        for i in reversed(range(len(items))):
            yield i, fn(items[i])


def test_default_host_is_serial_and_in_order() -> None:
    assert parallel.current_host() is parallel.SERIAL
    assert list(parallel.fan_out(_square, [1, 2, 3])) == [(0, 1), (1, 4), (2, 9)]
    assert list(parallel.fan_out(_square, [])) == []
    assert parallel.split(10) == [range(10)]


def test_hosting_installs_and_restores() -> None:
    host = _Reversed()
    with parallel.hosting(host):
        assert parallel.current_host() is host
        assert list(parallel.fan_out(_square, [1, 2, 3])) == [(2, 9), (1, 4), (0, 1)]
        # one piece never pays the host's dispatch
        assert list(parallel.fan_out(_square, [5])) == [(0, 25)]
    assert parallel.current_host() is parallel.SERIAL
    assert parallel.current_memo() is None


def test_split_covers_every_index_once() -> None:
    with parallel.hosting(_Reversed()):
        for n in (1, 2, 7, 12, 13, 100, 1001):
            for min_size in (1, 5, 50):
                chunks = parallel.split(n, min_size=min_size)
                flat = [i for c in chunks for i in c]
                assert flat == list(range(n))
                assert len(chunks) <= 3 * 4
                if n >= min_size:
                    assert all(len(c) >= min(min_size, n) or c is chunks[-1] for c in chunks)


def test_split_with_max_size_bounds_every_chunk_on_any_host() -> None:
    """``max_size`` (used by studies to report progress between chunks) cuts the serial
    host's single chunk too, and never leaves a chunk above it on a wide host."""
    assert parallel.split(10, max_size=4) == [range(0, 4), range(4, 8), range(8, 10)]
    assert parallel.split(3, max_size=16) == [range(3)]
    with parallel.hosting(_Reversed()):
        for n in (1, 7, 100, 1001):
            for max_size in (1, 3, 16):
                chunks = parallel.split(n, max_size=max_size)
                assert [i for c in chunks for i in c] == list(range(n))
                assert max(len(c) for c in chunks) <= max_size
