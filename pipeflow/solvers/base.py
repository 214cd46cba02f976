"""What every solver takes and returns, the base class they share, and the registry."""

from __future__ import annotations

import dataclasses
import math
import time
from abc import ABC, abstractmethod
from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np
from numpy.typing import NDArray

from pipeflow._types import FloatArray, Progress
from pipeflow.errors import BudgetExceeded, InvalidInput
from pipeflow.loading import Coefficients, Loading
from pipeflow.loads import ExternalForcing
from pipeflow.model import PipeModel
from pipeflow.solvers.checkpoint import Checkpointer, Checkpoints, fingerprint

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
        raise InvalidInput("step must be finite and > 0 s", parameter="step")
    return step


def forcing(
    model: PipeModel,
    loading: Loading,
    loads: ExternalForcing | None,
    t: FloatArray,
    c: Coefficients | None = None,
) -> FloatArray:
    """The forcing f(t) of z' = S(t) z + f(t) at the times ``t`` [s], shape ``(len(t), 2n)``
    [1/s x m]: the spin-up load f_wdot dw0/dt of the model plus, with ``loads``, the external
    loads sum_k g_k p_k(t) (``c``: the coefficients at ``t`` when the caller has them).  The
    one definition: :meth:`Problem.forcing` and the Magnus generator's forcing use it."""
    if loads is not None and c is None and loading.spin.is_constant:
        return loads.vector(t)  # no spin-up load: the coefficients are not needed
    f = model.forcing(loading.coefficients(t) if c is None else c)
    if loads is not None:
        f = f + loads.vector(t)
    return f


@dataclass(frozen=True)
class Problem:
    """One linear initial-value problem z' = S(t) z + f(t) in balanced coordinates.

    f(t) = f_wdot dw0/dt (the spin-up load of the model) plus, with ``loads``, the external
    loads sum_k g_k p_k(t) (:class:`pipeflow.loads.ExternalForcing`).  ``checkpoints``: the
    solvers that can (magnus, rk4) save their progress there and resume from it.
    """

    model: PipeModel
    loading: Loading
    z0: FloatArray
    t: FloatArray  # output times [s], t[0] == 0, strictly increasing
    options: Options = field(default_factory=Options)
    progress: Progress | None = None
    loads: ExternalForcing | None = None
    #: where a long solve keeps checkpoints to resume from (:mod:`pipeflow.solvers.checkpoint`)
    checkpoints: Checkpoints | None = None

    @property
    def forced(self) -> bool:
        """True when f(t) is not identically zero (varying spin or external loads)."""
        return self.loads is not None or not self.loading.spin.is_constant

    def forcing(self, t: FloatArray, c: Coefficients | None = None) -> FloatArray:
        """f(t) at the times ``t`` [s], shape ``(len(t), 2n)`` [1/s x m]: spin-up and loads
        (``c``: the coefficients at ``t`` when the caller has them)."""
        return forcing(self.model, self.loading, self.loads, t, c)

    def checkpointer(self, solver: str) -> Checkpointer:
        """``solver``'s side of :attr:`checkpoints` for this solve, its blobs told apart by
        the fingerprint of what determines the numbers: output times, initial state,
        options, the state-matrix pieces and the coefficients (and forcing) at the output
        times."""

        def identity() -> str:
            c = self.loading.coefficients(self.t)
            arrays = [self.t, self.z0, self.model.state_pieces, self.model.f_wdot]
            arrays += [c.weights(), c.wdot]
            if self.loads is not None:
                arrays.append(self.loads.vector(self.t))
            return fingerprint(solver, self.options, arrays)

        return Checkpointer(solver, self.checkpoints, identity)

    def report(self, fraction: float) -> None:
        if self.progress is not None:
            self.progress(min(max(fraction, 0.0), 1.0))


@dataclass
class SolverStats:
    """Work counters of one solve, the same record for every method (like the counters
    of scipy's ``OdeResult``: ``nfev``...).  A counter a method does not use stays 0.

    steps : time steps of the accepted run [-].
    rhs_evaluations : evaluations of S(t) z + f(t) (``nfev``) [-].
    matrix_exponentials : matrix exponentials formed, all attempts and checks included [-].
    eigendecompositions : eigen-decompositions of (integrated) state matrices [-].
    attempts : runs made to meet a tolerance (1 for a single run) [-].
    solve_seconds : wall time of the solve [s].
    """

    steps: int = 0
    rhs_evaluations: int = 0
    matrix_exponentials: int = 0
    eigendecompositions: int = 0
    attempts: int = 1
    solve_seconds: float = 0.0

    def as_dict(self) -> dict[str, Any]:
        return dataclasses.asdict(self)


