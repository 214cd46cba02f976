"""Batched linear algebra shared by the solvers and the Floquet analysis.

- :func:`expm_stack`: exp(X_k) for a stack of matrices by scaling and squaring of a
  Taylor polynomial, every operation a batched matrix product;
- :func:`product_of_steps`: the ordered product E_{m-1} ... E_0 of a stack of step
  propagators, pairwise;
- :func:`magnus4_omega`, :func:`magnus6_omega`: the Gauss-Legendre Magnus generators of
  orders 4 and 6 (Blanes, Casas, Oteo & Ros, Physics Reports 470 (2009), section 5.2;
  Blanes, Casas & Ros, BIT 40 (2000) 434-450) at the nodes :data:`GAUSS_NODES` and
  :data:`GAUSS3_NODES`.

All accept leading batch dimensions.  Used by :mod:`pipeflow.solvers.magnus` (steps of the
time-variant state equation), :mod:`pipeflow.solvers.cma` (exp of the integrated state
matrix) and :mod:`pipeflow.stability.floquet` (the monodromy matrix over a period).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from pipeflow._types import FloatArray

GAUSS_OFFSET = math.sqrt(3.0) / 6.0
#: the two Gauss-Legendre nodes on a step, as fractions of the step [-]
GAUSS_NODES = (0.5 - GAUSS_OFFSET, 0.5 + GAUSS_OFFSET)
COMMUTATOR_FACTOR = math.sqrt(3.0) / 12.0
#: the three Gauss-Legendre nodes of the 6th-order generator, as fractions of the step [-]
GAUSS3_NODES = (0.5 - math.sqrt(15.0) / 10.0, 0.5, 0.5 + math.sqrt(15.0) / 10.0)
#: the 1-norm to which a matrix is scaled before the degree-18 Taylor polynomial is applied
TAYLOR_THETA = 1.0
#: matrix entries per expm_stack work block: temporaries under ~100 kB are reused by the
#: allocator; larger ones cost page faults (3-5x slower here)
_CACHE_ENTRIES = 12_000


def magnus4_omega(A1: FloatArray, A2: FloatArray, h: float | FloatArray) -> FloatArray:
    """The fourth-order Magnus generator of steps of length ``h`` [s] (dimensionless).

    Omega = h/2 (A_1 + A_2) + sqrt(3) h^2 / 12 [A_2, A_1], with ``A1``, ``A2`` the state
    matrices [1/s] at the Gauss nodes t + GAUSS_NODES * h, stacks of shape (..., N, N);
    ``h`` is a number or an array of the leading shape (...).
    """
    hh = np.asarray(h, dtype=float)[..., None, None]
    return np.asarray(0.5 * hh * (A1 + A2) + (COMMUTATOR_FACTOR * hh * hh) * (A2 @ A1 - A1 @ A2))


def magnus6_omega(A1: FloatArray, A2: FloatArray, A3: FloatArray, h: float | FloatArray) -> Any:
    """The sixth-order Magnus generator of steps of length ``h`` [s] (dimensionless).

    Blanes, Casas & Ros (BIT 40, 2000), Physics Reports 470 (2009) eq. (4.9)-(4.10) form:
    ``A1``, ``A2``, ``A3`` are the state matrices [1/s] at t + GAUSS3_NODES * h, stacks of
    shape (..., N, N); ``h`` is a number or an array of the leading shape (...).
    """
    hh = np.asarray(h, dtype=float)[..., None, None]
    a1 = hh * A2
    a2 = (math.sqrt(15.0) / 3.0) * hh * (A3 - A1)
    a3 = (10.0 / 3.0) * hh * (A3 - 2.0 * A2 + A1)
    C1 = a1 @ a2 - a2 @ a1
    X = 2.0 * a3 + C1
    C2 = (-1.0 / 60.0) * (a1 @ X - X @ a1)
    Y = C1 - 20.0 * a1 - a3
    W = a2 + C2
    return a1 + a3 / 12.0 + (1.0 / 240.0) * (Y @ W - W @ Y)


def expm_stack(X: FloatArray) -> FloatArray:
    """exp(X_k) for a stack ``X`` of shape (..., N, N), by scaling and squaring.

    exp(X) = (T_18(X / 2^s))^(2^s) with T_18 a polynomial that agrees with the Taylor
    series to degree 18, evaluated in 5 matrix products (Bader, Blanes & Casas 2019:
    :data:`_T18_COEF`), and s chosen per matrix so |X/2^s|_1 <= TAYLOR_THETA = 1: the
    backward error is then below the unit roundoff (theirs holds to 1.09).  Every operation
    is a batched matrix product (numpy matmul over the stack); leading dimensions are
    flattened.
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


