"""Magnus propagation of orders 4 and 6: the paper's CMA applied on short intervals.

On each step [t, t + h] the propagator of z' = S(t) z + f(t) is exp(Omega) with a
Gauss-Legendre Magnus generator (Blanes, Casas, Oteo & Ros, Physics Reports 470 (2009),
section 5.2; Blanes, Casas & Ros, BIT 40 (2000) 434-450):

- order 4, two nodes A_1, A_2 = A(t + (1/2 -+ sqrt(3)/6) h)::

      Omega4 = h/2 (A_1 + A_2) + sqrt(3) h^2 / 12 [A_2, A_1]              (one commutator)

- order 6, three nodes A_1, A_2, A_3 = A(t + (1/2 - sqrt(15)/10, 1/2, 1/2 + sqrt(15)/10) h)::

      a1 = h A_2,  a2 = sqrt(15) h / 3 (A_3 - A_1),  a3 = 10 h / 3 (A_3 - 2 A_2 + A_1)
      C1 = [a1, a2],  C2 = -1/60 [a1, 2 a3 + C1]
      Omega6 = a1 + a3 / 12 + 1/240 [-20 a1 - a3 + C1, a2 + C2]           (three commutators)

which are O(h^5) and O(h^7) locally.  Without external loads ``A`` is the state matrix
augmented with the forcing of a varying spin: the state is extended by a constant c
(= |z0|), so the affine system becomes the linear one (z, c)' = [[S, f/c], [0, 0]] (z, c)
and the same exponential carries the Duhamel term.  With external loads the forcing is not
put in that border column (its commutators carry A (f(t_2) - f(t_1)), of size
h |xi_max| h |f'|, which made the steps follow h |xi_max| instead of the physics: 20-80x
the unforced steps): each step is an exponential-integrator step (:func:`forced_omega`),
the total forcing interpolated by a polynomial at Gauss nodes and the polynomial's
monomials added to the state as a nilpotent Jordan block, whose bordered Magnus generator
[[Omega, Y], [0, J]] sees the forcing only through A's variation; one exponential of size
N + 4 (order 4) per step, cut to the affine step [[P, r], [0, 1]].  For constant
coefficients Omega = h S exactly, so the method is exact to rounding (one exponential for a
uniform output grid).

Order per interval.  At :data:`LOCAL_SAMPLES` times the local errors of one step of each
order are compared by step doubling (|E_h - E_h/2 E_h/2|_1 / (1 - 2^-p) for order p), but
only where h |A|_1 <= :data:`ORDER6_NORM`: order 6 is used around a sample where its local
error is below 1/:data:`ORDER6_GAIN` of order 4's, order 4 elsewhere.  While h |xi_max| >> 1
(the paper's 10 modes at 2001 samples: h |A|_1 ~ 42) the Magnus series has not converged,
order 6's extra terms are larger than order 4's error (its local error is ~20x order 4's
there) and order 4 is used; with few modes or tight tolerances order 6 takes over where the
coefficients vary fast.

Error estimate and step control (``Options.tolerance``, relative global error of the
state).  The run is compared with one of twice the step on every other output time (the
same orders): estimate = max_k |Z_h(t_k) - Z_2h(t_k)| / max_k |Z_h(t_k)| / 4, conservative
for order 4 (ratio err(2h)/err(h) = 16) and more so for order 6; while h |xi_max| > pi the
observed ratio is 5-15 and the estimate is within a factor ~2.  Above the tolerance, every
interval's sub-step count is multiplied by (estimate / (SAFETY tolerance))^(1/rate), with
the rate log2(d2/d1) observed against a third run with four times the step (clipped to
[log2 5, order]): not halving over the whole run, and not the h^4 law where the error falls
slower (h |xi_max| > pi) or faster (the transition to the asymptotic regime).  A refined
attempt is checked against the previous attempt (no fresh run with twice the step): the
difference over ratio^2 - 1 (:data:`REFINED_FLOOR_RATE`: the error of a refinement is
assumed to fall at least like h^2; with log2 5, the first check's rate, the paper example
forced from rest reported 6.9e-9 for a true 7.2e-9).  Pulsating flow v = 2 + sin 50 t on the
paper example: 33,500 exponentials before, 23,500 now, for the same 20,000 steps.  Local
error control proper (per-step estimates) was tried and measured: on these oscillatory
systems the local errors of successive steps cancel, so their sum over-predicts the global
error ~50x (v = 0.4 t, 2001 steps: local 2e-10 per step, global 7e-9) and over-resolves
more than the global comparison does.

A step never crosses a time the control runs on.  On a sparse output grid those are the
output times: reaching an output inside a longer step would cost one exponential (of the
partial step) anyway, so the run takes at least one step per output interval.

Dense output (a uniform grid of more than :data:`DENSE_STEPS` intervals, no user step,
coefficients varying in time): the steps are decoupled from the samples.  The control runs
on a coarse subset of the output times (:func:`dense_selection`: every m-th sample and the
last, coarse intervals of at most min(pilot step, t_end / DENSE_STEPS), the step the
paper's 2,001-sample example meets 1e-8 with at its first attempt); a refinement splits
coarse intervals at samples (:func:`dense_refine`) instead of adding sub-steps, so a coarse
interval that spans several samples is always one Magnus step.  The samples inside are
then filled from the coarse state at its left end (:func:`dense_fill`), never accumulated
across coarse intervals: sample to sample by Magnus-4 steps of the sample spacing d, whose
propagator varies smoothly with the sample index j, so it is taken as a polynomial in j
through exact exponentials of sample steps at nodes (linear: the steps centred on the
two coarse times, each shared by two coarse intervals) and each sample costs two
matrix-vector products, batched over the coarse intervals; the neglected terms are second
order in the exponent's variation over the interval.  The fill's own error is measured on
about :data:`LOCAL_SAMPLES` coarse intervals against a march of exact sixth-order Magnus
exponentials of the sample steps and added to the estimate; where it exceeds
:data:`FILL_SHARE` of the tolerance (or what the coarse estimate leaves of it) the fill is
redone with a quadratic polynomial, then with one exact exponential per sample (a low-norm
one), batched over the coarse intervals.  A checkpoint (:class:`MagnusCheckpoints`) holds
the control's propagations on the coarse times; a resumed run fills again after them (the
fill is not checkpointed: a fraction of the run, with no long sequential chain).

All exponentials of a block of steps are computed at once
(:func:`~pipeflow.linalg.expm_stack`, scaling and squaring of a Taylor polynomial with
batched matrix products); only the final propagation is sequential, one matrix-vector
product per output interval: interval k gets m_k equal sub-steps, and their exponentials
are multiplied together (batched, pairwise: :func:`~pipeflow.linalg.product_of_steps`)
before they touch the state.

The building blocks (:data:`~pipeflow.linalg.GAUSS_NODES`,
:func:`~pipeflow.linalg.magnus4_omega`, :func:`~pipeflow.linalg.magnus6_omega`,
:func:`~pipeflow.linalg.expm_stack`, :func:`~pipeflow.linalg.product_of_steps`) live in
:mod:`pipeflow.linalg`, shared with the Floquet analysis (:mod:`pipeflow.stability.floquet`),
which propagates Z' = S(t) Z over a period.
"""

