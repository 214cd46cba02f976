"""Solvers of the state equation, chosen by name from :data:`SOLVERS`."""

from pipeflow.solvers import cma, magnus, reference, rk4
from pipeflow.solvers.base import SOLVERS, Options, Problem, Solver, SolverOutput

__all__ = [
    "SOLVERS",
    "Options",
    "Problem",
    "Solver",
    "SolverOutput",
    "cma",
    "magnus",
    "reference",
    "rk4",
]
