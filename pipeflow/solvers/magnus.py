"""Fourth-order Magnus propagation: the paper's CMA applied on short intervals.

On each step [t, t + h] the propagator of z' = S(t) z + f(t) is exp(Omega) with the
two-point Gauss-Legendre Magnus generator (Blanes, Casas, Oteo & Ros, Physics Reports 470,
2009, eq. 253)::

    A_1, A_2 = A(t + (1/2 -+ sqrt(3)/6) h),
    Omega    = h/2 (A_1 + A_2) + sqrt(3) h^2 / 12 [A_2, A_1],

which is O(h^5) locally (order 4 globally).  ``A`` is the state matrix augmented with the
forcing: the state is extended by a constant c (= |z0|), so the affine system becomes the
linear one  (z, c)' = [[S, f/c], [0, 0]] (z, c)  and the same exponential carries the
Duhamel term of a varying spin.  For constant coefficients Omega = h S exactly, so the
method is exact to rounding (one exponential for a uniform output grid).

All exponentials of a block of steps are computed at once (:func:`expm_stack`, scaling and
squaring of a Taylor polynomial with batched matrix products); only the final propagation
is sequential, one matrix-vector product per output interval.  Steps land on the output
times: interval k gets m_k equal sub-steps, and their exponentials are multiplied together
(batched, pairwise: :func:`product_of_steps`) before they touch the state.

The building blocks (:data:`GAUSS_NODES`, :func:`magnus4_omega`, :func:`expm_stack`,
:func:`product_of_steps`) accept leading batch dimensions and are shared with the Floquet
analysis (:mod:`pipeflow.stability.floquet`), which propagates Z' = S(t) Z over a period.

Error estimate and step selection (``Options.tolerance``, relative): the run is repeated
with twice the step on every other output time, and the estimate is
max_k |Z_h(t_k) - Z_2h(t_k)| / max_k |Z_h(t_k)| / 4.  For order 4 the ratio
err(2h)/err(h) is 16 and the estimate is ~4x conservative; while h |xi_max| > pi (the
fastest retained mode is not resolved, as for the paper's 10 modes at 2001 samples) the
observed ratio is 5-15 and the estimate is within a factor of ~2.  If the estimate exceeds
the tolerance, the step is shrunk by (estimate / (tolerance/2))^(1/4) and the run repeated
(the previous run then serves as the twice-the-step comparison when the step halves).
The first attempt uses one step per output interval, or at least 256 steps over the run.
"""

from __future__ import annotations

import math
from typing import Any, ClassVar

import numpy as np
from numpy.typing import NDArray

from pipeflow.errors import BudgetExceeded, InvalidInput
from pipeflow.model import Loading, PipeModel
from pipeflow.solvers.base import (
    FloatArray,
    Problem,
    Solver,
    SolverOutput,
    SolverStats,
    given_step,
    register,
    relative_difference,
    step_budget,
    step_counts,
)

GAUSS_OFFSET = math.sqrt(3.0) / 6.0
#: the two Gauss-Legendre nodes on a step, as fractions of the step [-]
GAUSS_NODES = (0.5 - GAUSS_OFFSET, 0.5 + GAUSS_OFFSET)
COMMUTATOR_FACTOR = math.sqrt(3.0) / 12.0
#: Taylor degree and the 1-norm to which a matrix is scaled before it is applied
TAYLOR_DEGREE = 18
TAYLOR_THETA = 1.0
#: fraction of the tolerance the step is chosen for (the rest is margin for the estimate)
SAFETY = 0.5
#: the estimate is |Z_h - Z_2h| / RICHARDSON_DIVISOR: an observed ratio err(2h)/err(h) of
#: at least 5 (order 4 gives 16; oscillatory modes outside h |xi| < pi give less)
RICHARDSON_DIVISOR = 4.0
#: the first attempt uses at least this many steps over the run
PILOT_STEPS = 256
#: attempts at meeting the tolerance (each refines the step from the previous estimate)
MAX_ATTEMPTS = 4
#: matrix entries per block of steps and per expm_stack work block: temporaries under
#: ~100 kB are reused by the allocator; larger ones cost page faults (3-5x slower here)
_BLOCK_ENTRIES = 12_000
_CACHE_ENTRIES = 12_000


def magnus4_omega(A1: FloatArray, A2: FloatArray, h: float | FloatArray) -> FloatArray:
    """The fourth-order Magnus generator of steps of length ``h`` [s] (dimensionless).

    Omega = h/2 (A_1 + A_2) + sqrt(3) h^2 / 12 [A_2, A_1], with ``A1``, ``A2`` the state
    matrices [1/s] at the Gauss nodes t + GAUSS_NODES * h, stacks of shape (..., N, N);
    ``h`` is a number or an array of the leading shape (...).
    """
    hh = np.asarray(h, dtype=float)[..., None, None]
    return np.asarray(0.5 * hh * (A1 + A2) + (COMMUTATOR_FACTOR * hh * hh) * (A2 @ A1 - A1 @ A2))


