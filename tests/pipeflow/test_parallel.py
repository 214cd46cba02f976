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


class _Recorder:
    """A serial host of width 2 that remembers the pieces it was given and whether its
    iteration was closed before the end."""

    width = 2

    def __init__(self) -> None:
        self.started: list[int] = []
        self.closed_early = False

    def map(self, fn: Callable[[Any], Any], items: Sequence[Any]) -> Iterator[tuple[int, Any]]:
        try:
            for i, item in enumerate(items):
                self.started.append(i)
                yield i, fn(item)
        except GeneratorExit:
            self.closed_early = len(self.started) < len(items)
            raise


def test_gather_merges_in_index_order_with_weighted_progress() -> None:
    seen: list[float] = []
    with parallel.hosting(_Reversed()):
        out = parallel.gather(_square, [1, 2, 3, 4], seen.append, weights=[1, 1, 1, 5])
    assert out == [1, 4, 9, 16]
    # reversed completion: the heavy last piece first
    assert seen == [5 / 8, 6 / 8, 7 / 8, 1.0]
    assert parallel.gather(_square, []) == []


def test_gather_closes_the_fan_out_when_progress_raises() -> None:
    """A cancel raised by the progress callback leaves the host's iteration (which is how a
    host abandons the pieces not yet finished) and reaches the caller."""

    class Stop(Exception):
        pass

    def stop(fraction: float) -> None:
        raise Stop

    host = _Recorder()
    with parallel.hosting(host):
        try:
            parallel.gather(_square, [1, 2, 3, 4], stop)
        except Stop:
            pass
        else:
            raise AssertionError("the callback's exception was swallowed")
    assert host.started == [0] and host.closed_early


def test_gather_refuses_a_host_that_loses_or_repeats_pieces() -> None:
    class Lossy:
        width = 2

        def map(self, fn: Callable[[Any], Any], items: Sequence[Any]) -> Iterator[tuple[int, Any]]:
            yield 0, fn(items[0])
            if len(items) > 2:  # repeats a piece; else loses the second one
                yield 0, fn(items[0])

    with parallel.hosting(Lossy()):
        for items in ([1, 2], [1, 2, 3]):
            try:
                parallel.gather(_square, items)
            except RuntimeError as exc:
                assert ("twice" if len(items) > 2 else "1 of 2") in str(exc)
            else:
                raise AssertionError("a faulty host went unnoticed")


def test_library_errors_survive_pickling_with_their_parameter() -> None:
    """A piece may run in another process: its PipeflowError comes back pickled, with the
    parameter, the request field and the subclass's own attributes."""
    import pickle

    from pipeflow.errors import BudgetExceeded, InvalidInput, UnstableStep

    for err in (
        InvalidInput("bad", parameter="modes").at("modes"),
        BudgetExceeded("big", parameter="step", smallest_step=1e-4),
        UnstableStep("unstable", "step", 2e-3),
    ):
        back = pickle.loads(pickle.dumps(err))
        assert type(back) is type(err) and str(back) == str(err)
        assert back.__dict__ == err.__dict__


# -- the allowance of metered work -------------------------------------------------------


def test_an_allowance_refuses_the_charge_that_would_pass_it_and_counts_nothing_of_it() -> None:
    import pytest

    from pipeflow.errors import OverAllowance

    parallel.charge(1e9, "without an allowance: nothing is counted or refused")
    with parallel.metered(1.0) as allowance:
        parallel.charge(0.6, "a")
        parallel.charge(0.4, "b")  # exactly at the bound: allowed
        with pytest.raises(OverAllowance) as refused:
            parallel.charge(1e-9, "c")
        assert allowance.spent_s == pytest.approx(1.0)  # the refused charge is not counted
        assert [what for what, _ in allowance.charges] == ["a", "b"]
        assert (refused.value.spent_s, refused.value.asked_s, refused.value.bound_s) == (
            pytest.approx(1.0),
            1e-9,
            1.0,
        )
        assert refused.value.what == "c" and "would pass the allowance" in str(refused.value)
        with parallel.metered(0.0):  # nested: the inner one counts, the outer one is kept
            with pytest.raises(OverAllowance):
                parallel.charge(1e-12, "d")
        assert allowance.spent_s == pytest.approx(1.0)
    parallel.charge(1e9, "the block's allowance is gone with the block")
