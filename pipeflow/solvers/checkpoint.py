"""Checkpoints of one long solve, so a run killed half-way resumes where it was.

A host that may lose a computation (the service's worker, SIGKILLed or its machine gone)
gives the solve a :class:`Checkpoints`: somewhere to keep one opaque blob
(:meth:`Checkpoints.save`) and to find it again in the next attempt
(:meth:`Checkpoints.load`).  It is passed as :attr:`pipeflow.solvers.base.Problem.checkpoints`,
or installed for every simulation run in a block by :func:`checkpointing` (a context
variable, like :func:`pipeflow.parallel.hosting`): :func:`pipeflow.simulation.simulate`
puts the installed one on its problem.

Which solvers checkpoint, and what:

- ``magnus`` (and ``auto`` where it runs magnus): the step control
  (:func:`pipeflow.solvers.magnus.step_control`) is a deterministic generator of
  propagations; a checkpoint holds the answers of the propagations it completed and the
  current propagation's states up to its last finished window of output intervals.  A
  resume replays the generator with the stored answers and continues the current
  propagation from that window: the same steps, the same exponentials, bit for bit the
  states of an uninterrupted run in one process (on another machine's BLAS: equal to
  rounding).
- ``rk4``: the state at a step boundary (block of steps) and the outputs before it; a
  resume continues the same fixed steps.
- ``cma``: not checkpointed.  Its states are closed forms per output time (one
  eigen-decomposition, or one batched exponential per time of the integrated matrix), with
  no long sequential chain to resume: its cost is bounded by the samples (the output
  budget) and is seconds, not minutes.
- ``reference``: not checkpointed.  scipy's ``solve_ivp`` keeps its own step size and
  error history; restarting it from a stored state would choose other steps, so the
  resumed result would differ from an uninterrupted run at the integrator's tolerance
  instead of rounding, and the reference is what the others are checked against.

A checkpoint is written at most every :attr:`Checkpoints.interval_s` of wall time, the
first one only after that long (runs shorter than the interval never pay for it), and only
when its arrays fit in :attr:`Checkpoints.max_bytes` (larger ones are skipped: the last
one that fitted stays valid).  Each blob carries a fingerprint of the solver and the
problem (output times, initial state, options, state-matrix pieces, coefficients and
forcing at the output times): a blob from another solve of the same computation (the
methods of a comparison, the cases of a study run in one process) is ignored, never
resumed from.
"""

from __future__ import annotations

import contextlib
import hashlib
import io
import json
import logging
import time
from collections.abc import Callable, Iterable, Iterator, Mapping
from contextvars import ContextVar
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np

log = logging.getLogger("pipeflow.checkpoint")

#: the blob's layout version (a blob of another version is ignored)
FORMAT = 1


class Checkpoints(Protocol):
    """Where one computation keeps its latest checkpoint (one blob, overwritten).

    interval_s : wall time between two saves, and before the first [s].
    max_bytes : a checkpoint larger than this is not saved [bytes].
    """

    @property
    def interval_s(self) -> float: ...

    @property
    def max_bytes(self) -> int: ...

    def load(self) -> bytes | None:
        """The latest blob saved for this computation, or None."""
        ...

    def save(self, data: bytes) -> None:
        """Keep ``data`` as the latest blob (a failure to keep it is the host's to report:
        a checkpoint is an optimisation, it must not fail the computation)."""
        ...


_CURRENT: ContextVar[Checkpoints | None] = ContextVar("pipeflow_checkpoints", default=None)


@contextlib.contextmanager
def checkpointing(checkpoints: Checkpoints | None) -> Iterator[None]:
    """Give the simulations run in this block ``checkpoints`` (None: none)."""
    token = _CURRENT.set(checkpoints)
    try:
        yield
    finally:
        _CURRENT.reset(token)


def current_checkpoints() -> Checkpoints | None:
    """The checkpoints installed by :func:`checkpointing`, if any."""
    return _CURRENT.get()


@dataclass
class Snapshot:
    """One checkpoint read back: the solver's ``header`` (JSON) and named ``arrays``."""

    header: dict[str, Any]
    arrays: dict[str, np.ndarray]


def fingerprint(solver: str, options: object, arrays: Iterable[Any]) -> str:
    """SHA-256 of what determines a solve's numbers: ``solver``, its ``options`` (their
    repr) and ``arrays`` (:meth:`pipeflow.solvers.base.Problem.checkpointer` gives the output
    times, initial state, state-matrix pieces and the coefficients and forcing at the output
    times)."""
    h = hashlib.sha256()
    h.update(f"{FORMAT}:{solver}:{options!r}".encode())
    for a in arrays:
        h.update(np.ascontiguousarray(a, dtype=float).tobytes())
    return h.hexdigest()


