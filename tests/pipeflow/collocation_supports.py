"""An independent solution of the supported, pressurised, tensioned, hanging pipe for the tests:
Chebyshev collocation of the non-dimensional PDE with the boundary conditions imposed
directly (Trefethen, *Spectral Methods in MATLAB*, SIAM 2000, ch. 6-7 and 14).

It shares nothing with ``pipeflow.beam_modes`` / ``pipeflow.model`` (no basis, no weak form).
The equation is Paidoussis, *Fluid-Structure Interactions* vol. 1 (2014), eqs. (3.70)-(3.71)
with gravity as in sec. 3.5.3, on xi in [0, 1] with tau = t sqrt(EI / (m L^4))::

    eta'''' + (u^2 - N) eta'' - N' eta' + 2 u sqrt(beta) eta_dot' + eta_ddot = 0,
    N(xi) = Gamma - Pi_eff + g_x (1 - xi)        (tension positive, [-], N L^2 / EI)

(g_x = +gamma hanging from xi = 0, -gamma standing), and at each end one of
clamped (eta = eta' = 0), pinned (eta = eta'' = 0), sliding (eta' = eta''' - N eta' = 0),
free (eta'' = 0, eta''' - N eta' = 0) or elastic (x = 0: eta'' = K_r eta',
eta''' - N eta' = -K_t eta; x = 1: eta'' = -K_r eta', eta''' - N eta' = K_t eta).
"""

from __future__ import annotations

import math

import numpy as np
import scipy.linalg

from tests.pipeflow.collocation import cheb

End = tuple[str, float, float]


def eigenvalues(
    x0: End,
    xL: End,
    u: float,
    beta: float,
    axial: tuple[float, float] = (0.0, 0.0),
    N: int = 48,
) -> np.ndarray:
    """Finite eigenvalues lambda (non-dimensional, e^(lambda tau)) of the collocated PDE.

    ``axial`` = (N0, g_x): N(xi) = N0 + g_x (1 - xi)."""
    t, D = cheb(N)
    x = 0.5 * (1.0 - t)  # x[0] = 0, x[N] = 1
    D1 = -2.0 * D
    D2 = D1 @ D1
    D3 = D2 @ D1
    D4 = D2 @ D2
    n = N + 1
    Id = np.eye(n)
    N0, gx = axial
    Nx = N0 + gx * (1.0 - x)
    dN = -gx * np.ones(n)
    A2 = Id.copy()
    A1 = 2.0 * u * math.sqrt(beta) * D1
    A0 = D4 + (u * u - Nx)[:, None] * D2 - dN[:, None] * D1
    rows = [0, 1, N - 1, N]
    for A in (A2, A1, A0):
        A[rows] = 0.0

    def conditions(spec: End, j: int) -> list[np.ndarray]:
        kind, kt, kr = spec
        shear = D3[j] - Nx[j] * D1[j]
        sign = 1.0 if j == N else -1.0
        return {
            "clamped": [Id[j], D1[j]],
            "pinned": [Id[j], D2[j]],
            "sliding": [D1[j], shear],
            "free": [D2[j], shear],
            "elastic": [D2[j] + sign * kr * D1[j], shear - sign * kt * Id[j]],
        }[kind]

    A0[0], A0[1] = conditions(x0, 0)
    A0[N - 1], A0[N] = conditions(xL, N)
    Z = np.zeros((n, n))
    A = np.block([[Z, Id], [-A0, -A1]])
    B = np.block([[Id, Z], [Z, A2]])
    lam = scipy.linalg.eig(A, B, right=False)
    return np.asarray(lam[np.isfinite(lam) & (np.abs(lam) < 1e8)])


def lowest(lam: np.ndarray, k: int) -> np.ndarray:
    """The ``k`` eigenvalues of smallest modulus with omega >= 0 (one of each pair)."""
    keep = lam[lam.imag >= -1e-9]
    return np.asarray(keep[np.argsort(np.abs(keep))][:k])


def eigenvalues_spans(
    x0: End, xL: End, xs: float, K: float, u: float, beta: float, N: int = 32
) -> np.ndarray:
    """As :func:`eigenvalues` (no axial force) with an intermediate support at ``xs``: a pin
    (``K`` = inf: eta = 0 on both sides) or a spring K = k L^3 / EI (eta continuous, the
    shear jump eta'''(xs+) - eta'''(xs-) = -K eta); eta' and eta'' continuous.  Two
    Chebyshev subdomains [0, xs] and [xs, 1] of N + 1 points each, the interface conditions
    in the rows of the points nearest it (as the end conditions)."""
    _, D = cheb(N)
    n = N + 1
    spans = ((0.0, xs), (xs, 1.0))
    Ds = []
    for a, b in spans:
        D1 = -2.0 / (b - a) * D  # x = a + (b - a) (1 - t) / 2: x[0] = a, x[N] = b
        Ds.append((np.eye(n), D1, D1 @ D1, D1 @ D1 @ D1, D1 @ D1 @ D1 @ D1))
    m = 2 * n
    A2, A1, A0 = np.eye(m), np.zeros((m, m)), np.zeros((m, m))
    for s, (_, D1, D2, _, D4) in enumerate(Ds):
        block = slice(s * n, (s + 1) * n)
        A1[block, block] = 2.0 * u * math.sqrt(beta) * D1
        A0[block, block] = D4 + u * u * D2
    rows = [0, 1, N - 1, N, n, n + 1, n + N - 1, n + N]
    for A in (A2, A1, A0):
        A[rows] = 0.0

    def row(s: int, k: int, j: int) -> np.ndarray:
        out = np.zeros(m)
        out[s * n : (s + 1) * n] = Ds[s][k][j]
        return out

    def end(spec: End, s: int, j: int, sign: float) -> list[np.ndarray]:
        kind, kt, kr = spec
        return {
            "clamped": [row(s, 0, j), row(s, 1, j)],
            "pinned": [row(s, 0, j), row(s, 2, j)],
            "sliding": [row(s, 1, j), row(s, 3, j)],
            "free": [row(s, 2, j), row(s, 3, j)],
            "elastic": [row(s, 2, j) + sign * kr * row(s, 1, j),
                        row(s, 3, j) - sign * kt * row(s, 0, j)],
        }[kind]  # fmt: skip

    A0[0], A0[1] = end(x0, 0, 0, -1.0)
    A0[n + N - 1], A0[n + N] = end(xL, 1, N, 1.0)
    if math.isinf(K):
        first, second = row(0, 0, N), row(1, 0, 0)
    else:
        first = row(0, 0, N) - row(1, 0, 0)
        second = row(1, 3, 0) - row(0, 3, N) + K * row(0, 0, N)
    A0[N - 1], A0[N] = first, row(0, 1, N) - row(1, 1, 0)
    A0[n], A0[n + 1] = second, row(0, 2, N) - row(1, 2, 0)
    Z = np.zeros((m, m))
    A = np.block([[Z, np.eye(m)], [-A0, -A1]])
    B = np.block([[np.eye(m), Z], [Z, A2]])
    lam = scipy.linalg.eig(A, B, right=False)
    return np.asarray(lam[np.isfinite(lam) & (np.abs(lam) < 1e8)])
