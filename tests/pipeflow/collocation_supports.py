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