@dataclass
class SolverOutput:
    """Balanced states at the output times plus what the solver wants to say about them.

    ``diagnostics`` carries the method's own entries and, after :meth:`Solver.solve`, the
    counters of ``stats``; ``method`` is the name of the solver that produced ``z``.
    """

    z: FloatArray  # (len(t), 2n)
    diagnostics: dict[str, Any] = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)
    stats: SolverStats = field(default_factory=SolverStats)
    method: str = ""


class Solver(ABC):
    """A method for the state equation: the template every solver fills in.

    :meth:`solve` owns what every method shares (timing, the counters of
    :class:`SolverStats`, final progress); a method implements :meth:`_solve_impl`, which
    fills the counters it uses, and bounds its step counts with :func:`step_counts`.
    What the rest of the library needs to know about a method is asked here, never by
    branching on its name:

    option_names : the :class:`Options` it reads (the others do not change its result).
    estimates_own_error : it reports ``estimated_relative_error`` itself; otherwise
        :func:`pipeflow.diagnostics.add_error_estimate` measures it.
    error_advice : what to do when its error is too large (for the warning).
    compared_by_default : :func:`pipeflow.compare.compare` runs it when given no methods.
    """

    name: ClassVar[str]
    description: ClassVar[str]
    option_names: ClassVar[tuple[str, ...]]
    estimates_own_error: ClassVar[bool] = False
    error_advice: ClassVar[str] = "use a more accurate method"
    compared_by_default: ClassVar[bool] = True

    def solve(self, problem: Problem) -> SolverOutput:
        """Solve ``problem``; the output's diagnostics include the counters and the time."""
        t0 = time.perf_counter()
        stats = SolverStats()
        loads = problem.loads
        if loads is not None and loads.impulsive and not self.applies_impulses(problem):
            out = self._solve_with_impulses(problem, stats)
        else:
            out = self._solve_impl(problem, stats)
        stats.solve_seconds = time.perf_counter() - t0
        out.stats = stats
        out.method = out.method or self.name
        out.diagnostics.update(stats.as_dict())
        problem.report(1.0)
        return out

    @abstractmethod
    def _solve_impl(self, problem: Problem, stats: SolverStats) -> SolverOutput:
        """The method itself: states at ``problem.t``, counting its work in ``stats``."""

    def applies_impulses(self, problem: Problem) -> bool:
        """True when :meth:`_solve_impl` applies the impulses of ``problem.loads`` itself;
        otherwise :meth:`solve` superposes them (:meth:`_solve_with_impulses`)."""
        return False

    def _solve_with_impulses(self, problem: Problem, stats: SolverStats) -> SolverOutput:
        """The run without its impulses plus, per impulse J g at t_j, the free response
        Phi(t, t_j) g J for t >= t_j (the system is linear): a run of this method from
        z = g J restarted at t_j (coefficients shifted by t_j; with a varying spin minus
        the same run from rest, which carries the spin-up load alone)."""
        loads = problem.loads
        assert loads is not None
        rest = loads.subset([not p.impulsive for p in loads.profiles])
        main = dataclasses.replace(problem, loads=rest)
        out = self._solve_impl(main, stats)
        t = problem.t
        for when, jump in loads.impulses():
            k = int(np.searchsorted(t, when, side="left"))  # first output time >= when
            if k == t.size:
                continue
            sub_t = t[k:] - when
            lead = int(sub_t[0] > 0.0)
            if lead:
                sub_t = np.concatenate([[0.0], sub_t])
            if sub_t.size == 1:
                out.z[k:] += jump
                continue
            loading = problem.loading.shifted(when)
            sub = Problem(problem.model, loading, jump, sub_t, problem.options)
            z = self._solve_impl(sub, stats).z
            if sub.forced:  # the spin-up load: subtract its own response
                z = z - self._solve_impl(dataclasses.replace(sub, z0=0.0 * jump), stats).z
            out.z[k:] += z[lead:]
        out.diagnostics["impulses"] = "superposed: one restarted run per impulse"
        return out

    def choose(self, problem: Problem) -> tuple[Solver, str]:
        """The solver that will run ``problem`` and why (one line): this one, as requested."""
        return self, f"{self.name} as requested"

    def exact_error(self, problem: Problem, out: SolverOutput) -> tuple[float, str] | None:
        """``(estimate, how)`` when this method knows its error without a check (exact up
        to rounding for this problem), else None."""
        return None

    def claimed_error(self, options: Options, diagnostics: dict[str, Any]) -> float:
        """Relative error [-] this result claims, for ranking methods (inf if unknown)."""
        value = diagnostics.get("estimated_relative_error")
        if isinstance(value, int | float) and math.isfinite(value):
            return float(value)
        return math.inf


