"""The Magnus generators Omega of orders 4 and 6 of the (augmented) state matrix, the order
chosen per output interval and the step plan (the method: :mod:`pipeflow.solvers.magnus`)."""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from pipeflow._types import FloatArray
from pipeflow.linalg import (
    COMMUTATOR_FACTOR,
    GAUSS3_NODES,
    GAUSS_NODES,
    expm_stack,
    magnus4_omega,
    magnus6_omega,
)
from pipeflow.loading import Loading
from pipeflow.loads import ExternalForcing
from pipeflow.model import PipeModel
from pipeflow.solvers.base import Problem, forcing
from pipeflow.solvers.magnus.states import ForcingStates

#: times at which the local errors of the two orders are compared (step doubling)
LOCAL_SAMPLES = 16
#: 10 modes, h |A|_1 ~ 42 at 2001 samples, its local error is 20x order 4's)
ORDER6_GAIN = 4.0
ORDER6_NORM = 8.0


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
        #: the loads as states of their own (exact forcing, :mod:`.states`), when their
        #: profiles allow and the coefficients are constant: each step is then exact, and
        #: so is the run (a harmonic tip force at 700 rad/s on the paper's pipe at
        #: v = 0.4 m/s: 5e-13 of cma's closed form in 2,000 steps, where the interpolated
        #: forcing refined to 4,000 steps for 6e-10).  None: the forcing is interpolated on
        #: each step.  With time-variant coefficients the exact form is not used: the step
        #: control's estimate of a refinement leans on the interpolation's own error there
        #: (the paper example forced from rest refines 2,000 -> 4,000 steps; with exact
        #: forcing its true error falls only 1.86x, 1.3e-8 -> 7.2e-9, still before the
        #: asymptotic regime, and the difference over ratio^2 - 1 reads 3.2e-9)
        self.states = (
            ForcingStates.of(loads, model.size)
            if loads is not None and loading.is_time_invariant
            else None
        )
        #: A(t) constant: constant coefficients and no load varying in time
        self.invariant = loading.is_time_invariant and (loads is None or loads.is_constant)
        self.scale = scale  # the constant c the state is augmented with [m]
        N = model.size
        self.size = N + (1 if self.forced else 0)
        pieces = model.state_pieces
        if self.jordan:  # the state alone: the forcing is the generator's border
            basis = np.asarray(pieces)
        else:
            extra = 1 if self.spin_forced else 0
            basis = np.zeros((len(pieces) + extra, self.size, self.size))
            basis[: len(pieces), :N, :N] = pieces
            if self.spin_forced:
                basis[len(pieces), :N, N] = model.f_wdot / scale
        self.basis = basis.reshape(basis.shape[0], -1)
        # order 4 (with loads: the homogeneous block): A = sum_i c_i B_i makes the
        # commutator bilinear,
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
        return self.model.size + self.forcing_width(6) if self.jordan else self.size

    def forcing_width(self, order: int) -> int:
        """The states of a step's forcing (with loads): the loads' own (:attr:`states`), or
        the interpolating polynomial's :data:`FORCING_NODES` of ``order``."""
        return FORCING_NODES[order] if self.states is None else self.states.count

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
        return np.asarray(forcing(self.model, self.loading, self.loads, times) / self.scale)

    def forcing_coefficients(self, starts: FloatArray, h: FloatArray, order: int) -> FloatArray:
        """The coefficients C (k, N, q) of each step's forcing polynomial
        sum_j c_j tau^j / j! (:func:`forced_omega`) from the forcing at the q =
        :data:`FORCING_NODES` Gauss-Legendre nodes of the steps [starts, starts + h]: for
        many steps at once, sliced per block of steps (:meth:`omega`'s ``forcing``)."""
        if self.states is not None:  # exact: the loads' states at each step's start
            return self.states.border(starts) / self.scale
        k, N = starts.size, self.model.size
        q = FORCING_NODES[order]
        tau, Vinv = FORCING_BASIS[q]
        F = self.forcing(np.concatenate([starts + g * h for g in tau])).reshape(q, k * N)
        return np.asarray((Vinv @ F).reshape(q, k, N).transpose(1, 2, 0))

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
        forcing: FloatArray | None = None,
    ) -> FloatArray:
        """Omega of ``order`` (4 or 6) for steps [starts, starts + h] (equal lengths) [-];
        ``weights``: their :meth:`node_weights`, when already computed; ``coefficients``:
        their :meth:`omega4_coefficients` (order 4), when already computed; ``forcing``:
        with loads, their :meth:`forcing_coefficients`, when already computed.

        With loads, the generator of the step's exponential-integrator form
        (:func:`forced_omega`), of size N + :meth:`forcing_width`."""
        k = starts.size
        n = self.model.size if self.jordan else self.size
        if order == 4:
            if weights is None and (coefficients is None or self.jordan):
                weights = self.node_weights(starts, h, order)
            if coefficients is None:
                assert weights is not None
                coefficients = self.omega4_coefficients(h, weights)
            omega = np.asarray(coefficients @ self._omega4_basis).reshape(k, n, n)
            if not self.jordan:
                return omega
            assert weights is not None
            variation = ((weights[1] - weights[0]) @ self.basis).reshape(k, n, n)  # A_2 - A_1
            return forced_omega4(self, omega, variation, starts, h, forcing)
        if weights is None:
            weights = self.node_weights(starts, h, order)
        A = (weights.reshape(-1, weights.shape[-1]) @ self.basis).reshape(-1, n, n)
        if self.jordan:
            return forced_omega(self, A, starts, h, order, forcing)
        return np.asarray(magnus6_omega(A[:k], A[k : 2 * k], A[2 * k :], h))

    def propagators(self, omega: FloatArray) -> FloatArray:
        """exp(Omega) of each step's generator (:meth:`omega`); with loads the affine step
        [[P, r], [0, 1]] (size N + 1) cut from the exponential of the bordered generator
        (the forcing's states start each step from e_0)."""
        if not self.jordan:
            return expm_stack(omega)
        # exp([[Omega, Y], [0, B]]) restricted to (z, w_0): [[P, r], [0, 1]].  The forcing's
        # states restart from e_0 at each step (the loads' value at the step's start is in
        # its border), so the last row carries the constant: [0, 1] by definition, whatever
        # B is (the polynomial's shift J gives it exactly; the loads' generator does not)
        N = self.model.size
        E = expm_stack(omega)
        out = np.ascontiguousarray(E[:, : N + 1, : N + 1])
        out[:, N, :N] = 0.0
        out[:, N, N] = 1.0
        return out

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


