"""The Galerkin integrals of the model's basis (:func:`mode_integrals`): Gauss-Legendre
products of the cantilever modes (:mod:`pipeflow.basis`) or of the basis of any supports
(:func:`pipeflow.beam_modes.support_basis`), and the basis functions themselves
(:func:`basis_shapes`)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from pipeflow._types import FloatArray
from pipeflow.basis import (
    MAX_MODES,
    default_quadrature_order,
    gauss_legendre_unit,
    mode_shapes,
    tip_slopes,
    tip_values,
)
from pipeflow.beam_modes import BasisKey, support_basis

#: N(xi) = a0 + a1 xi + a2 xi^2 [N]: an axial force distribution (tension positive)
AxialForce = tuple[float, float, float]


@dataclass(frozen=True)
class ModeIntegrals:
    """Non-dimensional Galerkin integrals on xi in [0, 1] for ``n`` normalised modes.

    Entry (i, j) of each matrix is the integral over [0, 1] of the named product, with
    primes meaning d/dxi: ``gram = phi_i phi_j``, ``b = phi_i phi_j'``, ``c = phi_i phi_j''``,
    ``xb = xi phi_i phi_j'``, ``tc = (1 - xi^2) phi_i phi_j''``, ``k4 = phi_i phi_j''''``;
    ``d = phi_i' phi_j'``, ``xd = xi phi_i' phi_j'``; ``xf = xi phi_i`` and ``f = phi_i`` are
    vectors, and so are the end values ``tip = phi_i(1)`` and ``tip_slope = phi_i'(1)``.
    ``flex = phi_i'' phi_j''`` is the beam's own strain energy: ``k4`` less the springs'
    (None when no spring holds the pipe: it then equals ``k4``).
    """

    n: int
    quadrature_order: int
    gram: FloatArray
    b: FloatArray
    c: FloatArray
    xb: FloatArray
    tc: FloatArray
    k4: FloatArray
    xf: FloatArray
    d: FloatArray
    xd: FloatArray
    f: FloatArray
    tip: FloatArray
    x2d: FloatArray
    tip_slope: FloatArray
    flex: FloatArray | None = None


@lru_cache(maxsize=64)
def mode_integrals(
    n: int, quadrature_order: int | None = None, supports: BasisKey | None = None
) -> ModeIntegrals:
    """Gauss-Legendre evaluation of the Galerkin integrals (cached per ``(n, order)``) on the
    cantilever modes, or with ``supports`` (:attr:`Pipe.basis_key`) on the basis of
    :func:`pipeflow.beam_modes.support_basis` (``k4`` is then its diagonal bending matrix,
    the springs included)."""
    if not 1 <= n <= MAX_MODES:
        raise ValueError(f"modes must be between 1 and {MAX_MODES}, got {n}")
    if supports is None:
        q = default_quadrature_order(n) if quadrature_order is None else int(quadrature_order)
    else:
        basis = support_basis(n, *supports)
        top = max(m.lam for m in basis.modes)
        q = int(max(48, np.ceil(top + 40))) if quadrature_order is None else int(quadrature_order)
    if q < 2 * n:
        raise ValueError(f"quadrature order {q} is too low for {n} modes (need >= {2 * n})")
    xi, w = gauss_legendre_unit(q) if supports is None else basis.quadrature(q)
    if supports is None:
        p0, p1, p2, p4 = (mode_shapes(n, xi, k) for k in (0, 1, 2, 4))
        k4 = (p0 * w) @ p4.T
        tip, slope = tip_values(n), tip_slopes(n)
    else:
        p0, p1, p2 = (basis.shapes(xi, k) for k in (0, 1, 2))
        k4 = np.diag(basis.lam4)
        tip, slope = basis.shapes(np.ones(1), 0)[:, 0], basis.shapes(np.ones(1), 1)[:, 0]
    pw = p0 * w

    def ro(a: FloatArray) -> FloatArray:
        a = np.asarray(a)
        a.setflags(write=False)
        return a

    return ModeIntegrals(
        n=n,
        quadrature_order=q,
        gram=ro(pw @ p0.T),
        b=ro(pw @ p1.T),
        c=ro(pw @ p2.T),
        xb=ro((pw * xi) @ p1.T),
        tc=ro((pw * (1.0 - xi**2)) @ p2.T),
        k4=ro(k4),
        xf=ro(pw @ xi),
        d=ro((p1 * w) @ p1.T),
        xd=ro((p1 * (w * xi)) @ p1.T),
        f=ro(pw.sum(axis=1)),
        tip=ro(tip),
        tip_slope=ro(slope),
        x2d=ro((p1 * (w * xi * xi)) @ p1.T),
        flex=ro((p2 * w) @ p2.T) if supports is not None and _has_springs(supports) else None,
    )


def _has_springs(supports: BasisKey) -> bool:
    """Whether an elastic end or a point spring holds the pipe (its bending matrix then
    carries spring energy the beam's material damping does not act on)."""
    x0, xL, points = supports
    return x0[0] == "elastic" or xL[0] == "elastic" or any(not math.isinf(k) for _, k in points)


def basis_shapes(
    n: int, xi: FloatArray, derivative: int = 0, supports: BasisKey | None = None
) -> FloatArray:
    """d^k phi_j / dxi^k [-] of the model's basis (cantilever modes, or the supports' basis),
    shape ``(n, len(xi))``."""
    xi = np.atleast_1d(np.asarray(xi, dtype=float))
    if supports is None:
        return mode_shapes(n, xi, derivative)
    return support_basis(n, *supports).shapes(xi, derivative)


def axial_matrix(a: AxialForce, g: ModeIntegrals, L: float) -> FloatArray:
    """Weak form of -(N w')' on the basis: integral of N phi_i' phi_j' dx / L^2 [N/m]."""
    return np.asarray((a[0] * g.d + a[1] * g.xd + a[2] * g.x2d) / L)