from __future__ import annotations

import math
from collections.abc import Generator
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np
from numpy.typing import NDArray

from pipeflow._types import FloatArray
from pipeflow.errors import BudgetExceeded, InvalidInput
from pipeflow.linalg import (
    COMMUTATOR_FACTOR,
    GAUSS3_NODES,
    GAUSS_NODES,
    expm_stack,
    magnus4_omega,
    magnus6_omega,
    product_of_steps,
)
from pipeflow.loads import ExternalForcing
from pipeflow.model import Loading, PipeModel
from pipeflow.parallel import charge
from pipeflow.solvers.base import (
    Problem,
    Solver,
    SolverOutput,
    SolverStats,
    given_step,
    relative_difference,
    step_budget,
    step_counts,
)
from pipeflow.solvers.checkpoint import Checkpointer

#: fraction of the tolerance the steps are chosen for (the rest is margin for the estimate)
SAFETY = 0.5
#: times at which the local errors of the two orders are compared (step doubling)
LOCAL_SAMPLES = 16
#: the cost of filling one sample by the dense fill's polynomial march (two batched
#: matrix-vector products and the write), as a share of one Magnus step's
#: (:func:`step_seconds`): the paper example's 18,000 filled samples of 20,001 took
#: ~25 ms beyond the fill's 2,136 exponentials, ~1.4 us each against a step's ~15 us
FILL_SAMPLE_SHARE = 0.125
#: order 6 where its local error is below 1/ORDER6_GAIN of order 4's; it is measured only
#: where h |A|_1 <= ORDER6_NORM (beyond, order 6 is worse than order 4: at the paper's
#: 10 modes, h |A|_1 ~ 42 at 2001 samples, its local error is 20x order 4's)
ORDER6_GAIN = 4.0
ORDER6_NORM = 8.0
#: the estimate is |Z_h - Z_2h| / RICHARDSON_DIVISOR: an observed ratio err(2h)/err(h) of
#: at least 5 (order 4 gives 16, order 6 64; oscillatory modes outside h |xi| < pi less)
RICHARDSON_DIVISOR = 4.0
#: a refined attempt's estimate is its difference from the previous attempt over
#: ratio^REFINED_FLOOR_RATE - 1 (step ratio ratio): the error is assumed to fall at least
#: like h^2 between attempts (measured: 4.8x from 2,000 to 4,000 steps, forced from rest)
REFINED_FLOOR_RATE = 2.0
#: rounding allowance of the estimate per step (the unit roundoff) [-]
ROUNDING_PER_STEP = float(np.finfo(float).eps)
#: the first attempt uses at least this many steps over the run
PILOT_STEPS = 256
#: attempts at meeting the tolerance (each refines the steps from the previous estimate)
MAX_ATTEMPTS = 4
#: matrix entries per block of steps: temporaries under ~100 kB are reused by the
#: allocator; larger ones cost page faults (3-5x slower here)
_BLOCK_ENTRIES = 12_000
#: output intervals whose propagators are formed before they are applied (bounds memory)
_WINDOW = 256
#: dense output: a uniform grid whose intervals are at most half of min(pilot step,
#: t_end / DENSE_STEPS) runs the control on coarse intervals of at most that length, a
#: whole number of samples (the paper's example, 10 modes at w0 = 100 rad/s, meets 1e-8
#: with 2,000 steps at its first attempt, its 2,001-sample run; with 2,223 steps its
#: estimate was above 1e-8 and it refined to 6,670; the 256-step pilot on 257 output
#: times refined to 11,000) [-]
DENSE_STEPS = 2000
#: share of the tolerance the fill's own measured error may take (less where the coarse
#: estimate leaves less) before the fill is redone by the next, costlier form [-]
FILL_SHARE = 0.1
#: the fill's estimate is its largest measured difference times this: the intervals not
#: checked may do a little worse than the checked ones, and the reference march has its
#: own error (measured against a converged run, 4 modes, 20,001 samples over 0.2 s, a tip
#: force: the largest error at a sample 1.00x the largest checked difference with the
#: checked intervals chosen as in :func:`dense_fill`; with an earlier fill on the
#: pulsating flow, 2.3x when they were only spread over the run) [-]
FILL_MARGIN = 1.5
#: matrix entries of the step exponentials one batch of a checking march holds [-]
_MARCH_ENTRIES = 1_000_000


