"""Load-dependent Ritz vectors: the Galerkin basis of a frequency response enriched with the
static response of the continuous pipe to its load (issue 32).

With flow a force at the tip converges like n^-2 in modes (the flow terms meet the shear
the force puts at the end, which no mode has), and a static correction added to the modal
sum (:func:`pipeflow.statics.truncation_residual`) does not help above the first resonance:
the modes left out are coupled to the retained ones by the Coriolis and flow terms.  Instead
the basis is enriched (Wilson, Yuan & Dickens, *Earthquake Eng. Struct. Dyn.* 10, 1982:
load-dependent Ritz vectors; Dickens, Nakagawa & Wittbrodt, *Comput. Struct.* 62, 1997:
modal truncation augmentation) with

    psi_1 = K^-1 f                (the continuous pipe's static deflection under the load),
    psi_(k+1) = K^-1 (M psi_k)    (its response to the inertia of the previous vector:
                                   m psi_k along the pipe, m_t psi_k(L) on a tip mass),

each the exact static solution of the continuous problem
(:func:`pipeflow.statics.static_deflection`: flow, spin, supports, springs, axial loads),
made orthonormal to the modes and to each other,
and the model's matrices are assembled on the n modes plus these functions by the same
:func:`pipeflow.model.second_order` (bending in weak form with the springs).  psi_1 in the
basis makes the response exact at W = 0 (the Galerkin solution is the static one when that
lies in the basis); the vectors also carry the end shear into the coupling, and a tip force
with flow at 10 modes improves from 7e-3 to 1e-5 (docs/frequency-response.md).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from pipeflow._types import FloatArray
from pipeflow.beam_modes import span_quadrature
from pipeflow.integrals import ModeIntegrals, basis_shapes, mode_integrals
from pipeflow.model import Pipe
from pipeflow.statics import StaticSolution, static_solution, statics_cover

#: load-dependent Ritz vectors added to the modes
RITZ_VECTORS = 2
#: a vector whose part outside the span of the modes (and of the vectors before it) is below
#: this fraction of its norm adds nothing and is left out
INDEPENDENCE = 1e-8


def load_vectors(
    pipe: Pipe, velocity: float, omega0: float, force_at: float | None, count: int = RITZ_VECTORS
) -> list[StaticSolution] | None:
    """``count`` load-dependent Ritz vectors of a unit force at ``force_at`` [m] (None: a
    unit acceleration of the supports) at the frozen operating point ``velocity`` [m/s],
    ``omega0`` [rad/s]; None where the static problem has no solution (a rigid rotation,
    divergence)."""
    if not statics_cover(pipe):
        return None
    first = static_solution(pipe, velocity, omega0, force_at=force_at)
    if not np.all(np.isfinite(first.at(np.linspace(0.0, pipe.L, 9)))):
        return None
    out = [first]
    for _ in range(count - 1):
        before = out[-1]
        # the inertia of the previous vector: the pipe's, and the tip mass's at L
        tip = pipe.tip_mass * float(before.at(np.array([pipe.L]))[0])
        out.append(
            static_solution(
                pipe,
                velocity,
                omega0,
                force_at=None,
                density=_Inertia(pipe.mass, before),
                tip_force=tip,
            )
        )
    return out


@dataclass(frozen=True)
class _Inertia:
    """The distributed load m psi(x) [N/m per unit load] of a vector's inertia."""

    mass: float  # [kg/m]
    vector: StaticSolution

    def __call__(self, x: FloatArray) -> FloatArray:
        return np.asarray(self.mass * self.vector.at(x))


@dataclass(frozen=True)
class Enriched:
    """The n basis functions of the model followed by the orthonormalised vectors, on
    xi = x / L: function j = sum_i ``coef[j, i]`` g_i, with g = (phi_1 .. phi_n, psi_1 ..
    psi_k) (psi in xi: psi(L xi)); the model's functions unchanged (the identity rows)."""

    pipe: Pipe
    n: int
    vectors: tuple[StaticSolution, ...]
    coef: FloatArray  # (n + k, n + k), lower triangular

    @property
    def size(self) -> int:
        return int(self.coef.shape[0])

    def raw(self, xi: FloatArray, r: int) -> FloatArray:
        """g_i^(r)(xi) (d/dxi), shape (n + k, len(xi))."""
        return self.raws(xi, (r,))[0]

    def raws(self, xi: FloatArray, orders: tuple[int, ...]) -> list[FloatArray]:
        """:meth:`raw` for each derivative of ``orders`` (each vector's interpolation to
        ``xi`` formed once)."""
        xi = np.atleast_1d(np.asarray(xi, dtype=float))
        L = self.pipe.L
        scale = np.array([L**r for r in orders])[:, None]
        extra = [psi.derivatives(xi * L, orders) * scale for psi in self.vectors]
        return [
            np.vstack([basis_shapes(self.n, xi, r, self.pipe.basis_key), *(e[i] for e in extra)])
            for i, r in enumerate(orders)
        ]

    def shapes(self, xi: FloatArray, r: int = 0) -> FloatArray:
        """The enriched basis' r-th derivatives (d/dxi) at ``xi``, shape (size, len(xi))."""
        return np.asarray(self.coef @ self.raw(xi, r))


