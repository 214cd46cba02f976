"""The paper's complex modal analysis (section 3), vectorised over output times.

    z(t) = exp(P(t)) [ z0 + integral_0^t exp(-P(tau)) f(tau) dtau ],   P(t) = integral_0^t S

with exp(P) = Y diag(e^xi) Y^-1 from the eigen-decomposition of P (eq. 19-26) for constant
coefficients (P = t S: one decomposition serves every output time).  For time-variant
coefficients exp(P(t)) at every output time is the batched scaling-and-squaring
exponential (:func:`pipeflow.linalg.expm_stack`): the same matrix function, without
one eigen-decomposition per output time (the CMA exponents, eigenvalues of P(t)/t, are
decomposed only at the times a result reports them).  This is
exact when the S(t) commute with each other (constant coefficients); otherwise it is the
first term of the Magnus expansion and an approximation (physics notes, section 2).  The
Duhamel term is written as in the notes (the paper's eq. 27 is loose): it is evaluated
with Gauss-Legendre quadrature fine enough for the fastest retained mode.

External loads (:mod:`pipeflow.loads`) enter through the particular integral of eq. (17),
the convolution of the fundamental solution with the load.  Constant coefficients:
:mod:`pipeflow.solvers.convolution` evaluates it in the eigenbasis of S: in closed form for
analytic profiles (constant, polynomial, harmonic, half-sine, impulse: exact to rounding,
in the same modal sum as the homogeneous solution), and for tables interval by output
interval, exact up to a 16-point Gauss-Legendre rule on pieces of at most 20 rad (phase of
the fastest mode plus the load frequency) split at table knots: a relative quadrature
error below ~1e-12 (:data:`pipeflow.solvers.convolution.QUADRATURE_ERROR`).
Time-variant coefficients: the loads join the Duhamel term above,
exp(P(t)) integral_0^t exp(-P(tau)) f(tau) dtau, with the same quadrature (pieces of at
most 20 rad of the spectral radius plus the load frequency); the result carries CMA's
first-Magnus-term error (physics notes, section 2), which the error estimate measures.
"""

from __future__ import annotations

from typing import ClassVar

import numpy as np
from scipy.linalg import expm

from pipeflow._types import FloatArray
from pipeflow.errors import BudgetExceeded
from pipeflow.linalg import expm_stack
from pipeflow.solvers.base import (
    Problem,
    Solver,
    SolverOutput,
    SolverStats,
    spectral_radius,
)
from pipeflow.solvers.convolution import (
    QUADRATURE_ERROR,
    ClosedForm,
    dense_particular,
    modal_exponentials,
    modal_particular,
    uniform_step,
)

#: at most this many exp(-P) evaluations for the Duhamel integral
MAX_DUHAMEL_NODES = 400_000
_CHUNK = 512  # output times per batched exponential (bounds memory at 40 modes)
_BLOCK_TIMES = 16_384  # output times per block of the constant-coefficient product


def exp_apply(
    P: FloatArray, vectors: FloatArray, condition_limit: float
) -> tuple[FloatArray, FloatArray, np.ndarray]:
    """exp(P_k) @ vectors_k for a stack of matrices, by eigen-decomposition.

    Returns ``(result, condition_numbers, fell_back)``: where the eigenvector matrix of
    P_k has a 1-norm condition number ||Y||_1 ||Y^-1||_1 above ``condition_limit``
    (coalescing eigenvalues) or the decomposition is not finite, that entry is recomputed
    with scipy's Pade ``expm``.  (The 1-norm condition number is within a factor 2n of the
    2-norm one and costs an inverse we need anyway instead of an SVD.)
    """
    w, V = np.linalg.eig(P)
    with np.errstate(all="ignore"):
        try:
            Vinv = np.linalg.inv(V)
        except np.linalg.LinAlgError:  # an exactly singular Y somewhere in the stack
            Vinv = np.full_like(V, np.nan)
        cond = np.abs(V).sum(axis=-2).max(axis=-1) * np.abs(Vinv).sum(axis=-2).max(axis=-1)
        coeff = np.einsum("kij,kj->ki", Vinv, vectors.astype(complex))
        out = np.einsum("kij,kj->ki", V, np.exp(w) * coeff).real
    bad = ~np.isfinite(cond) | (cond > condition_limit) | ~np.all(np.isfinite(out), axis=1)
    if np.any(bad):
        idx = np.flatnonzero(bad)
        out[idx] = np.einsum("kij,kj->ki", expm(P[idx]), vectors[idx])
    return out, cond, bad


