"""Checkpoints of a long solve (:mod:`pipeflow.solvers.checkpoint`): a solve interrupted
after a checkpoint resumes from it and ends with the uninterrupted run's result.

Interruptions are made by the checkpoints themselves: :class:`Memory` raises
:class:`Killed` from its ``save`` once it has kept the blob (as if the process died right
after the write), so the solve stops half-way with a blob stored, and a fresh solve on the
same blob resumes.  In one process the resumed states are expected bit for bit equal to
the uninterrupted run's (same steps, same exponentials, same order of operations:
``np.array_equal``); the work done after the resume is counted (matrices exponentiated,
RK4 steps), never timed.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from dataclasses import replace

import numpy as np
import pytest

from pipeflow.profiles import Harmonic, polynomial
from pipeflow.simulation import Result, Simulation, simulate
from pipeflow.solvers import Options, magnus, rk4
from pipeflow.solvers.checkpoint import checkpointing, decode, encode
from tests.pipeflow.cases import paper_sim


class Killed(Exception):
    """The process 'died' right after a checkpoint was written."""


class Memory:
    """Checkpoints in memory: every window is due (``interval_s`` 0), and the solve is
    interrupted after the ``kill_at``-th save (None: never)."""

    def __init__(
        self, kill_at: int | None = None, interval_s: float = 0.0, max_bytes: int = 1 << 30
    ) -> None:
        self.blob: bytes | None = None
        self.saves = 0
        self.kill_at = kill_at
        self.interval_s = interval_s
        self.max_bytes = max_bytes

    def load(self) -> bytes | None:
        return self.blob

    def save(self, data: bytes) -> None:
        self.blob = data
        self.saves += 1
        if self.kill_at is not None and self.saves >= self.kill_at:
            raise Killed


def run(sim: Simulation, cp: Memory | None) -> Result:
    with checkpointing(cp):
        return simulate(sim)


def interrupted(sim: Simulation, cp: Memory) -> None:
    with pytest.raises(Killed):
        run(sim, cp)
    assert cp.blob is not None


@pytest.fixture
def exponentials(monkeypatch: pytest.MonkeyPatch) -> Iterator[Callable[[], int]]:
    """Counts the matrices magnus exponentiates (its one call of expm_stack)."""
    count = [0]
    real = magnus.generator.expm_stack

    def counted(a: np.ndarray) -> np.ndarray:
        count[0] += a.shape[0]
        return real(a)

    monkeypatch.setattr(magnus.generator, "expm_stack", counted)

    def read_and_reset() -> int:
        n, count[0] = count[0], 0
        return n

    yield read_and_reset


#: pulsating flow on 4 modes at a tight tolerance: two attempts (the first run, its checks
#: with twice and four times the step, a refinement) and four windows of output intervals
#: per full propagation, so checkpoints land in every propagation
PULSATING = paper_sim(
    Harmonic(2.0, 1.0, 50.0), "magnus", samples=1001, options=Options(tolerance=1e-9)
)


def test_magnus_resumes_where_it_was_interrupted_twice(exponentials: Callable[[], int]) -> None:
    """Killed after the 3rd checkpoint (in the first run), resumed and killed again after
    7 more (in a later propagation), resumed to the end: the same states as the
    uninterrupted run (bit for bit, one process), the same counters, and the last resume
    computes only the exponentials the checkpoint did not carry over."""
    whole = run(PULSATING, None)
    total = exponentials()
    assert whole.diagnostics["attempts"] == 2
    assert total == whole.diagnostics["matrix_exponentials"]

    cp = Memory(kill_at=3)
    interrupted(PULSATING, cp)
    cp.kill_at = cp.saves + 7
    interrupted(PULSATING, cp)
    exponentials()
    cp.kill_at = None
    resumed = run(PULSATING, cp)
    diag = resumed.diagnostics
    assert np.array_equal(resumed.d, whole.d) and np.array_equal(resumed.ddot, whole.ddot)
    for name in ("steps", "attempts", "matrix_exponentials", "estimated_relative_error"):
        assert diag[name] == whole.diagnostics[name], name
    assert diag["resumed_run"] > 1  # the second interruption was past the first propagation
    assert 0.0 < diag["resumed_from_time"] < PULSATING.t_end
    carried = diag["resumed_exponentials"]
    assert 0 < carried < total
    assert exponentials() == total - carried  # not one exponential more than the remainder
    assert "resumed_from_time" not in whole.diagnostics


@pytest.mark.parametrize(
    "sim",
    [
        # auto runs magnus for time-variant flow: the same checkpoints
        replace(PULSATING, method="auto"),
        # a spin-up (forced: the state augmented by the forcing's scale) and v = 0.4 t
        paper_sim(
            polynomial(0, 0.4),
            "magnus",
            samples=801,
            spin=polynomial(100.0, 200.0),
            options=Options(tolerance=1e-9),
        ),
    ],
    ids=["auto", "spin-up"],
)
def test_magnus_resume_other_problems(sim: Simulation) -> None:
    whole = run(sim, None)
    cp = Memory(kill_at=3)
    interrupted(sim, cp)
    cp.kill_at = None
    resumed = run(sim, cp)
    assert np.array_equal(resumed.d, whole.d) and np.array_equal(resumed.ddot, whole.ddot)
    assert resumed.diagnostics["resumed_exponentials"] > 0
    assert resumed.diagnostics["matrix_exponentials"] == whole.diagnostics["matrix_exponentials"]


def test_magnus_checkpoints_only_after_the_interval() -> None:
    """A run shorter than the interval never saves (short runs do not pay); with an
    interval of 0 every window of 256 output intervals saves."""
    never = Memory(interval_s=3600.0)
    run(PULSATING, never)
    assert never.saves == 0
    every = Memory()
    run(PULSATING, every)
    assert every.saves >= 8


def test_magnus_checkpoint_over_max_bytes_is_skipped() -> None:
    cp = Memory(max_bytes=1000)
    result = run(PULSATING, cp)
    assert cp.saves == 0 and cp.blob is None
    assert "resumed_from_time" not in result.diagnostics


def test_checkpoint_of_another_solve_is_ignored() -> None:
    """A blob written by another problem (other tolerance: other steps) is not resumed from:
    the result is the fresh run's."""
    cp = Memory(kill_at=2)
    interrupted(PULSATING, cp)
    other = replace(PULSATING, options=Options(tolerance=1e-8))
    cp.kill_at = None
    result = run(other, cp)
    assert "resumed_from_time" not in result.diagnostics
    assert np.array_equal(result.d, run(other, None).d)