class MagnusGenerator:
    """Builds the Magnus generators Omega (orders 4 and 6) of the (augmented) state matrix.

    A(t) = sum_i c_i(t) B_i with c = (1, v, dv/dt, v^2, w0^2[, dw0/dt][, p_1 .. p_K]) and
    constant B_i (the balanced S_0, S_v, S_vdot, S_v2, S_w2, and in the border column
    f_wdot / c when the spin varies and g_k / c for the external loads p_k(t),
    :class:`pipeflow.loads.ExternalForcing`), so A at many times is one matrix product.
    The border column's time function is the total forcing f(t)/c: the Magnus generator,
    the order choice and the error control (on the state z) cover it like S(t).
    """

    def __init__(
        self,
        model: PipeModel,
        loading: Loading,
        scale: float,
        loads: ExternalForcing | None = None,
    ) -> None:
        self.model = model
        self.loading = loading
        self.loads = loads
        self.spin_forced = not loading.spin.is_constant
        self.forced = self.spin_forced or loads is not None
        #: with external loads the forcing is integrated by the exponential-integrator step
        #: (a polynomial on each step, a Jordan block in the exponential), not as a border
        #: column of the Magnus generator
        self.jordan = loads is not None
        #: A(t) constant: constant coefficients and no load varying in time
        self.invariant = loading.is_time_invariant and (loads is None or loads.is_constant)
        self.scale = scale  # the constant c the state is augmented with [m]
        N = model.size
        self.size = N + (1 if self.forced else 0)
        pieces = model.state_pieces
        if self.jordan:
            self.basis = pieces.reshape(pieces.shape[0], -1)
            return
        extra = 1 if self.spin_forced else 0
        basis = np.zeros((len(pieces) + extra, self.size, self.size))
        basis[: len(pieces), :N, :N] = pieces
        if self.spin_forced:
            basis[len(pieces), :N, N] = model.f_wdot / scale
        self.basis = basis.reshape(basis.shape[0], -1)
        # order 4 without loads: A = sum_i c_i B_i makes the commutator bilinear,
        # [A_2, A_1] = sum_{i<j} (c2_i c1_j - c2_j c1_i) [B_i, B_j], so Omega4 of many steps
        # is one product of their (P + P(P-1)/2) coefficients with the pieces and the
        # pieces' commutators (no A at the nodes, no batched 20 x 20 products)
        self._pairs = np.triu_indices(basis.shape[0], 1)
        Bi, Bj = basis[self._pairs[0]], basis[self._pairs[1]]
        commutators = (Bi @ Bj - Bj @ Bi).reshape(Bi.shape[0], -1)
        self._omega4_basis = np.concatenate([self.basis, commutators])

    @property
    def exponent_size(self) -> int:
        """Size of the matrices exponentiated (the largest order's, with loads)."""
        return self.model.size + FORCING_NODES[6] if self.jordan else self.size

    def coefficients(self, times: FloatArray) -> FloatArray:
        c = self.loading.coefficients(times)
        w = c.weights()
        if self.jordan:
            return w
        return np.concatenate([w, c.wdot[:, None]], axis=1) if self.forced else w

    def matrices(self, times: FloatArray) -> FloatArray:
        """A(t) at ``times``: S(t), bordered by f(t)/c when the spin varies and there are
        no loads [1/s]; S(t) alone with loads (their forcing: :meth:`forcing`)."""
        n = self.model.size if self.jordan else self.size
        return (self.coefficients(times) @ self.basis).reshape(times.size, n, n)

    def forcing(self, times: FloatArray) -> FloatArray:
        """The total forcing f(t) / c at ``times`` (spin-up and loads), shape (k, N) [1/s]."""
        assert self.loads is not None
        f = self.loads.vector(times)
        if self.spin_forced:
            wdot = self.loading.coefficients(times).wdot
            f = f + wdot[:, None] * self.model.f_wdot[None]
        return np.asarray(f / self.scale)

    def node_weights(self, starts: FloatArray, h: FloatArray, order: int = 4) -> FloatArray:
        """The coefficient rows (:meth:`coefficients`) at the Gauss nodes of ``order``'s
        generator for steps [starts, starts + h], shape (nodes, steps, coefficients): computed
        once for many steps, sliced per block of steps (:meth:`omega`'s ``weights``)."""
        nodes = GAUSS_NODES if order == 4 else GAUSS3_NODES
        w = self.coefficients(np.concatenate([starts + g * h for g in nodes]))
        return w.reshape(len(nodes), starts.size, w.shape[-1])

    def omega4_coefficients(self, h: FloatArray, weights: FloatArray) -> FloatArray:
        """The rows of Omega4 on the pieces and their commutators (order 4 without loads):
        Omega4 = h/2 (A_1 + A_2) + sqrt(3)/12 h^2 [A_2, A_1] = c @ (pieces, [B_i, B_j]),
        for steps of lengths ``h`` [s] whose :meth:`node_weights` are ``weights``; shape
        (steps, P + P(P-1)/2) [-].  Computed once for many steps and sliced per block of
        steps (:meth:`omega`'s ``coefficients``)."""
        w1, w2 = weights[0], weights[1]
        hh = np.broadcast_to(np.asarray(h, dtype=float), (w1.shape[0],))[:, None]
        i, j = self._pairs
        return np.concatenate(
            [
                (0.5 * hh) * (w1 + w2),
                (COMMUTATOR_FACTOR * hh * hh) * (w2[:, i] * w1[:, j] - w2[:, j] * w1[:, i]),
            ],
            axis=1,
        )

    def omega(
        self,
        starts: FloatArray,
        h: FloatArray,
        order: int = 4,
        weights: FloatArray | None = None,
        coefficients: FloatArray | None = None,
    ) -> FloatArray:
        """Omega of ``order`` (4 or 6) for steps [starts, starts + h] (equal lengths) [-];
        ``weights``: their :meth:`node_weights`, when already computed; ``coefficients``:
        their :meth:`omega4_coefficients` (order 4 without loads), when already computed.

        With loads, the generator of the step's exponential-integrator form
        (:func:`forced_omega`), of size N + FORCING_NODES[order]."""
        k = starts.size
        n = self.model.size if self.jordan else self.size
        if order == 4 and not self.jordan:
            if coefficients is None:
                if weights is None:
                    weights = self.node_weights(starts, h, order)
                coefficients = self.omega4_coefficients(h, weights)
            return np.asarray(coefficients @ self._omega4_basis).reshape(k, n, n)
        if weights is None:
            weights = self.node_weights(starts, h, order)
        A = (weights.reshape(-1, weights.shape[-1]) @ self.basis).reshape(-1, n, n)
        if self.jordan:
            return forced_omega(self, A, starts, h, order)
        if order == 4:
            return magnus4_omega(A[:k], A[k:], h)
        return np.asarray(magnus6_omega(A[:k], A[k : 2 * k], A[2 * k :], h))

    def propagators(self, omega: FloatArray) -> FloatArray:
        """exp(Omega) of each step's generator (:meth:`omega`); with loads the affine step
        [[P, r], [0, 1]] (size N + 1) cut from the exponential of the Jordan-bordered
        generator."""
        if not self.jordan:
            return expm_stack(omega)
        # exp([[Omega, Y], [0, J]]) restricted to (z, w_0): [[P, r], [0, 1]] (exp(J) is
        # lower triangular with unit diagonal, and w(0) = e_0)
        N = self.model.size
        E = expm_stack(omega)
        return np.ascontiguousarray(E[:, : N + 1, : N + 1])

    def local_errors(self, starts: FloatArray, h: FloatArray, order: int) -> FloatArray:
        """Local error of one step of ``order`` from each start, relative (1-norm) [-].

        Step doubling: |E_h - E_h/2 E_h/2|_1 / |E_h|_1, divided by 1 - 2^-order (the two
        half steps carry 2^-order of the one step's leading error term).
        """
        k = starts.size
        E = self.propagators(
            self.omega(
                np.concatenate([starts, starts, starts + h / 2]),
                np.concatenate([h, h / 2, h / 2]),
                order,
            )
        )
        full, two = E[:k], E[2 * k :] @ E[k : 2 * k]
        with np.errstate(all="ignore"):
            diff = np.abs(full - two).sum(axis=-2).max(axis=-1)
            size = np.abs(full).sum(axis=-2).max(axis=-1)
            err = diff / size / (1.0 - 2.0**-order)
        return np.where(np.isfinite(err), err, np.inf)


def _forcing_basis(count: int) -> tuple[FloatArray, FloatArray]:
    """Gauss-Legendre nodes (``count`` of them, fractions of the step) and the matrix that
    takes the forcing at them to the coefficients c_j of its interpolation polynomial
    sum_j c_j tau^j / j! (tau = s / h in [0, 1])."""
    x, _ = np.polynomial.legendre.leggauss(count)
    tau = 0.5 * (x + 1.0)
    V = tau[:, None] ** np.arange(count)[None, :] / np.array(
        [math.factorial(j) for j in range(count)]
    )
    return tau, np.linalg.inv(V)


#: forcing nodes per Magnus order: as many as the order (degree order - 1, local error
#: O(h^(order+1)) like the Magnus step's).  Measured on the paper example with a 700 rad/s
#: tip force from rest: 2,000 steps give 2.7e-8 with 4 nodes, 1.3e-8 with 5 or 6 (the
#: Magnus part's); both refine to 4,000 steps (7.2e-9), where 4 nodes' estimate is the
#: more faithful (6.9e-9 against 2.4e-9) and its exponentials (size N + 4) the cheaper
FORCING_NODES = {4: 4, 6: 6}
#: per node count: the nodes and the inverse of their scaled Vandermonde matrix
FORCING_BASIS = {q: _forcing_basis(q) for q in FORCING_NODES.values()}