#: Bader, Blanes & Casas (Mathematics 7 (2019) 1174, eq. (16); the coefficients of
#: PyTorch's ``matrix_exp``): a degree-18 polynomial equal to the Taylor polynomial T_18 up to
#: degree 18, in 5 matrix products instead of Paterson-Stockmeyer's 7.  With
#: A2 = Y^2, A3 = Y^3, A6 = A3^2 and B_i = sum_j _T18_COEF[i, j] (I, Y, A2, A3, A6)_j:
#: A9 = B_1 B_5 + B_4, T = B_2 + (B_3 + A9) A9.  Its backward error is below the unit
#: roundoff for |Y|_1 <= 1.09 (their theta_18), so TAYLOR_THETA = 1 keeps a margin.
_T18_COEF = np.array(
    [
        [
            0.0,
            -1.00365581030144618291e-01,
            -8.02924648241156932449e-03,
            -8.92138498045729985177e-04,
            0.0,
        ],
        [
            0.0,
            3.97849749499645077844e-01,
            1.36783778460411720168e00,
            4.98289622525382669416e-01,
            -6.37898194594723280150e-04,
        ],
        [
            -1.09676396052962061844e01,
            1.68015813878906206114e00,
            5.71779846478865511061e-02,
            -6.98210122488052056106e-03,
            3.34975017086070470649e-05,
        ],
        [
            -9.04316832390810593223e-02,
            -6.76404519071381882256e-02,
            6.75961301770459654925e-02,
            2.95552570429315521194e-02,
            -1.39180257516060693404e-05,
        ],
        [
            0.0,
            0.0,
            -9.23364619367118555360e-02,
            -1.69364939002081722752e-02,
            -1.40086798182036094347e-05,
        ],
    ]
)


def _expm_block(X: FloatArray) -> FloatArray:
    # the 1-norms (column sums, as one batched product with a row of ones: half the cost
    # of numpy's reduction over the middle axis at 30 x 20 x 20); a nan or inf shows in
    # the max
    norms = (np.ones((1, X.shape[-2])) @ np.abs(X)).max(axis=(1, 2))
    if not math.isfinite(norms.max()):
        return np.full_like(X, np.nan)
    # per-matrix scaling: over-scaling a small matrix would only amplify rounding
    # (log2 of a positive number: no divide-by-zero to silence)
    scal = np.ceil(np.log2(np.maximum(norms, 1e-300) / TAYLOR_THETA))
    scal = np.maximum(scal, 0).astype(np.int64)
    s = int(scal.max())
    K, n, _ = X.shape
    # the powers Y, Y^2, Y^3, Y^6 written into one array (no stacking copy)
    P = np.empty((4, K, n, n))
    np.multiply(X, (0.5**scal)[:, None, None], out=P[0])
    np.matmul(P[0], P[0], out=P[1])
    np.matmul(P[1], P[0], out=P[2])
    np.matmul(P[2], P[2], out=P[3])
    flat = (_T18_COEF[:, 1:] @ P.reshape(4, -1)).reshape(5, K, n * n)
    flat[:, :, :: n + 1] += _T18_COEF[:, :1, None]
    B = flat.reshape(5, K, n, n)
    A9 = B[0] @ B[4]
    A9 += B[3]
    R = B[2] + A9
    R = R @ A9
    R += B[1]
    if scal.min() == s:
        spare = P[0]  # Y is no longer needed: the other buffer of the squarings
        for _ in range(s):
            np.matmul(R, R, out=spare)
            R, spare = spare, R
        return R.copy() if R.base is P else R
    # most squarings first: the matrices still being squared are a leading slice (a view)
    order = np.argsort(-scal, kind="stable")
    R, counts = R[order], np.count_nonzero(scal[:, None] > np.arange(s)[None, :], axis=0)
    for j in range(s):
        head = R[: counts[j]]
        R[: counts[j]] = head @ head
    out = np.empty_like(R)
    out[order] = R
    return out


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
