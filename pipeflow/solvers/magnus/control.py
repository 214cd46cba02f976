"""The Magnus solver (:class:`Magnus`) and its step control: the plan of each attempt, the
error estimate (Richardson against a run with twice the step, then against the previous
attempt), the refinement and the solver's output (the method:
:mod:`pipeflow.solvers.magnus`).  One definition of the control for the single run
(:class:`Magnus`, which drives it with single propagations, resumable from its
checkpoints) and the stacked runs of a study (:mod:`pipeflow.solvers.magnus.stack`)."""

from __future__ import annotations

import math
from collections.abc import Generator
from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np
from numpy.typing import NDArray

from pipeflow._types import FloatArray
from pipeflow.errors import BudgetExceeded, InvalidInput
from pipeflow.solvers.base import (
    Problem,
    Solver,
    SolverOutput,
    SolverStats,
    given_step,
    load_step_cap,
    relative_difference,
    step_budget,
    step_counts,
)
from pipeflow.solvers.magnus import stepper
from pipeflow.solvers.magnus.checkpoints import MagnusCheckpoints
from pipeflow.solvers.magnus.dense import DenseOutput
from pipeflow.solvers.magnus.generator import (
    MagnusGenerator,
    StepPlan,
    choose_orders,
    load_scale,
)

#: fraction of the tolerance the steps are chosen for (the rest is margin for the estimate)
SAFETY = 0.5
#: at least 5 (order 4 gives 16, order 6 64; oscillatory modes outside h |xi| < pi less)
RICHARDSON_DIVISOR = 4.0
#: like h^2 between attempts (measured: 4.8x from 2,000 to 4,000 steps, forced from rest)
REFINED_FLOOR_RATE = 2.0
#: rounding allowance of the estimate per step (the unit roundoff) [-]
ROUNDING_PER_STEP = float(np.finfo(float).eps)
#: the first attempt uses at least this many steps over the run
PILOT_STEPS = 256
#: attempts at meeting the tolerance (each refines the steps from the previous estimate)
MAX_ATTEMPTS = 4
#: the most one refinement multiplies the steps by (:meth:`_Control.refine`)
MAX_REFINEMENT = 8.0


def observed_rate(d1: float, Zc: FloatArray, Zcc: FloatArray, size: int, order: int) -> float:
    """Observed convergence rate log2(d2 / d1) [-], with d1 = |Z - Zc| of runs with the
    step and twice the step, and d2 = |Zc - Zcc| with four times the step (relative, max
    over time), clipped to [log2(RICHARDSON_DIVISOR + 1), order]: order 4 gives 4 in the
    asymptotic regime, while h |xi_max| > pi it is lower."""
    d2 = relative_difference(Zcc, Zc, size)
    r = d2 / d1 if d1 > 0 else math.inf
    r = min(max(r, RICHARDSON_DIVISOR + 1.0), 2.0**order) if math.isfinite(r) else 2.0**order
    return math.log2(r)


def check_budget(
    n_steps: int, budget: int, dt: FloatArray, substeps: NDArray[np.int64], tol: float
) -> None:
    """Refuse a run of ``n_steps`` steps over the step ``budget`` (options.max_steps)."""
    if n_steps > budget:
        raise BudgetExceeded(
            f"magnus needs {n_steps} steps of {float(np.max(dt / substeps)):.3g} s for "
            f"this run (tolerance {tol:.3g}, including the error check), above the step "
            f"budget of {budget}; raise max_steps, loosen the tolerance or "
            "use fewer modes",
            parameter="max_steps",
        )


def _substeps(
    dt: FloatArray,
    h: float,
    budget: int,
    factor: float = 1.0,
    current: NDArray[np.int64] | None = None,
) -> NDArray[np.int64]:
    """Sub-steps per output interval: none longer than ``h`` [s], or ``current`` refined by
    ``factor``; each count is bounded by budget + 1 before the cast to integers (a huge
    count must not wrap around; the budget check then refuses it)."""
    with np.errstate(over="ignore", divide="ignore", invalid="ignore"):
        if current is None:
            count = np.ceil(np.asarray(dt, dtype=float) / h * (1 - 1e-12))
        else:
            # whole multiples per interval: spreading a fractional factor over the
            # intervals (1 and 2 steps alternating) was tried and loses the cancellation
            # of successive local errors that equal steps have (paper example forced from
            # rest: 3,496 such steps gave 1.9e-8, 2,000 equal steps 1.3e-8)
            count = np.ceil(current * factor)
    count = np.nan_to_num(count, nan=budget + 1.0, posinf=budget + 1.0)
    return np.clip(count, 1, budget + 1).astype(np.int64)


