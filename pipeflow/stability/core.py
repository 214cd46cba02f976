"""Frozen spectra of the undamped pipe for constant flow and spin, and branch following.

For constant flow velocity v [m/s] and spin w0 [rad/s] the state matrix of
:mod:`pipeflow.model` is ``S(v, w0) = S_0 + v S_v + v^2 S_v2 + w0^2 S_w2`` (dv/dt = 0) and
the motion is a sum of ``exp(xi t)`` with xi = sigma + i omega its eigenvalues: sigma [1/s]
> 0 means growth.  Everything here is batched: a set of (v, w0) points is one stacked
``numpy.linalg.eig`` call.

Conventions used by the whole :mod:`pipeflow.stability` package

- Branches are followed, and numbered, by :mod:`pipeflow.spectra` (:func:`follow`,
  :func:`mode_numbers`), the tracker the simulation's traces use too.
- A branch is *unstable* where sigma > ``tol``, with ``tol`` a rounding level of the
  spectrum (:func:`~pipeflow.spectra.rounding_level`).  At v = 0 the undamped model
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
from typing import Any

import numpy as np
from numpy.typing import ArrayLike
from scipy.optimize import brentq, minimize_scalar

from pipeflow._types import ComplexArray, FloatArray
from pipeflow.basis import MAX_MODES
from pipeflow.errors import InvalidInput
from pipeflow.model import DIMENSIONLESS_GROUPS, PLANES, Pipe, PipeModel


def check_modes(modes: int, parameter: str = "modes") -> None:
    if not 1 <= int(modes) <= MAX_MODES:
        raise InvalidInput(
            f"modes must be between 1 and {MAX_MODES}, got {modes}", parameter=parameter
        )


def check_range(lo: float, hi: float, parameter: str) -> None:
    if not (math.isfinite(lo) and math.isfinite(hi)):
        raise InvalidInput(f"{parameter} must be finite, got [{lo}, {hi}]", parameter=parameter)
    if not lo < hi:
        raise InvalidInput(f"{parameter} must be increasing, got [{lo}, {hi}]", parameter=parameter)


def state_matrices(model: PipeModel, v: ArrayLike, w0: ArrayLike) -> FloatArray:
    """Balanced state matrices S(v, w0), shape ``(N, 2n, 2n)`` [1/s], for constant v, w0.

    ``v`` [m/s] and ``w0`` [rad/s] broadcast against each other (flattened).
    """
    vv, ww = np.broadcast_arrays(np.asarray(v, dtype=float), np.asarray(w0, dtype=float))
    return model.frozen_state_matrix(vv.ravel(), 0.0, ww.ravel() ** 2)


def eigenvalues(model: PipeModel, v: ArrayLike, w0: ArrayLike) -> ComplexArray:
    """All 2n eigenvalues xi [1/s] at each (v, w0) point, shape ``(N, 2n)`` (unordered)."""
    return np.asarray(np.linalg.eigvals(state_matrices(model, v, w0)))


def growth_rate(model: PipeModel, v: ArrayLike, w0: ArrayLike) -> FloatArray:
    """Largest real part max(sigma) [1/s] at each (v, w0) point: > 0 means unstable."""
    return np.asarray(eigenvalues(model, v, w0).real.max(axis=-1))


def damping_ratio(xi: ComplexArray) -> FloatArray:
    """zeta = -sigma / |xi| [-] (1 for a decaying real eigenvalue, < 0 when growing)."""
    mag = np.abs(xi)
    with np.errstate(invalid="ignore", divide="ignore"):
        z = np.where(mag > 0, -xi.real / np.where(mag > 0, mag, 1.0), 0.0)
    return np.asarray(z)


#: the :class:`Pipe` field that carries each group of :data:`pipeflow.model.GROUPS` (on the
#: unit pipe of :func:`nondimensional_pipe` group and field are equal)
GROUP_FIELDS = {g.name: g.field for g in DIMENSIONLESS_GROUPS}


def nondimensional_pipe(
    beta: float, groups: Mapping[str, float] | None = None, plane: str = "in-plane"
) -> Pipe:
    """A pipe with E = I = L = 1, M1 + M2 = 1, M2 = beta: then v = u / sqrt(beta), w0 = gamma
    and time is tau (Paidoussis' non-dimensional groups, physics notes section 1).

    ``groups``: the extended model's groups by name (:data:`pipeflow.model.GROUPS`; missing
    ones are 0), ``plane`` its plane.
    """
    if not 0 < beta < 1:
        raise InvalidInput(f"beta must be in (0, 1), got {beta}", parameter="beta")
    extra: dict[str, Any] = {}  # the group fields (floats)
    for name, value in (groups or {}).items():
        if name not in GROUP_FIELDS:
            raise InvalidInput(
                f"unknown group {name!r}; use {', '.join(GROUP_FIELDS)}", parameter="groups"
            )
        if not (math.isfinite(value) and value >= 0):
            raise InvalidInput(f"{name} must be finite and >= 0, got {value}", parameter=name)
        extra[GROUP_FIELDS[name]] = float(value)
    if plane not in PLANES:
        raise InvalidInput(f"unknown plane {plane!r}", parameter="plane")
    return Pipe(E=1.0, I=1.0, L=1.0, M1=1.0 - beta, M2=beta, plane=plane, **extra)


def sign_changes(
    p: FloatArray,
    s: FloatArray,
    tol: FloatArray,
    sigma: Callable[[float, int], float],
    start: int = 0,
    rtol: float = 1e-10,
    spectrum: Callable[[float], ComplexArray] | None = None,
) -> list[tuple[float, int, bool]]:
    """Where a real part ``s`` sampled on ``p`` crosses the stability threshold.

    ``s[k]`` is sigma at ``p[k]`` [1/s], unstable where ``s > tol``; ``sigma(x, k)`` evaluates
    the same quantity anywhere in the interval around point k.  Every change of state after
    index ``start`` is located by Brent's method to relative tolerance ``rtol``; a narrow
    window inside one interval (a local maximum of s poking above zero between stable
    samples, or a local minimum dipping below it between unstable ones, which is how the
    S-shaped parts of u_cr(beta) look on a coarse grid) is found by bounded optimisation
    where the extremum lies within a few sample steps of zero.

    ``spectrum(x)``, the whole spectrum whose largest real part ``s`` is (optional), lets a
    divergence of a conservative pipe be located on a quantity that crosses zero linearly
    (:func:`collision_root`) instead of sigma's square-root onset.

    Returns ``(x, k, loss)`` per crossing: position, interval index, and whether the
    quantity becomes unstable there with increasing p.
    """
    unstable = s > tol
    out: list[tuple[float, int, bool]] = []

    def root(a: float, b: float, k: int) -> float:
        if spectrum is not None:
            x = collision_root(spectrum, a, b, float(tol[k]), rtol)
            if x is not None:
                return x
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
            if np.max(np.abs(s[k - 1 : k + 2])) <= tol[k]:
                continue  # rounding on the imaginary axis (a conservative, supported pipe)
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


def collision_root(
    spectrum: Callable[[float], ComplexArray], a: float, b: float, tol: float, rtol: float
) -> float | None:
    """Where a conservative pipe diverges between ``a`` and ``b`` (one end stable, every
    eigenvalue on the imaginary axis to ``tol`` [1/s]; the other diverging, its leading
    eigenvalue real), or None when the crossing is not of that kind.

    There a pair +-i omega meets at 0 and leaves along the real axis as +-sigma: sigma grows
    like the square root of the distance past the point, flat on the stable side, which
    Brent's method can only bisect (~45 eigenvalue problems to 1e-10); lambda^2, -omega^2
    of the slowest eigenvalue on the axis and +sigma^2 past the point, crosses zero
    linearly, and the same search takes ~8.  ``rtol``: relative tolerance of the point."""

    def square(x: float) -> float | None:
        xi = np.asarray(spectrum(x))
        radius = float(np.max(np.abs(xi)))
        lead = xi[int(np.argmax(xi.real))]
        if lead.real > tol:  # diverging (a real eigenvalue) or fluttering (None)
            return float(lead.real) ** 2 if abs(lead.imag) <= 1e-7 * radius else None
        if np.any(xi.real < -tol):
            return None  # damped: sigma itself crosses zero linearly
        return -(float(np.min(np.abs(xi))) ** 2)

    fa = square(a)
    fb = None if fa is None else square(b)
    if fa is None or fb is None or fa * fb >= 0:
        return None
    scale = max(abs(a), abs(b))

    def f(x: float) -> float:
        value = square(x)
        if value is None:  # left the pattern inside the interval: sigma's own search
            raise _NotACollision
        return value

    try:
        return float(brentq(f, a, b, xtol=1e-14 * scale + 1e-300, rtol=rtol))
    except _NotACollision:
        return None


class _NotACollision(Exception):
    """:func:`collision_root` met a spectrum that is not a conservative divergence."""


def mechanisms(xi: ComplexArray, tol: float, radius: float) -> list[str]:
    """How the spectrum ``xi`` [1/s] is unstable: "divergence" (a real eigenvalue with
    sigma > ``tol``) and/or "flutter" (a complex pair with sigma > ``tol``), each once,
    the fastest-growing first; empty when stable.  An eigenvalue is real when
    |omega| <= 1e-7 ``radius`` (the spectral radius of the sweep), the rule the crossings
    are classified by."""
    out: list[str] = []
    for x in sorted(np.asarray(xi).ravel(), key=lambda x: -x.real):
        if x.real <= tol:
            break
        kind = "divergence" if abs(x.imag) <= 1e-7 * radius else "flutter"
        if kind not in out:
            out.append(kind)
    return out


def crossing_kind(
    spectrum: Callable[[float], ComplexArray], x: float, loss: bool
) -> tuple[str, float]:
    """``(kind, omega)`` of a change of stability at ``x``: the fastest-growing eigenvalue on
    the unstable side (x (1 + 1e-6) for a loss, x (1 - 1e-6) for a gain) is real
    ("divergence", omega 0) or a pair ("flutter", its |omega| [rad/s]).  Read on the unstable
    side because at x itself a divergence is a pair meeting at 0, whose rounding leaves an
    omega of order sqrt(eps) |xi| that a test at x would call flutter."""
    side = x * (1 + 1e-6) if loss else x * (1 - 1e-6)
    w = np.asarray(spectrum(side))
    top = w[np.argmax(w.real)]
    if abs(top.imag) <= 1e-3 * max(abs(top), 1e-300):
        return "divergence", 0.0
    return "flutter", abs(float(top.imag))


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