class CMA(Solver):
    name: ClassVar[str] = "cma"
    description: ClassVar[str] = (
        "Complex modal analysis (Wang & Zhong 2018): exp of the integrated state matrix. "
        "Exact for constant coefficients; an approximation (first Magnus term) otherwise."
    )
    option_names: ClassVar[tuple[str, ...]] = ("condition_limit",)
    error_advice: ClassVar[str] = (
        "CMA is exact only for constant flow and spin; use method 'magnus' (or 'auto')"
    )

    def _solve_impl(self, problem: Problem, stats: SolverStats) -> SolverOutput:
        loading, t = problem.loading, problem.t
        limit = problem.options.condition_limit
        diagnostics: dict[str, object] = {"time_invariant": loading.is_time_invariant}
        warnings: list[str] = []
        eig: tuple[np.ndarray, np.ndarray] | None = None
        if loading.is_time_invariant:
            z, cond, fallbacks, eig = self._time_invariant(problem, diagnostics)
            stats.eigendecompositions = 1
            diagnostics["eigenvector_condition_max"] = float(np.max(cond))
        else:
            # exp(P(t)) by the batched exponential: no eigen-decomposition (the exponents
            # P(t)/t reported with a result are decomposed at the eigenvalue sample times)
            z, cond, fallbacks = self._time_variant(problem, warnings)
            stats.eigendecompositions = 0
            stats.matrix_exponentials = int(t.size)
        loads = problem.loads
        if loads is not None and loading.is_time_invariant:
            if fallbacks or not all(loads.closed_form):  # else in the homogeneous sum
                z += self._particular(problem, stats, diagnostics, eig if not fallbacks else None)
        stats.matrix_exponentials += int(fallbacks)
        diagnostics["expm_fallbacks"] = int(fallbacks)
        if fallbacks:
            warnings.append(
                f"eigenvector matrix ill-conditioned (condition number up to "
                f"{float(np.max(cond)):.3g} > {limit:.3g}) at {fallbacks} time(s): "
                "used a Pade matrix exponential there"
            )
        return SolverOutput(z=z, diagnostics=diagnostics, warnings=warnings)

    def applies_impulses(self, problem: Problem) -> bool:
        return problem.loading.is_time_invariant  # as jumps of the modal coordinates

    def exact_error(self, problem: Problem, out: SolverOutput) -> tuple[float, str] | None:
        """Constant coefficients: exact up to rounding, amplified by the eigenvector
        condition number (and the quadrature of tabulated loads)."""
        if not problem.loading.is_time_invariant:
            return None
        cond = float(out.diagnostics.get("eigenvector_condition_max", 1.0))
        how = str(out.diagnostics.get("load_convolution", ""))
        if problem.loads is not None and "quadrature" in how:
            return (
                max(float(np.finfo(float).eps * max(cond, 1.0)), QUADRATURE_ERROR),
                "exact for constant coefficients up to the load convolution's quadrature "
                f"(bound {QUADRATURE_ERROR:g}) and rounding (eps x eigenvector condition)",
            )
        return (
            float(np.finfo(float).eps * max(cond, 1.0)),
            "exact for constant coefficients: rounding only (eps x eigenvector condition)",
        )

    def _time_invariant(
        self, problem: Problem, diagnostics: dict[str, object]
    ) -> tuple[FloatArray, FloatArray, int, tuple[np.ndarray, np.ndarray] | None]:
        """exp(S t) z0 plus the closed-form particular integral of the analytic loads (in
        the same modal sum); the tables' and impulses' parts are :meth:`_particular`'s."""
        # P(t) = t S: one eigen-decomposition serves every output time (eq. 25-26)
        model, t, z0 = problem.model, problem.t, problem.z0
        S = model.state_matrix(problem.loading.coefficients(np.zeros(1)))[0]
        w, V = np.linalg.eig(S)
        try:
            cond = float(np.linalg.norm(V, 1) * np.linalg.norm(np.linalg.inv(V), 1))
        except np.linalg.LinAlgError:
            cond = float("inf")
        if not np.isfinite(cond) or cond > problem.options.condition_limit:
            Z = _expm_marching(S, t, z0)
            return Z, np.array([cond]), 1, None
        c = np.linalg.solve(V, z0.astype(complex))
        # S is real, so LAPACK returns exact conjugate pairs: keep one of each pair and
        # double its real part (half the exponentials and the product), real ones once
        keep = w.imag >= 0
        weight = np.where(w.imag[keep] > 0, 2.0, 1.0)
        coef, Vt = weight * c[keep], V[:, keep].T
        closed = None
        if problem.loads is not None:
            analytic = problem.loads.subset(problem.loads.closed_form)
            if analytic is not None:
                closed = ClosedForm(analytic, w, V)
                diagnostics["load_convolution"] = (
                    "closed form in the eigenbasis (analytic profiles)"
                )
        dt = uniform_step(t)
        # in blocks of output times written into the result: the complex temporaries stay
        # a block's size instead of 4x the output (1e6 samples: 640 MB -> the output's 160)
        Z = np.empty((t.size, model.size))
        block = _BLOCK_TIMES
        with np.errstate(over="ignore", invalid="ignore"):
            for s0 in range(0, t.size, block):
                sl = slice(s0, min(s0 + block, t.size))
                E = modal_exponentials(t[sl], w[keep], start=s0, dt=dt)
                if closed is None:
                    A = E * coef
                else:  # the free response's E c0 and the loads' in one pass over E
                    A = closed.amplitudes(t[sl], None if dt is None else (s0, dt), E, coef)
                Z[sl] = (A @ Vt).real
        return Z, np.array([cond]), 0, (w, V)

    def _particular(
        self,
        problem: Problem,
        stats: SolverStats,
        diagnostics: dict[str, object],
        eig: tuple[np.ndarray, np.ndarray] | None,
    ) -> FloatArray:
        """The loads' particular integral at constant coefficients (eq. 17's convolution,
        :mod:`pipeflow.solvers.convolution`): in the eigenbasis of S, in closed form for
        analytic profiles and by quadrature for tables; or with matrix exponentials where
        the homogeneous solution fell back to them (``eig`` None; else the eigenvalues and
        eigenvectors of S it used).  Impulses are jumps of the state."""
        loads, t = problem.loads, problem.t
        assert loads is not None
        if eig is None:
            S = problem.model.state_matrix(problem.loading.coefficients(np.zeros(1)))[0]
            Zp, exps = dense_particular(t, loads, S)  # an impulse samples to zero here
            for when, jump in loads.impulses():
                k = int(np.searchsorted(t, when, side="left"))
                if k < t.size:
                    sub_t = np.concatenate([[0.0], t[k:] - when])
                    Zp[k:] += _expm_marching(S, sub_t, jump)[1:]
                    exps += 1
            stats.matrix_exponentials += exps
            diagnostics["load_convolution"] = (
                "quadrature with matrix exponentials at the nodes' offsets (ill-conditioned S)"
            )
            return Zp
        w, V = eig  # the homogeneous solution's decomposition
        closed = loads.closed_form
        Zp = np.zeros((t.size, problem.model.size))
        how = [str(diagnostics["load_convolution"])] if "load_convolution" in diagnostics else []
        tabulated = loads.subset([not f for f in closed])
        if tabulated is not None:
            Zq, nodes = modal_particular(t, tabulated, w, V)
            Zp += Zq
            diagnostics["load_quadrature_nodes"] = nodes
            how.append("modal quadrature of the tables (16-point Gauss-Legendre, pieces <= 20 rad)")
        diagnostics["load_convolution"] = "; ".join(how)
        return Zp

    def _time_variant(
        self, problem: Problem, warnings: list[str]
    ) -> tuple[FloatArray, FloatArray, int]:
        model, loading, t = problem.model, problem.loading, problem.t
        forced = problem.forced  # varying spin or external loads
        base = np.broadcast_to(problem.z0, (t.size, model.size)).copy()
        if forced:
            base += self._duhamel(problem)
        Z = np.empty((t.size, model.size))
        for start in range(0, t.size, _CHUNK):
            sl = slice(start, min(start + _CHUNK, t.size))
            P = model.integrated_state_matrix(loading.integrals(t[sl]))
            Z[sl] = np.einsum("kij,kj->ki", expm_stack(P), base[sl])
            problem.report(sl.stop / t.size)
        return Z, np.ones(1), 0

    def _duhamel(self, problem: Problem) -> FloatArray:
        """Cumulative integral_0^t_k exp(-P(tau)) f(tau) dtau at every output time."""
        model, loading, t = problem.model, problem.loading, problem.t
        rho = spectral_radius(model, loading, float(t[-1]))
        if problem.loads is not None:
            rho += problem.loads.rate  # the load's own oscillation on top of the modes'
        dt = np.diff(t)
        # Gauss-Legendre with q nodes resolves ~q/2 radians per node pair; split long intervals
        pieces = np.maximum(1, np.ceil(rho * dt / 20.0)).astype(int)
        q = 16
        total = int(pieces.sum()) * q
        if total > MAX_DUHAMEL_NODES:
            fits = float(t[-1]) * MAX_DUHAMEL_NODES / total
            raise BudgetExceeded(
                f"the Duhamel integral of this forced run needs {total} matrix "
                f"exponentials (limit {MAX_DUHAMEL_NODES}); use time.t_end <= {fits:.3g} s, "
                "fewer modes or the 'magnus' method (what 'auto' runs here)",
                parameter="modes",
            )
        x, wq = np.polynomial.legendre.leggauss(q)
        owner = np.repeat(np.arange(dt.size), pieces)  # interval of each piece
        starts = np.concatenate([[0], np.cumsum(pieces)[:-1]])
        local = np.arange(owner.size) - starts[owner]
        width = dt[owner] / pieces[owner]
        left = t[owner] + local * width
        nodes = (left[:, None] + 0.5 * width[:, None] * (x[None, :] + 1.0)).ravel()
        weights = (0.5 * width[:, None] * wq[None, :]).ravel()
        contrib = np.zeros((owner.size, model.size))
        chunk = 4096
        for s0 in range(0, nodes.size, chunk):
            sl = slice(s0, min(s0 + chunk, nodes.size))
            P = model.integrated_state_matrix(loading.integrals(nodes[sl]))
            f = problem.forcing(nodes[sl])
            g, _, _ = exp_apply(-P, f, problem.options.condition_limit)
            np.add.at(contrib, np.arange(sl.start, sl.stop) // q, weights[sl, None] * g)
        per_interval = np.zeros((dt.size, model.size))
        np.add.at(per_interval, owner, contrib)
        out = np.zeros((t.size, model.size))
        out[1:] = np.cumsum(per_interval, axis=0)
        return out


def _expm_marching(S: FloatArray, t: FloatArray, z0: FloatArray) -> FloatArray:
    """Fallback for a defective S: exp(S dt) applied step by step (exact for constant S)."""
    Z = np.empty((t.size, z0.size))
    Z[0] = z0
    dts = np.diff(t)
    uniform = dts.size > 0 and np.allclose(dts, dts[0], rtol=1e-12, atol=0)
    E = expm(S * dts[0]) if uniform else None
    for k, h in enumerate(dts):
        step = E if E is not None else expm(S * h)
        Z[k + 1] = step @ Z[k]
    return Z
