"""The checkpoints of one Magnus solve (:mod:`pipeflow.solvers.checkpoint`)."""

from __future__ import annotations

from typing import Any

from pipeflow._types import FloatArray
from pipeflow.solvers.base import Problem


class MagnusCheckpoints:
    """The checkpoints of one :class:`Magnus` solve (:mod:`pipeflow.solvers.checkpoint`):
    the answers of the step control's finished propagations (``answers``: replayed into
    the generator on a resume) and the current propagation's augmented states up to its
    last finished window of output intervals (:func:`propagate` continues from there)."""

    def __init__(self, problem: Problem) -> None:
        self.cp = problem.checkpointer("magnus")
        self.answers: list[tuple[FloatArray, int]] = []
        self._start: tuple[int, FloatArray, int] | None = None
        self.resumed: dict[str, Any] = {}
        snap = self.cp.restore()
        if snap is not None:
            used = snap.header["exponentials"]
            self.answers = [(snap.arrays[f"answer{i}"], int(n)) for i, n in enumerate(used)]
            partial = snap.header["partial"]
            self._start = (int(partial["k"]), snap.arrays["partial"], int(partial["exponentials"]))

    def resume(self, t: FloatArray, Zaug: FloatArray) -> tuple[int, int]:
        """Where the current propagation (output times ``t`` [s]) starts: ``(k, exps)``, the
        output index reached and the exponentials used to get there, with ``Zaug[: k + 1]``
        filled in; ``(0, 0)`` unless it is the one the checkpoint stopped in."""
        start, self._start = self._start, None
        if start is None:
            return 0, 0
        k, prefix, exps = start
        if prefix.shape != (k + 1, Zaug.shape[1]) or k >= t.size:
            return 0, 0  # not the propagation it was written in (cannot happen: logged)
        Zaug[: k + 1] = prefix
        self.resumed = {
            "resumed_from_time": float(t[k]),
            "resumed_run": len(self.answers) + 1,
            "resumed_exponentials": exps + sum(n for _, n in self.answers),
        }
        return k, exps

    def answered(self, answer: tuple[FloatArray, int]) -> None:
        """The current propagation finished with ``answer`` (kept for the next checkpoints)."""
        if self.cp.enabled:
            self.answers.append(answer)

    def due(self) -> bool:
        return self.cp.due()

    def save(self, t: FloatArray, k: int, Zaug: FloatArray, exps: int) -> None:
        """A checkpoint in the current propagation after output ``k`` (``exps`` used)."""
        arrays = {f"answer{i}": Z for i, (Z, _) in enumerate(self.answers)}
        arrays["partial"] = Zaug[: k + 1]
        header = {
            "exponentials": [n for _, n in self.answers],
            "partial": {"k": k, "exponentials": exps, "time": float(t[k])},
        }
        self.cp.save(header, arrays)

    def diagnostics(self) -> dict[str, Any]:
        """What the result says of a resume (nothing when it did not resume): the output
        time [s] the resumed propagation continued from, its number among the step
        control's propagations (1: the first attempt, then its checks and refinements),
        and the exponentials carried over from the checkpoint instead of recomputed."""
        return dict(self.resumed)
