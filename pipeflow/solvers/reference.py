"""Tight-tolerance reference: scipy ``solve_ivp`` on the same state equation.

Independent of the exponential-based methods (it only evaluates S(t) z + f(t)), so it is
what the other solvers are tested against.  Its cost is bounded by an evaluation budget.
"""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np
from scipy.integrate import solve_ivp

from pipeflow._types import FloatArray
from pipeflow.errors import BudgetExceeded, InvalidInput
from pipeflow.solvers.base import (
    MAX_EVALUATIONS_CEILING,
    Options,
    Problem,
    Solver,
    SolverOutput,
    SolverStats,
)

INTEGRATORS = ("DOP853", "RK45", "RK23", "Radau", "BDF", "LSODA")


class _OverBudget(Exception):
    pass


class Reference(Solver):
    name: ClassVar[str] = "reference"
    description: ClassVar[str] = (
        "scipy solve_ivp (DOP853 by default) at tight tolerance, for cross-checks."
    )
    option_names: ClassVar[tuple[str, ...]] = ("rtol", "atol", "integrator", "max_steps")
    estimates_own_error: ClassVar[bool] = True
    error_advice: ClassVar[str] = "use a smaller rtol"
    compared_by_default: ClassVar[bool] = False  # the slow cross-check
    #: its error is taken as this multiple of its rtol when ranking methods (measured:
    #: rtol 1e-12 gives ~3e-10 on the paper's example)
    ERROR_PER_RTOL: ClassVar[float] = 300.0

    def claimed_error(self, options: Options, diagnostics: dict[str, Any]) -> float:
        return self.ERROR_PER_RTOL * float(options.rtol)

    def _solve_impl(self, problem: Problem, stats: SolverStats) -> SolverOutput:
        model, loading, t = problem.model, problem.loading, problem.t
        opts = problem.options
        if opts.integrator not in INTEGRATORS:
            raise InvalidInput(
                f"unknown integrator {opts.integrator!r}; choose one of {', '.join(INTEGRATORS)}",
                parameter="integrator",
            )
        A = model.state_pieces
        forced = not loading.spin.is_constant
        loads = problem.loads
        budget = min(opts.max_steps * 12, MAX_EVALUATIONS_CEILING)
        t_end = float(t[-1])
        count = [0]

        invariant = loading.is_time_invariant
        S_const = model.state_matrix(loading.coefficients(np.zeros(1)))[0]

        def matrix(s: float) -> FloatArray:
            if invariant:
                return S_const
            return model.state_matrix(loading.coefficients(np.array([s])))[0]

        def rhs(s: float, z: FloatArray) -> FloatArray:
            count[0] += 1
            if count[0] > budget:
                raise _OverBudget
            if count[0] % 2000 == 0:
                problem.report(s / t_end)
            if invariant:
                out = S_const @ z
            else:
                c = loading.coefficients(np.array([s]))
                out = (A @ z).T @ c.weights()[0]  # S(s) z without forming S(s)
                if forced:
                    out = out + c.wdot[0] * model.f_wdot
            if loads is not None:  # external loads: sum_k g_k p_k(s)
                out = out + loads.values(np.array([s]))[0] @ loads.columns
            return out

        implicit = opts.integrator in ("Radau", "BDF", "LSODA")
        try:
            sol = solve_ivp(
                rhs,
                (0.0, t_end),
                problem.z0.astype(float),
                method=opts.integrator,
                t_eval=t,
                rtol=opts.rtol,
                atol=opts.atol,
                **({"jac": lambda s, z: matrix(s)} if implicit else {}),
            )
        except _OverBudget:
            raise BudgetExceeded(
                f"the reference integrator exceeded its budget of {budget} right-hand-side "
                "evaluations; loosen rtol/atol, use fewer modes or a shorter t_end",
                parameter="max_steps",
            ) from None
        if not sol.success:
            raise InvalidInput(f"reference integrator failed: {sol.message}", parameter="method")
        stats.rhs_evaluations = int(sol.nfev)
        diagnostics = {"integrator": opts.integrator, "rtol": opts.rtol, "atol": opts.atol}
        return SolverOutput(z=sol.y.T.copy(), diagnostics=diagnostics)
