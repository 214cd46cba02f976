"""Static deflection of the continuous pipe at a frozen operating point (issue 32).

The static (W = 0) form of the pipe's equation (``docs/model.md``; physics notes sec. 1, 5)
at constant flow v [m/s] and spin w0 [rad/s]::

    EI u'''' + (M2 v^2 - T) u'' - T' u' - s m w0^2 u = q(x) + F delta(x - a),
    T(x) = M1 w0^2 [R (L - x) + (L^2 - x^2)/2] + m_t w0^2 (R + L),
    x = 0: u = u' = 0;   x = L: EI u'' = 0,  EI u''' - T(L) u' + s m_t w0^2 u = -F_L,

(m = M1 + M2; s = 1 in-plane, 0 out-of-plane; damping, the Coriolis term and the tip's
rotary inertia have no static part).  A point force at 0 < a < L is a jump of the shear
force, EI [u''']_a = F, with u, u', u'' continuous; at a = L it is F_L.  A clamp
acceleration A is the inertial load q = -m A and F_L = -m_t A.

Solved by Chebyshev collocation on the two subdomains [0, a] and [a, L] (Trefethen,
*Spectral Methods in MATLAB*, SIAM 2000) in the integral form (Greengard, SIAM J. Numer.
Anal. 28, 1991): the unknowns are u'''' at the points and u, u', u'', u''' at the left end
of each subdomain; the lower derivatives follow by Chebyshev cumulative integration, the
field equation holds at every point and the 8 end and interface conditions fix the 8
constants.  Powers of the differentiation matrix would lose ~N^8 eps (5.7e-7 at N = 32);
integration loses next to nothing.  The solution is smooth on each subdomain, so the
collocation converges spectrally: with :data:`COLLOCATION_POINTS` per subdomain it is exact
to rounding for the bare cantilever (a cubic) and converged with flow and spin.

:func:`pipeflow.frequency.frequency_response` uses it for the residual flexibility (the
static correction of the modes the Galerkin sum leaves out).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from functools import lru_cache

import numpy as np
from numpy.polynomial import chebyshev as C
from numpy.typing import ArrayLike, NDArray

from pipeflow.model import Pipe
from pipeflow.supports import spin_axial_force, static_axial_force

FloatArray = NDArray[np.float64]

#: Chebyshev points per subdomain, minus one (the polynomial degree)
COLLOCATION_POINTS = 24


@lru_cache(maxsize=8)
def _integration(N: int) -> tuple[FloatArray, FloatArray]:
    """Chebyshev points t_j = -cos(pi j / N) on [-1, 1] (from -1 to 1) and the matrix Q
    with (Q g)_j = integral from -1 to t_j of the interpolant of g at the points (through
    the Chebyshev coefficients; cumulative integration is well conditioned, unlike powers
    of the differentiation matrix)."""
    t: FloatArray = -np.cos(np.pi * np.arange(N + 1) / N)
    coef = np.linalg.solve(C.chebvander(t, N), np.eye(N + 1))  # values -> coefficients
    Q: FloatArray = np.asarray(C.chebval(t, C.chebint(coef, lbnd=-1.0)).T, dtype=float)
    t.setflags(write=False)
    Q.setflags(write=False)
    return t, Q


def _interpolation(t: FloatArray, to: FloatArray) -> FloatArray:
    """The matrix taking values at the Chebyshev points ``t`` (-cos(pi j / N)) to the
    interpolant's values at ``to`` (both on [-1, 1]): the barycentric formula with the
    points' own weights (-1)^j, halved at the ends (Berrut & Trefethen, SIAM Rev. 46, 2004)."""
    w = (-1.0) ** np.arange(t.size)
    w[0] *= 0.5
    w[-1] *= 0.5
    diff = to[:, None] - t[None, :]
    exact = diff == 0.0
    with np.errstate(divide="ignore", invalid="ignore"):
        terms = w[None, :] / diff
        P = terms / terms.sum(axis=1, keepdims=True)
    hit = exact.any(axis=1)
    P[hit] = exact[hit].astype(float)
    return np.asarray(P)


