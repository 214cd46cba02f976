"""An independent discretisation of the extended pipe PDE for the tests: Chebyshev
collocation with the boundary conditions, tip body included, imposed directly.

It shares nothing with ``pipeflow.model`` / ``pipeflow.basis`` (no cantilever modes, no
Galerkin integrals, no weak form): the strong-form PDE of ``docs/model.md`` is collocated
at Chebyshev points on [0, L] and two rows at each end are replaced by the boundary
conditions (Trefethen, *Spectral Methods in MATLAB*, SIAM 2000, ch. 6-7 and 14)::

    m u_tt + (c + 2 M2 v d/dx) u_t + EI (1 + alpha d/dt) u_xxxx - s m w0^2 u
        - (T u_x)_x + M2 v^2 u_xx = 0,
    T(x) = M1 w0^2 [R (L - x) + (L^2 - x^2)/2] + m_t w0^2 (R + L),
    x = 0: u = u_x = 0,
    x = L: EI (1 + alpha d/dt) u_xx = -J_t u_xtt,
           EI (1 + alpha d/dt) u_xxx - T(L) u_x = m_t u_tt - s m_t w0^2 u,

s = 1 in-plane, 0 out-of-plane.  With u = U e^(lambda t) this is a quadratic eigenvalue
problem (A2 lambda^2 + A1 lambda + A0) U = 0, solved by linearisation with
``scipy.linalg.eig``; boundary rows without lambda^2 give infinite eigenvalues, dropped.
"""

from __future__ import annotations

import numpy as np
import scipy.linalg

from pipeflow.model import Pipe


def cheb(N: int) -> tuple[np.ndarray, np.ndarray]:
    """Chebyshev points x_j = cos(pi j / N) on [-1, 1] and the differentiation matrix
    (Trefethen 2000, program cheb.m)."""
    x = np.cos(np.pi * np.arange(N + 1) / N)
    c = np.ones(N + 1)
    c[0] = c[-1] = 2.0
    c *= (-1.0) ** np.arange(N + 1)
    X = np.tile(x, (N + 1, 1)).T
    dX = X - X.T
    D = np.outer(c, 1.0 / c) / (dX + np.eye(N + 1))
    D -= np.diag(D.sum(axis=1))
    return x, D


def eigenvalues(pipe: Pipe, v: float, w0: float, N: int = 48) -> np.ndarray:
    """Finite eigenvalues lambda [1/s] of the collocated PDE at constant v [m/s], w0 [rad/s]."""
    L, m, M1, M2, EI = pipe.L, pipe.mass, pipe.M1, pipe.M2, pipe.EI
    R, mt, J = pipe.hub_radius, pipe.tip_mass, pipe.tip_inertia
    alpha, c = pipe.kelvin_voigt, pipe.viscous
    s = 1.0 if pipe.plane == "in-plane" else 0.0
    t, D = cheb(N)
    x = 0.5 * L * (1.0 - t)  # x[0] = 0 (clamped), x[N] = L (free)
    D1 = -2.0 / L * D
    D2, D3 = D1 @ D1, D1 @ D1 @ D1
    D4 = D2 @ D2
    n = N + 1
    Id = np.eye(n)
    w2 = w0 * w0
    T = M1 * w2 * (R * (L - x) + 0.5 * (L**2 - x**2)) + mt * w2 * (R + L)
    dT = -M1 * w2 * (R + x)
    A2 = m * Id
    A1 = c * Id + 2.0 * M2 * v * D1 + alpha * EI * D4
    A0 = EI * D4 - s * m * w2 * Id - (T[:, None] * D2 + dT[:, None] * D1) + M2 * v * v * D2
    # boundary rows: 0, 1 at x = 0; N - 1, N at x = L
    for A in (A2, A1, A0):
        A[[0, 1, N - 1, N]] = 0.0
    A0[0, 0] = 1.0  # u(0) = 0
    A0[1] = D1[0]  # u_x(0) = 0
    A0[N - 1] = EI * D2[N]  # moment
    A1[N - 1] = alpha * EI * D2[N]
    A2[N - 1] = J * D1[N]
    A0[N] = EI * D3[N] - T[N] * D1[N] + s * mt * w2 * Id[N]  # shear
    A1[N] = alpha * EI * D3[N]
    A2[N] = -mt * Id[N]
    Z = np.zeros((n, n))
    A = np.block([[Z, Id], [-A0, -A1]])
    B = np.block([[Id, Z], [Z, A2]])
    lam = scipy.linalg.eig(A, B, right=False)
    return lam[np.isfinite(lam) & (np.abs(lam) < 1e12)]


def lowest(lam: np.ndarray, k: int) -> np.ndarray:
    """The k eigenvalues with Im >= 0 of smallest modulus (the low modes)."""
    up = lam[lam.imag >= -1e-9 * np.abs(lam)]
    return up[np.argsort(np.abs(up))][:k]


