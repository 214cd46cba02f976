"""Complex eigenvalues xi = sigma + i omega of a family of state matrices, tracked.

The paper's damping and frequency figures (Figs. 3-4, 6-7, ...) are the eigenvalues of
the frozen state matrix S(t): sigma [1/s] (negative: decaying) and omega [rad/s].
Eigenvalues of non-symmetric matrices cross and veer as parameters change, so a branch is
followed from one point to the next by correlating the *left* eigenvectors of the previous
point with the *right* eigenvectors of the next (biorthogonality, W V = I) and solving the
optimal assignment on the overlaps, never by re-sorting.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import linear_sum_assignment

ComplexArray = NDArray[np.complex128]
FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class Traces:
    """Tracked eigenvalue branches.

    ``xi[k, j]`` is branch j at point k [1/s]; ``confidence[k, j]`` in [0, 1] is the
    eigenvector overlap that linked point k to point k-1 (1 at k = 0), a low value
    flags a point where the branch identity is uncertain (coalescence or too coarse a grid).
    """

    xi: ComplexArray
    confidence: FloatArray

    @property
    def sigma(self) -> FloatArray:
        """Real parts: damping [1/s] (negative: decaying)."""
        return self.xi.real

    @property
    def omega(self) -> FloatArray:
        """Imaginary parts: frequencies [rad/s]."""
        return self.xi.imag


def _decompose(S: NDArray[np.float64]) -> tuple[ComplexArray, ComplexArray, ComplexArray]:
    w, V = np.linalg.eig(S)
    V = V / np.linalg.norm(V, axis=-2, keepdims=True)
    with np.errstate(all="ignore"):
        W = np.linalg.inv(V)
    return w, V, W


def damped_modes(w: ComplexArray) -> tuple[NDArray[np.intp], dict[int, int]]:
    """Modes of a damped spectrum at one point, by natural frequency.

    Returns one representative eigenvalue index per mode, ordered by the mode's natural
    frequency, and ``partner`` (index -> representative) for the other eigenvalue of each
    mode. A damped mode's two eigenvalues solve lambda^2 + 2 zeta w lambda + w^2 = 0, so
    its natural frequency is w = |lambda| for a complex pair (representative: omega > 0) and
    w = sqrt(s1 s2) for an over-damped pair of real roots -s1, -s2 (representative: the
    slower root). Decaying real roots are paired smallest with largest, which is exact when
    over-damping comes from one mechanism (Kelvin-Voigt: high modes, roots near 1/alpha and
    alpha w^2; viscous: low modes); any other real root is a mode of frequency 0 (first).
    """
    scale = max(float(np.max(np.abs(w))), 1e-300)
    tol = 1e-9 * scale
    real = np.abs(w.imag) <= tol
    key: dict[int, float] = {}
    partner: dict[int, int] = {}
    for i in np.flatnonzero(w.imag > tol):
        key[int(i)] = float(abs(w[i]))
        lower = np.flatnonzero(w.imag < -tol)
        if lower.size:
            j = int(lower[np.argmin(np.abs(w[lower] - np.conj(w[i])))])
            partner.setdefault(j, int(i))
    decaying = np.flatnonzero(real & (w.real < 0))
    decaying = decaying[np.argsort(-w.real[decaying])]  # slowest first
    k = decaying.size // 2
    for a, b in zip(decaying[:k], decaying[::-1][:k], strict=True):
        key[int(a)] = math.sqrt(float(w[a].real * w[b].real))
        partner[int(b)] = int(a)
    for i in np.flatnonzero(real):
        if int(i) not in key and int(i) not in partner:
            key[int(i)] = 0.0
    reps = np.array(sorted(key, key=lambda i: (key[i], w[i].real)), dtype=np.intp)
    return reps, partner


def order_lowest(w: ComplexArray, count: int, damped: bool = False) -> NDArray[np.intp]:
    """Indices of the ``count`` lowest-frequency modes at one point.

    One eigenvalue per conjugate pair (omega >= 0); real eigenvalues (divergence or
    over-damped motion) count as modes of zero frequency.  ``damped``: order by natural
    frequency instead, an over-damped pair of real roots being one mode
    (:func:`damped_modes`), so that the heavily damped high modes of Kelvin-Voigt damping
    do not displace the fundamental.
    """
    if damped:
        return damped_modes(w)[0][:count]
    scale = max(float(np.max(np.abs(w))), 1e-300)
    upper = np.flatnonzero(w.imag > -1e-12 * scale)
    order = np.lexsort((w.real[upper], np.abs(w.imag[upper])))
    return upper[order][:count]


def decompose(S: NDArray[np.float64]) -> tuple[ComplexArray, ComplexArray, ComplexArray]:
    """Batched eigen-decomposition of ``S`` (shape ``(N, m, m)``).

    Returns eigenvalues ``w`` (N, m), right eigenvectors ``V`` (unit columns) and the left
    ones ``W = V^-1`` (rows), so that ``W V = I`` (non-finite where V is singular).
    """
    return _decompose(S)


def assign(
    w: ComplexArray, V: ComplexArray, W: ComplexArray
) -> tuple[NDArray[np.intp], FloatArray]:
    """Follow every eigenvalue branch through consecutive decompositions.

    Returns ``perm`` (N, m): column j of ``w[k, perm[k]]`` is branch j at point k (branch
    j is eigenvalue j of the first point), and ``confidence`` (N, m) in [0, 1]: the
    left/right eigenvector overlap that linked point k to point k-1 (1 at k = 0).
    Optimal assignment (Hungarian algorithm) on the overlaps, not greedy matching.
    """
    N, m = w.shape
    perm = np.empty((N, m), dtype=np.intp)
    conf = np.ones((N, m))
    perm[0] = np.arange(m)
    for k in range(1, N):
        overlap = np.abs(W[k - 1][perm[k - 1]] @ V[k])  # rows: previous branches
        if not np.all(np.isfinite(overlap)):
            # defective previous point: fall back to nearest eigenvalues
            dist = np.abs(w[k - 1][perm[k - 1]][:, None] - w[k][None, :])
            rows, cols = linear_sum_assignment(dist)
            conf[k] = 0.0
        else:
            rows, cols = linear_sum_assignment(-overlap)
            conf[k, rows] = np.minimum(1.0, overlap[rows, cols])
        perm[k, rows] = cols
    return perm, conf


def track(S: NDArray[np.float64], modes: int, damped: bool = False) -> Traces:
    """Eigenvalues of each ``S[k]`` (shape ``(N, m, m)``), the ``modes`` lowest tracked.

    Branches are chosen at the first point (lowest frequencies, one per conjugate pair;
    ``damped``: by natural frequency, see :func:`order_lowest`) and followed by optimal
    assignment of left/right eigenvector overlaps.
    """
    w, V, W = _decompose(S)
    perm, conf = assign(w, V, W)
    chosen = order_lowest(w[0], modes, damped)
    xi = np.take_along_axis(w, perm[:, chosen], axis=1)
    return Traces(xi=xi, confidence=conf[:, chosen])


_order_lowest = order_lowest  # backwards-compatible private name