def statics_cover(pipe: Pipe) -> bool:
    """Whether :func:`static_deflection` solves ``pipe``: every support set but a pipe free
    to rotate as a rigid body (its static problem is singular)."""
    return not pipe.rotates_rigidly


def _domain(
    x0: float, x1: float, t: FloatArray, Q0: FloatArray
) -> tuple[FloatArray, list[FloatArray]]:
    """xi on [x0, x1], and per derivative r = 0..4 the map from (g, c_0..c_3) to wr at xi
    (wr = sum_k c_k d^(k-r) / (k-r)! + Q^(4-r) g, d = xi - x0)."""
    n = t.size
    h = 0.5 * (x1 - x0)
    xi = x0 + h * (t + 1.0)
    Q = h * Q0
    d = xi - x0
    maps = []
    for r in range(5):
        Mr = np.zeros((n, n + 4))
        Mr[:, :n] = np.linalg.matrix_power(Q, 4 - r)
        for k in range(r, 4):
            Mr[:, n + k] = d ** (k - r) / math.factorial(k - r)
        maps.append(Mr)
    return xi, maps


class StaticSolution:
    """A solved static problem (:func:`static_solution`): the deflection and its
    derivatives anywhere on [0, L] by the subdomains' Chebyshev interpolants."""

    def __init__(
        self, L: float, EI: float, edges: list[float], nodes: FloatArray, values: list[FloatArray]
    ) -> None:
        self.L, self.EI = L, EI
        self._edges = np.asarray(edges)
        self._t = nodes
        #: per subdomain, (5, points): w^(r) at its points, xi = x / L, w = u EI / L^3
        self._values = values

    def at(self, positions: ArrayLike, derivative: int = 0) -> FloatArray:
        """d^r u / dx^r at ``positions`` x [m] in [0, L], r = 0..3 [m^(1-r) per unit load]
        (non-finite where the static problem is singular)."""
        return np.asarray(self.derivatives(positions, (derivative,))[0])

    def derivatives(self, positions: ArrayLike, orders: tuple[int, ...]) -> FloatArray:
        """:meth:`at` for each derivative of ``orders`` (r in 0..3), shape
        (len(orders), len(positions)): the interpolation to the positions formed once."""
        xo = np.atleast_1d(np.asarray(positions, dtype=float)) / self.L
        K = len(self._values)
        where = np.clip(np.searchsorted(self._edges, xo, side="right") - 1, 0, K - 1)
        rows = list(orders)
        out = np.empty((len(rows), xo.size))
        for k in range(K):
            sel = where == k
            if np.any(sel):
                x0, x1 = self._edges[k], self._edges[k + 1]
                to = 2.0 * (xo[sel] - x0) / (x1 - x0) - 1.0
                out[:, sel] = self._values[k][rows] @ _interpolation(self._t, to).T
        scale = np.array([self.L ** (3 - r) for r in rows]) / self.EI
        return np.asarray(out * scale[:, None])


def static_deflection(
    pipe: Pipe,
    velocity: float,
    omega0: float,
    positions: ArrayLike,
    *,
    force_at: float | None,
    N: int = COLLOCATION_POINTS,
) -> FloatArray:
    """Static deflection u(x) [m per unit load] at ``positions`` x [m] in [0, L]
    (:func:`static_solution`)."""
    return static_solution(pipe, velocity, omega0, force_at=force_at, N=N).at(positions)