def enrich(
    pipe: Pipe, n: int, vectors: list[StaticSolution], cuts: tuple[float, ...] = ()
) -> tuple[Enriched, ModeIntegrals]:
    """The model's ``n`` functions and the ``vectors`` orthonormalised (Gram-Schmidt, twice,
    in the integral over xi; a vector dependent to :data:`INDEPENDENCE` is left out) and
    their Galerkin integrals, by Gauss-Legendre on the pieces between the supports and
    ``cuts`` (xi where a vector's third derivative jumps: the load point)."""
    key = pipe.basis_key
    points = () if key is None else key[2]
    edges = tuple(sorted({0.0, 1.0, *(xs for xs, _ in points), *cuts}))
    order = mode_integrals(n, None, key).quadrature_order
    xi, w = span_quadrature(edges, order)
    basis = Enriched(pipe, n, tuple(vectors), np.eye(n + len(vectors)))
    raw = basis.raws(xi, (0, 1, 2))
    G = raw[0]
    coef = np.eye(n + len(vectors))
    kept = list(range(n))
    for j in range(n, n + len(vectors)):
        row = coef[j].copy()
        norm0 = math.sqrt(float((G[j] * G[j]) @ w))
        Q = coef[kept]
        QGw = (Q @ G) * w
        for _ in range(2):  # twice is enough (Giraud et al., Numer. Math. 101, 2005)
            row = row - (QGw @ (row @ G)) @ Q  # classical Gram-Schmidt against the kept
        value = row @ G
        norm = math.sqrt(float((value * value) @ w))
        if norm > INDEPENDENCE * norm0:
            coef[j] = row / norm
            kept.append(j)
    coef = coef[kept]
    enriched = Enriched(pipe, n, tuple(vectors), coef)
    return enriched, _integrals(enriched, xi, w, order, raw)


def _integrals(
    basis: Enriched, xi: FloatArray, w: FloatArray, order: int, raw: list[FloatArray]
) -> ModeIntegrals:
    """:class:`ModeIntegrals` of ``basis`` from the raw functions' derivatives 0..2 at the
    nodes ``xi`` (weights ``w``); bending in weak form with the supports' springs (end
    springs K_t u^2 + K_r u'^2, point springs K u(x_s)^2): the modes' own lambda^4."""
    p0, p1, p2 = (basis.coef @ g for g in raw)
    pw = p0 * w
    flex = (p2 * w) @ p2.T
    k4 = flex.copy()
    key = basis.pipe.basis_key
    springs = False
    if key is not None:
        x0, xL, points = key
        for at, (kind, kt, kr) in ((0.0, x0), (1.0, xL)):
            if kind == "elastic":
                u, du = (basis.shapes(np.array([at]), r)[:, 0] for r in (0, 1))
                k4 += kt * np.outer(u, u) + kr * np.outer(du, du)
                springs = True
        for xs, K in points:
            if not math.isinf(K):
                u = basis.shapes(np.array([xs]), 0)[:, 0]
                k4 += K * np.outer(u, u)
                springs = True
    tip, tip_slope = (basis.coef @ g[:, 0] for g in basis.raws(np.ones(1), (0, 1)))
    return ModeIntegrals(
        n=basis.size,
        quadrature_order=order,
        gram=pw @ p0.T,
        b=pw @ p1.T,
        c=pw @ p2.T,
        xb=(pw * xi) @ p1.T,
        tc=(pw * (1.0 - xi**2)) @ p2.T,
        k4=k4,
        xf=pw @ xi,
        d=(p1 * w) @ p1.T,
        xd=(p1 * (w * xi)) @ p1.T,
        f=pw.sum(axis=1),
        tip=tip,
        tip_slope=tip_slope,
        x2d=(p1 * (w * xi * xi)) @ p1.T,
        flex=flex if springs else None,
    )
