"""Solvers of the state equation, chosen by name from :data:`SOLVERS`."""

from pipeflow.solvers import auto, cma, magnus, reference, rk4
from pipeflow.solvers.base import Options, Problem, Solver, SolverOutput, SolverStats

_cma, _magnus = cma.CMA(), magnus.Magnus()
#: every solver by name; the order is that of the API's method description and of
#: :func:`pipeflow.compare.compare`'s default methods (the order the registrations used to
#: happen in: magnus first, imported through the Floquet analysis)
SOLVERS: dict[str, Solver] = {
    "magnus": _magnus,
    "cma": _cma,
    "auto": auto.Auto(_cma, _magnus),
    "reference": reference.Reference(),
    "rk4": rk4.RK4(),
}

__all__ = [
    "SOLVERS",
    "Options",
    "Problem",
    "Solver",
    "SolverOutput",
    "SolverStats",
    "auto",
    "cma",
    "magnus",
    "reference",
    "rk4",
]