def static_solution(
    pipe: Pipe,
    velocity: float,
    omega0: float,
    *,
    force_at: float | None,
    N: int = COLLOCATION_POINTS,
    density: Callable[[FloatArray], FloatArray] | None = None,
    tip_force: float = 0.0,
) -> StaticSolution:
    """The static deflection of ``pipe`` per unit load (:class:`StaticSolution`).

    ``force_at`` a [m] in (0, L]: a unit transverse force [N] there (u in m/N);
    ``None``: a unit acceleration [m/s^2] of the supports (u relative to them, in s^2), or
    with ``density`` the distributed load q(x) [N/m per unit load] it gives at x [m] and
    ``tip_force`` [N per unit load] on a free or elastic end at L.
    ``velocity`` v [m/s] and ``omega0`` w0 [rad/s] set the frozen operating point.
    Any end supports and springs, intermediate pins and springs (a spring as stiff as
    :data:`pipeflow.supports.RIGID_POINT_SPRING` is a pin, as in the model), the axial force
    of tension, pressure and gravity (:func:`pipeflow.supports.static_axial_force`) and of
    the spin (:func:`pipeflow.supports.spin_axial_force`), a tip mass.  Non-finite values
    where the static problem is singular (divergence, a rigid rotation).
    """
    L, m, M2, EI = pipe.L, pipe.mass, pipe.M2, pipe.EI
    mt = pipe.tip_mass
    s = 1.0 if pipe.in_plane else 0.0
    w2 = float(omega0) ** 2
    v2 = float(velocity) ** 2
    x0_end, xL_end = pipe.supports.x0, pipe.supports.xL
    at_tip = force_at is not None and force_at >= L
    t, Q0 = _integration(N)
    if at_tip and xL_end.fixes_deflection:
        # a force on a support that holds the deflection is its reaction: no deflection
        return StaticSolution(L, EI, [0.0, 1.0], t, [np.zeros((5, t.size))])
    key = pipe.basis_key
    springs = dict(key[2]) if key is not None else {}  # xi -> K = k L^3 / EI (inf: a pin)
    a_load = None if (force_at is None or at_tip) else float(force_at) / L
    breaks = sorted(set(springs) | ({a_load} if a_load is not None else set()))
    edges = [0.0, *breaks, 1.0]
    n = N + 1
    size = n + 4
    K = len(edges) - 1  # subdomains
    # N(xi) [N], tension positive, at rest plus the spin's: each a0 + a1 xi + a2 xi^2
    a_rest, a_spin = static_axial_force(pipe), spin_axial_force(pipe)
    a = [a_rest[k] + w2 * a_spin[k] for k in range(3)]
    # In xi = x / L with u = (L^3 / EI) w, the field equation times L^4 / EI over L^3 / EI:
    #   w4 + (M2 v^2 - N) L^2 / EI w2 - N' L^3 / EI w1 - s m w0^2 L^4 / EI w = q L
    # (wr the r-th derivative, N' = dN/dx).  On each subdomain the unknowns are g = w4 at its
    # points and c_r = wr at its left end (:func:`_domain`).  The field equation holds at
    # every point; the ends give 2 conditions each and every interface 4.
    A = np.zeros((K * size, K * size))
    rhs = np.zeros(K * size)
    doms = [_domain(edges[k], edges[k + 1], t, Q0) for k in range(K)]
    cols = [slice(k * size, (k + 1) * size) for k in range(K)]
    for k, (xi, maps) in enumerate(doms):
        Nx = a[0] + a[1] * xi + a[2] * xi * xi
        dN = (a[1] + 2.0 * a[2] * xi) / L
        rows = slice(k * n, (k + 1) * n)
        A[rows, cols[k]] = (
            maps[4]
            + ((M2 * v2 - Nx) * L * L / EI)[:, None] * maps[2]
            - (dN * L**3 / EI)[:, None] * maps[1]
            - s * m * w2 * L**4 / EI * maps[0]
        )
        if density is not None:
            rhs[rows] = density(xi * L) * L
        elif force_at is None:
            rhs[rows] = -m * L
    row = K * n
    for k, b in enumerate(breaks):  # the interface between subdomains k and k + 1
        left, right = doms[k][1], doms[k + 1][1]
        lc, rc = cols[k], cols[k + 1]
        stiffness = springs.get(b, 0.0)
        if math.isinf(stiffness):  # a pin: w = 0 on both sides, slope and moment go on
            A[row, lc], A[row + 1, rc] = left[0][N], right[0][0]
            for r, at in ((1, row + 2), (2, row + 3)):
                A[at, lc], A[at, rc] = left[r][N], -right[r][0]
        else:  # w, w', w'' go on; the shear jumps by the force less the spring's pull
            for r in range(3):
                A[row + r, lc], A[row + r, rc] = left[r][N], -right[r][0]
            A[row + 3, lc] = -left[3][N] + stiffness * left[0][N]
            A[row + 3, rc] = right[3][0]
            if b == a_load:
                rhs[row + 3] = 1.0
        row += 4
    # each end's two conditions (docs/model.md 9), with its springs and the axial force
    ends = (
        (x0_end, doms[0][1], 0, -1.0, a[0], cols[0], row),
        (xL_end, doms[-1][1], N, 1.0, a[0] + a[1] + a[2], cols[-1], row + 2),
    )
    for end, maps, j, sign, N_end, c, at in ends:
        kind, Kt, Kr = end.nondimensional(EI, L)
        w, w1, w2_, w3 = (maps[r][j] for r in range(4))
        shear = w3 - N_end * L * L / EI * w1
        if kind == "clamped":
            conds = (w, w1)
        elif kind == "pinned":
            conds = (w, w2_)
        elif kind == "sliding":
            conds = (w1, shear)
        else:
            # free or elastic: EI u'' = -sign k_r u', EI u''' - N u' = sign k_t u at x = 0
            # (sign -1) and x = L (sign +1), where a tip mass adds s m_t w0^2 u
            pull = s * mt * w2 * L**3 / EI if sign > 0 else 0.0
            conds = (w2_ + sign * Kr * w1, shear - sign * Kt * w + pull * w)
        if sign > 0 and at_tip:  # the tip's shear condition carries the force F_L = 1
            rhs[at + 1] = -1.0
        elif sign > 0 and force_at is None and kind in ("free", "elastic"):
            rhs[at + 1] = -tip_force if density is not None else mt  # F_L = -m_t A, A = 1
        A[at, c], A[at + 1, c] = conds
    with np.errstate(all="ignore"):
        try:
            z = np.linalg.solve(A, rhs)
        except np.linalg.LinAlgError:
            z = np.full(K * size, np.nan)
    values = [
        np.array([maps[r] @ z[cols[k]] for r in range(5)]) for k, (_, maps) in enumerate(doms)
    ]
    return StaticSolution(L, EI, edges, t, values)


def truncation_residual(
    pipe: Pipe,
    velocity: float,
    omega0: float,
    positions: ArrayLike,
    *,
    force_at: float | None,
    K: FloatArray,
    f: FloatArray,
    shapes: FloatArray,
) -> FloatArray | None:
    """The static response of the modes a Galerkin model leaves out [m per unit load]: the
    continuous pipe's :func:`static_deflection` at ``positions`` minus the model's own
    static part ``shapes @ K^-1 f`` (``K`` the model's stiffness at the operating point
    [N/m], ``f`` the load's generalised force per unit load, ``shapes`` phi_j at the
    positions, shape (p, n)).  None where the static problem is singular or ill-posed
    (divergence: cond(K) >= 1e12).  One definition for the frequency response's residual
    flexibility and the time history's mode-acceleration correction."""
    exact = static_deflection(pipe, velocity, omega0, positions, force_at=force_at)
    with np.errstate(all="ignore"):
        try:
            modal = shapes @ np.linalg.solve(K, f)
        except np.linalg.LinAlgError:
            return None
    r = np.asarray(exact - modal, dtype=float)
    if not (np.all(np.isfinite(r)) and np.linalg.cond(K) < 1e12):
        return None
    return r
