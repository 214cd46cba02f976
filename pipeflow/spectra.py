"""Complex eigenvalues xi = sigma + i omega of a family of state matrices, tracked.

The one eigenvalue tracker and the one mode numbering of pipeflow: the simulation's
frozen-spectrum traces (:func:`track`) and the stability package's sweeps and critical
velocities (:func:`follow`) both use them.

The paper's damping and frequency figures (Figs. 3-4, 6-7, ...) are the eigenvalues of
the frozen state matrix S(t): sigma [1/s] (negative: decaying) and omega [rad/s].
Eigenvalues of non-symmetric matrices cross and veer as parameters change, so a branch is
followed from one point to the next by correlating the *left* eigenvectors of the previous
point with the *right* eigenvectors of the next (biorthogonality, W V = I) and solving the
optimal assignment on the overlaps, never by re-sorting.

Conventions

- A branch is *unstable* where sigma > :func:`rounding_level` (``MARGINAL_RTOL`` times the
  spectral radius).  At v = 0 the undamped model has every eigenvalue on the imaginary axis
  (sigma = 0 to rounding); that point counts as stable.
- Mode numbers (:func:`mode_numbers`) are 1, 2, ... in order of frequency at the first
  point; both members of a conjugate pair carry the same number, and so do both members of
  a real pair +-s (a divergent mode of the conservative system); other real eigenvalues
  (over-damped motion) are modes of frequency 0 and come first.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.optimize import linear_sum_assignment

from pipeflow._types import ComplexArray, FloatArray, Progress

#: sigma below this fraction of the spectral radius is rounding, not growth
MARGINAL_RTOL = 1e-11


@dataclass(frozen=True)
class Traces:
    """Tracked eigenvalue branches.

    ``xi[k, j]`` is branch j at point k [1/s]; ``confidence[k, j]`` in [0, 1] says how
    surely point k was linked to point k-1 (1 at k = 0): 1 - d1/d2 (> 0.99) where the
    eigenvalues alone decided (:func:`link`: the nearest eigenvalue d1 much nearer than the
    second nearest d2), else the eigenvector overlap; a low value flags a point where the
    branch identity is uncertain (coalescence or too coarse a grid).
    ``mode[j]`` is the mode number of branch j (:func:`mode_numbers` at the first point);
    ``least_stable`` the column of the least stable branch of the whole spectrum (largest
    sigma over the points), when it was asked for; ``branch[j]`` the index of column j's
    eigenvalue at the first point.
    """

    xi: ComplexArray
    confidence: FloatArray
    mode: NDArray[np.intp] | None = None
    least_stable: int | None = None
    branch: NDArray[np.intp] | None = None

    @property
    def sigma(self) -> FloatArray:
        """Real parts: damping [1/s] (negative: decaying)."""
        return self.xi.real

    @property
    def omega(self) -> FloatArray:
        """Imaginary parts: frequencies [rad/s]."""
        return self.xi.imag

    def mode_number(self, j: int) -> int:
        """Mode number of column j (its position + 1 when none were recorded)."""
        return int(self.mode[j]) if self.mode is not None else j + 1


def rounding_level(xi: ComplexArray) -> FloatArray:
    """Per-point level [1/s] below which sigma is rounding (``MARGINAL_RTOL`` x radius)."""
    return np.asarray(MARGINAL_RTOL * np.max(np.abs(xi), axis=-1))


def max_growth_rates(xi: ComplexArray) -> FloatArray:
    """Per-point largest sigma [1/s], 0 where it is within :func:`rounding_level` of 0.

    The one test of growth: a point is unstable where this is > 0.  (The paper's v = 0.4 t
    has sigma = 0 exactly at t = 0, computed as +1e-12; with viscous damping 1e9 N s/m^2
    the spectral radius is 3e13 1/s and the largest sigma comes out +2e-3, rounding.)
    """
    sigma = np.asarray(xi.real.max(axis=-1))
    return np.where(np.abs(sigma) > rounding_level(xi), sigma, 0.0)


def decompose(S: NDArray[np.float64]) -> tuple[ComplexArray, ComplexArray, ComplexArray]:
    """Batched eigen-decomposition of ``S`` (shape ``(N, m, m)``).

    Returns eigenvalues ``w`` (N, m), right eigenvectors ``V`` (unit columns) and the left
    ones ``W = V^-1`` (rows), so that ``W V = I`` (non-finite where V is singular).
    """
    w, V = np.linalg.eig(S)
    V = V / np.linalg.norm(V, axis=-2, keepdims=True)
    with np.errstate(all="ignore"):
        W = np.linalg.inv(V)
    return w, V, W


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
        prev = perm[k - 1]
        perm[k], conf[k] = _link_by_vectors(w[k - 1][prev], W[k - 1][prev], V[k], w[k])
    return perm, conf


def _link_by_vectors(
    w_prev: ComplexArray, W_prev: ComplexArray, V: ComplexArray, w: ComplexArray
) -> tuple[NDArray[np.intp], FloatArray]:
    """One step of :func:`assign`: ``w_prev`` and the left eigenvectors ``W_prev`` (rows)
    of the branches at the previous point, ``V`` and ``w`` of the next; returns the index
    in ``w`` of each branch and the overlap that linked it."""
    m = w.size
    idx = np.empty(m, dtype=np.intp)
    conf = np.zeros(m)
    overlap = np.abs(W_prev @ V)  # rows: previous branches
    if not np.all(np.isfinite(overlap)):
        # defective previous point: fall back to nearest eigenvalues
        dist = np.abs(w_prev[:, None] - w[None, :])
        rows, cols = linear_sum_assignment(dist)
    else:
        rows, cols = linear_sum_assignment(-overlap)
        conf[rows] = np.minimum(1.0, overlap[rows, cols])
    idx[rows] = cols
    return idx, conf


#: consecutive points are linked by their eigenvalues alone (:func:`link`) when every
#: eigenvalue's nearest one at the next point is closer than this fraction of its second
#: nearest (and the nearest ones are a permutation); elsewhere by eigenvector overlaps
LINK_RATIO = 0.01


def link(S: NDArray[np.float64], w: ComplexArray) -> tuple[NDArray[np.intp], FloatArray]:
    """Follow every eigenvalue branch of ``S[k]`` (eigenvalues ``w[k]``), as :func:`assign`,
    with eigenvectors only where the eigenvalues cannot decide.

    From point k-1 to k each eigenvalue goes to its nearest eigenvalue of point k when that
    is unambiguous: the nearest ones form a permutation and each is nearer than
    :data:`LINK_RATIO` times the second nearest (d1 < 0.01 d2).  The branches are then
    continuous in the eigenvalues, and the confidence is 1 - d1/d2 (> 0.99).  Elsewhere
    (crossings, veering, coalescence, a coarse grid) the two points are decomposed with
    vectors (:func:`decompose`) and linked by eigenvector overlap, the confidence being the
    overlap, exactly as :func:`assign`.  On the paper's example (201 times, 20 eigenvalues)
    d1/d2 stays below 2e-4: no eigenvectors at all.
    """
    N, m = w.shape
    perm = np.empty((N, m), dtype=np.intp)
    conf = np.ones((N, m))
    perm[0] = np.arange(m)
    if N == 1:
        return perm, conf
    D = np.abs(w[:-1, :, None] - w[1:, None, :])  # (N-1, m, m): from point k-1 to k
    near = np.argmin(D, axis=2)
    d1 = np.take_along_axis(D, near[..., None], axis=2)[..., 0]
    np.put_along_axis(D, near[..., None], np.inf, axis=2)
    d2 = D.min(axis=2) if m > 1 else np.full_like(d1, np.inf)
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = d1 / d2  # 0/0 (repeated eigenvalues): nan, never "unambiguous"
    permutation = np.all(np.sort(near, axis=1) == np.arange(m), axis=1)
    by_values = permutation & np.all(ratio < LINK_RATIO, axis=1)
    hard = np.flatnonzero(~by_values)  # interval k-1 -> k at index k-1
    V: dict[int, ComplexArray] = {}
    Wl: dict[int, ComplexArray] = {}
    points = np.unique(np.concatenate([hard, hard + 1]))
    if points.size:
        we, Ve, We = decompose(S[points])
        for i, p in enumerate(points):
            # the vectors in the order of w[p] (eig's eigenvalues equal eigvals' to rounding)
            order = match_branches(we[i], w[p])
            V[int(p)], Wl[int(p)] = Ve[i][:, order], We[i][order, :]
    for k in range(1, N):
        prev = perm[k - 1]
        if by_values[k - 1]:
            perm[k] = near[k - 1].take(prev)
        else:
            perm[k], conf[k] = _link_by_vectors(w[k - 1][prev], Wl[k - 1][prev], V[k], w[k])
    rows = np.flatnonzero(by_values) + 1
    conf[rows] = 1.0 - np.take_along_axis(ratio[rows - 1], perm[rows - 1], axis=1)
    return perm, conf


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


def _numbering(w: ComplexArray, damped: bool = False) -> tuple[NDArray[np.intp], NDArray[np.intp]]:
    """(mode number of each eigenvalue, representatives in mode order): see :func:`mode_numbers`."""
    if damped:
        reps, partners = damped_modes(w)
        numbers = np.zeros(w.size, dtype=np.intp)
        numbers[reps] = np.arange(1, reps.size + 1)
        for other, rep in partners.items():
            numbers[other] = numbers[rep]
        return numbers, reps
    scale = max(float(np.max(np.abs(w))), 1e-300)
    tol = 1e-9 * scale
    real = np.abs(w.imag) <= tol
    lower = w.imag < -tol
    for i in np.flatnonzero(real & (w.real < 0)):
        mirror = real & (w.real > 0) & (np.abs(w.real + w[i].real) <= 1e-6 * scale)
        if mirror.any():
            lower[i] = True
    upper = np.flatnonzero(~lower)
    order = upper[np.lexsort((w.real[upper], np.abs(w.imag[upper])))]
    number = np.zeros(w.size, dtype=np.intp)
    number[order] = np.arange(1, order.size + 1)
    low = np.flatnonzero(lower)
    if low.size:  # each lower eigenvalue's partner among the numbered ones, all at once
        wo, wl = w[order][None, :], w[low][:, None]
        partner = order[np.argmin(np.abs(wo - np.conj(wl)) * np.abs(wo + wl), axis=1)]
        number[low] = number[partner]
    return number, order


def mode_numbers(w: ComplexArray, damped: bool = False) -> NDArray[np.intp]:
    """Mode number (1-based, by frequency) of each eigenvalue of one point; pairs share it.

    A conjugate pair is one mode, and so is a real pair +-s (a divergent mode of the
    conservative v = 0 system); other real eigenvalues are modes of frequency 0 (they
    come first).  ``damped``: by natural frequency, an over-damped pair of real roots being
    one mode (:func:`damped_modes`), so that the heavily damped high modes of Kelvin-Voigt
    damping do not displace the fundamental.
    """
    return _numbering(w, damped)[0]


def order_lowest(w: ComplexArray, count: int, damped: bool = False) -> NDArray[np.intp]:
    """Indices of the ``count`` lowest-numbered modes at one point (:func:`mode_numbers`),
    one eigenvalue per mode: omega >= 0 of a conjugate pair, +s of a real pair +-s."""
    return _numbering(w, damped)[1][:count]


def least_stable_branch(xi: ComplexArray, candidates: NDArray[np.intp]) -> int:
    """The branch among ``candidates`` (columns of ``xi``, in order of preference: the
    modes' representatives by mode number first) whose largest sigma over the points is
    largest; within rounding of the maximum, the first candidate."""
    peak = xi[:, candidates].real.max(axis=0)
    level = float(np.max(rounding_level(xi)))
    return int(candidates[np.flatnonzero(peak >= peak.max() - level)[0]])


def match_branches(w: ComplexArray, targets: ComplexArray) -> NDArray[np.intp]:
    """Indices into the eigenvalues ``w`` of one point of the ones nearest ``targets``
    (optimal assignment on |w_i - target_j|): how another decomposition of the same matrix,
    or of the same first point, finds the branches a selection traced."""
    rows, cols = linear_sum_assignment(np.abs(w[:, None] - np.asarray(targets)[None, :]))
    out = np.empty(cols.size, dtype=np.intp)
    out[cols] = rows
    return out


def track(
    S: NDArray[np.float64], modes: int, least_stable: bool = False, damped: bool = False
) -> Traces:
    """Eigenvalues of each ``S[k]`` (shape ``(N, m, m)``), the ``modes`` lowest tracked.

    Branches are chosen at the first point (lowest mode numbers, one per mode) and
    followed by optimal assignment of left/right eigenvector overlaps.  With
    ``least_stable`` the least stable branch of the whole spectrum
    (:func:`least_stable_branch`) is traced too, as an extra column when it is not among
    the lowest, and its column recorded in ``Traces.least_stable``.  ``damped``: modes
    numbered by natural frequency (:func:`mode_numbers`).
    """
    return select(*spectrum(S, damped), modes, least_stable, damped)


def spectrum(
    S: NDArray[np.float64], damped: bool = False
) -> tuple[ComplexArray, FloatArray, NDArray[np.intp]]:
    """Every branch of ``S[k]`` followed: ``(xi, confidence, mode)`` with ``xi[k, j]``
    branch j at point k [1/s] and ``mode[j]`` its mode number at the first point.

    Eigenvalues by one batched ``numpy.linalg.eigvals``; eigenvectors only at the points
    where the eigenvalues alone cannot link the branches (:func:`link`)."""
    w = np.asarray(np.linalg.eigvals(S), dtype=complex)
    perm, conf = link(S, w)
    return np.take_along_axis(w, perm, axis=1), conf, mode_numbers(w[0], damped)


def select(
    xi: ComplexArray,
    confidence: FloatArray,
    mode: NDArray[np.intp],
    modes: int | ComplexArray,
    least_stable: bool = False,
    damped: bool = False,
) -> Traces:
    """Branches of a followed spectrum: the ``modes`` lowest (and, with ``least_stable``,
    the least stable one), or the branches whose first-point eigenvalues ``modes`` gives
    (``Traces.xi[0]`` of another selection, e.g. the same branches of P(t)/t; matched by
    :func:`match_branches`); ``damped``: numbered as :func:`mode_numbers` says."""
    representatives = _numbering(xi[0], damped)[1]
    if isinstance(modes, int):
        chosen = representatives[:modes]
    else:
        chosen = match_branches(xi[0], np.asarray(modes))
    flagged: int | None = None
    if least_stable:
        # every branch is a candidate: after a pair splits on the real axis the growing
        # root may be followed by the member that was not its mode's representative
        others = np.setdiff1d(np.arange(xi.shape[1]), representatives)
        j = least_stable_branch(xi, np.concatenate([representatives, others]))
        hit = np.flatnonzero(chosen == j)
        if hit.size:
            flagged = int(hit[0])
        else:
            chosen = np.append(chosen, j)
            flagged = chosen.size - 1
    return Traces(
        xi=xi[:, chosen],
        confidence=confidence[:, chosen],
        mode=mode[chosen],
        least_stable=flagged,
        branch=chosen,
    )


@dataclass
class Branches:
    """Every eigenvalue branch of ``S(p)`` followed along a 1-D parameter grid ``p``.

    ``xi[k, j]``: branch j at ``p[k]`` [1/s]; ``confidence[k, j]``: the eigenvector overlap
    that linked point k to k-1 (1 at k = 0); ``mode[j]``: its mode number at ``p[0]``;
    ``inserted[k]``: point k was added by refinement.  ``W`` holds the left eigenvectors
    (rows, ordered like ``xi``) for evaluating a branch between grid points.
    """

    p: FloatArray
    xi: ComplexArray
    confidence: FloatArray
    mode: NDArray[np.intp]
    inserted: NDArray[np.bool_]
    W: ComplexArray
    matrices: Callable[[FloatArray], FloatArray]

    def branch_at(self, j: int, k: int, p: float) -> complex:
        """Eigenvalue [1/s] of branch j at parameter ``p`` (near the grid interval of point k).

        Picked by the largest overlap of the left eigenvector of branch j at ``p[k]`` with
        the right eigenvectors at ``p``.
        """
        # anchor at the nearer grid point, so that the grid values are reproduced exactly
        if k + 1 < self.p.size and abs(p - self.p[k + 1]) < abs(p - self.p[k]):
            k += 1
        w, V, _ = decompose(self.matrices(np.array([float(p)])))
        overlap = np.abs(self.W[k, j] @ V[0])
        if not np.all(np.isfinite(overlap)):
            return complex(w[0][np.argmin(np.abs(w[0] - self.xi[k, j]))])
        return complex(w[0][np.argmax(overlap)])

    def upper(self, j: int, k: int) -> bool:
        """Branch j at point k has omega >= 0 (one member of a pair, or real)."""
        return bool(self.xi[k, j].imag >= -1e-9 * abs(self.xi[k, j]))


def follow(
    matrices: Callable[[FloatArray], FloatArray],
    grid: ArrayLike,
    watch: Callable[[ComplexArray], NDArray[np.intp]] | None = None,
    min_confidence: float = 0.0,
    max_points: int = 0,
    max_levels: int = 6,
    progress: Progress | None = None,
    damped: bool = False,
) -> Branches:
    """Follow all eigenvalue branches of ``matrices(p)`` along ``grid``, refining as needed.

    Where the tracking confidence of a watched branch (``watch(xi[0])`` gives their
    indices; all branches by default) drops below ``min_confidence`` between two points, the
    midpoint is inserted, up to ``max_levels`` halvings and ``max_points`` points in all.
    Near a coalescence of eigenvalues (exceptional point) the eigenvectors become parallel
    and the confidence stays low however fine the grid: the refinement stops there and the
    low confidence is reported.  Without refinement this is :func:`spectrum`.  ``damped``:
    modes numbered by natural frequency (:func:`mode_numbers`).
    """
    p = np.asarray(grid, dtype=float)
    inserted = np.zeros(p.size, dtype=bool)
    w, V, W = decompose(matrices(p))
    perm, conf = assign(w, V, W)
    watched = np.arange(w.shape[1]) if watch is None else watch(w[0])
    for level in range(max_levels):
        if min_confidence <= 0 or p.size >= max_points:
            break
        low = np.min(conf[:, watched], axis=1)
        bad = np.flatnonzero(low[1:] < min_confidence)  # interval (k, k+1)
        bad = bad[: max(0, max_points - p.size)]
        if bad.size == 0:
            break
        new = 0.5 * (p[bad] + p[bad + 1])
        w2, V2, W2 = decompose(matrices(new))
        order = np.argsort(np.concatenate([p, new]), kind="stable")
        p = np.concatenate([p, new])[order]
        inserted = np.concatenate([inserted, np.ones(new.size, dtype=bool)])[order]
        w = np.concatenate([w, w2])[order]
        V = np.concatenate([V, V2])[order]
        W = np.concatenate([W, W2])[order]
        perm, conf = assign(w, V, W)
        if progress is not None:
            progress(min(0.9, 0.5 + 0.1 * level))
    xi = np.take_along_axis(w, perm, axis=1)
    Wb = np.take_along_axis(W, perm[:, :, None], axis=1)
    return Branches(
        p=p,
        xi=xi,
        confidence=conf,
        mode=mode_numbers(w[0], damped),
        inserted=inserted,
        W=Wb,
        matrices=matrices,
    )
