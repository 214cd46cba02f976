"""The Magnus solver (:class:`Magnus`): the step control driven with single propagations,
resumable from its checkpoints (the method: :mod:`pipeflow.solvers.magnus`)."""

from __future__ import annotations

from typing import ClassVar

from pipeflow.solvers.base import Problem, Solver, SolverOutput, SolverStats
from pipeflow.solvers.magnus import stepper
from pipeflow.solvers.magnus.checkpoints import MagnusCheckpoints
from pipeflow.solvers.magnus.control import step_control


class Magnus(Solver):
    name: ClassVar[str] = "magnus"
    description: ClassVar[str] = (
        "Magnus integrator of order 4 or 6 (2 or 3 Gauss points, chosen per interval) on "
        "steps controlled for options.tolerance: accurate for time-variant flow and spin; "
        "exact for constant."
    )
    option_names: ClassVar[tuple[str, ...]] = ("step", "max_steps", "tolerance")
    estimates_own_error: ClassVar[bool] = True
    error_advice: ClassVar[str] = "use a smaller tolerance or step"

    def _solve_impl(self, problem: Problem, stats: SolverStats) -> SolverOutput:
        """Drive :func:`step_control` with :func:`propagate` (the stacked solver of
        :mod:`pipeflow.solvers.magnus.stack` drives the same control over many problems)."""
        control = step_control(problem, stats)
        resume = MagnusCheckpoints(problem)
        run = next(control)
        try:
            # a resume replays the deterministic control with the stored answers
            for answer in resume.answers:
                run = control.send(answer)
            while True:
                answer = stepper.propagate(problem, run.gen, run.t, run.plan, resume)
                resume.answered(answer)
                run = control.send(answer)
        except StopIteration as stop:
            out: SolverOutput = stop.value
            out.diagnostics.update(resume.diagnostics())
            return out
