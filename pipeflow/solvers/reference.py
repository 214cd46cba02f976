"""Tight-tolerance reference: scipy ``solve_ivp`` on the same state equation.

Independent of the exponential-based methods (it only evaluates S(t) z + f(t)), so it is
what the other solvers are tested against.  Its cost is bounded by an evaluation budget.
"""

from __future__ import annotations

import itertools
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
        # the loads' break points (a pulse's ends, table knots) bound the pieces integrated one
        # after another: an adaptive step from rest would step over a load that starts late
        # or lasts shortly (a half-sine of 0.1 ms at 0.12 s came back as zero)
        knots = loads.knots(t_end) if loads is not None else np.zeros(0)
        edges = np.concatenate([[0.0], knots, [t_end]])
        z = problem.z0.astype(float)
        out = np.empty((t.size, z.size))
        nfev = 0
        for a, b in itertools.pairwise(edges):
            last = b == t_end
            inside = (t >= a) & ((t <= b) if last else (t < b))
            try:
                sol = solve_ivp(
                    rhs,
                    (a, b),
                    z,
                    method=opts.integrator,
                    t_eval=np.concatenate([t[inside], [b]]) if not last else t[inside],
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
                raise InvalidInput(
                    f"reference integrator failed: {sol.message}", parameter="method"
                )
            nfev += int(sol.nfev)
            k = int(inside.sum())
            out[inside] = sol.y[:, :k].T
            z = sol.y[:, -1] if not last else z
        stats.rhs_evaluations = nfev
        diagnostics = {"integrator": opts.integrator, "rtol": opts.rtol, "atol": opts.atol}
        return SolverOutput(z=out, diagnostics=diagnostics)
