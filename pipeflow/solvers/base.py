"""What every solver takes and returns, and the registry they are chosen from."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, ClassVar, Protocol

import numpy as np
from numpy.typing import NDArray

from pipeflow.errors import InvalidInput
from pipeflow.model import Loading, PipeModel

FloatArray = NDArray[np.float64]
ProgressCallback = Callable[[float], None]

#: hard ceilings that no option may lift (they bound what one request can cost)
MAX_STEPS_CEILING = 20_000_000
MAX_EVALUATIONS_CEILING = 50_000_000


@dataclass(frozen=True)
class Options:
    """Method options; each solver reads the ones named in its ``option_names``.

    step : time step [s] for fixed-step methods (``rk4``, ``magnus``); None = automatic.
    max_steps : refuse a run needing more steps than this [-].
    rtol, atol : tolerances of the ``reference`` integrator (atol in the units of the
        balanced state, i.e. metres of modal amplitude).
    integrator : ``solve_ivp`` method for ``reference`` (DOP853, RK45, Radau, BDF, LSODA).
    tolerance : relative accuracy target of ``magnus`` [-].
    condition_limit : eigenvector-matrix 1-norm condition number above which ``cma`` falls back to
        a Pade matrix exponential for that time [-].
    """

    step: float | None = None
    max_steps: int = 2_000_000
    rtol: float = 1e-12
    atol: float = 1e-15
    integrator: str = "DOP853"
    tolerance: float = 1e-8
    condition_limit: float = 1e8


def given_step(options: Options) -> float | None:
    """``options.step`` [s] if given, after checking it is finite and > 0 (InvalidInput)."""
    step = options.step
    if step is not None and not (math.isfinite(step) and step > 0):
        raise InvalidInput("options.step must be finite and > 0 s", field="options.step")
    return step


@dataclass(frozen=True)
class Problem:
    """One linear initial-value problem z' = S(t) z + f(t) in balanced coordinates."""

    model: PipeModel
    loading: Loading
    z0: FloatArray
    t: FloatArray  # output times [s], t[0] == 0, strictly increasing
    options: Options = field(default_factory=Options)
    progress: ProgressCallback | None = None

    def report(self, fraction: float) -> None:
        if self.progress is not None:
            self.progress(min(max(fraction, 0.0), 1.0))


@dataclass
class SolverOutput:
    """Balanced states at the output times plus what the solver wants to say about them."""

    z: FloatArray  # (len(t), 2n)
    diagnostics: dict[str, Any] = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)


class Solver(Protocol):
    name: ClassVar[str]
    description: ClassVar[str]
    option_names: ClassVar[tuple[str, ...]]

    def solve(self, problem: Problem) -> SolverOutput: ...


SOLVERS: dict[str, Solver] = {}


def register(solver: Solver) -> Solver:
    SOLVERS[solver.name] = solver
    return solver


def frozen_eigenvalues(
    model: PipeModel, loading: Loading, t_end: float, samples: int = 65
) -> NDArray[np.complex128]:
    """Eigenvalues of S(t) [1/s] at ``samples`` times over [0, t_end] (one if invariant)."""
    ts = np.linspace(0.0, t_end, 1 if loading.is_time_invariant else samples)
    S = model.state_matrix(loading.coefficients(ts))
    return np.asarray(np.linalg.eigvals(S), dtype=complex)


def spectral_radius(model: PipeModel, loading: Loading, t_end: float, samples: int = 33) -> float:
    """Largest |eigenvalue| [1/s] of the frozen S(t), sampled at ``samples`` times in [0, t_end]."""
    return float(np.max(np.abs(frozen_eigenvalues(model, loading, t_end, samples))))
