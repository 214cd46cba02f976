"""The Galerkin basis of a pipe with any end supports, springs and intermediate supports.

Choice (``docs/model.md`` 9): the basis is the set of **eigenfunctions of the beam with the
pipe's own supports and springs**, phi'''' = lambda^4 phi on xi = x / L in [0, 1], computed
to rounding from the exact solution, not a fixed basis with penalties.  Each function then
satisfies every geometric *and* natural end condition, so the Galerkin model converges as
fast as the cantilever's (eigenvalues exact at u = 0 with any number of modes) and the
bending matrix is diagonal, lambda_j^4 (the balancing of :mod:`pipeflow.model` keeps
working).

Numerical form
--------------
On one span every eigenfunction is ``phi = sum_i c_i f_i(xi)`` with four fundamental
solutions.  Two forms of the f_i are used, each where it is well conditioned:

- lambda >= 4: ``f = (e^(lambda (xi - 1)), e^(-lambda xi), cos(lambda xi), sin(lambda xi))``
  (only decaying exponentials, as in :mod:`pipeflow.basis`: no e^lambda to overflow or
  cancel, entries O(1) up to the 40th mode and beyond);
- lambda < 4: the Krylov-Duncan functions scaled to stay finite as lambda -> 0,
  ``f = (S(z), T(z)/lambda, U(z)/lambda^2, V(z)/lambda^3)``, z = lambda xi, by their power
  series (no cancellation), which at lambda = 0 are the rigid-body polynomials
  1, xi, xi^2/2, xi^3/6.

The end conditions give a 4 x 4 matrix B(lambda) (each row scaled to unit norm); its
determinant is a real entire function of lambda whose roots are the eigenvalues.  They are
bracketed on a grid (geometric from 1e-4 to 4, then steps of 0.02) and refined by Brent's
method to rounding; rigid-body modes (lambda = 0) are the null space of B(0).  A spring
with K_t = k_t L^3/EI or K_r = k_r L/EI below :data:`SPRING_FLOOR` is no spring (its
frequency would be below 1e-3 of the beam's first).

Intermediate supports: a spring k at xi_s adds K phi(xi_s) phi(xi_s)^T to the bending
matrix, a pin constrains phi(xi_s) = 0.  The basis is then the Ritz eigenvectors, in the
span of the first ``n + p + 8`` end-support eigenfunctions (p pins) restricted to the pins'
null space, of the bending matrix with the point springs: orthonormal, satisfying every pin
exactly, diagonal bending.  Convergence is algebraic (the pins' shear jump), measured in
``docs/model.md`` 9.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
import scipy.linalg
from scipy.optimize import brentq

from pipeflow._types import FloatArray
from pipeflow.basis import gauss_legendre_unit

#: (kind, K_t, K_r): an end's support on the unit interval (supports.Support.nondimensional)
EndSpec = tuple[str, float, float]
#: (xi_s, K): an intermediate support; K = inf for a pin
PointSpec = tuple[float, float]

#: non-dimensional springs below this are zero (K_t = k_t L^3/EI, K_r = k_r L/EI)
SPRING_FLOOR = 1e-12
#: Krylov-Duncan form below this lambda, exponential form above
_SWITCH = 4.0
#: extra end-support eigenfunctions behind the Ritz basis of intermediate supports
_EXTRA = 8
_SERIES_TERMS = 12


def _series(z: FloatArray, shift: int) -> FloatArray:
    """sum_k z^(4k) / (4k + shift)! for |z| <= 4 (the scaled Krylov-Duncan functions)."""
    out = np.zeros_like(z)
    term = np.full_like(z, 1.0 / math.factorial(shift))
    z4 = z**4
    for k in range(_SERIES_TERMS):
        out = out + term
        s = 4 * k + shift
        term = term * z4 / ((s + 1) * (s + 2) * (s + 3) * (s + 4))
    return out


def _krylov(lam: FloatArray | float, xi: FloatArray | float, k: int) -> FloatArray:
    """d^k/dxi^k of (S(z), T(z)/lam, U(z)/lam^2, V(z)/lam^3), z = lam xi, for broadcast
    ``lam`` and ``xi``: shape (4,) + their shape."""
    la, x = np.broadcast_arrays(np.asarray(lam, dtype=float), np.asarray(xi, dtype=float))
    z = la * x
    f = [_series(z, 0), x * _series(z, 1), x**2 * _series(z, 2), x**3 * _series(z, 3)]
    # d/dxi maps (f1, f2, f3, f4) -> (lam^4 f4, f1, f2, f3)
    for _ in range(k):
        f = [la**4 * f[3], f[0], f[1], f[2]]
    return np.array(f)


def _exponential(lam: FloatArray | float, xi: FloatArray | float, k: int) -> FloatArray:
    """d^k/dxi^k of (e^(lam (xi-1)), e^(-lam xi), cos(lam xi), sin(lam xi)) for broadcast
    ``lam`` and ``xi``: shape (4,) + their shape."""
    la, x = np.broadcast_arrays(np.asarray(lam, dtype=float), np.asarray(xi, dtype=float))
    z = la * x
    ph = k * np.pi / 2
    lk = la**k
    return np.array(
        [lk * np.exp(z - la), (-la) ** k * np.exp(-z), lk * np.cos(z + ph), lk * np.sin(z + ph)]
    )


def _fundamental(
    lam: FloatArray | float, xi: FloatArray | float, k: int, krylov: bool
) -> FloatArray:
    return _krylov(lam, xi, k) if krylov else _exponential(lam, xi, k)


def _end_rows(spec: EndSpec, lam: FloatArray, at: float, krylov: bool) -> FloatArray:
    """The two rows of B(lam) for the end at xi = ``at`` (0 or 1), each of unit norm:
    shape (G, 2, 4) for the G values of ``lam``."""
    kind, kt, kr = spec
    d = [np.asarray(_fundamental(lam, at, k, krylov).T) for k in range(4)]  # each (G, 4)
    sign = 1.0 if at == 1.0 else -1.0
    rows = {
        "clamped": (d[0], d[1]),
        "pinned": (d[0], d[2]),
        "sliding": (d[1], d[3]),
        "free": (d[2], d[3]),
        # x = L: w'' = -K_r w', w''' = K_t w; x = 0: w'' = K_r w', w''' = -K_t w
        "elastic": (d[2] + sign * kr * d[1], d[3] - sign * kt * d[0]),
    }[kind]
    out = np.stack(rows, axis=1)
    return np.asarray(out / np.linalg.norm(out, axis=2, keepdims=True))


def _matrix(x0: EndSpec, xL: EndSpec, lam: FloatArray, krylov: bool) -> FloatArray:
    """B(lam), shape (G, 4, 4)."""
    lam = np.atleast_1d(np.asarray(lam, dtype=float))
    return np.concatenate([_end_rows(x0, lam, 0.0, krylov), _end_rows(xL, lam, 1.0, krylov)], 1)


def _det(x0: EndSpec, xL: EndSpec, lam: FloatArray, krylov: bool) -> FloatArray:
    return np.asarray(np.linalg.det(_matrix(x0, xL, lam, krylov)))


def _clean(spec: EndSpec) -> EndSpec:
    kind, kt, kr = spec
    kt = kt if kt >= SPRING_FLOOR else 0.0
    kr = kr if kr >= SPRING_FLOOR else 0.0
    if kind == "elastic" and kt == 0.0 and kr == 0.0:
        return ("free", 0.0, 0.0)
    return (kind, kt, kr)


@dataclass(frozen=True)
class _Mode:
    lam: float
    coef: tuple[float, ...]  # coefficients of the fundamental solutions

    def values(self, xi: FloatArray, k: int) -> FloatArray:
        f = _fundamental(self.lam, xi, k, self.lam < _SWITCH)
        return np.asarray(np.asarray(self.coef) @ f)


def _null_vector(B: FloatArray) -> FloatArray:
    _, _, vt = np.linalg.svd(B)
    return np.asarray(vt[-1])


def _roots_in(x0: EndSpec, xL: EndSpec, grid: FloatArray, krylov: bool) -> list[float]:
    vals = _det(x0, xL, grid, krylov)
    out: list[float] = []

    def f(s: float) -> float:
        return float(_det(x0, xL, np.array([s]), krylov)[0])

    for a, b, fa, fb in zip(grid[:-1], grid[1:], vals[:-1], vals[1:], strict=True):
        if fa == 0.0:
            out.append(float(a))
        elif fa * fb < 0:
            out.append(float(brentq(f, a, b, xtol=1e-15, rtol=4 * np.finfo(float).eps)))
    return out


def _bracket_roots(x0: EndSpec, xL: EndSpec, count: int) -> list[float]:
    """The first ``count`` positive roots of det B(lambda), ascending.  Each grid is scanned
    in one form of the fundamental solutions (the two forms' determinants differ by a
    factor that may change sign, so no bracket straddles the switch)."""
    found = _roots_in(x0, xL, np.geomspace(1e-4, _SWITCH, 400), True)
    lo = _SWITCH
    while len(found) < count:
        grid = np.arange(lo, lo + np.pi * (count - len(found) + 2), 0.02)
        found += _roots_in(x0, xL, grid, False)
        lo = float(grid[-1])
    return sorted(found)[:count]


def _normalised(mode: _Mode) -> _Mode:
    """Scale to integral phi^2 = 1, sign: the largest sample positive."""
    q = int(max(64, math.ceil(mode.lam + 60)))
    xi, w = gauss_legendre_unit(q)
    v = mode.values(xi, 0)
    norm = math.sqrt(float(w @ (v * v)))
    grid = mode.values(np.linspace(0.0, 1.0, 401), 0)
    sign = 1.0 if grid[np.argmax(np.abs(grid))] > 0 else -1.0
    return _Mode(mode.lam, tuple(float(c) * sign / norm for c in mode.coef))


@lru_cache(maxsize=32)
def end_support_modes(x0: EndSpec, xL: EndSpec, count: int) -> tuple[tuple[_Mode, ...], FloatArray]:
    """The first ``count`` eigenfunctions of the beam with end conditions ``x0``, ``xL``
    (normalised, ascending) and their lambda_j^4 [-] (0 for a rigid-body mode)."""
    x0, xL = _clean(x0), _clean(xL)
    B0 = _matrix(x0, xL, np.zeros(1), True)[0]
    _, s, vt = np.linalg.svd(B0)
    rigid = int(np.sum(s <= 1e-12 * s[0]))
    modes: list[_Mode] = []
    if rigid:
        polys = vt[-rigid:]
        xi, w = gauss_legendre_unit(16)
        vals = polys @ _krylov(0.0, xi, 0)
        c = np.linalg.cholesky((vals * w) @ vals.T)
        polys = np.linalg.solve(c, polys)  # orthonormal rigid-body modes
        modes += [_normalised(_Mode(0.0, tuple(p))) for p in polys]
    if count > len(modes):
        for lam in _bracket_roots(x0, xL, count - len(modes)):
            B = _matrix(x0, xL, np.array([lam]), lam < _SWITCH)[0]
            modes.append(_normalised(_Mode(lam, tuple(_null_vector(B)))))
    lam4 = np.array([m.lam**4 for m in modes[:count]])
    lam4.setflags(write=False)
    return tuple(modes[:count]), lam4


@dataclass(frozen=True, eq=False)
class SupportBasis:
    """``n`` orthonormal basis functions on [0, 1]: ``coef`` (n, N) times the end-support
    eigenfunctions ``modes``; ``lam4`` the diagonal of the bending matrix (with the springs)
    [-], i.e. (omega_j / sqrt(EI / (m L^4)))^2 of the bare beam with its supports."""

    n: int
    modes: tuple[_Mode, ...]
    coef: FloatArray
    lam4: FloatArray
    #: ``{derivative: stations}`` the supports hold at zero: w at a clamped or pinned end
    #: and at a pin, w' at a clamped or sliding end (exactly 0 there, not rounding's 1e-15)
    held: tuple[tuple[int, tuple[float, ...]], ...] = ()

    def shapes(self, xi: FloatArray, derivative: int = 0) -> FloatArray:
        """d^k phi_j / dxi^k at ``xi`` [-], shape ``(n, len(xi))``; exactly 0 where a
        support holds that derivative (:attr:`held`)."""
        xi = np.atleast_1d(np.asarray(xi, dtype=float))
        lam = np.array([m.lam for m in self.modes])
        coef = np.array([m.coef for m in self.modes])  # (N, 4)
        under = np.empty((lam.size, xi.size))
        for krylov in (True, False):
            rows = (lam < _SWITCH) == krylov
            if rows.any():
                f = _fundamental(lam[rows, None], xi[None, :], derivative, krylov)  # (4, r, P)
                under[rows] = np.einsum("ri,irp->rp", coef[rows], f)
        out = np.asarray(self.coef @ under)
        for k, stations in self.held:
            if k == derivative:
                out[:, np.isin(xi, stations)] = 0.0
        return out


def _held(
    x0: EndSpec, xL: EndSpec, points: tuple[PointSpec, ...]
) -> tuple[tuple[int, tuple[float, ...]], ...]:
    """:attr:`SupportBasis.held` of the supports."""
    value = [at for at, spec in ((0.0, x0), (1.0, xL)) if spec[0] in ("clamped", "pinned")]
    value += [xs for xs, k in points if math.isinf(k)]
    slope = [at for at, spec in ((0.0, x0), (1.0, xL)) if spec[0] in ("clamped", "sliding")]
    return ((0, tuple(value)), (1, tuple(slope)))


@lru_cache(maxsize=32)
def support_basis(
    n: int, x0: EndSpec, xL: EndSpec, points: tuple[PointSpec, ...] = ()
) -> SupportBasis:
    """The Galerkin basis of ``n`` functions for the supports (see the module docstring)."""
    if not points:
        modes, lam4 = end_support_modes(x0, xL, n)
        return SupportBasis(n, modes, np.eye(n), lam4, _held(x0, xL, points))
    pins = [p for p in points if math.isinf(p[1])]
    count = n + len(pins) + _EXTRA
    modes, lam4 = end_support_modes(x0, xL, count)
    under = SupportBasis(count, modes, np.eye(count), lam4)
    K = np.diag(lam4)
    for xs, k in points:
        if not math.isinf(k):
            phi = under.shapes(np.array([xs]))[:, 0]
            K = K + k * np.outer(phi, phi)
    Z = np.eye(count)
    if pins:
        A = under.shapes(np.array([p[0] for p in pins]), 0).T  # (p, count)
        Z = scipy.linalg.null_space(A)
    mu, Y = np.linalg.eigh(Z.T @ K @ Z)
    coef = (Z @ Y[:, :n]).T
    lam4_n = np.asarray(mu[:n], dtype=float)
    lam4_n.setflags(write=False)
    return SupportBasis(n, modes, coef, lam4_n, _held(x0, xL, points))