def test_unreadable_checkpoint_starts_from_zero() -> None:
    cp = Memory()
    cp.blob = b"not a checkpoint"
    cp.kill_at = None
    result = run(PULSATING, cp)
    assert "resumed_from_time" not in result.diagnostics


def test_blob_round_trip() -> None:
    a = np.arange(6.0).reshape(2, 3)
    blob = encode({"k": 3, "name": "x"}, {"a": a})
    snap = decode(blob)
    assert snap is not None
    assert snap.header == {"k": 3, "name": "x"} and np.array_equal(snap.arrays["a"], a)
    assert decode(blob, lambda header: header["k"] == 4) is None


@pytest.mark.parametrize(("kill_at", "at_output"), [(1, False), (5, True), (7, False)])
def test_rk4_resumes_at_a_step_boundary(
    kill_at: int, at_output: bool, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Blocks of 16 steps (the block size shrunk for the test), three output intervals of
    66 steps: saves after 16, 32, 48, 64 steps of an interval and at its end; interrupted
    inside the first interval (1st save), at the first output time (5th) or inside the
    second (7th); the resumed run takes the same steps and ends bit for bit where the
    uninterrupted one does, and says how many steps it carried over."""
    monkeypatch.setattr(rk4, "_BLOCK_ENTRIES", 3 * 8**2 * 16)  # 4 modes: a state of 8
    sim = paper_sim(polynomial(0, 0.4), "rk4", samples=4, t_end=0.05)
    whole = run(sim, None)
    steps = whole.diagnostics["steps"]
    assert steps > 3 * 16 * 2  # several blocks per interval
    cp = Memory(kill_at=kill_at)
    interrupted(sim, cp)
    cp.kill_at = None
    resumed = run(sim, cp)
    assert np.array_equal(resumed.d, whole.d) and np.array_equal(resumed.ddot, whole.ddot)
    assert resumed.diagnostics["steps"] == steps
    carried = resumed.diagnostics["resumed_steps"]
    assert 0 < carried < steps
    assert 0.0 < resumed.diagnostics["resumed_from_time"] < sim.t_end
    per_interval = steps // 3
    assert steps == 3 * per_interval == 3 * 66
    assert (carried % per_interval == 0) == at_output
    assert carried % per_interval % 16 == 0  # a block boundary


def test_rk4_constant_coefficients_resume() -> None:
    """The constant-coefficient loop (one state matrix) checkpoints and resumes too."""
    sim = paper_sim(polynomial(2.0), "rk4", samples=6, t_end=0.02)
    whole = run(sim, None)
    cp = Memory(kill_at=2)
    interrupted(sim, cp)
    cp.kill_at = None
    resumed = run(sim, cp)
    assert np.array_equal(resumed.d, whole.d)
    assert resumed.diagnostics["resumed_steps"] > 0
