"""Solvers of the state equation, chosen by name from :data:`SOLVERS`."""

from pipeflow.solvers import auto, cma, magnus, reference, rk4
from pipeflow.solvers.base import SOLVERS, Options, Problem, Solver, SolverOutput, SolverStats

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
