"""Frozen spectra of the undamped pipe for constant flow and spin, and branch following.

For constant flow velocity v [m/s] and spin w0 [rad/s] the state matrix of
:mod:`pipeflow.model` is ``S(v, w0) = S_0 + v S_v + v^2 S_v2 + w0^2 S_w2`` (dv/dt = 0) and
the motion is a sum of ``exp(xi t)`` with xi = sigma + i omega its eigenvalues: sigma [1/s]
> 0 means growth.  Everything here is batched: a set of (v, w0) points is one stacked
``numpy.linalg.eig`` call.

Conventions used by the whole :mod:`pipeflow.stability` package

- A branch is *unstable* where sigma > ``tol``, with ``tol`` a rounding level of the
  spectrum (``MARGINAL_RTOL`` times the spectral radius).  At v = 0 the undamped model
  has every eigenvalue on the imaginary axis (sigma = 0 to rounding); that point counts
  as stable, which is what the sign of d sigma/dv says just above it (the Coriolis term
  2 M2 v u_xt removes energy through the free end for v > 0).
- Mode numbers are 1, 2, ... in order of frequency at the first point of a sweep (for a
  velocity sweep that is v = 0, the rotating-beam modes), both members of a conjugate pair
  carry the same number.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.optimize import brentq, minimize_scalar

from pipeflow.basis import MAX_MODES
from pipeflow.eigen import assign, damped_modes, decompose
from pipeflow.errors import InvalidInput
from pipeflow.model import PLANES, Coefficients, Pipe, PipeModel

FloatArray = NDArray[np.float64]
ComplexArray = NDArray[np.complex128]
Progress = Callable[[float], None]

#: sigma below this fraction of the spectral radius is rounding, not growth
MARGINAL_RTOL = 1e-11


def check_modes(modes: int, field: str = "modes") -> None:
    if not 1 <= int(modes) <= MAX_MODES:
        raise InvalidInput(f"modes must be between 1 and {MAX_MODES}, got {modes}", field=field)


def check_range(lo: float, hi: float, field: str) -> None:
    if not (math.isfinite(lo) and math.isfinite(hi)):
        raise InvalidInput(f"{field} must be finite, got [{lo}, {hi}]", field=field)
    if not lo < hi:
        raise InvalidInput(f"{field} must be increasing, got [{lo}, {hi}]", field=field)


def frozen_matrices(model: PipeModel, v: ArrayLike, vdot: ArrayLike, w2: ArrayLike) -> FloatArray:
    """S = S_0 + v S_v + vdot S_vdot + v^2 S_v2 + w0^2 S_w2 [1/s] for any batch shape.

    ``v`` [m/s], ``vdot`` [m/s^2] and ``w2`` = w0^2 [rad^2/s^2] broadcast to one shape
    ``B``; the result has shape ``B + (2n, 2n)`` (:meth:`PipeModel.state_matrix` on the
    flattened batch).
    """
    vv, aa, ww = np.broadcast_arrays(*(np.asarray(x, dtype=float) for x in (v, vdot, w2)))
    flat = vv.ravel()
    S = model.state_matrix(
        Coefficients(v=flat, vdot=aa.ravel(), w2=ww.ravel(), wdot=np.zeros_like(flat))
    )
    return np.asarray(S.reshape(vv.shape + S.shape[1:]))


def state_matrices(model: PipeModel, v: ArrayLike, w0: ArrayLike) -> FloatArray:
    """Balanced state matrices S(v, w0), shape ``(N, 2n, 2n)`` [1/s], for constant v, w0.

    ``v`` [m/s] and ``w0`` [rad/s] broadcast against each other (flattened).
    """
    vv, ww = np.broadcast_arrays(np.asarray(v, dtype=float), np.asarray(w0, dtype=float))
    return frozen_matrices(model, vv.ravel(), 0.0, ww.ravel() ** 2)


def eigenvalues(model: PipeModel, v: ArrayLike, w0: ArrayLike) -> ComplexArray:
    """All 2n eigenvalues xi [1/s] at each (v, w0) point, shape ``(N, 2n)`` (unordered)."""
    return np.asarray(np.linalg.eigvals(state_matrices(model, v, w0)))


def growth_rate(model: PipeModel, v: ArrayLike, w0: ArrayLike) -> FloatArray:
    """Largest real part max(sigma) [1/s] at each (v, w0) point: > 0 means unstable."""
    return np.asarray(eigenvalues(model, v, w0).real.max(axis=-1))


def rounding_level(xi: ComplexArray) -> FloatArray:
    """Per-point level [1/s] below which sigma is rounding (``MARGINAL_RTOL`` x radius)."""
    return np.asarray(MARGINAL_RTOL * np.max(np.abs(xi), axis=-1))


def damping_ratio(xi: ComplexArray) -> FloatArray:
    """zeta = -sigma / |xi| [-] (1 for a decaying real eigenvalue, < 0 when growing)."""
    mag = np.abs(xi)
    with np.errstate(invalid="ignore", divide="ignore"):
        z = np.where(mag > 0, -xi.real / np.where(mag > 0, mag, 1.0), 0.0)
    return np.asarray(z)


def mode_numbers(w: ComplexArray, damped: bool = False) -> NDArray[np.intp]:
    """Mode number (1-based, by frequency) of each eigenvalue of one point; pairs share it.

    A conjugate pair is one mode, and so is a real pair +-s (a divergent mode of the
    conservative v = 0 system); other real eigenvalues are modes of frequency 0 (they
    come first).  ``damped``: by natural frequency, an over-damped pair of real roots being
    one mode (:func:`pipeflow.eigen.damped_modes`).
    """
    if damped:
        reps, partner = damped_modes(w)
        number = np.zeros(w.size, dtype=np.intp)
        number[reps] = np.arange(1, reps.size + 1)
        for other, rep in partner.items():
            number[other] = number[rep]
        return number
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
    for i in np.flatnonzero(lower):
        partner = order[np.argmin(np.abs(w[order] - np.conj(w[i])) * np.abs(w[order] + w[i]))]
        number[i] = number[partner]
    return number


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
    low confidence is reported.
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


#: the :class:`Pipe` field that carries each group of :meth:`Pipe.dimensionless_groups` on
#: the unit pipe of :func:`nondimensional_pipe`, where group and field are equal
GROUP_FIELDS = {
    "alpha": "kelvin_voigt",
    "sigma": "viscous",
    "tip_mass_ratio": "tip_mass",
    "tip_inertia_ratio": "tip_inertia",
    "hub_ratio": "hub_radius",
}


def nondimensional_pipe(
    beta: float, groups: Mapping[str, float] | None = None, plane: str = "in-plane"
) -> Pipe:
    """A pipe with E = I = L = 1, M1 + M2 = 1, M2 = beta: then v = u / sqrt(beta), w0 = gamma
    and time is tau (Paidoussis' non-dimensional groups, physics notes section 1).

    ``groups``: the extended model's groups (keys of :data:`GROUP_FIELDS`: alpha, sigma,
    tip_mass_ratio, tip_inertia_ratio, hub_ratio; missing ones are 0), ``plane`` its plane.
    """
    if not 0 < beta < 1:
        raise InvalidInput(f"beta must be in (0, 1), got {beta}", field="beta")
    extra: dict[str, float] = {}
    for name, value in (groups or {}).items():
        if name not in GROUP_FIELDS:
            raise InvalidInput(
                f"unknown group {name!r}; use {', '.join(GROUP_FIELDS)}", field="groups"
            )
        if not (math.isfinite(value) and value >= 0):
            raise InvalidInput(f"{name} must be finite and >= 0, got {value}", field=name)
        extra[GROUP_FIELDS[name]] = float(value)
    if plane not in PLANES:
        raise InvalidInput(f"unknown plane {plane!r}", field="plane")
    return Pipe(E=1.0, I=1.0, L=1.0, M1=1.0 - beta, M2=beta, plane=plane, **extra)


def sign_changes(
    p: FloatArray,
    s: FloatArray,
    tol: FloatArray,
    sigma: Callable[[float, int], float],
    start: int = 0,
    rtol: float = 1e-10,
) -> list[tuple[float, int, bool]]:
    """Where a real part ``s`` sampled on ``p`` crosses the stability threshold.

    ``s[k]`` is sigma at ``p[k]`` [1/s], unstable where ``s > tol``; ``sigma(x, k)`` evaluates
    the same quantity anywhere in the interval around point k.  Every change of state after
    index ``start`` is located by Brent's method to relative tolerance ``rtol``; a narrow
    window inside one interval (a local maximum of s poking above zero between stable
    samples, or a local minimum dipping below it between unstable ones, which is how the
    S-shaped parts of u_cr(beta) look on a coarse grid) is found by bounded optimisation
    where the extremum lies within a few sample steps of zero.

    Returns ``(x, k, loss)`` per crossing: position, interval index, and whether the
    quantity becomes unstable there with increasing p.
    """
    unstable = s > tol
    out: list[tuple[float, int, bool]] = []

    def root(a: float, b: float, k: int) -> float:
        fa, fb = sigma(a, k), sigma(b, k)
        shift = 0.0
        if fa * fb > 0:  # one end sits in the rounding band (v = 0): use the band's edge
            shift = float(tol[k])
        scale = max(abs(a), abs(b))
        return float(
            brentq(lambda x: sigma(x, k) - shift, a, b, xtol=1e-14 * scale + 1e-300, rtol=rtol)
        )

    for k in range(start, p.size - 1):
        if unstable[k] != unstable[k + 1]:
            out.append((root(p[k], p[k + 1], k), k, bool(unstable[k + 1])))
    for k in range(max(start, 1), p.size - 1):
        trio = unstable[k - 1 : k + 2]
        if trio.all():
            if not (s[k] <= s[k - 1] and s[k] <= s[k + 1]):
                continue
            sign = 1.0  # minimise: does it dip below zero?
        elif not trio.any():
            if not (s[k] >= s[k - 1] and s[k] >= s[k + 1]):
                continue
            sign = -1.0  # maximise: does it poke above zero?
        else:
            continue
        reach = 4.0 * max(abs(s[k] - s[k - 1]), abs(s[k] - s[k + 1]))
        if abs(s[k]) > reach:
            continue
        a, b = float(p[k - 1]), float(p[k + 1])
        res = minimize_scalar(
            lambda x, k=k, sign=sign: -sign * sigma(x, k),
            bounds=(a, b),
            method="bounded",
            options={"xatol": 1e-12 * max(abs(a), abs(b))},
        )
        x = float(res.x)
        ext = sigma(x, k)
        if (sign < 0 and ext > tol[k]) or (sign > 0 and ext <= tol[k]):
            first_loss = sign < 0
            for (lo, hi), loss in (((a, x), first_loss), ((x, b), not first_loss)):
                if (sigma(lo, k) - tol[k]) * (sigma(hi, k) - tol[k]) < 0:
                    out.append((root(lo, hi, k), k, loss))
    return sorted(out)


def stable_intervals(
    lo: float, hi: float, stable_at_start: bool, boundary: list[tuple[float, bool]]
) -> list[list[float]]:
    """Intervals of [lo, hi] where the pipe is stable, from the boundary crossings.

    ``boundary`` holds ``(x, loss)`` for each change of the pipe's stability, in order.
    """
    out: list[list[float]] = []
    begin: float | None = lo if stable_at_start else None
    for x, loss in boundary:
        if loss and begin is not None:
            out.append([begin, x])
            begin = None
        elif not loss and begin is None:
            begin = x
    if begin is not None:
        out.append([begin, hi])
    return out