def harmonic_response(
    pipe: Pipe,
    v: float,
    w0: float,
    W: float,
    x_out: np.ndarray,
    a: float | None,
    N: int = 24,
) -> np.ndarray:
    """Steady harmonic response U(x_out) [m per unit load] of the collocated PDE to a unit
    point force e^(i W t) at x = a [m] (``a=None``: a unit transverse acceleration of the
    clamp, response relative to the clamp), at constant v [m/s], w0 [rad/s].

    The same strong form as :func:`eigenvalues` with u = U e^(i W t), on two Chebyshev
    subdomains [0, s] and [s, L] (s = a, or L/2 for the base load) joined by continuity
    of U, U_x, U_xx and the shear jump EI (1 + i W alpha) [U_xxx] = F (physics notes sec. 5:
    integrating the field equation across x = a, every other term being continuous); a
    force at the tip enters the shear condition instead, and the base acceleration is the
    inertial load -m per unit length and -m_t on the tip mass.  Interpolation to
    ``x_out`` is barycentric on each subdomain's Chebyshev points.
    """
    from scipy.interpolate import BarycentricInterpolator

    L, m, M1, M2, EI = pipe.L, pipe.mass, pipe.M1, pipe.M2, pipe.EI
    R, mt, J = pipe.hub_radius, pipe.tip_mass, pipe.tip_inertia
    alpha, c = pipe.kelvin_voigt, pipe.viscous
    s_plane = 1.0 if pipe.plane == "in-plane" else 0.0
    w2 = w0 * w0
    EIc = EI * (1.0 + 1j * W * alpha)
    at_tip = a is not None and a >= L
    split = L / 2 if (a is None or at_tip) else a
    t, D = cheb(N)
    n = N + 1
    Id = np.eye(n)

    def domain(x0: float, x1: float) -> tuple[np.ndarray, list[np.ndarray], np.ndarray]:
        x = x0 + 0.5 * (x1 - x0) * (1.0 - t)  # x[0] = x0, x[N] = x1
        D1 = -2.0 / (x1 - x0) * D
        D2 = D1 @ D1
        Ds = [Id, D1, D2, D2 @ D1, D2 @ D2]
        T = M1 * w2 * (R * (L - x) + 0.5 * (L**2 - x**2)) + mt * w2 * (R + L)
        dT = -M1 * w2 * (R + x)
        op = (
            (-W * W * m + 1j * W * c - s_plane * m * w2) * Id
            + 2j * W * M2 * v * D1
            + EIc * Ds[4]
            - (T[:, None] * D2 + dT[:, None] * D1)
            + M2 * v * v * D2
        )
        return x, Ds, op

    x1, D1s, op1 = domain(0.0, split)
    x2, D2s, op2 = domain(split, L)
    A = np.zeros((2 * n, 2 * n), dtype=complex)
    rhs = np.zeros(2 * n, dtype=complex)
    A[:n, :n] = op1
    A[n:, n:] = op2
    if a is None:
        rhs[:] = -m
    Tl = mt * w2 * (R + L)
    rows = [0, 1, N - 1, N, n, n + 1, 2 * n - 2, 2 * n - 1]
    A[rows] = 0.0
    rhs[rows] = 0.0
    A[0, 0] = 1.0  # U(0) = 0
    A[1, :n] = D1s[1][0]  # U_x(0) = 0
    # interface x = split (point N of domain 1, point 0 of domain 2)
    for row, k in ((N - 1, 0), (N, 1), (n, 2)):
        A[row, :n] = D1s[k][N]
        A[row, n:] = -D2s[k][0]
    A[n + 1, :n] = -EIc * D1s[3][N]
    A[n + 1, n:] = EIc * D2s[3][0]
    if a is not None and not at_tip:
        rhs[n + 1] = 1.0  # EI (1 + i W alpha) [U_xxx] = F
    # tip x = L: moment EI U_xx = W^2 J U_x; shear EI U_xxx - T(L) U_x = (-W^2 - s w0^2) m_t U - F
    A[2 * n - 2, n:] = EIc * D2s[2][N] - W * W * J * D2s[1][N]
    A[2 * n - 1, n:] = EIc * D2s[3][N] - Tl * D2s[1][N] + (W * W + s_plane * w2) * mt * Id[N]
    if at_tip:
        rhs[2 * n - 1] = -1.0
    elif a is None:
        rhs[2 * n - 1] = mt  # the tip mass's inertial load -m_t A, A = 1
    U = np.linalg.solve(A, rhs)
    x_out = np.asarray(x_out, dtype=float)
    out = np.empty(x_out.size, dtype=complex)
    left = x_out <= split
    for sel, x, u in ((left, x1, U[:n]), (~left, x2, U[n:])):
        if np.any(sel):
            out[sel] = BarycentricInterpolator(x, u)(x_out[sel])
    return out
