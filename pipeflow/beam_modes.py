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
method to rounding; rigid-body modes (lambda = 0) are the lines the supports leave.  A spring
with K_t = k_t L^3/EI or K_r = k_r L/EI below :data:`SPRING_FLOOR` is no spring (its
frequency would be below 1e-3 of the beam's first).

Intermediate supports (:func:`span_basis`): the eigenfunctions of the beam on its spans,
the same fundamental solutions in each span's own coordinate, B(lambda) of size 4S x 4S
(S spans: the ends, and at each support w' and w'' continuous, w = 0 on both sides of a
pin, or w continuous and the shear jump -K w at a spring), then a Rayleigh-Ritz step on
the computed functions (orthonormal to rounding in clusters of nearly equal eigenvalues).
Exact at u = 0 with any number of modes, like the end supports.  Its roots are checked
against the Ritz basis of the first ``n + p + 8`` end-support eigenfunctions restricted to
the pins' null space, with the point springs (an upper bound); that basis, whose
convergence is algebraic (the supports' shear jump), is the fallback.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable
from dataclasses import dataclass
from functools import lru_cache
from typing import Any

import numpy as np
import scipy.linalg
from scipy.optimize import brentq

from pipeflow._types import FloatArray
from pipeflow.basis import gauss_legendre_unit

#: (kind, K_t, K_r): an end's support on the unit interval (supports.Support.nondimensional)
EndSpec = tuple[str, float, float]
#: (xi_s, K): an intermediate support; K = inf for a pin
PointSpec = tuple[float, float]
#: a support set on the unit interval: (x0 spec, xL spec, intermediate points), the key of
#: its basis (:func:`support_basis`; pipeflow.supports.basis_key makes it from a pipe)
BasisKey = tuple[EndSpec, EndSpec, tuple[PointSpec, ...]]

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


def _exponential(
    lam: FloatArray | float, xi: FloatArray | float, k: int, length: float = 1.0
) -> FloatArray:
    """d^k/dxi^k of (e^(lam (xi-length)), e^(-lam xi), cos(lam xi), sin(lam xi)) for
    broadcast ``lam`` and ``xi`` in [0, ``length``]: shape (4,) + their shape."""
    la, x = np.broadcast_arrays(np.asarray(lam, dtype=float), np.asarray(xi, dtype=float))
    z = la * x
    ph = k * np.pi / 2
    lk = la**k
    return np.array(
        [
            lk * np.exp(z - la * length),
            (-la) ** k * np.exp(-z),
            lk * np.cos(z + ph),
            lk * np.sin(z + ph),
        ]
    )


def _fundamental(
    lam: FloatArray | float, xi: FloatArray | float, k: int, krylov: bool, length: float = 1.0
) -> FloatArray:
    return _krylov(lam, xi, k) if krylov else _exponential(lam, xi, k, length)


def _end_pair(spec: EndSpec, d: list[FloatArray], sign: float) -> tuple[FloatArray, FloatArray]:
    """The two end conditions of ``spec`` on the derivatives ``d`` (k = 0..3) of the
    fundamental solutions at the end; ``sign`` +1 at x = L, -1 at x = 0."""
    kind, kt, kr = spec
    return {
        "clamped": (d[0], d[1]),
        "pinned": (d[0], d[2]),
        "sliding": (d[1], d[3]),
        "free": (d[2], d[3]),
        # x = L: w'' = -K_r w', w''' = K_t w; x = 0: w'' = K_r w', w''' = -K_t w
        "elastic": (d[2] + sign * kr * d[1], d[3] - sign * kt * d[0]),
    }[kind]


def _end_rows(spec: EndSpec, lam: FloatArray, at: float, krylov: bool) -> FloatArray:
    """The two rows of B(lam) for the end at xi = ``at`` (0 or 1), each of unit norm:
    shape (G, 2, 4) for the G values of ``lam``."""
    d = [np.asarray(_fundamental(lam, at, k, krylov).T) for k in range(4)]  # each (G, 4)
    out = np.stack(_end_pair(spec, d, 1.0 if at == 1.0 else -1.0), axis=1)
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


def rigid_lines(
    x0: EndSpec, xL: EndSpec, points: tuple[PointSpec, ...]
) -> list[tuple[float, float]]:
    """The rigid-body modes (lambda = 0) of the supports as lines a + b xi, (a, b): zero
    bending and spring energy leaves a straight line with w = 0 at every pin, translational
    spring and pinned or clamped end, and w' = 0 at a clamped, sliding or rotationally
    sprung end.  Counted from the supports, not from the rank of B(0): two supports close
    together (a pin 1e-6 L from a clamp) make B(0) nearly singular although they leave no
    rigid mode."""
    at: set[float] = {xs for xs, k in points if k >= SPRING_FLOOR}
    slope = False
    for end, (kind, kt, kr) in ((0.0, x0), (1.0, xL)):
        if kind in ("clamped", "pinned") or (kind == "elastic" and kt >= SPRING_FLOOR):
            at.add(end)
        if kind in ("clamped", "sliding") or (kind == "elastic" and kr >= SPRING_FLOOR):
            slope = True
    if len(at) + slope >= 2:
        return []
    if at:
        return [(-at.pop(), 1.0)]  # a rotation about the one support
    return [(1.0, 0.0)] if slope else [(1.0, 0.0), (0.0, 1.0)]


@lru_cache(maxsize=32)
def end_support_modes(x0: EndSpec, xL: EndSpec, count: int) -> tuple[tuple[_Mode, ...], FloatArray]:
    """The first ``count`` eigenfunctions of the beam with end conditions ``x0``, ``xL``
    (normalised, ascending) and their lambda_j^4 [-] (0 for a rigid-body mode)."""
    x0, xL = _clean(x0), _clean(xL)
    modes: list[_Mode] = []
    if lines := rigid_lines(x0, xL, ()):
        polys = np.array([(a, b, 0.0, 0.0) for a, b in lines])  # Krylov form at lambda = 0
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
class _Basis:
    """``n`` orthonormal basis functions on [0, 1]: ``coef`` (n, N) times eigenfunctions
    ``modes``; ``lam4`` the diagonal of the bending matrix (with the springs) [-], i.e.
    (omega_j / sqrt(EI / (m L^4)))^2 of the bare beam with its supports."""

    n: int
    modes: tuple[Any, ...]
    coef: FloatArray
    lam4: FloatArray
    #: ``{derivative: stations}`` the supports hold at zero: w at a clamped or pinned end
    #: and at a pin, w' at a clamped or sliding end (exactly 0 there, not rounding's 1e-15)
    held: tuple[tuple[int, tuple[float, ...]], ...] = ()

    def _under(self, xi: FloatArray, derivative: int) -> FloatArray:
        raise NotImplementedError

    def shapes(self, xi: FloatArray, derivative: int = 0) -> FloatArray:
        """d^k phi_j / dxi^k at ``xi`` [-], shape ``(n, len(xi))``; exactly 0 where a
        support holds that derivative (:attr:`held`)."""
        xi = np.atleast_1d(np.asarray(xi, dtype=float))
        out = np.asarray(self.coef @ self._under(xi, derivative))
        for k, stations in self.held:
            if k == derivative:
                out[:, np.isin(xi, stations)] = 0.0
        return out


@dataclass(frozen=True, eq=False)
class SupportBasis(_Basis):
    """The end supports' eigenfunctions ``modes`` (:func:`end_support_modes`), or the Ritz
    basis of intermediate supports in their span (``coef`` then mixes them)."""

    def _under(self, xi: FloatArray, derivative: int) -> FloatArray:
        lam = np.array([m.lam for m in self.modes])
        coef = np.array([m.coef for m in self.modes])  # (N, 4)
        under = np.empty((lam.size, xi.size))
        for krylov in (True, False):
            rows = (lam < _SWITCH) == krylov
            if rows.any():
                f = _fundamental(lam[rows, None], xi[None, :], derivative, krylov)  # (4, r, P)
                under[rows] = np.einsum("ri,irp->rp", coef[rows], f)
        return under

    def quadrature(self, order: int) -> tuple[FloatArray, FloatArray]:
        """Nodes and weights on [0, 1] for the Galerkin integrals: Gauss-Legendre of
        ``order`` points."""
        return gauss_legendre_unit(order)


def _held(
    x0: EndSpec, xL: EndSpec, points: tuple[PointSpec, ...]
) -> tuple[tuple[int, tuple[float, ...]], ...]:
    """:attr:`SupportBasis.held` of the supports."""
    value = [at for at, spec in ((0.0, x0), (1.0, xL)) if spec[0] in ("clamped", "pinned")]
    value += [xs for xs, k in points if math.isinf(k)]
    slope = [at for at, spec in ((0.0, x0), (1.0, xL)) if spec[0] in ("clamped", "sliding")]
    return ((0, tuple(value)), (1, tuple(slope)))


# -- intermediate supports: the eigenfunctions of the beam on its spans ---------------------
#: below this lambda x span length a span's functions take the Krylov-Duncan form
_SPAN_SWITCH = 4.0
#: the scan of det B(lambda) for the spans' eigenvalues: its step, and finer steps tried
#: when the roots found miss one (two roots inside one step: no sign change)
_SCAN_STEP = 0.02
_FINER_SCANS = (0.002,)
#: relative slack of the Ritz bound lambda_k (exact) <= lambda_k (Ritz) the roots are checked by
_RITZ_SLACK = 1e-8


@dataclass(frozen=True)
class _SpanMode:
    """An eigenfunction of the beam on spans ``edges`` (0 = e_0 < ... < e_S = 1): on span s,
    ``sum_i coef[s][i] f_i(xi - e_s)`` in the span's own form of the fundamental solutions."""

    lam: float
    edges: tuple[float, ...]
    coef: tuple[tuple[float, ...], ...]

    def values(self, xi: FloatArray, k: int) -> FloatArray:
        xi = np.atleast_1d(np.asarray(xi, dtype=float))
        out = np.zeros(xi.shape)
        last = len(self.edges) - 2
        for s, (a, b) in enumerate(itertools.pairwise(self.edges)):
            inside = (xi >= a) & ((xi < b) if s < last else (xi <= b))
            if inside.any():
                length = b - a
                f = _fundamental(self.lam, xi[inside] - a, k, self.lam * length < _SPAN_SWITCH,
                                 length)  # fmt: skip
                out[inside] = np.asarray(self.coef[s]) @ f
        return out


def _span_derivatives(lam: FloatArray, z: float, length: float, krylov: bool) -> list[FloatArray]:
    """d^k/dxi^k, k = 0..3, of one span's fundamental solutions at its local ``z``: four
    arrays (G, 4) for the G values of ``lam``."""
    if not krylov:
        return [np.asarray(_exponential(lam, z, k, length).T) for k in range(4)]
    f = list(_krylov(lam, z, 0))  # d/dxi maps (f1, f2, f3, f4) -> (lam^4 f4, f1, f2, f3)
    out = [np.stack(f, axis=-1)]
    for _ in range(3):
        f = [lam**4 * f[3], f[0], f[1], f[2]]
        out.append(np.stack(f, axis=-1))
    return out


def _span_matrix(
    x0: EndSpec, xL: EndSpec, points: tuple[PointSpec, ...], lam: FloatArray,
    krylov: tuple[bool, ...],
) -> FloatArray:  # fmt: skip
    """B(lam) of the spans between ``points``, shape (G, 4 S, 4 S), rows of unit norm: two end
    conditions at each end; at a pin w = 0 on both sides, at a spring K w continuous and
    the shear jump w'''(+) - w'''(-) = -K w; w' and w'' continuous at both.  ``krylov``: the
    form of each span's functions."""
    lam = np.atleast_1d(np.asarray(lam, dtype=float))
    edges = (0.0, *(xs for xs, _ in points), 1.0)
    lengths = np.diff(edges)
    S = len(lengths)
    B = np.zeros((lam.size, 4 * S, 4 * S))
    start = _span_derivatives(lam, 0.0, lengths[0], krylov[0])
    B[:, 0], B[:, 1] = (np.pad(r, ((0, 0), (0, 4 * S - 4))) for r in _end_pair(x0, start, -1.0))
    for p, (_, K) in enumerate(points):
        left = _span_derivatives(lam, lengths[p], lengths[p], krylov[p])
        right = _span_derivatives(lam, 0.0, lengths[p + 1], krylov[p + 1])
        cl, cr, r = slice(4 * p, 4 * p + 4), slice(4 * p + 4, 4 * p + 8), 2 + 4 * p
        if math.isinf(K):
            B[:, r, cl], B[:, r + 1, cr] = left[0], right[0]
        else:
            B[:, r, cl], B[:, r, cr] = left[0], -right[0]
            B[:, r + 1, cl], B[:, r + 1, cr] = K * left[0] - left[3], right[3]
        for j, k in ((2, 1), (3, 2)):
            B[:, r + j, cl], B[:, r + j, cr] = left[k], -right[k]
    end = _span_derivatives(lam, lengths[-1], lengths[-1], krylov[-1])
    for j, row in enumerate(_end_pair(xL, end, 1.0)):
        B[:, 4 * S - 2 + j, 4 * S - 4 :] = row
    return np.asarray(B / np.sqrt(np.einsum("gij,gij->gi", B, B))[..., None])


def _span_forms(lam: float, lengths: FloatArray) -> tuple[bool, ...]:
    return tuple(bool(lam * length < _SPAN_SWITCH) for length in lengths)


def _span_roots(
    x0: EndSpec, xL: EndSpec, points: tuple[PointSpec, ...], count: int, step: float
) -> list[float]:
    """The first ``count`` positive roots of the spans' det B(lambda), ascending: scanned
    on a grid (geometric below 1, then ``step``) cut where a span changes form (the two
    forms' determinants differ by a factor that may change sign), refined by Brent."""
    lengths = np.diff((0.0, *(xs for xs, _ in points), 1.0))
    switches = sorted({_SPAN_SWITCH / float(length) for length in lengths})
    found: list[float] = []
    lo, grid = 1e-4, np.geomspace(1e-4, 1.0, 200)
    while len(found) < count:
        hi = float(grid[-1])
        cuts = [lo, *(w for w in switches if lo < w < hi), hi]
        for a, b in itertools.pairwise(cuts):
            piece = np.concatenate([[a], grid[(grid > a) & (grid < b)], [b]])
            mid = 0.5 * (a + b)
            forms = _span_forms(mid, lengths)

            def det(x: FloatArray, forms: tuple[bool, ...] = forms) -> FloatArray:
                return np.asarray(np.linalg.det(_span_matrix(x0, xL, points, x, forms)))

            vals = det(piece)
            found += [float(u) for u, fu in zip(piece[:-1], vals[:-1], strict=True) if fu == 0]
            change = np.flatnonzero(vals[:-1] * vals[1:] < 0)
            if change.size:
                found += _bracketed_roots(det, piece[change], piece[change + 1],
                                          vals[change], vals[change + 1])  # fmt: skip
        lo = hi
        grid = np.arange(hi, hi + np.pi * (count - len(found) + 2), step)
    return sorted(found)[:count]


def _bracketed_roots(
    f: Callable[[FloatArray], FloatArray],
    a: FloatArray,
    b: FloatArray,
    fa: FloatArray,
    fb: FloatArray,
) -> list[float]:
    """The roots of ``f`` in the brackets [a, b] (fa fb < 0), all at once: the Illinois
    variant of false position (superlinear, the bracket kept), one call of ``f`` on every
    unfinished bracket per iteration (a Brent search per root made one small determinant
    call per step), to 4 eps relative."""
    a, b, fa, fb = (np.array(v, dtype=float) for v in (a, b, fa, fb))
    x = 0.5 * (a + b)
    kept = np.zeros(a.size, dtype=int)  # +1: a kept twice running, -1: b
    todo = np.ones(a.size, dtype=bool)
    for _ in range(200):
        i = np.flatnonzero(todo)
        if i.size == 0:
            break
        x[i] = (a[i] * fb[i] - b[i] * fa[i]) / (fb[i] - fa[i])
        bad = ~((x[i] > a[i]) & (x[i] < b[i]))  # (rounding at the bracket's end)
        x[i[bad]] = 0.5 * (a[i[bad]] + b[i[bad]])
        fx = f(x[i])
        left = fx * fa[i] < 0  # the root is in [a, x]
        j, k = i[left], i[~left]
        b[j], fb[j] = x[j], fx[left]
        fa[j] = np.where(kept[j] > 0, 0.5 * fa[j], fa[j])
        kept[j] = 1
        a[k], fa[k] = x[k], fx[~left]
        fb[k] = np.where(kept[k] < 0, 0.5 * fb[k], fb[k])
        kept[k] = -1
        width = b[i] - a[i]
        todo[i] = (fx != 0) & (width > 4 * np.finfo(float).eps * np.abs(x[i]) + 1e-15)
    return [float(v) for v in x]


def span_quadrature(edges: tuple[float, ...], order: int) -> tuple[FloatArray, FloatArray]:
    """Gauss-Legendre on each span (its functions are analytic there; the third derivative
    jumps at a support): about ``order`` points per unit length, at least 24 a span."""
    xs, ws = [], []
    for a, b in itertools.pairwise(edges):
        x, w = gauss_legendre_unit(8 * math.ceil(max(24, order * (b - a) + 16) / 8))
        xs.append(a + (b - a) * x)
        ws.append((b - a) * w)
    return np.concatenate(xs), np.concatenate(ws)


def _span_normalised(mode: _SpanMode) -> _SpanMode:
    """Scale to integral phi^2 = 1, sign: the largest sample positive."""
    xi, w = span_quadrature(mode.edges, 32 * math.ceil((mode.lam + 60) / 32))  # (shared)
    v = mode.values(xi, 0)
    norm = math.sqrt(float(w @ (v * v)))
    grid = mode.values(np.linspace(0.0, 1.0, 401), 0)
    sign = 1.0 if grid[np.argmax(np.abs(grid))] > 0 else -1.0
    coef = tuple(tuple(float(c) * sign / norm for c in span) for span in mode.coef)
    return _SpanMode(mode.lam, mode.edges, coef)


@dataclass(frozen=True, eq=False)
class SpanBasis(_Basis):
    """The eigenfunctions of the beam with its end and intermediate supports ``modes``
    (:class:`_SpanMode`); ``coef`` (n, n) is a rotation within clusters of nearly equal
    eigenvalues, whose computed eigenfunctions are orthogonal only to eps / gap (the
    identity to rounding elsewhere)."""

    def _under(self, xi: FloatArray, derivative: int) -> FloatArray:
        return np.array([m.values(xi, derivative) for m in self.modes]).reshape(-1, xi.size)

    def quadrature(self, order: int) -> tuple[FloatArray, FloatArray]:
        """Nodes and weights on [0, 1] for the Galerkin integrals: Gauss-Legendre on each
        span (spectral; across a support the third derivative jumps)."""
        return span_quadrature(self.modes[0].edges, order)


def _span_modes(
    x0: EndSpec, xL: EndSpec, points: tuple[PointSpec, ...], n: int, step: float
) -> tuple[_SpanMode, ...]:
    """The first ``n`` normalised eigenfunctions on the spans (rigid-body modes first)."""
    edges = (0.0, *(xs for xs, _ in points), 1.0)
    lengths = np.diff(edges)
    S = lengths.size
    lines = rigid_lines(x0, xL, points)
    modes: list[_SpanMode] = []
    if lines:
        # on span s (Krylov form at lambda = 0: 1, xi, xi^2/2, xi^3/6 from e_s) the line
        # a + b xi has the coefficients (a + b e_s, b, 0, 0)
        vt = np.array([[c for e in edges[:-1] for c in (a + b * e, b, 0.0, 0.0)]
                       for a, b in lines])  # fmt: skip
        raw = [_SpanMode(0.0, edges, tuple(map(tuple, v.reshape(S, 4)))) for v in vt]
        xi, w = span_quadrature(edges, 16)
        vals = np.array([m.values(xi, 0) for m in raw])
        c = np.linalg.cholesky((vals * w) @ vals.T)
        coefs = np.linalg.solve(c, vt)  # orthonormal rigid-body modes
        modes += [
            _span_normalised(_SpanMode(0.0, edges, tuple(map(tuple, v.reshape(S, 4)))))
            for v in coefs
        ]
    if n > len(modes):
        for lam in _span_roots(x0, xL, points, n - len(modes), step):
            B = _span_matrix(x0, xL, points, np.array([lam]), _span_forms(lam, lengths))[0]
            v = _null_vector(B).reshape(S, 4)
            modes.append(_span_normalised(_SpanMode(lam, edges, tuple(map(tuple, v)))))
    return tuple(modes[:n])


def span_basis(
    n: int, x0: EndSpec, xL: EndSpec, points: tuple[PointSpec, ...], ritz: FloatArray
) -> SpanBasis | None:
    """The exact basis of the spans, or None when its roots cannot be confirmed: each
    lambda_k^4 must lie at or below the Ritz value ``ritz[k]`` (an upper bound of the
    exact one), within :data:`_RITZ_SLACK`; a root missed by the scan (two inside one
    step) fails that, and finer scans are tried.  The functions are made orthonormal by
    the smallest rotation (it mixes only nearly equal eigenvalues' functions)."""
    for step in (_SCAN_STEP, *_FINER_SCANS):
        modes = _span_modes(x0, xL, points, n, step)
        if len(modes) < n:
            continue
        # the computed eigenfunctions are orthogonal only to eps / gap inside a cluster of
        # nearly equal eigenvalues (equal spans): made orthonormal by the smallest rotation
        # (Lowdin's, G^-1/2), which mixes only such near-equal ones, so the bending matrix
        # stays diag(lambda^4) of the roots (a Rayleigh-Ritz step instead reads the low
        # eigenvalues through the quadrature's rounding of the highest: 3e-12 at 30 modes)
        lam4 = np.array([m.lam**4 for m in modes])
        if not np.all(lam4 <= ritz[:n] * (1 + _RITZ_SLACK) + 1e-9):
            continue
        raw = SpanBasis(n, modes, np.eye(n), lam4)
        xi, w = raw.quadrature(int(modes[-1].lam) + 60)
        p0 = raw.shapes(xi, 0)
        g, V = np.linalg.eigh((p0 * w) @ p0.T)
        coef = np.ascontiguousarray((V / np.sqrt(g)) @ V.T)
        for array in (coef, lam4):
            array.setflags(write=False)  # (shared by the cache)
        return SpanBasis(n, modes, coef, lam4, _held(x0, xL, points))
    return None


@lru_cache(maxsize=32)
def support_basis(
    n: int, x0: EndSpec, xL: EndSpec, points: tuple[PointSpec, ...] = ()
) -> SupportBasis | SpanBasis:
    """The Galerkin basis of ``n`` functions for the supports (see the module docstring).
    Springs below :data:`SPRING_FLOOR` are no springs here too, as for the rigid-body
    modes (:func:`rigid_lines`): a basis that kept them would hold the rigid line and a
    nearly equal root of det B twice."""
    clean = (_clean(x0), _clean(xL), tuple(p for p in points if p[1] >= SPRING_FLOOR))
    if clean != (x0, xL, points):
        return support_basis(n, *clean)
    if not points:
        modes, lam4 = end_support_modes(x0, xL, n)
        eye = np.eye(n)
        eye.setflags(write=False)
        return SupportBasis(n, modes, eye, lam4, _held(x0, xL, points))
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
    exact = span_basis(n, x0, xL, points, mu)
    if exact is not None:
        return exact
    coef = np.ascontiguousarray((Z @ Y[:, :n]).T)
    lam4_n = np.maximum(np.asarray(mu[:n], dtype=float), 0.0)  # (rounding below 0)
    for array in (coef, lam4_n):
        array.setflags(write=False)  # (shared by the cache)
    return SupportBasis(n, modes, coef, lam4_n, _held(x0, xL, points))