def encode(header: Mapping[str, Any], arrays: Mapping[str, np.ndarray]) -> bytes:
    """The blob of a checkpoint: an uncompressed ``.npz`` (no pickles) with the header as
    JSON bytes (states do not compress: zlib level 1 kept 97 % of a magnus checkpoint and
    took 68 ms per MB, benchmarks/bench_checkpoint.py)."""
    buf = io.BytesIO()
    head = np.frombuffer(json.dumps(dict(header)).encode(), dtype=np.uint8)
    # (numpy's stub types **kwds as if it could set allow_pickle)
    np.savez(buf, __header__=head, **dict(arrays))  # type: ignore[arg-type]
    return buf.getvalue()


def decode(data: bytes, wanted: Callable[[dict[str, Any]], bool] | None = None) -> Snapshot | None:
    """:func:`encode`'s blob read back (ValueError, KeyError, OSError if it is not one);
    with ``wanted``, None unless ``wanted(header)``, and the arrays are not read then."""
    with np.load(io.BytesIO(data), allow_pickle=False) as npz:
        header = json.loads(npz["__header__"].tobytes().decode())
        if not isinstance(header, dict):
            raise ValueError("checkpoint header is not an object")
        if wanted is not None and not wanted(header):
            return None
        arrays = {name: npz[name] for name in npz.files if name != "__header__"}
    return Snapshot(header, arrays)


class Checkpointer:
    """A solver's side of :class:`Checkpoints` for one solve: reads the blob meant for it
    (:meth:`restore`), and writes new ones when one is due (:meth:`due`, :meth:`save`).
    Without checkpoints every call is a no-op and :meth:`due` is always False."""

    def __init__(
        self, solver: str, checkpoints: Checkpoints | None, identity: Callable[[], str]
    ) -> None:
        """``identity``: the solve's fingerprint (:func:`fingerprint`), computed when a blob
        is read or written."""
        self.checkpoints = checkpoints
        self.solver = solver
        self._identity = identity
        self._fingerprint: str | None = None
        self.last = time.monotonic()  # the solve's start, then the last save [monotonic s]
        self.saves = 0
        self.skipped = 0  # checkpoints over max_bytes, not saved

    @property
    def enabled(self) -> bool:
        return self.checkpoints is not None

    def _print(self) -> str:
        if self._fingerprint is None:
            self._fingerprint = self._identity()
        return self._fingerprint

    def restore(self) -> Snapshot | None:
        """The stored checkpoint of this very solve, or None (none, unreadable, or another
        solve's: ignored, and logged)."""
        if self.checkpoints is None:
            return None
        data = self.checkpoints.load()
        if not data:
            return None
        try:
            snap = decode(data, self._mine)
        except (ValueError, KeyError, OSError) as exc:
            log.warning("checkpoint unreadable, starting from zero: %s", exc)
            return None
        if snap is None:
            log.info("checkpoint of another solve, not resumed from")
            return None
        self.last = time.monotonic()
        return snap

    def _mine(self, header: dict[str, Any]) -> bool:
        """Whether a blob with ``header`` was written by this very solve (the arrays of
        another solve's blob are not read)."""
        return header.get("format") == FORMAT and header.get("fingerprint") == self._print()

    def due(self) -> bool:
        """Whether a checkpoint should be written now (interval elapsed since the start or
        the last save)."""
        cp = self.checkpoints
        return cp is not None and time.monotonic() - self.last >= cp.interval_s

    def save(self, header: Mapping[str, Any], arrays: Mapping[str, np.ndarray]) -> bool:
        """Write a checkpoint of ``arrays`` unless they exceed ``max_bytes``; True if
        written.  The interval restarts either way (an oversize state is not re-measured
        at every window)."""
        cp = self.checkpoints
        if cp is None:
            return False
        self.last = time.monotonic()
        size = sum(int(a.nbytes) for a in arrays.values())
        if size > cp.max_bytes:
            self.skipped += 1
            if self.skipped == 1:
                log.info("checkpoint of %d bytes over max_bytes %d: skipped", size, cp.max_bytes)
            return False
        head = {"format": FORMAT, "solver": self.solver, "fingerprint": self._print(), **header}
        cp.save(encode(head, arrays))
        self.saves += 1
        self.last = time.monotonic()
        return True