def relative_difference(a: Any, ref: Any, size: int | None = None) -> float:
    """max_k |a_k - ref_k| / max_k |ref_k| [-]: the one relative difference of pipeflow.

    Rows k of 2-D arrays are states (Euclidean norm over their first ``size`` components,
    all by default), entries of 1-D arrays are samples (e.g. a tip history).  0 when both
    vanish, inf when only ``a`` does not or the difference is not finite.
    """
    a, ref = np.asarray(a), np.asarray(ref)
    if ref.size == 0:
        return 0.0
    if ref.ndim == 1:
        a, ref = a[:, None], ref[:, None]
    cols = slice(None) if size is None else slice(0, size)
    with np.errstate(all="ignore"):
        scale = float(np.max(np.linalg.norm(ref[:, cols], axis=1)))
        diff = float(np.max(np.linalg.norm(a[:, cols] - ref[:, cols], axis=1)))
    if not math.isfinite(diff):
        return math.inf
    if scale == 0.0:
        return 0.0 if diff == 0.0 else math.inf
    return diff / scale


#: steps per shortest stretch between the loads' break points (a pulse, a table segment)
STEPS_PER_LOAD_PIECE = 4


def load_step_cap(problem: Problem) -> float:
    """The longest step [s] that cannot pass over a load's piece: the shortest stretch
    between the loads' break points (a pulse's ends, table knots, 0 and t_end) over
    :data:`STEPS_PER_LOAD_PIECE`; inf without loads.  A step plan from the spectrum alone
    had stepped over a short or late pulse (an all-zero answer with a tiny estimate)."""
    if problem.loads is None:
        return math.inf
    t_end = float(problem.t[-1])
    edges = np.concatenate([[0.0], problem.loads.knots(t_end), [t_end]])
    return float(np.min(np.diff(edges))) / STEPS_PER_LOAD_PIECE


def step_budget(options: Options) -> int:
    """Steps one run may take: ``options.max_steps``, never above :data:`MAX_STEPS_CEILING`."""
    return int(min(options.max_steps, MAX_STEPS_CEILING))


def step_counts(
    dt: FloatArray,
    h: float,
    budget: int,
    method: str,
    user_step: bool,
    extra: float = 0.0,
) -> NDArray[np.int64]:
    """Sub-steps per output interval so that none is longer than ``h`` [s], bounded.

    Every count is computed and checked in floating point before any integer cast (a step
    of 1e-300 s gives an infinite count, which would wrap to a negative int64).  When the
    total plus ``extra`` (steps the caller adds, e.g. an error check) exceeds ``budget``,
    :class:`BudgetExceeded` names ``step`` if the step was the user's (``user_step``),
    else ``max_steps``, and says the smallest step the budget allows.
    """
    with np.errstate(over="ignore", invalid="ignore"):
        counts = np.maximum(1.0, np.ceil(dt / h * (1 - 1e-12)))
        total = float(np.sum(counts)) + extra
    if not total <= budget:  # also catches inf and nan
        per_interval = budget // dt.size if dt.size else 0
        smallest = float(np.max(dt)) / per_interval if per_interval >= 1 else math.inf
        shown = f"{total:.3g}" if math.isfinite(total) else "more than 1e308"
        advice = (
            f"the smallest step this budget allows is {smallest:.3g} s"
            if math.isfinite(smallest)
            else "the budget does not cover one step per output interval: use fewer samples"
        )
        raise BudgetExceeded(
            f"{method} needs {shown} steps of {min(h, float(np.max(dt))):.3g} s for this run, "
            f"above the step budget of {budget}: {advice}, or raise max_steps",
            parameter="step" if user_step else "max_steps",
            smallest_step=smallest if math.isfinite(smallest) else None,
        )
    return counts.astype(np.int64)


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