def _bordered(
    gen: MagnusGenerator,
    starts: FloatArray,
    h: FloatArray,
    order: int,
    forcing: FloatArray | None = None,
) -> tuple[FloatArray, FloatArray]:
    """The bordered generators' frame (k, N + q, N + q) with the shift J in place, and the
    forcing polynomial's coefficients C (k, N, q) of each step (:func:`forced_omega`;
    ``forcing``: C, when already computed)."""
    k, N = starts.size, gen.model.size
    q = gen.forcing_width(order)
    C = gen.forcing_coefficients(starts, h, order) if forcing is None else forcing
    out = np.zeros((k, N + q, N + q))
    if gen.states is None:
        out[:, N + 1 :, N : N + q - 1] = np.eye(q - 1)  # J: w_j' = w_{j-1}
    else:  # the loads' own generator, in tau = s / h
        out[:, N:, N:] = np.asarray(h, dtype=float)[:, None, None] * gen.states.generator
    return out, C


def forced_omega4(
    gen: MagnusGenerator,
    omega: FloatArray,
    variation: FloatArray,
    starts: FloatArray,
    h: FloatArray,
    forcing: FloatArray | None = None,
) -> FloatArray:
    """:func:`forced_omega` at order 4 from the homogeneous generator ``omega`` (k, N, N)
    and A's variation over the step A_2 - A_1 (``variation``): [[Omega, Y], [0, J]] with
    Y = h C + sqrt(3)/12 h^2 (A_2 - A_1) C."""
    out, C = _bordered(gen, starts, h, 4, forcing)
    N = gen.model.size
    hh = np.asarray(h, dtype=float)[:, None, None]
    out[:, :N, :N] = omega
    out[:, :N, N:] = hh * C + (COMMUTATOR_FACTOR * hh * hh) * (variation @ C)
    return out


def forced_omega(
    gen: MagnusGenerator,
    A: FloatArray,
    starts: FloatArray,
    h: FloatArray,
    order: int,
    forcing: FloatArray | None = None,
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
    (stacked node-major), ``h`` the step lengths; the state's constant c is in C
    (``forcing``: C, when already computed).
    """
    k = starts.size
    if order == 4:
        omega = magnus4_omega(A[:k], A[k:], h)
        return forced_omega4(gen, omega, A[k:] - A[:k], starts, h, forcing)
    out, C = _bordered(gen, starts, h, order, forcing)
    N = gen.model.size
    hh = np.asarray(h, dtype=float)[:, None, None]
    # order 6: the generic three-node generator of the bordered matrices (tau units)
    Ab = np.repeat(out[None], 3, axis=0)
    Ab[:, :, :N, :N] = hh[None] * A.reshape(3, k, N, N)
    Ab[:, :, :N, N:] = hh[None] * C[None]
    return np.asarray(magnus6_omega(Ab[0], Ab[1], Ab[2], 1.0))


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


def augmented_initial_state(problem: Problem, gen: MagnusGenerator) -> FloatArray:
    """The state :func:`propagate` starts from: the problem's, with the forcing's scale
    appended when ``gen`` is forced (the spin's acceleration or loads)."""
    z = problem.z0.astype(float)
    return np.append(z, gen.scale) if gen.forced else z
