"""Clamped-free (cantilever) beam modes: the Galerkin basis of eq. (2)-(3).

All functions work on the non-dimensional coordinate ``xi = x / L`` in [0, 1].
The modes returned here are normalised so that ``integral_0^1 phi_j(xi)^2 dxi = 1``
(tip value ``|phi_j(1)| = 2``).  The paper's eq. (3) shape is a multiple of ours:
``phi_paper_j = paper_scale(j) * phi_j`` (tip value of the first paper mode: 2.7244).

Numerical form
--------------
The textbook form ``cosh z - cos z - s (sinh z - sin z)`` subtracts two numbers of size
``e^z / 2``; with ``z`` up to ``lambda_40 ~ 124.9`` that loses every digit past about the
twelfth mode.  We rewrite it with decaying exponentials only (Goncalves, Brennan & Elliott,
J. Sound Vib. 301, 2007; Tang, J. Eng. Mech. 129, 2003)::

    phi(z) = a e^(z - lambda) + b e^(-z) - cos z + s sin z

with ``a = (1 - s) e^lambda / 2`` and ``b = (1 + s) / 2`` computed without overflow.
"""

from __future__ import annotations

from functools import cache, lru_cache

import numpy as np
from scipy.optimize import brentq

from pipeflow._types import FloatArray

MAX_MODES = 40


def _root_function(z: float) -> float:
    # cos z cosh z + 1 = 0 rewritten as cos z + 1/cosh z = 0: no overflow, same roots.
    return float(np.cos(z) + 1.0 / np.cosh(z))


@cache
def cantilever_roots(n: int) -> tuple[float, ...]:
    """First ``n`` roots ``lambda_j = theta_j L`` of ``cos(z) cosh(z) = -1`` [-].

    Each root is bracketed in ``((j - 1/2) pi, j pi)`` and refined with Brent's method
    to full double precision (xtol 4 ulp).  Values agree with Rao, *Mechanical
    Vibrations*, Table 8.1: 1.8751040687, 4.6940911330, 7.8547574382, 10.995540735.
    """
    if n < 1:
        raise ValueError(f"number of modes must be >= 1, got {n}")
    roots = []
    for j in range(1, n + 1):
        lo, hi = (j - 0.5) * np.pi, j * np.pi
        if j > 1:
            # for j >= 2 the root sits within 1e-2 of (j - 1/2) pi; keep the bracket tight
            lo, hi = (j - 0.5) * np.pi - 0.1, (j - 0.5) * np.pi + 0.1
        roots.append(brentq(_root_function, lo, hi, xtol=1e-15, rtol=4 * np.finfo(float).eps))
    return tuple(float(r) for r in roots)


def _coefficients(lam: float) -> tuple[float, float, float]:
    """Return ``(a, b, s)`` of the stable form for one root ``lam``."""
    e = np.exp(-lam)
    sn, cs = np.sin(lam), np.cos(lam)
    # s = (cosh lam + cos lam) / (sinh lam + sin lam), multiplied through by 2 e^-lam
    den = 1.0 - e * e + 2.0 * sn * e
    s = (1.0 + e * e + 2.0 * cs * e) / den
    # a = (1 - s) e^lam / 2 = (sin lam - cos lam - e^-lam) / den
    a = (sn - cs - e) / den
    b = 0.5 * (1.0 + s)
    return float(a), float(b), float(s)


def mode_shapes(n: int, xi: FloatArray, derivative: int = 0) -> FloatArray:
    """Mode shapes or their derivatives on the unit interval.

    Parameters
    ----------
    n : int
        Number of modes.
    xi : array
        Non-dimensional positions ``x / L`` [-].
    derivative : int
        Order ``k`` of the derivative with respect to ``xi`` (0 to 4).

    Returns
    -------
    array of shape ``(n, len(xi))``: ``d^k phi_j / d xi^k`` [-].  For a derivative
    with respect to the dimensional ``x``, divide by ``L**k``.
    """
    if not 0 <= derivative <= 4:
        raise ValueError("derivative order must be 0..4")
    xi = np.asarray(xi, dtype=float).reshape(-1)
    k = derivative
    lam, a, b, s = _all_coefficients(n)  # every mode at once: (n, 1) columns
    z = lam * xi[None, :]
    # d^k/dz^k of -cos z + s sin z: rotate the phase by k * pi/2
    trig = -np.cos(z + k * np.pi / 2) + s * np.sin(z + k * np.pi / 2)
    return np.asarray(lam**k * (a * np.exp(z - lam) + (-1) ** k * b * np.exp(-z) + trig))


@cache
def _all_coefficients(n: int) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """The roots and ``(a, b, s)`` of the first ``n`` modes as (n, 1) columns (read-only)."""
    lam = np.array(cantilever_roots(n))
    cols = [lam, *np.array([_coefficients(r) for r in lam]).T]
    out = tuple(np.ascontiguousarray(c, dtype=float).reshape(-1, 1) for c in cols)
    for c in out:
        c.setflags(write=False)
    return out  # type: ignore[return-value]


def tip_values(n: int) -> FloatArray:
    """``phi_j(1)`` for the normalised modes [-] (equal to ``2 (-1)^(j+1)``)."""
    return mode_shapes(n, np.array([1.0]))[:, 0]


def paper_scale(n: int) -> FloatArray:
    """Factor from our normalised modes to the paper's eq. (3) shapes [-].

    Eq. (3) is ``sin - sinh + r (cosh - cos)`` with ``r = (sin + sinh)/(cos + cosh)``,
    which equals ``r * phi_j``; ``r = 1.3622`` for the first mode.
    """
    out = np.empty(n)
    for j, lam in enumerate(cantilever_roots(n)):
        _, _, s = _coefficients(lam)
        out[j] = 1.0 / s
    return out


@lru_cache(maxsize=256)
def gauss_legendre_unit(order: int) -> tuple[FloatArray, FloatArray]:
    """Gauss-Legendre nodes and weights on [0, 1] (cached: read-only arrays)."""
    x, w = np.polynomial.legendre.leggauss(order)
    nodes, weights = 0.5 * (x + 1.0), 0.5 * w
    nodes.setflags(write=False)
    weights.setflags(write=False)
    return nodes, weights


def default_quadrature_order(n: int) -> int:
    """Quadrature order that integrates products of ``n`` modes to rounding.

    The highest product oscillates like ``sin(2 lambda_n xi)``; Gauss-Legendre with
    ``q`` points is exact to rounding once ``q`` exceeds about ``lambda_n + 30``.
    """
    return int(max(48, np.ceil(cantilever_roots(n)[-1] + 40)))


def tip_slopes(n: int) -> FloatArray:
    """``phi_j'(1)``, the slopes d phi_j / d xi at the free end [-] (tip-inertia terms)."""
    return mode_shapes(n, np.array([1.0]), 1)[:, 0]
