"""The default method: ``cma`` where it is exact, ``magnus`` otherwise.

The paper's CMA is exact for constant flow velocity and spin (the state matrices commute:
one eigen-decomposition serves every output time) and is the first Magnus term, an
approximation, when either varies (physics notes, section 2).  ``auto`` runs ``cma`` in the
first case and the tolerance-controlled ``magnus`` in the second, and says which and why
(``method_used``, ``method_reason`` of the result).  It never refuses what one of them can
serve: where cma's quadrature of tabulated loads would exceed its bound it runs magnus
(analytic loads need no quadrature: their particular integral is in closed form).
"""

from __future__ import annotations

from typing import ClassVar

from pipeflow.solvers.base import Problem, Solver, SolverOutput, SolverStats, spectral_radius
from pipeflow.solvers.cma import CMA
from pipeflow.solvers.convolution import MAX_CONVOLUTION_NODES, PIECE_NODES, quadrature_nodes
from pipeflow.solvers.magnus import Magnus


class Auto(Solver):
    name: ClassVar[str] = "auto"
    description: ClassVar[str] = (
        "Default: 'cma' for constant flow and spin (exact there), 'magnus' at "
        "options.tolerance when either varies in time."
    )
    option_names: ClassVar[tuple[str, ...]] = tuple(
        sorted(set(CMA.option_names) | set(Magnus.option_names))
    )
    compared_by_default: ClassVar[bool] = False  # it is one of the others

    def __init__(self, cma: CMA, magnus: Magnus) -> None:
        self.cma = cma  # the instances of :data:`pipeflow.solvers.SOLVERS`
        self.magnus = magnus

    def choose(self, problem: Problem) -> tuple[Solver, str]:
        if problem.loading.is_time_invariant:
            nodes = self._table_nodes(problem)
            if nodes > MAX_CONVOLUTION_NODES:
                return self.magnus, (
                    f"constant flow and spin, but cma's quadrature of the tabulated loads "
                    f"would need {nodes:.3g} nodes (limit {MAX_CONVOLUTION_NODES}): magnus "
                    f"at the tolerance {problem.options.tolerance:g}"
                )
            return self.cma, ("constant flow and spin: cma is exact (one eigen-decomposition)")
        return self.magnus, (
            "time-variant flow or spin: cma would be only the first Magnus term; magnus "
            f"meets the tolerance {problem.options.tolerance:g}"
        )

    @staticmethod
    def _table_nodes(problem: Problem) -> float:
        """Quadrature nodes cma would need for the tabulated loads of ``problem`` (0 when
        every load has a closed form)."""
        loads = problem.loads
        if loads is None or all(loads.closed_form):
            return 0.0
        rate = spectral_radius(problem.model, problem.loading, float(problem.t[-1]), 1)
        return quadrature_nodes(problem.t, rate + loads.rate) * PIECE_NODES

    def applies_impulses(self, problem: Problem) -> bool:
        return self.choose(problem)[0].applies_impulses(problem)

    def _solve_impl(self, problem: Problem, stats: SolverStats) -> SolverOutput:
        solver, _ = self.choose(problem)
        out = solver._solve_impl(problem, stats)
        out.method = solver.name
        return out
