"""The frozen model at one operating point for the frequency response and the state space:
its second-order matrices and the eigen-decomposition of its balanced state matrix, with the
response from them by the modal sum or by direct solves (:class:`Operator`), on the model's
modes (:func:`operator_at`) or on the modes enriched with
load-dependent Ritz vectors (:func:`enriched_operator`, :mod:`pipeflow.enrichment`)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.linalg import lapack

from pipeflow import enrichment
from pipeflow._types import ComplexArray, FloatArray
from pipeflow.enrichment import Enriched
from pipeflow.loading import Coefficients
from pipeflow.model import Pipe, PipeModel, build_model, second_order


@dataclass(frozen=True, eq=False)
class Operator:
    """The frozen model at (v, w0): second-order matrices and the eigen-decomposition."""

    model: PipeModel
    M: FloatArray
    C: FloatArray
    K: FloatArray
    xi: ComplexArray
    V_low: ComplexArray  # displacement rows of the right eigenvectors, (n, 2n)
    V_lu: tuple[ComplexArray, NDArray[np.int32]]  # LU factors of V (LAPACK getrf)
    condition: float
    omega_ref: FloatArray  # the balancing scales [rad/s]: z = (q' / omega_ref, q)

    def modal(self, b: ComplexArray) -> ComplexArray:
        """V^-1 b: the modal coordinates of the state-space input ``b``."""
        lu, piv = self.V_lu
        out, _ = lapack.zgetrs(lu, piv, b)
        return np.asarray(out)

    def modal_sum(self, out: FloatArray, b: ComplexArray, W: FloatArray) -> ComplexArray:
        """Phi_out V_low diag(1/(iW - xi)) V^-1 b for all W, ``b`` real (a real input).

        The state matrix is real, so its complex eigenvalues come in conjugate pairs whose
        residues r (p x 1 each) are conjugate too, and a pair sums to
        (2 Re(r) iW - 2 Re(r conj(xi))) / ((|xi|^2 - W^2) - 2 i W Re(xi)): one complex
        reciprocal per pair instead of two, and the numerators' real coefficients times the
        reciprocals as one *real* product (the complex array viewed as pairs of floats), where
        the sum over all 2n poles was a complex product (p x 2n) @ (2n x nW): 0.19 against 0.28
        ms at 20 modes and 2,000 frequencies, equal to rounding (7e-16 relative).  Real
        eigenvalues (overdamped, a rigid rotation) are summed as they are."""
        left = (out @ self.V_low) * self.modal(b)[None, :]
        xi = self.xi
        up, real = np.flatnonzero(xi.imag > 0), np.flatnonzero(xi.imag == 0)
        p = out.shape[0]
        with np.errstate(divide="ignore", invalid="ignore"):  # W on an undamped pole
            x, r = xi[up], left[:, up]
            d = np.empty((up.size, W.size), dtype=complex)
            d.real = (x.real**2 + x.imag**2)[:, None] - (W * W)[None, :]
            d.imag = (-2.0 * x.real)[:, None] * W[None, :]
            # in place: a fresh array from ``1.0 / d`` made the product that follows 4x slower
            # (measured 1.1 ms against 0.27 ms at 40 x 2,000, numpy 2.4, OpenBLAS)
            np.reciprocal(d, out=d)
            coef = np.concatenate([2.0 * r.real, -2.0 * (r * np.conj(x)).real])  # (2p, pairs)
            both = (coef @ d.view(float)).view(complex)  # (2p, nW)
            H = both[:p] * (1j * W)[None, :] + both[p:]
            if real.size:
                H += left[:, real] @ (1.0 / (1j * W[None, :] - xi[real][:, None]))
        return np.asarray(H)

    def direct(self, out: FloatArray, f: FloatArray, W: FloatArray) -> ComplexArray:
        """Phi_out (K - W^2 M + i W C)^-1 f, one batched solve per frequency."""
        D = (
            self.K[None]
            - (W**2)[:, None, None] * self.M[None]
            + (1j * W)[:, None, None] * self.C[None]
        )
        rhs = np.broadcast_to(f.astype(complex), (W.size, f.size))[..., None]
        q = np.linalg.solve(D, rhs)[..., 0]
        return np.asarray(out @ q.T)


def operator_at(pipe: Pipe, v: float, w0: float, modes: int) -> Operator:
    model = build_model(pipe, modes)
    c = Coefficients(np.array([v]), np.zeros(1), np.array([w0 * w0]), np.zeros(1))
    C = model.C_0 + v * model.C_v
    K = model.K_0 + v * v * model.K_v2 + w0 * w0 * model.K_w2
    return decomposed(model, model.M, C, K, model.state_matrix(c)[0], model.omega_ref)


def enriched_operator(
    pipe: Pipe, v: float, w0: float, modes: int, force_at: float | None, count: int
) -> tuple[Operator, Enriched, FloatArray] | None:
    """The operator on the model's modes and ``count`` load-dependent Ritz vectors of a
    unit force at ``force_at`` [m] (None: a unit acceleration of the supports)
    (:mod:`pipeflow.enrichment`), the enriched basis and the load's generalised force on
    it; None where the static problem has no solution."""
    a = force_at
    vectors = enrichment.load_vectors(pipe, v, w0, a, count)
    if vectors is None:
        return None
    cuts = (a / pipe.L,) if a is not None and a < pipe.L else ()
    basis, g = enrichment.enrich(pipe, modes, vectors, cuts)
    so = second_order(pipe, g)
    C = so.C_0 + v * so.C_v
    K = so.K_0 + v * v * so.K_v2 + w0 * w0 * so.K_w2
    size = basis.size
    # balanced as the model's state matrix (pipeflow.model.build_model)
    omega_ref = np.maximum(
        np.sqrt(np.diag(so.K_bend) / np.diag(so.M)), math.sqrt(pipe.EI / (pipe.mass * pipe.L**4))
    )
    T = np.concatenate([omega_ref, np.ones(size)])
    A = np.zeros((2 * size, 2 * size))
    A[:size, :size] = -np.linalg.solve(so.M, C)
    A[:size, size:] = -np.linalg.solve(so.M, K)
    A[size:, :size] = np.eye(size)
    A = A * (1.0 / T)[:, None] * T[None, :]
    if a is not None:
        f = basis.shapes(np.array([a / pipe.L]))[:, 0]
    else:
        f = -pipe.mass * pipe.L * g.f - pipe.tip_mass * g.tip
    op = decomposed(build_model(pipe, modes), so.M, C, K, A, omega_ref)
    return op, basis, np.asarray(f)


def decomposed(
    model: PipeModel, M: FloatArray, C: FloatArray, K: FloatArray, A: FloatArray,
    omega_ref: FloatArray,
) -> Operator:  # fmt: skip
    """The eigen-decomposition of the balanced state matrix ``A``."""
    xi, V = np.linalg.eig(A)
    V = V / np.linalg.norm(V, axis=0, keepdims=True)
    # LU of V, and LAPACK's estimate of its 1-norm condition number (Hager-Higham: exact
    # or within a small factor, without forming V^-1)
    lu, piv, info = lapack.zgetrf(V)
    rcond = lapack.zgecon(lu, float(np.linalg.norm(V, 1)), norm="1")[0] if info == 0 else 0.0
    cond = 1.0 / rcond if rcond > 0 else math.inf
    n = M.shape[0]
    return Operator(model, M, C, K, xi, V[n:], (lu, piv), cond, omega_ref)