@dataclass
class MagnusRun:
    """One propagation :func:`step_control` asks for: ``plan`` over the output times ``t``
    [s] with the generators ``gen``, from the problem's initial state."""

    gen: MagnusGenerator
    t: FloatArray
    plan: StepPlan


#: :func:`step_control`'s type: yields runs, is sent (states, exponentials used)
StepControl = Generator[MagnusRun, tuple[FloatArray, int], SolverOutput]


@dataclass
class _Check:
    """The first attempt's Richardson check: the output indices ``idx`` of the run with
    twice the step and its states ``Zc``, their difference ``d1`` from the attempt, and the
    run with four times the step (``idx2`` into ``idx``, its plan ``coarser``) that gives
    the observed rate when a refinement is needed."""

    idx: NDArray[np.int64]
    Zc: FloatArray
    d1: float
    idx2: NDArray[np.int64]
    coarser: StepPlan


@dataclass
class _Control:
    """What the control carries from attempt to attempt."""

    problem: Problem
    gen: MagnusGenerator
    budget: int
    step: float | None  # the user's step [s], or None: chosen for the tolerance
    h0: float  # the first step [s]
    t: FloatArray  # the times the control runs on [s]
    dense: DenseOutput | None
    exps: int = 0
    attempts: int = 0
    estimate: float = 0.0
    rate: float = 4.0
    method: str = ""
    #: the previous attempt's states, steps and coarse times (dense output)
    previous: tuple[FloatArray, int, NDArray[np.int64] | None] | None = None
    warnings: list[str] = field(default_factory=list)

    @property
    def tolerance(self) -> float:
        return self.problem.options.tolerance

    @property
    def size(self) -> int:
        return self.problem.model.size

    def first_substeps(self) -> NDArray[np.int64]:
        """The first attempt's sub-steps per interval, bounded in floating point before the
        cast; the error check's run with twice the step takes half as many again, and when
        it may refine (no user step) the run with four times the step a quarter: the first
        run gets 2/3 or 4/7 of the budget."""
        dt, budget = np.diff(self.t), self.budget
        refines = self.step is None
        first = (
            budget if self.gen.invariant else (4 * budget) // 7 if refines else (2 * budget) // 3
        )
        substeps = step_counts(dt, self.h0, first, "magnus", self.step is not None)
        if dt.size == 1 and not self.gen.invariant:
            substeps = np.maximum(substeps, 2)  # the check needs a coarser run to compare with
        return substeps

    def plan(self, substeps: NDArray[np.int64]) -> StepPlan:
        """The next attempt's plan (its orders chosen per interval)."""
        self.attempts += 1
        dt = np.diff(self.t)
        check_budget(int(substeps.sum()), self.budget, dt, substeps, self.tolerance)
        if self.gen.invariant:
            return StepPlan(substeps, np.full(dt.size, 4, dtype=np.int64))
        orders, used = choose_orders(self.gen, self.t, substeps)
        self.exps += used
        return StepPlan(substeps, orders)

    def versus_previous(self, plan: StepPlan, Zaug: FloatArray) -> None:
        """The estimate of a refinement: the previous attempt is the coarser run of the
        check (no fresh run with twice the step); Richardson with the step ratio at the
        slowest rate a refinement is assumed to converge at, REFINED_FLOOR_RATE = 2: not the
        observed rate, which before the asymptotic regime under-estimated the error 5x
        (paper example forced from rest: 1.3e-9 for a true 7.2e-9), nor
        log2(RICHARDSON_DIVISOR + 1) = 2.32 as the first check, which under-reported there
        too (6.9e-9 for 7.2e-9: the error fell 4.8x from 2,000 to 4,000 steps, not 5x)."""
        assert self.previous is not None
        Zprev, steps_prev, sel_prev = self.previous
        ratio = plan.steps / steps_prev
        # dense output: the previous coarse times are a subset of these
        Znow = Zaug if self.dense is None or sel_prev is None else self.dense.at(Zaug, sel_prev)
        d1 = relative_difference(Zprev, Znow[:, : self.size], self.size)
        self.estimate = d1 / max(ratio**REFINED_FLOOR_RATE - 1.0, 1e-300)
        self.method = (
            f"difference from the previous attempt ({steps_prev} steps, step ratio "
            f"{ratio:.3g}) over ratio^{REFINED_FLOOR_RATE:.2f} - 1"
        )

    def richardson(
        self, plan: StepPlan, Zaug: FloatArray
    ) -> Generator[MagnusRun, tuple[FloatArray, int], _Check]:
        """The first attempt's estimate: the same orders with twice the step (and four
        times, counted in the budget when it may refine: never with a user step)."""
        t, dt = self.t, np.diff(self.t)
        idx, coarse = plan.coarse(t)
        idx2, coarser = coarse.coarse(t[idx])
        check = coarse.steps + (coarser.steps if self.step is None else 0)
        check_budget(plan.steps + check, self.budget, dt, plan.substeps, self.tolerance)
        Zc, used = yield MagnusRun(self.gen, t[idx], coarse)
        self.exps += used
        d1 = relative_difference(Zc, Zaug[idx], self.size)
        self.estimate = d1 / RICHARDSON_DIVISOR
        self.method = (
            f"difference from a run with twice the step, divided by {RICHARDSON_DIVISOR:g}"
        )
        return _Check(idx, Zc, d1, idx2, coarser)

    def recheck(
        self, plan: StepPlan, Zaug: FloatArray
    ) -> Generator[MagnusRun, tuple[FloatArray, int], None]:
        """A refinement :meth:`versus_previous` could not accept: before refining again,
        compare with a fresh run of twice the step at this level (half its cost), divided
        by 2^REFINED_FLOOR_RATE - 1 (the same floor rate).  The attempt before may lie
        outside the asymptotic regime (h |xi_max| >> pi), where the difference from it
        over-states this attempt's error many times: a pinned-pinned pipe under
        accelerating flow, 10 modes, refined from 2,000 to 30,000 steps, was estimated at
        4.8e-8 (and refined again to 80,000) for a true error near 1e-12."""
        t = self.t
        idx, coarse = plan.coarse(t)
        check_budget(plan.steps + coarse.steps, self.budget, np.diff(t), plan.substeps,
                     self.tolerance)  # fmt: skip
        Zc, used = yield MagnusRun(self.gen, t[idx], coarse)
        self.exps += used
        d1 = relative_difference(Zc, Zaug[idx], self.size)
        fresh = d1 / (2.0**REFINED_FLOOR_RATE - 1.0)
        if fresh < self.estimate:
            self.estimate = fresh
            self.method = (
                "difference from a run with twice the step (after a refinement), over "
                f"2^{REFINED_FLOOR_RATE:.2f} - 1"
            )

    def done(self) -> bool:
        """Whether the attempts end here: a user step, the tolerance met, or no more
        attempts (or a non-finite estimate: a warning)."""
        if self.step is not None or self.estimate <= self.tolerance:
            return True
        if self.attempts >= MAX_ATTEMPTS or not math.isfinite(self.estimate):
            self.warnings.append(
                f"magnus could not verify the tolerance {self.tolerance:.3g}: estimated "
                f"relative error {self.estimate:.3g} after {self.attempts} attempts (each "
                f"refinement multiplies the steps by at most {MAX_REFINEMENT:g}); give "
                "options.step, or a looser tolerance"
            )
            return True
        return False

    def observed(
        self, plan: StepPlan, check: _Check
    ) -> Generator[MagnusRun, tuple[FloatArray, int], None]:
        """The rate observed against a run with four times the step (not h^4: it over- or
        under-shoots while h |xi_max| > pi)."""
        Zcc, used = yield MagnusRun(self.gen, self.t[check.idx][check.idx2], check.coarser)
        self.exps += used
        self.rate = observed_rate(
            check.d1, check.Zc[check.idx2], Zcc, self.size, int(plan.order.max())
        )

    def refine(self, plan: StepPlan, Zaug: FloatArray) -> NDArray[np.int64]:
        """The next attempt's sub-steps: refined by the factor that brings the estimate to
        SAFETY * tolerance at the rate, at most MAX_REFINEMENT (the next attempt's own check
        decides whether more is needed), spread over the intervals (no rounding up to whole
        multiples); on a dense grid, coarse intervals split at samples."""
        wanted = (self.estimate / (SAFETY * self.tolerance)) ** (1.0 / self.rate)
        factor = min(wanted, MAX_REFINEMENT)
        sel = None if self.dense is None else self.dense.sel
        self.previous = (Zaug[:, : self.size].copy(), plan.steps, sel)
        substeps = _substeps(np.diff(self.t), self.h0, self.budget, factor, plan.substeps)
        if self.dense is not None:
            self.t, substeps = self.dense.refine(substeps)
        return substeps

    def output(self, plan: StepPlan, Zaug: FloatArray, stats: SolverStats) -> SolverOutput:
        """The solver's output after the last attempt (the dense output filled)."""
        N, opts = self.size, self.problem.options
        extra: dict[str, Any] = {}
        fill_note = ""
        if self.dense is None:
            Z = Zaug[:, :N].copy()
        else:
            fill = self.dense.fill(self.gen, Zaug, self.tolerance, self.estimate)
            Z = np.ascontiguousarray(fill.Z[:, :N])  # (a copy only when the state is augmented)
            self.exps += fill.exponentials
            self.estimate += fill.estimate
            fill_note = self.dense.note(fill)
            extra["dense_output"] = self.dense.diagnostics(fill, plan.steps)
            if not self.estimate <= self.tolerance and not self.warnings:
                self.warnings.append(
                    f"magnus could not verify the tolerance {self.tolerance:.3g}: estimated "
                    f"relative error {self.estimate:.3g} with the dense output's fill"
                )
        h_used = np.diff(self.t) / plan.substeps
        stats.steps, stats.attempts, stats.matrix_exponentials = (
            plan.steps,
            self.attempts,
            self.exps,
        )
        diagnostics: dict[str, Any] = {
            "time_invariant": self.gen.invariant,
            "step_source": "step" if opts.step is not None else "tolerance",
            "step_max": float(h_used.max()),
            "step_min": float(h_used.min()),
            "steps_order_6": int(plan.substeps[plan.order == 6].sum()),
            "tolerance": opts.tolerance,
            "estimated_relative_error": self.estimate,
            "error_estimate_method": (
                "exact for constant coefficients (rounding only)"
                if self.gen.invariant
                else f"{self.method}, plus one unit roundoff per step (rounding){fill_note}"
            ),
            **extra,
        }
        return SolverOutput(z=Z, diagnostics=diagnostics, warnings=self.warnings)