def forced_omega(
    gen: MagnusGenerator, A: FloatArray, starts: FloatArray, h: FloatArray, order: int
) -> FloatArray:
    """The generator of one exponential-integrator step of z' = A(t) z + f(t), size N + q.

    On the step, in tau = s / h, the forcing is replaced by its interpolation polynomial
    p(tau) = sum_j c_j tau^j / j! at q = :data:`FORCING_NODES` Gauss-Legendre nodes
    (degree q - 1 = order - 1: its local error O(h^(order+1)) matches the Magnus step's),
    and w_j = tau^j / j! (w' = J w, J the
    shift, w(0) = e_0) makes the system linear with a *constant* border:
    (z, w)' = [[h A(tau), h C], [0, J]] (z, w).  Its Magnus generator (the same Gauss
    nodes for A) is [[Omega, Y], [0, J]] with Omega the homogeneous one and, at order 4,
    Y = h C + sqrt(3)/12 h^2 (A_2 - A_1) C: the commutators see the forcing only through
    A's variation (A_2 - A_1), never through A times f's variation, which in the border
    column form made the steps follow h |xi_max| (Al-Mohy & Higham 2011, Saad 1992 for the
    phi-function trick: the exponential of the bordered matrix carries the integral of
    exp((1 - tau) Omega) p(tau)).  ``A`` are the state matrices at the Magnus nodes
    (stacked node-major), ``h`` the step lengths; the state's constant c is in C.
    """
    k, N = starts.size, gen.model.size
    q = FORCING_NODES[order]
    tau, Vinv = FORCING_BASIS[q]
    F = gen.forcing(np.concatenate([starts + g * h for g in tau])).reshape(q, k, N)
    C = (Vinv @ F.reshape(q, k * N)).reshape(q, k, N).transpose(1, 2, 0)  # (k, N, q)
    hh = np.asarray(h, dtype=float)[:, None, None]
    out = np.zeros((k, N + q, N + q))
    out[:, N + 1 :, N : N + q - 1] = np.eye(q - 1)  # J: w_j' = w_{j-1}
    if order == 4:
        A1, A2 = A[:k], A[k:]
        out[:, :N, :N] = magnus4_omega(A1, A2, h)
        out[:, :N, N:] = hh * C + (COMMUTATOR_FACTOR * hh * hh) * ((A2 - A1) @ C)
        return out
    # order 6: the generic three-node generator of the bordered matrices (tau units)
    Ab = np.repeat(out[None], 3, axis=0)
    Ab[:, :, :N, :N] = hh[None] * A.reshape(3, k, N, N)
    Ab[:, :, :N, N:] = hh[None] * C[None]
    return np.asarray(magnus6_omega(Ab[0], Ab[1], Ab[2], 1.0))


def observed_rate(d1: float, Zc: FloatArray, Zcc: FloatArray, size: int, order: int) -> float:
    """Observed convergence rate log2(d2 / d1) [-], with d1 = |Z - Zc| of runs with the
    step and twice the step, and d2 = |Zc - Zcc| with four times the step (relative, max
    over time), clipped to [log2(RICHARDSON_DIVISOR + 1), order]: order 4 gives 4 in the
    asymptotic regime, while h |xi_max| > pi it is lower."""
    d2 = relative_difference(Zcc, Zc, size)
    r = d2 / d1 if d1 > 0 else math.inf
    r = min(max(r, RICHARDSON_DIVISOR + 1.0), 2.0**order) if math.isfinite(r) else 2.0**order
    return math.log2(r)