def expm_stack(X: FloatArray) -> FloatArray:
    """exp(X_k) for a stack ``X`` of shape (..., N, N), by scaling and squaring.

    exp(X) = (T_18(X / 2^s))^(2^s) with T_18 the degree-18 Taylor polynomial, evaluated by
    Paterson-Stockmeyer (7 matrix products), and s chosen per matrix so |X/2^s|_1 <= 1:
    the truncation error is then below 1/19! e < 1e-16 relative.  Every operation is a
    batched matrix product (numpy matmul over the stack); leading dimensions are flattened.
    """
    X = np.asarray(X, dtype=float)
    shape = X.shape
    X = X.reshape(-1, shape[-2], shape[-1])
    if X.shape[0] == 0:
        return X.reshape(shape).copy()
    # small blocks keep the temporaries in cache (large temporaries cost page faults)
    block_size = max(1, _CACHE_ENTRIES // (X.shape[-1] ** 2))
    if X.shape[0] > block_size:
        out = np.empty_like(X)
        for b in range(0, X.shape[0], block_size):
            out[b : b + block_size] = _expm_block(X[b : b + block_size])
        return out.reshape(shape)
    return _expm_block(X).reshape(shape)


#: Taylor coefficients 1/j! arranged for Paterson-Stockmeyer with p = 4: row i holds the
#: coefficients of Y^1, Y^2, Y^3 in block i (degrees 4i .. 4i+3), _PS_DIAG the Y^0 ones
_FACT = [1.0 / math.factorial(j) for j in range(TAYLOR_DEGREE + 4)]
_PS_COEF = np.array(
    [[_FACT[4 * i + k] if 4 * i + k <= TAYLOR_DEGREE else 0.0 for k in (1, 2, 3)] for i in range(5)]
)
_PS_DIAG = np.array([_FACT[4 * i] for i in range(5)])


def _expm_block(X: FloatArray) -> FloatArray:
    norms = np.sum(np.abs(X), axis=-2).max(axis=-1)
    if not np.all(np.isfinite(norms)):
        return np.full_like(X, np.nan)
    # per-matrix scaling: over-scaling a small matrix would only amplify rounding
    with np.errstate(divide="ignore"):
        scal = np.ceil(np.log2(np.maximum(norms, 1e-300) / TAYLOR_THETA))
    scal = np.maximum(scal, 0).astype(np.int64)
    s = int(scal.max())
    K, n, _ = X.shape
    Y = X * (0.5**scal)[:, None, None]
    # Paterson-Stockmeyer, p = 4: T_18(Y) = B_0 + Y^4 (B_1 + Y^4 (B_2 + Y^4 (B_3 + Y^4 B_4)))
    # with B_i = sum_k c_{4i+k} Y^k (k < 4), all five formed by one product of coefficients
    P2 = Y @ Y
    P3 = P2 @ Y
    P4 = P2 @ P2
    powers = np.stack([Y, P2, P3]).reshape(3, -1)
    flat = (_PS_COEF @ powers).reshape(5, K, n * n)
    flat[:, :, :: n + 1] += _PS_DIAG[:, None, None]
    B = flat.reshape(5, K, n, n)
    R = B[4]
    for i in (3, 2, 1, 0):
        R = R @ P4
        R += B[i]
    if np.all(scal == s):
        for _ in range(s):
            R = R @ R
        return R
    for j in range(s):
        sel = scal > j
        R[sel] = R[sel] @ R[sel]
    return R


def product_of_steps(E: FloatArray) -> FloatArray:
    """E[..., m-1, :, :] @ ... @ E[..., 0, :, :] for a stack (..., m, N, N), pairwise.

    The propagator of m consecutive steps from their step propagators (earliest first),
    in ceil(log2 m) rounds of batched products.
    """
    while E.shape[-3] > 1:
        m = E.shape[-3]
        even = m - m % 2
        paired = E[..., 1:even:2, :, :] @ E[..., 0:even:2, :, :]
        E = np.concatenate([paired, E[..., m - 1 :, :, :]], axis=-3) if m % 2 else paired
    return np.asarray(E[..., 0, :, :])


class MagnusGenerator:
    """Builds the Magnus-4 generators Omega of the (augmented) state matrix.

    A(t) = sum_i c_i(t) B_i with c = (1, v, dv/dt, v^2, w0^2[, dw0/dt]) and constant B_i
    (the balanced S_0, S_v, S_vdot, S_v2, S_w2, and f_wdot / c in the border column when
    the spin varies), so A at many times is one matrix product.
    """

    def __init__(self, model: PipeModel, loading: Loading, scale: float) -> None:
        self.model = model
        self.loading = loading
        self.forced = not loading.spin.is_constant
        self.scale = scale  # the constant c the state is augmented with [m]
        N = model.size
        self.size = N + (1 if self.forced else 0)
        pieces = model.state_pieces
        basis = np.zeros((len(pieces) + (1 if self.forced else 0), self.size, self.size))
        basis[: len(pieces), :N, :N] = pieces
        if self.forced:
            basis[-1, :N, N] = model.f_wdot / scale
        self.basis = basis.reshape(basis.shape[0], -1)

    def coefficients(self, times: FloatArray) -> FloatArray:
        c = self.loading.coefficients(times)
        w = c.weights()
        return np.concatenate([w, c.wdot[:, None]], axis=1) if self.forced else w

    def matrices(self, times: FloatArray) -> FloatArray:
        """A(t) at ``times``: S(t), bordered by f(t)/c when the spin varies [1/s]."""
        return (self.coefficients(times) @ self.basis).reshape(times.size, self.size, self.size)

    def omega(self, starts: FloatArray, h: FloatArray) -> FloatArray:
        """Omega for steps [starts, starts + h] (arrays of equal length) [-]."""
        k = starts.size
        A = self.matrices(np.concatenate([starts + g * h for g in GAUSS_NODES]))
        return magnus4_omega(A[:k], A[k:], h)

    def propagators(self, starts: FloatArray, h: FloatArray) -> FloatArray:
        return expm_stack(self.omega(starts, h))


def coarse_grid(t: FloatArray, substeps: NDArray[np.int64]) -> tuple[NDArray[np.int64], Any]:
    """Every other output time (and the last) and sub-steps giving twice the step there."""
    K = t.size - 1
    idx = np.arange(0, K + 1, 2)
    if idx[-1] != K:
        idx = np.append(idx, K)
    pairs = substeps[: 2 * (K // 2)].reshape(-1, 2).sum(axis=1)
    coarse = np.maximum(1, np.round(pairs / 2.0)).astype(np.int64)
    if K % 2:
        coarse = np.append(coarse, max(1, int(substeps[-1]) // 2))
    return idx, coarse


class Magnus(Solver):
    name: ClassVar[str] = "magnus"
    description: ClassVar[str] = (
        "4th-order Magnus (two Gauss points, one commutator) on steps chosen for "
        "options.tolerance: accurate for time-variant flow and spin; exact for constant."
    )
    option_names: ClassVar[tuple[str, ...]] = ("step", "max_steps", "tolerance")
    estimates_own_error: ClassVar[bool] = True
    error_advice: ClassVar[str] = "use a smaller tolerance or step"

    def _solve_impl(self, problem: Problem, stats: SolverStats) -> SolverOutput:
        loading, t = problem.loading, problem.t
        opts = problem.options
        dt = np.diff(t)
        t_end = float(t[-1])
        N = problem.model.size
        scale = float(np.linalg.norm(problem.z0)) or 1.0
        gen = MagnusGenerator(problem.model, loading, scale)
        invariant = loading.is_time_invariant
        uniform = bool(np.allclose(dt, dt[0], rtol=1e-9, atol=0.0))
        budget = step_budget(opts)
        step = given_step(opts)
        if step is not None:
            h0 = step
        else:
            if not (0 < opts.tolerance < 1):
                raise InvalidInput("tolerance must be in (0, 1)", parameter="tolerance")
            h0 = t_end / PILOT_STEPS
        # bounded in floating point before the cast; the error check's run with twice the
        # step takes half as many again, so the first run gets 2/3 of the budget
        first = budget if invariant else (2 * budget) // 3
        substeps = step_counts(dt, h0, first, "magnus", step is not None)
        if dt.size == 1 and not invariant:
            substeps = np.maximum(substeps, 2)  # the check needs a coarser run to compare with
        warnings: list[str] = []
        exps = 0
        attempts = 0
        estimate = 0.0
        previous: tuple[NDArray[np.int64], FloatArray] | None = None
        while True:
            attempts += 1
            n_steps = int(substeps.sum())
            self._check_budget(n_steps, budget, dt, substeps, opts.tolerance)
            Zaug, used = self._propagate(problem, gen, t, substeps)
            exps += used
            if invariant:
                break
            # Richardson-type check against the same method with twice the step
            idx, coarse = coarse_grid(t, substeps)
            if previous is not None and uniform and np.array_equal(substeps, 2 * previous[0]):
                Zc = previous[1][idx]  # the previous attempt took exactly twice this step
            else:
                self._check_budget(
                    n_steps + int(coarse.sum()), budget, dt, substeps, opts.tolerance
                )
                Zc, used = self._propagate(problem, gen, t[idx], coarse)
                exps += used
            estimate = relative_difference(Zc, Zaug[idx], N) / RICHARDSON_DIVISOR
            if opts.step is not None or estimate <= opts.tolerance:
                break
            if attempts >= MAX_ATTEMPTS or not math.isfinite(estimate):
                warnings.append(
                    f"magnus could not verify the tolerance {opts.tolerance:.3g}: estimated "
                    f"relative error {estimate:.3g} after {attempts} attempts"
                )
                break
            # global error ~ h^4: shrink the step to reach SAFETY * tolerance
            factor = (estimate / (SAFETY * opts.tolerance)) ** 0.25
            # bounded before the cast: a count beyond the budget is refused just below
            wanted = np.minimum(np.ceil(substeps * factor), budget + 1.0).astype(np.int64)
            previous = (substeps, Zaug)
            substeps = np.where(wanted <= 2 * substeps, 2 * substeps, wanted)
        Z = Zaug[:, :N].copy()
        h_used = dt / substeps
        stats.steps, stats.attempts, stats.matrix_exponentials = n_steps, attempts, exps
        diagnostics: dict[str, Any] = {
            "time_invariant": invariant,
            "step_source": "step" if opts.step is not None else "tolerance",
            "step_max": float(h_used.max()),
            "step_min": float(h_used.min()),
            "tolerance": opts.tolerance,
            "estimated_relative_error": estimate,
            "error_estimate_method": (
                "exact for constant coefficients (rounding only)"
                if invariant
                else f"difference from a run with twice the step, divided by {RICHARDSON_DIVISOR:g}"
            ),
        }
        return SolverOutput(z=Z, diagnostics=diagnostics, warnings=warnings)

    @staticmethod
    def _check_budget(
        n_steps: int, budget: int, dt: FloatArray, substeps: NDArray[np.int64], tol: float
    ) -> None:
        if n_steps > budget:
            raise BudgetExceeded(
                f"magnus needs {n_steps} steps of {float(np.max(dt / substeps)):.3g} s for "
                f"this run (tolerance {tol:.3g}, including the error check), above the step "
                f"budget of {budget}; raise max_steps, loosen the tolerance or "
                "use fewer modes",
                parameter="max_steps",
            )

    def _propagate(
        self, problem: Problem, gen: MagnusGenerator, t: FloatArray, substeps: NDArray[np.int64]
    ) -> tuple[FloatArray, int]:
        """Augmented states at the times ``t`` [s], and the number of exponentials used."""
        Zaug = np.empty((t.size, gen.size))
        z = problem.z0.astype(float)
        if gen.forced:
            z = np.append(z, gen.scale)
        Zaug[0] = z
        dt = np.diff(t)
        if problem.loading.is_time_invariant:
            # exact: one exponential per distinct interval length (one for a uniform grid)
            if np.allclose(dt, dt[0], rtol=1e-12, atol=0.0):
                lengths, inverse = dt[:1], np.zeros(dt.size, dtype=np.int64)
            else:
                lengths, inverse = np.unique(dt, return_inverse=True)
            E = gen.propagators(np.zeros(lengths.size), lengths.astype(float))
            for k in range(dt.size):
                z = E[inverse[k]] @ z
                Zaug[k + 1] = z
            return Zaug, int(lengths.size)
        per = gen.size * gen.size
        exps = 0
        k = 0
        while k < dt.size:
            # a block of output intervals with equal sub-step counts, sized to stay in cache
            m = int(substeps[k])
            limit = max(1, _BLOCK_ENTRIES // (per * m))
            stop = k + 1
            while stop < dt.size and stop - k < limit and substeps[stop] == m:
                stop += 1
            idx = np.arange(k, stop)
            h = dt[idx] / m
            starts = (t[idx][:, None] + h[:, None] * np.arange(m)[None, :]).ravel()
            E = gen.propagators(starts, np.repeat(h, m))
            exps += E.shape[0]
            E = product_of_steps(E.reshape(idx.size, m, gen.size, gen.size))
            for j in range(idx.size):
                z = E[j] @ z
                Zaug[k + j + 1] = z
            k = stop
            problem.report(k / dt.size)
        return Zaug, exps


register(Magnus())