def _start(problem: Problem) -> _Control:
    """The control's state before its first attempt (the generators, the budget, the first
    step and, on a dense grid, the coarse times)."""
    opts = problem.options
    scale = float(np.linalg.norm(problem.z0)) or 1.0
    if problem.loads is not None:
        scale = load_scale(problem)
    gen = MagnusGenerator(problem.model, problem.loading, scale, problem.loads)
    step = given_step(opts)
    if step is None and not (0 < opts.tolerance < 1):
        raise InvalidInput("tolerance must be in (0, 1)", parameter="tolerance")
    h0 = (
        step
        if step is not None
        else min(float(problem.t[-1]) / PILOT_STEPS, load_step_cap(problem))
    )
    # dense output: the control runs on the coarse times (None: on every output time)
    dense = None if gen.invariant or step is not None else DenseOutput.on(problem.t, h0)
    t = problem.t if dense is None else dense.times
    return _Control(problem, gen, step_budget(opts), step, h0, t, dense)


def step_control(problem: Problem, stats: SolverStats) -> StepControl:
    """The step control of :class:`Magnus` for one problem,
    as a generator: it yields each propagation it needs (a :class:`MagnusRun`) and is sent
    back the augmented states at the run's output times and the exponentials used; it
    returns the solver's output.  One definition for the single run
    (:meth:`Magnus._solve_impl`, which sends :func:`~pipeflow.solvers.magnus.propagate`'s
    answers) and the stacked runs of a study (:mod:`pipeflow.solvers.magnus.stack`, which
    propagates many problems' runs at once).

    On a dense output grid (:class:`~pipeflow.solvers.magnus.dense.DenseOutput`) the
    control runs on a coarse subset of the output times and the samples between are filled
    after the last attempt."""
    run = _start(problem)
    substeps = run.first_substeps()
    while True:
        plan = run.plan(substeps)
        Zaug, used = yield MagnusRun(run.gen, run.t, plan)
        run.exps += used
        if run.gen.invariant:
            break
        check = None
        if run.previous is not None:
            run.versus_previous(plan, Zaug)
            rounding = plan.steps * ROUNDING_PER_STEP
            if run.step is None and run.estimate + rounding > run.tolerance:
                yield from run.recheck(plan, Zaug)
        else:
            check = yield from run.richardson(plan, Zaug)
        # the rounding of the sequential propagation (one unit roundoff per step, a
        # bound of its random walk of ~20 eps sqrt(steps) past 400 steps): below it
        # two runs cannot tell their errors apart (4 modes, 38,400 steps: a difference
        # of 1e-14, a true error of 1e-13)
        run.estimate += plan.steps * ROUNDING_PER_STEP
        if run.done():
            break
        if check is not None:
            yield from run.observed(plan, check)
        substeps = run.refine(plan, Zaug)
    return run.output(plan, Zaug, stats)


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