class StepPlan:
    """Sub-steps and order per output interval: ``substeps[k]`` equal steps of
    ``order[k]`` (4 or 6) span output interval k."""

    def __init__(self, substeps: NDArray[np.int64], order: NDArray[np.int64]) -> None:
        self.substeps = substeps
        self.order = order

    @property
    def steps(self) -> int:
        return int(self.substeps.sum())

    def coarse(self, t: FloatArray) -> tuple[NDArray[np.int64], StepPlan]:
        """Every other output time (and the last) and the plan with twice the step there."""
        K = t.size - 1
        idx = np.arange(0, K + 1, 2)
        if idx[-1] != K:
            idx = np.append(idx, K)
        pairs = self.substeps[: 2 * (K // 2)].reshape(-1, 2).sum(axis=1)
        coarse = np.maximum(1, np.round(pairs / 2.0)).astype(np.int64)
        order = self.order[: 2 * (K // 2) : 2]
        if K % 2:
            coarse = np.append(coarse, max(1, int(self.substeps[-1]) // 2))
            order = np.append(order, self.order[-1])
        return idx, StepPlan(coarse, order)


def choose_orders(
    gen: MagnusGenerator, t: FloatArray, substeps: NDArray[np.int64]
) -> tuple[NDArray[np.int64], int]:
    """Order (4 or 6) per output interval for the given sub-steps, and the exponentials
    this cost.

    At :data:`LOCAL_SAMPLES` times the local error of one step of each order is measured
    by step doubling (:meth:`MagnusGenerator.local_errors`); order 6 is used around a
    sample where its local error is below 1/ORDER6_GAIN of order 4's (there its extra
    commutators pay for themselves), order 4 elsewhere.  While h |xi_max| >> 1 (the paper's
    10 modes at 2001 samples: h |xi_max| ~ 37) the Magnus series has not converged, the
    sixth-order terms are larger than the fourth-order ones and order 4 is chosen.
    """
    dt = np.diff(t)
    K = dt.size
    n_s = min(K, LOCAL_SAMPLES)
    owner = np.minimum(np.arange(K) * n_s // K, n_s - 1)
    first = np.searchsorted(owner, np.arange(n_s))  # an interval of each sample
    h = dt[first] / substeps[first]
    starts = t[first] + 0.5 * (dt[first] - h)  # one step in the middle of the interval
    A = gen.matrices(starts + 0.5 * h)
    # only where h |A|_1 is small can the series have converged far enough for order 6
    near = np.flatnonzero(h * np.abs(A).sum(axis=-2).max(axis=-1) <= ORDER6_NORM)
    six = np.zeros(n_s, dtype=bool)
    if near.size:
        e4 = gen.local_errors(starts[near], h[near], 4)
        e6 = gen.local_errors(starts[near], h[near], 6)
        six[near] = np.isfinite(e6) & (e6 * ORDER6_GAIN < e4)
    return np.where(six[owner], 6, 4).astype(np.int64), 6 * int(near.size)


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
        :mod:`pipeflow.solvers.magnus_stack` drives the same control over many problems)."""
        control = step_control(problem, stats)
        resume = MagnusCheckpoints(problem)
        run = next(control)
        try:
            # a resume replays the deterministic control with the stored answers
            for answer in resume.answers:
                run = control.send(answer)
            while True:
                answer = propagate(problem, run.gen, run.t, run.plan, resume)
                resume.answered(answer)
                run = control.send(answer)
        except StopIteration as stop:
            out: SolverOutput = stop.value
            out.diagnostics.update(resume.diagnostics())
            return out

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


#: estimated cost of one step of :func:`propagate` (its exponential, generator and share of
#: the products) on one core of the 2-core reference machine, fixed + per size^2.5 of the
#: exponent [s]: measured 5.0, 6.5, 12.5, 66, 190 and 362 us at sizes 6, 10, 20, 40, 60, 80
#: (the paper's example at 3-40 modes, 3,000 exponentials each; this gives 4.5, 6.0, 15.3,
#: 68, 180 and 365 us).  What :func:`~pipeflow.parallel.charge` is told before a propagation
STEP_FIXED_S = 4e-6
STEP_PER_SIZE25_S = 6.3e-9


def step_seconds(size: int) -> float:
    """Estimated run time of one Magnus step whose exponent is ``size`` x ``size`` [s]."""
    return STEP_FIXED_S + STEP_PER_SIZE25_S * size**2.5


def propagate(
    problem: Problem,
    gen: MagnusGenerator,
    t: FloatArray,
    plan: StepPlan,
    checkpoints: MagnusCheckpoints | None = None,
) -> tuple[FloatArray, int]:
    """Augmented states at the times ``t`` [s] following ``plan``, and the exponentials used;
    ``checkpoints``: continue from its stored window, and save one after a window when due.

    A metered caller (:func:`pipeflow.parallel.metered`) is charged the plan's estimated
    cost before any of it is paid (the exact time-invariant path, one exponential, is not)."""
    if not gen.invariant:
        charge(
            plan.steps * step_seconds(gen.exponent_size),
            f"a magnus propagation of {plan.steps} steps of size {gen.exponent_size}",
        )
    Zaug = np.empty((t.size, gen.size))
    z = augmented_initial_state(problem, gen)
    Zaug[0] = z
    dt = np.diff(t)
    if gen.invariant:
        # exact: one exponential per distinct interval length (one for a uniform grid)
        if np.allclose(dt, dt[0], rtol=1e-12, atol=0.0):
            lengths, inverse = dt[:1], np.zeros(dt.size, dtype=np.int64)
        else:
            lengths, inverse = np.unique(dt, return_inverse=True)
        E = gen.propagators(gen.omega(np.zeros(lengths.size), lengths.astype(float)))
        for k in range(dt.size):
            z = E[inverse[k]] @ z
            Zaug[k + 1] = z
        return Zaug, int(lengths.size)
    substeps, orders = plan.substeps, plan.order
    # entries of one exponent (with loads: the Jordan-bordered generator), so a batch is one
    # expm_stack block
    per = gen.exponent_size**2
    exps = 0
    k = 0
    if checkpoints is not None:
        k, exps = checkpoints.resume(t, Zaug)
    while k < dt.size:
        # a window of output intervals: the propagators of its intervals are formed in
        # batches of equal sub-step count and order (sized to stay in cache), whether or
        # not those intervals are adjacent, then applied in order
        stop = min(dt.size, k + _WINDOW)
        window = np.arange(k, stop)
        E_win = np.empty((window.size, gen.size, gen.size))
        keys = substeps[window] * 16 + orders[window]
        for key in np.unique(keys):
            m, q = int(key) // 16, int(key) % 16
            members = window[keys == key]
            limit = max(1, _BLOCK_ENTRIES // (per * m))
            # every step of the group at once: start times, lengths and the coefficients at
            # their Gauss nodes (one profile evaluation per group, not per block)
            h_all = np.repeat(dt[members] / m, m)
            starts_all = t[members][:, None] + np.arange(m)[None, :] * (dt[members] / m)[:, None]
            starts_all = starts_all.ravel()
            weights = gen.node_weights(starts_all, h_all, q)
            # order 4 without loads: Omega's rows on the pieces, for the group at once
            coeffs = gen.omega4_coefficients(h_all, weights) if q == 4 and not gen.jordan else None
            for b in range(0, members.size, limit):
                idx = members[b : b + limit]
                rows = slice(b * m, (b + idx.size) * m)
                omega = gen.omega(
                    starts_all[rows],
                    h_all[rows],
                    q,
                    weights[:, rows],
                    None if coeffs is None else coeffs[rows],
                )
                E = gen.propagators(omega)
                exps += E.shape[0]
                E_win[idx - k] = product_of_steps(E.reshape(idx.size, m, gen.size, gen.size))
        # written in place, no temporary per output time; ndarray.dot (BLAS gemv, as
        # matmul) costs half of np.matmul's per-call dispatch on 20 x 20 (~0.7 vs ~1.6 us)
        for E_j, z_j, z_next in zip(E_win, Zaug[k:stop], Zaug[k + 1 : stop + 1], strict=True):
            E_j.dot(z_j, out=z_next)
        k = stop
        problem.report(k / dt.size)
        if checkpoints is not None and checkpoints.due():
            checkpoints.save(t, k, Zaug, exps)
    return Zaug, exps


def dense_selection(t: FloatArray, h0: float) -> NDArray[np.int64] | None:
    """Indices of the output times the step control runs on when ``t`` is a dense grid:
    uniform, with intervals at most half of min(``h0``, t_end / :data:`DENSE_STEPS`) [s];
    every m-th time (m the intervals of that length) and the last.  None otherwise."""
    K = t.size - 1
    d = float(t[1] - t[0])
    m = int(min(h0, float(t[-1] - t[0]) / DENSE_STEPS) / d * (1 + 1e-9))
    if m < 2 or not np.allclose(np.diff(t), d, rtol=1e-9, atol=0.0):
        return None
    sel = np.arange(0, K + 1, m)
    return sel if sel[-1] == K else np.append(sel, K)


def dense_refine(
    sel: NDArray[np.int64], counts: NDArray[np.int64]
) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """A refinement on a dense grid: coarse interval k (between output times ``sel[k]``
    and ``sel[k + 1]``) was to take ``counts[k]`` steps; it is split at output times
    into min(counts[k], its samples) nearly equal coarse intervals (one step each), or,
    where it has fewer samples than that, into all of them with equal sub-steps.  Returns
    the new coarse times (a superset of ``sel``) and the sub-steps of their intervals."""
    m = np.diff(sel)
    p = np.minimum(counts, m)
    q = np.where(counts > m, -(-counts // m), 1)
    owner = np.repeat(np.arange(m.size), p)
    i = np.arange(owner.size) - np.repeat(np.cumsum(p) - p, p)
    # round(i m / p) past the interval's start
    new = sel[owner] + (2 * i * m[owner] + p[owner]) // (2 * p[owner])
    return np.append(new, sel[-1]), np.repeat(q, p).astype(np.int64)


@dataclass
class DenseFill:
    """The dense output of :func:`dense_fill`: augmented states ``Z`` at every output
    time, the fill's own estimated relative error [-], the exponentials it took, how the
    samples were filled, and on how many coarse intervals its error was measured."""

    Z: FloatArray
    estimate: float
    exponentials: int
    method: str
    checked: int


def _march(
    gen: MagnusGenerator,
    starts: FloatArray,
    h: float,
    steps: int,
    z0: FloatArray,
    order: int = 4,
) -> FloatArray:
    """Magnus steps of ``order`` and length ``h`` [s] from each of ``starts`` [s] (exact
    exponentials, batched over the starts), from the augmented states ``z0``: the states
    after each step, shape (starts, steps, size)."""
    S, n = z0.shape
    out = np.empty((S, steps, n))
    chunk = max(1, _MARCH_ENTRIES // (S * gen.exponent_size**2))
    z = z0
    for c in range(0, steps, chunk):
        j = np.arange(c, min(steps, c + chunk))
        st = (starts[:, None] + j[None, :] * h).ravel()
        P = gen.propagators(gen.omega(st, np.full(st.size, h), order)).reshape(S, j.size, n, n)
        for i in range(j.size):
            z = np.matmul(P[:, i], z[:, :, None])[:, :, 0]
            out[:, c + i] = z
    return out


def _poly_march(C: list[FloatArray], z0: FloatArray, m: int, sigma: FloatArray) -> FloatArray:
    """A march z_{j+1} = sum_q sigma_j^q C_q z_j over j = 0 .. m - 1 for k coarse
    intervals at once: ``C`` the monomial coefficients (k, n, n) of the sample-step
    propagator in sigma, ``sigma`` (k, m) its variable at each sample step, ``z0`` (k, n)
    the augmented states at the intervals' left ends.  One batched matrix-vector product of
    size (len(C) n) x n per sample; returns the states after each step, (k, m, n)."""
    k, n = z0.shape
    G = np.concatenate(C, axis=1)  # (k, len(C) n, n)
    out = np.empty((m, k, n))  # sample-major: each step writes one contiguous block
    w = np.empty((k, len(C) * n, 1))
    z = z0
    for j in range(m):
        np.matmul(G, z[:, :, None], out=w)
        s = sigma[:, j, None]
        z = out[j]
        np.multiply(w[:, n : 2 * n, 0], s, out=z)
        z += w[:, :n, 0]
        for q in range(2, len(C)):
            z += s**q * w[:, q * n : (q + 1) * n, 0]
    return out.transpose(1, 0, 2)


#: the fills :func:`dense_fill` tries in turn: the degree of the sample-step propagator
#: as a polynomial in the sample, then (None) one exact exponential per sample step
FILL_METHODS: dict[int | None, str] = {
    1: "propagator linear in the sample",
    2: "propagator quadratic in the sample",
    None: "exponential per sample",
}


def dense_fill(
    gen: MagnusGenerator, t: FloatArray, sel: NDArray[np.int64], Zc: FloatArray, allowance: float
) -> DenseFill:
    """The augmented states at every output time ``t`` [s] (uniform, spacing d) from those
    at the coarse times ``t[sel]`` (``Zc``, one Magnus step per coarse interval of several
    samples), filled from the left end of each coarse interval (module docstring).

    Inside a coarse interval of m samples, Magnus-4 steps of length d from sample to
    sample, the step from sample j to j + 1 (j = 0 .. m - 1) with a propagator P(j) that
    is a polynomial in j through exact exponentials of sample steps at nodes: linear
    through the steps centred on the interval's two coarse times (j = -1/2 and m - 1/2;
    the first interval's left node is the step from t_0, j = 0), each shared with the
    neighbouring interval (one exponential per coarse interval, two matrix-vector
    products per sample); quadratic with the step centred between them added (one more
    exponential, one more product); then one exact exponential per sample step.  Per
    sample count m all coarse intervals at once (:func:`_poly_march`); the first fill
    whose estimated error is within ``allowance`` (relative [-]) is kept.  The
    error is measured on about :data:`LOCAL_SAMPLES` coarse intervals (spread over the
    run, those where the exponent varies most between the nodes and those where the first
    fill's march ends farthest from the next coarse state) against a march of exact
    Magnus-6 exponentials of the sample steps: the estimate is :data:`FILL_MARGIN`
    times the largest difference at a sample, relative to the largest coarse state.
    """
    n, N = gen.size, gen.model.size
    d = float(t[-1] - t[0]) / (t.size - 1)
    Z = np.empty((t.size, n))
    Z[sel] = Zc
    counts = np.diff(sel)
    scale = float(np.max(np.linalg.norm(Zc[:, :N], axis=1)))
    filled = np.flatnonzero(counts > 1)
    # the end nodes: the sample steps centred on the coarse times (from t_0 at the start)
    nodes = np.unique(np.concatenate([filled, filled + 1]))
    starts = t[sel[nodes]] - 0.5 * d
    starts[nodes == 0] = t[0]
    # a metered caller (the fast lane) is charged each stage of the fill before it is
    # paid, as :func:`propagate` charges the steps: exponentials at one step's cost, a
    # sample of the polynomial march at FILL_SAMPLE_SHARE of it
    step = step_seconds(gen.exponent_size)
    charge(
        (nodes.size + FILL_SAMPLE_SHARE * (t.size - sel.size)) * step,
        f"the dense fill of {t.size - sel.size} samples ({nodes.size} exponentials)",
    )
    omega = gen.omega(starts, np.full(starts.size, d))
    P_nodes = gen.propagators(omega)
    exps, checked, estimate = int(nodes.size), 0, 0.0
    methods: list[str] = []
    for value in np.unique(counts[filled]):
        m = int(value)
        ks = np.flatnonzero(counts == m)
        T = t[sel[ks]]
        left, right = np.searchsorted(nodes, ks), np.searchsorted(nodes, ks + 1)
        a = np.where(ks == 0, 0.0, -0.5)  # the left node's j
        mid, half = 0.5 * (a + m - 0.5), 0.5 * (m - 0.5 - a)
        sigma = (np.arange(m)[None, :] - mid[:, None]) / half[:, None]
        PL, PR = P_nodes[left], P_nodes[right]
        variation = np.einsum("kij,kij->k", *(2 * [omega[right] - omega[left]]))
        picks = np.empty(0, dtype=np.int64)
        for degree in FILL_METHODS:
            if degree == 1:
                states = _poly_march([0.5 * (PL + PR), 0.5 * (PR - PL)], Zc[ks], m, sigma)
            elif degree == 2:
                charge(ks.size * step, f"the dense fill's quadratic form ({ks.size} exponentials)")
                PM = gen.propagators(gen.omega(T + mid * d, np.full(ks.size, d)))
                exps += ks.size
                C = [PM, 0.5 * (PR - PL), 0.5 * (PR + PL) - PM]
                states = _poly_march(C, Zc[ks], m, sigma)
            else:
                charge(ks.size * m * step, f"the dense fill by {ks.size * m} exponentials")
                states = _march(gen, T, d, m, Zc[ks])
                exps += ks.size * m
            if not picks.size:
                # checked: spread over the run, where the exponent varies most, and where
                # the march ends farthest from the coarse state (its own error there, or
                # the coarse step's)
                end = np.linalg.norm(states[:, -1, :N] - Zc[ks + 1, :N], axis=-1)
                part = LOCAL_SAMPLES // 4
                spread = np.linspace(0, ks.size - 1, min(ks.size, 2 * part)).round()
                picks = np.unique(
                    np.concatenate(
                        [
                            spread.astype(np.int64),
                            np.argsort(variation)[-part:],
                            np.argsort(end)[-part:],
                        ]
                    )
                )
                charge(picks.size * (m - 1) * step, "the dense fill's check")
                ref = _march(gen, T[picks], d, m - 1, Zc[ks[picks]], 6)[..., :N]
                exps += picks.size * (m - 1)
                checked += picks.size
            states = states[:, : m - 1]
            diff = float(np.max(np.linalg.norm(states[picks, :, :N] - ref, axis=-1)))
            err = FILL_MARGIN * diff / scale if scale > 0 else (0.0 if diff == 0 else math.inf)
            if err <= allowance:
                break
        Z[sel[ks][:, None] + np.arange(1, m)[None, :]] = states
        if not err <= estimate:  # (not max(): a nan, an overflowed fill, is kept)
            estimate = err
        methods.append(FILL_METHODS[degree])
    method = ", ".join(dict.fromkeys(methods)) or "none: every sample is a coarse time"
    return DenseFill(Z, estimate, exps, method, checked)


class MagnusCheckpoints:
    """The checkpoints of one :class:`Magnus` solve (:mod:`pipeflow.solvers.checkpoint`):
    the answers of the step control's finished propagations (``answers``: replayed into
    the generator on a resume) and the current propagation's augmented states up to its
    last finished window of output intervals (:func:`propagate` continues from there)."""

    def __init__(self, problem: Problem) -> None:
        self.cp = Checkpointer("magnus", problem)
        self.answers: list[tuple[FloatArray, int]] = []
        self._start: tuple[int, FloatArray, int] | None = None
        self.resumed: dict[str, Any] = {}
        snap = self.cp.restore()
        if snap is not None:
            used = snap.header["exponentials"]
            self.answers = [(snap.arrays[f"answer{i}"], int(n)) for i, n in enumerate(used)]
            partial = snap.header["partial"]
            self._start = (int(partial["k"]), snap.arrays["partial"], int(partial["exponentials"]))

    def resume(self, t: FloatArray, Zaug: FloatArray) -> tuple[int, int]:
        """Where the current propagation (output times ``t`` [s]) starts: ``(k, exps)``, the
        output index reached and the exponentials used to get there, with ``Zaug[: k + 1]``
        filled in; ``(0, 0)`` unless it is the one the checkpoint stopped in."""
        start, self._start = self._start, None
        if start is None:
            return 0, 0
        k, prefix, exps = start
        if prefix.shape != (k + 1, Zaug.shape[1]) or k >= t.size:
            return 0, 0  # not the propagation it was written in (cannot happen: logged)
        Zaug[: k + 1] = prefix
        self.resumed = {
            "resumed_from_time": float(t[k]),
            "resumed_run": len(self.answers) + 1,
            "resumed_exponentials": exps + sum(n for _, n in self.answers),
        }
        return k, exps

    def answered(self, answer: tuple[FloatArray, int]) -> None:
        """The current propagation finished with ``answer`` (kept for the next checkpoints)."""
        if self.cp.enabled:
            self.answers.append(answer)

    def due(self) -> bool:
        return self.cp.due()

    def save(self, t: FloatArray, k: int, Zaug: FloatArray, exps: int) -> None:
        """A checkpoint in the current propagation after output ``k`` (``exps`` used)."""
        arrays = {f"answer{i}": Z for i, (Z, _) in enumerate(self.answers)}
        arrays["partial"] = Zaug[: k + 1]
        header = {
            "exponentials": [n for _, n in self.answers],
            "partial": {"k": k, "exponentials": exps, "time": float(t[k])},
        }
        self.cp.save(header, arrays)

    def diagnostics(self) -> dict[str, Any]:
        """What the result says of a resume (nothing when it did not resume): the output
        time [s] the resumed propagation continued from, its number among the step
        control's propagations (1: the first attempt, then its checks and refinements),
        and the exponentials carried over from the checkpoint instead of recomputed."""
        return dict(self.resumed)


def load_scale(problem: Problem) -> float:
    """The constant c [m] the state is augmented with when there are external loads:
    max(|z0|, |f|_max / |S_0|_1), the initial state or the size of a quasi-static forced
    response (so the border column f/c is no larger than the state matrix: the exponential's
    scaling is set by S, not by the loads, also for a start at rest, z0 = 0); 1 when both
    vanish."""
    assert problem.loads is not None
    z0 = float(np.linalg.norm(problem.z0))
    norm_s = float(np.abs(problem.model.S_0).sum(axis=0).max())
    forced = problem.loads.peak(float(problem.t[-1])) / norm_s if norm_s > 0 else 0.0
    return max(z0, forced) or 1.0


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


def step_control(problem: Problem, stats: SolverStats) -> StepControl:
    """The step control of :class:`Magnus` for one problem, as a generator: it yields each
    propagation it needs (a :class:`MagnusRun`) and is sent back the augmented states at
    the run's output times and the exponentials used; it returns the solver's output.
    One definition for the single run (:meth:`Magnus._solve_impl`, which sends
    :func:`propagate`'s answers) and the stacked runs of a study
    (:mod:`pipeflow.solvers.magnus_stack`, which propagates many problems' runs at once).

    On a dense output grid (:func:`dense_selection`) the control runs on a coarse subset
    of the output times and the samples between are filled (:func:`dense_fill`) after
    the last attempt."""
    loading, t = problem.loading, problem.t
    opts = problem.options
    t_end = float(t[-1])
    N = problem.model.size
    scale = float(np.linalg.norm(problem.z0)) or 1.0
    if problem.loads is not None:
        scale = load_scale(problem)
    gen = MagnusGenerator(problem.model, loading, scale, problem.loads)
    invariant = gen.invariant
    budget = step_budget(opts)
    step = given_step(opts)
    if step is None and not (0 < opts.tolerance < 1):
        raise InvalidInput("tolerance must be in (0, 1)", parameter="tolerance")
    h0 = step if step is not None else t_end / PILOT_STEPS
    # dense output: the control runs on the coarse times t[sel] (None: on every output time)
    sel = None if invariant or step is not None else dense_selection(t, h0)
    if sel is not None:
        t = t[sel]
    dt = np.diff(t)
    # bounded in floating point before the cast; the error check's run with twice the
    # step takes half as many again, and when it may refine (no user step) the run with
    # four times the step a quarter: the first run gets 2/3 or 4/7 of the budget
    refines = step is None
    first = budget if invariant else (4 * budget) // 7 if refines else (2 * budget) // 3
    substeps = step_counts(dt, h0, first, "magnus", step is not None)
    if dt.size == 1 and not invariant:
        substeps = np.maximum(substeps, 2)  # the check needs a coarser run to compare with
    warnings: list[str] = []
    exps = 0
    attempts = 0
    estimate = 0.0
    rate = 4.0
    method = ""
    previous: tuple[FloatArray, int, NDArray[np.int64] | None] | None = None
    while True:
        attempts += 1
        Magnus._check_budget(int(substeps.sum()), budget, dt, substeps, opts.tolerance)
        if invariant:
            plan = StepPlan(substeps, np.full(dt.size, 4, dtype=np.int64))
        else:
            orders, used = choose_orders(gen, t, substeps)
            exps += used
            plan = StepPlan(substeps, orders)
        Zaug, used = yield MagnusRun(gen, t, plan)
        exps += used
        if invariant:
            break
        if previous is not None:
            # a refinement: the previous attempt is the coarser run of the check (no
            # fresh run with twice the step); Richardson with the step ratio at the
            # slowest rate a refinement is assumed to converge at, REFINED_FLOOR_RATE
            # = 2: not the observed rate, which before the asymptotic regime
            # under-estimated the error 5x (paper example forced from rest: 1.3e-9 for a
            # true 7.2e-9), nor log2(RICHARDSON_DIVISOR + 1) = 2.32 as the first check,
            # which under-reported there too (6.9e-9 for 7.2e-9: the error fell 4.8x
            # from 2,000 to 4,000 steps, not 5x)
            Zprev, steps_prev, sel_prev = previous
            ratio = plan.steps / steps_prev
            # dense output: the previous coarse times are a subset of these
            Znow = Zaug if sel is None or sel_prev is None else Zaug[np.searchsorted(sel, sel_prev)]
            d1 = relative_difference(Zprev, Znow[:, :N], N)
            floor_rate = REFINED_FLOOR_RATE
            estimate = d1 / max(ratio**floor_rate - 1.0, 1e-300)
            method = (
                f"difference from the previous attempt ({steps_prev} steps, step ratio "
                f"{ratio:.3g}) over ratio^{floor_rate:.2f} - 1"
            )
        else:
            # Richardson-type check: the same orders with twice and four times the step
            idx, coarse = plan.coarse(t)
            idx2, coarser = coarse.coarse(t[idx])
            # the run with four times the step is counted too when it may be made (the
            # estimate asks for a refinement, never with a user step)
            check = coarse.steps + (coarser.steps if refines else 0)
            Magnus._check_budget(plan.steps + check, budget, dt, substeps, opts.tolerance)
            Zc, used = yield MagnusRun(gen, t[idx], coarse)
            exps += used
            d1 = relative_difference(Zc, Zaug[idx], N)
            estimate = d1 / RICHARDSON_DIVISOR
            method = f"difference from a run with twice the step, divided by {RICHARDSON_DIVISOR:g}"
        # the rounding of the sequential propagation (one unit roundoff per step, a
        # bound of its random walk of ~20 eps sqrt(steps) past 400 steps): below it
        # two runs cannot tell their errors apart (4 modes, 38,400 steps: a difference
        # of 1e-14, a true error of 1e-13)
        estimate += plan.steps * ROUNDING_PER_STEP
        if step is not None or estimate <= opts.tolerance:
            break
        if attempts >= MAX_ATTEMPTS or not math.isfinite(estimate):
            warnings.append(
                f"magnus could not verify the tolerance {opts.tolerance:.3g}: estimated "
                f"relative error {estimate:.3g} after {attempts} attempts"
            )
            break
        if previous is None:
            # the rate observed against a run with four times the step (not h^4: it
            # over- or under-shoots while h |xi_max| > pi)
            Zcc, used = yield MagnusRun(gen, t[idx][idx2], coarser)
            exps += used
            rate = observed_rate(d1, Zc[idx2], Zcc, N, int(plan.order.max()))
        # refine by the factor that brings the estimate to SAFETY * tolerance at that
        # rate, spread over the intervals (no rounding up to whole multiples)
        factor = (estimate / (SAFETY * opts.tolerance)) ** (1.0 / rate)
        previous = (Zaug[:, :N].copy(), plan.steps, sel)
        substeps = _substeps(dt, h0, budget, factor, substeps)
        if sel is not None:
            sel, substeps = dense_refine(sel, substeps)
            t = problem.t[sel]
            dt = np.diff(t)
    dense: dict[str, Any] | None = None
    fill_note = ""
    if sel is None:
        Z = Zaug[:, :N].copy()
    else:
        # the fill may add what the coarse estimate leaves of the tolerance, at most
        # FILL_SHARE of it (and that share when the coarse run is above the tolerance)
        left = opts.tolerance - estimate
        allowance = FILL_SHARE * opts.tolerance
        fill = dense_fill(
            gen, problem.t, sel, Zaug, allowance if left <= 0 else min(allowance, left)
        )
        Z = np.ascontiguousarray(fill.Z[:, :N])  # (a copy only when the state is augmented)
        exps += fill.exponentials
        estimate += fill.estimate
        if fill.checked:
            fill_note = (
                f"; dense output: plus {FILL_MARGIN:g} times the fill's largest difference "
                f"from a march of sixth-order Magnus steps between samples on {fill.checked} "
                "coarse intervals"
            )
        dense = {
            "steps": plan.steps,
            "coarse_times": int(sel.size),
            "samples_filled": int(problem.t.size - sel.size),
            "method": fill.method,
            "fill_estimated_relative_error": fill.estimate,
            "fill_exponentials": fill.exponentials,
        }
        if not estimate <= opts.tolerance and not warnings:
            warnings.append(
                f"magnus could not verify the tolerance {opts.tolerance:.3g}: estimated "
                f"relative error {estimate:.3g} with the dense output's fill"
            )
    h_used = dt / plan.substeps
    stats.steps, stats.attempts, stats.matrix_exponentials = plan.steps, attempts, exps
    diagnostics: dict[str, Any] = {
        "time_invariant": invariant,
        "step_source": "step" if opts.step is not None else "tolerance",
        "step_max": float(h_used.max()),
        "step_min": float(h_used.min()),
        "steps_order_6": int(plan.substeps[plan.order == 6].sum()),
        "tolerance": opts.tolerance,
        "estimated_relative_error": estimate,
        "error_estimate_method": (
            "exact for constant coefficients (rounding only)"
            if invariant
            else f"{method}, plus one unit roundoff per step (rounding){fill_note}"
        ),
    }
    if dense is not None:
        diagnostics["dense_output"] = dense
    return SolverOutput(z=Z, diagnostics=diagnostics, warnings=warnings)


def augmented_initial_state(problem: Problem, gen: MagnusGenerator) -> FloatArray:
    """The state :func:`propagate` starts from: the problem's, with the forcing's scale
    appended when ``gen`` is forced (the spin's acceleration or loads)."""
    z = problem.z0.astype(float)
    return np.append(z, gen.scale) if gen.forced else z
