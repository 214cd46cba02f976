"""How a shipped study is cut into pieces (pipeflow.computations.study_runner.plan) and that the
cut does not change a row.

The plan is checked against its definition (every case exactly once, contiguous, sizes
within the bounds); the rows of a shipped study against the serial host's run of the same
study in this process, cell for cell: keys, statuses and counts exactly, numbers to 1e-12
relative (the same numerics on stacks of other sizes: LAPACK's per-matrix eigenproblems do
not depend on their batch-mates, a blocked matrix product may round in the last bits).
"""

from __future__ import annotations

import math
import pickle
from collections.abc import Sequence
from typing import Any

import pytest

from pipeflow import parallel
from pipeflow.computations import study_runner as sr
from pipeflow.computations.registry import COMPUTATIONS
from pipeflow.schema.simulation import PAPER_EXAMPLE, SimulationSpec
from pipeflow.schema.study import StudySpec

#: constant flow and spin (batchable: one stacked computation per batch), 2 modes, 11
#: samples: ~0.1 ms a case
LTI = {"pipe": PAPER_EXAMPLE["pipe"], "modes": 2, "time": {"t_end": 0.05, "samples": 11}}


@pytest.mark.parametrize("width", [1, 2, 3, 8])
@pytest.mark.parametrize("many", [True, False])
@pytest.mark.parametrize("total", [0, 1, 7, 255, 1024, 1025, 1100, 4097, 10_000])
def test_the_plan_cuts_every_case_once_in_bounded_contiguous_pieces(
    total: int, width: int, many: bool
) -> None:
    class Wide:
        def __init__(self) -> None:
            self.width = width

        def map(self, fn: Any, items: Sequence[Any]) -> Any:
            raise AssertionError("not used")

    with parallel.hosting(host=Wide()):
        pieces = sr.plan(total, width, many)
    assert [i for r in pieces for i in r] == list(range(total))
    assert all(len(r) > 0 for r in pieces)
    biggest = sr.BATCH_PIECE_CASES if many else sr.CHUNK_CASES
    assert all(len(r) <= max(biggest, 2 * sr.BATCH_CASES) for r in pieces)
    if many and total > 4 * width * sr.BATCH_CASES:
        # guided: sizes never grow; none under half a batch, and only the last two under
        # a batch (they share a remainder under two batches)
        sizes = [len(r) for r in pieces]
        assert sizes == sorted(sizes, reverse=True)
        assert min(sizes) >= sr.BATCH_CASES // 2
        assert all(n >= sr.BATCH_CASES for n in sizes[:-2])


def test_the_10000_case_study_is_17_pieces_ending_small_on_two_workers() -> None:
    """The defect: 40 pieces of 250 cases, each dispatch leaving a worker idle ~5-15 ms
    on the 2-core machine.  Now few large pieces first and small ones at the end (the
    last three of 128 cases, ~30 ms: the workers end close together)."""
    pieces = sr.plan(10_000, 2, True)
    sizes = [len(r) for r in pieces]
    assert len(pieces) == 17
    assert sizes[0] == sr.BATCH_PIECE_CASES and sum(sizes) == 10_000
    assert sizes[-3:] == [sr.BATCH_CASES] * 3


def test_a_piece_summarised_in_batches_gives_the_whole_batchs_summaries() -> None:
    """``Piece.batch``: ``summarize_many`` on runs of 128 cases, not all 300 at once: the
    same summaries (1e-12 relative, see the module docstring)."""
    base = COMPUTATIONS["simulation"]
    requests = [
        SimulationSpec.model_validate(
            {
                **LTI,
                "flow": {"velocity": {"kind": "constant", "value": 0.05 * i}},
                "rotation": {"omega0": {"kind": "constant", "value": 0.5 * i}},
            }
        )
        for i in range(300)
    ]
    whole = sr.run_cases(sr.Piece(base, requests=requests))
    batched = sr.run_cases(sr.Piece(base, requests=requests, batch=sr.BATCH_CASES))
    _same_summaries(batched, whole)


class Shipping:
    """Width 2; every piece and its result through pickle, run here."""

    width = 2

    def __init__(self) -> None:
        self.sizes: list[int] = []
        self.batches: list[int | None] = []

    def map(self, fn: Any, items: Sequence[Any]) -> Any:
        for i, item in enumerate(items):
            shipped = pickle.loads(pickle.dumps(item))
            self.sizes.append(len(shipped.overrides))
            self.batches.append(shipped.batch)
            yield i, pickle.loads(pickle.dumps(fn(shipped)))


def test_a_large_shipped_lti_study_gives_the_serial_hosts_table() -> None:
    """1,600 batchable cases on a width-2 shipping host: guided pieces (none over
    :data:`BATCH_PIECE_CASES`, summarised in batches of :data:`BATCH_CASES`), the serial
    host's rows, counts and statistics."""
    spec = StudySpec.model_validate(
        {
            "base": {"kind": "simulation", "spec": LTI},
            "grid": {
                "flow.velocity.value": [0.5 * i for i in range(40)],
                "rotation.omega0.value": [5.0 * i for i in range(40)],
            },
        }
    )
    serial = COMPUTATIONS["study"].execute(spec)
    host = Shipping()
    with parallel.hosting(host=host):
        shipped = COMPUTATIONS["study"].execute(spec)
    assert host.sizes == [len(r) for r in sr.plan(1600, 2, True)] and len(host.sizes) == 8
    assert set(host.batches) == {sr.BATCH_CASES}
    assert shipped["counts"] == serial["counts"]
    assert len(shipped["rows"]) == len(serial["rows"]) == 1600
    for got, want in zip(shipped["rows"], serial["rows"], strict=True):
        assert len(got) == len(want)
        for a, b in zip(got, want, strict=True):
            if isinstance(b, float):
                assert a == pytest.approx(b, rel=1e-12, abs=0.0)
            else:
                assert a == b
    assert shipped["statistics"].keys() == serial["statistics"].keys()


def _same_summaries(got: list[dict[str, Any]], want: list[dict[str, Any]]) -> None:
    assert len(got) == len(want)
    for a, b in zip(got, want, strict=True):
        assert a.keys() == b.keys()
        for k, v in b.items():
            if isinstance(v, float) and math.isfinite(v):
                assert a[k] == pytest.approx(v, rel=1e-12, abs=0.0), k
            else:
                assert a[k] == v, k
