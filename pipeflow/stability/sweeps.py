"""Eigenvalue sweeps: Argand diagrams (against flow velocity) and Campbell diagrams (spin).

Modes are followed from point to point by the optimal assignment of left/right eigenvector
overlaps (:func:`pipeflow.spectra.assign`), never by sorting; each point carries the overlap
that linked it to the previous one as a tracking confidence, and where it drops below
``min_confidence`` midpoints are inserted (up to ``max_points``).  A conjugate pair is one
mode: frequencies are reported as |omega| >= 0 (after a branch passes the real axis the
followed member of the pair may be the lower one; its partner is the conjugate).

A sweep does not fan out (:mod:`pipeflow.parallel`): its frozen spectra are one batched
call, and measured on 2 workers (``benchmarks/bench_fanout.py --sweeps``, figures in
``benchmarks/RESULTS.md``) shipping their eigenvectors back costs more than computing them
at the usual sizes (10 modes, 201 points: 25 ms here, 43 ms in 8 pieces) and gains at most
14% of the whole sweep at the largest (40 modes, 2001 points), whose time is mostly the
serial tracking and crossing searches.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from functools import partial
from typing import Literal, Protocol

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import brentq

from pipeflow._types import ComplexArray, FloatArray, Progress
from pipeflow.errors import BudgetExceeded, InvalidInput
from pipeflow.model import REVERSE_FLOW_CAVEAT, Pipe, build_model
from pipeflow.spectra import follow, order_lowest, rounding_level
from pipeflow.stability.core import (
    check_modes,
    check_range,
    crossing_kind,
    mechanisms,
    sign_changes,
    stable_intervals,
    state_matrices,
)

Parameter = Literal["velocity", "spin"]
RPM = 60.0 / (2.0 * math.pi)  # rpm per rad/s

#: refinement can at most multiply the number of points by this factor
MAX_REFINEMENT_FACTOR = 4
#: relative tolerance of located crossings (excitation lines, sigma = 0) [-]
CROSSING_RTOL = 1e-12


class Branches(Protocol):
    """What the crossing searches read of followed branches (``follow``'s result)."""

    p: FloatArray
    xi: ComplexArray
    mode: NDArray[np.intp]

    def branch_at(self, j: int, k: int, p: float) -> complex: ...


@dataclass(frozen=True)
class ExcitationCrossing:
    """Campbell: a tracked branch meets the excitation line omega = order x w0.

    order : n of the line n x w0 [-] (1: synchronous, 2: twice per revolution, ...).
    mode : mode number of the branch.
    spin : w0 at the crossing [rad/s]; frequency = order x |spin| [rad/s].
    sigma : damping of the branch there [1/s] (> 0: unstable).
    """

    order: float
    mode: int
    spin: float
    frequency: float
    sigma: float


@dataclass(frozen=True)
class ZeroCrossing:
    """A tracked branch crossing sigma = 0 along the sweep (the Argand plot's imaginary axis).

    value : swept parameter there [m/s or rad/s]; frequency : |omega| there [rad/s];
    direction : "loss" (becomes unstable with increasing parameter) or "gain".
    """

    mode: int
    value: float
    frequency: float
    direction: Literal["loss", "gain"]


def _abs_omega_minus(br: Branches, j: int, order: float, x: float, k: int) -> float:
    return abs(br.branch_at(j, k, x).imag) - order * abs(x)


def excitation_crossings(
    br: Branches, chosen: Sequence[int], orders: Sequence[float]
) -> list[ExcitationCrossing]:
    """Every root of |omega_j(w0)| - n |w0| of the tracked branches ``chosen`` of a spin sweep
    (the excitation lines n |w0| at either sense of rotation).

    Bracketed on the sweep grid ``br.p`` [rad/s] and located by Brent's method on the frozen
    spectrum (:meth:`Branches.branch_at`, the branch followed by eigenvector overlap) to
    :data:`CROSSING_RTOL`.  A bracket whose ends disagree once re-evaluated (a tracking swap)
    is skipped.  Sorted by order, then spin.
    """
    out: list[ExcitationCrossing] = []
    p = br.p
    for n in orders:
        for j in chosen:
            g = np.abs(br.xi[:, j].imag) - n * np.abs(p)
            for k in np.flatnonzero(np.sign(g[:-1]) * np.sign(g[1:]) < 0):
                f = partial(_abs_omega_minus, br, int(j), float(n))
                a, b = float(p[k]), float(p[k + 1])
                if f(a, int(k)) * f(b, int(k)) > 0:
                    continue
                scale = max(abs(a), abs(b))
                w = float(
                    brentq(f, a, b, args=(int(k),), xtol=1e-14 * scale + 1e-300, rtol=CROSSING_RTOL)
                )
                xi = br.branch_at(int(j), int(k), w)
                out.append(ExcitationCrossing(float(n), int(br.mode[j]), w, n * abs(w), xi.real))
    return sorted(out, key=lambda c: (c.order, c.spin))


def _branch_sigma(br: Branches, j: int, x: float, k: int) -> float:
    return br.branch_at(j, k, x).real


def zero_crossings(br: Branches, chosen: Sequence[int]) -> list[ZeroCrossing]:
    """Where the tracked branches ``chosen`` cross sigma = 0 (the rounding band of
    :func:`~pipeflow.stability.core.rounding_level` counts as zero), by parameter value."""
    tol = rounding_level(br.xi)
    out: list[ZeroCrossing] = []
    for j in chosen:
        sigma = partial(_branch_sigma, br, int(j))
        for x, k, loss in sign_changes(br.p, br.xi[:, j].real, tol, sigma, 0, CROSSING_RTOL):
            xi = br.branch_at(int(j), k, x)
            direction: Literal["loss", "gain"] = "loss" if loss else "gain"
            out.append(ZeroCrossing(int(br.mode[j]), x, abs(xi.imag), direction))
    return sorted(out, key=lambda c: c.value)


@dataclass(frozen=True)
class BoundaryCrossing:
    """The pipe (its whole spectrum, tracked or not) changing stability along the sweep.

    value : swept parameter there [m/s or rad/s]; direction : "loss" or "gain" with
    increasing parameter; kind : "flutter" or "divergence" (the eigenvalue that crosses,
    the fastest-growing on the unstable side); frequency : its |omega| [rad/s].
    """

    value: float
    direction: Literal["loss", "gain"]
    kind: Literal["flutter", "divergence"]
    frequency: float


def pipe_stability(
    br: Branches, matrices: Callable[[FloatArray], FloatArray]
) -> tuple[bool, list[str], list[BoundaryCrossing], list[list[float]]]:
    """The pipe's stability along the sweep, from its whole spectrum (largest sigma over
    every eigenvalue, as the maps do; not only the tracked branches, which may leave out
    the one that diverges): whether it is stable at the first point, how it is unstable
    there (:func:`~pipeflow.stability.core.mechanisms`), every change of stability
    located to :data:`CROSSING_RTOL` and the intervals where it is stable."""
    tol = rounding_level(br.xi)
    radius = float(np.max(np.abs(br.xi)))

    def spectrum(x: float) -> ComplexArray:
        return np.asarray(np.linalg.eigvals(matrices(np.array([x]))[0]))

    def growth(x: float, k: int) -> float:
        return float(spectrum(x).real.max())

    how = mechanisms(br.xi[0], float(tol[0]), radius)
    out = []
    g = br.xi.real.max(axis=1)
    for x, _, loss in sign_changes(br.p, g, tol, growth, 0, CROSSING_RTOL, spectrum):
        kind, omega = crossing_kind(spectrum, x, loss)
        out.append(BoundaryCrossing(x, "loss" if loss else "gain", kind, omega))  # type: ignore[arg-type]
    intervals = stable_intervals(
        float(br.p[0]), float(br.p[-1]), not how, [(c.value, c.direction == "loss") for c in out]
    )
    return not how, how, out, intervals


@dataclass
class Sweep:
    """Tracked eigenvalues along a sweep (SI units; JSON form:
    :func:`pipeflow.computations.documents.sweep`).

    parameter : "velocity" (Argand: values in m/s at constant spin ``fixed`` rad/s) or
        "spin" (Campbell: values in rad/s at constant flow velocity ``fixed`` m/s).
    values : swept parameter at each point (refined points included).
    xi : (points, modes) eigenvalues sigma + i|omega| [1/s].
    confidence : (points, modes) tracking confidence in [0, 1].
    mode : mode numbers (1 = lowest frequency at the first point).
    inserted : the point was added by refinement.
    stable_at_start : the pipe (every eigenvalue, not only the tracked branches) is
        stable at the first point; instability_at_start : how it is unstable there
        ("divergence" and/or "flutter", fastest first; empty when stable); boundary :
        every change of its stability along the sweep; stable_intervals : [[a, b], ...]
        of the swept parameter where it is stable (:func:`pipe_stability`).
    """

    pipe: Pipe
    modes: int
    parameter: Parameter
    fixed: float
    values: FloatArray
    xi: ComplexArray
    confidence: FloatArray
    mode: NDArray[np.intp]
    inserted: NDArray[np.bool_]
    warnings: list[str] = field(default_factory=list)
    orders: tuple[float, ...] = ()
    excitation: list[ExcitationCrossing] = field(default_factory=list)
    zero_crossings: list[ZeroCrossing] = field(default_factory=list)
    stable_at_start: bool = True
    instability_at_start: list[str] = field(default_factory=list)
    boundary: list[BoundaryCrossing] = field(default_factory=list)
    stable_intervals: list[list[float]] = field(default_factory=list)

    @property
    def sigma(self) -> FloatArray:
        """Damping [1/s] (negative: decaying)."""
        return np.asarray(self.xi.real)

    @property
    def omega(self) -> FloatArray:
        """Frequency [rad/s]."""
        return np.asarray(self.xi.imag)


def sweep(
    pipe: Pipe,
    parameter: Parameter,
    value_range: tuple[float, float],
    fixed: float = 0.0,
    modes: int = 10,
    tracked: int = 4,
    points: int = 201,
    min_confidence: float = 0.9,
    max_points: int | None = None,
    progress: Progress | None = None,
    orders: Sequence[float] = (1.0, 2.0),
) -> Sweep:
    """Eigenvalues against flow velocity (Argand) or spin (Campbell), modes tracked.

    Parameters
    ----------
    pipe : pipe and fluid properties.
    parameter : "velocity" (value_range in m/s, ``fixed`` = spin w0 in rad/s) or "spin"
        (value_range in rad/s, ``fixed`` = flow velocity v in m/s).
    value_range : (first, last) value of the swept parameter; evenly spaced ``points``.
    modes : Galerkin modes n; tracked : how many of the lowest modes to report (<= n).
    min_confidence : refine (insert midpoints) where tracking confidence falls below this.
    max_points : cap on the points after refinement (default 4 x points).
    progress : called with a fraction in [0, 1]; may raise ``Cancelled``.
    orders : Campbell only: excitation orders n [-] whose lines omega = n w0 are crossed with
        the tracked branches (:func:`excitation_crossings`); ignored for velocity sweeps.
    """
    check_modes(modes)
    if any(not (math.isfinite(n) and n > 0) for n in orders):
        raise InvalidInput(f"excitation orders must be positive, got {list(orders)}", "orders")
    if not 1 <= tracked <= modes:
        raise InvalidInput(
            f"tracked modes must be between 1 and {modes}", parameter="tracked_modes"
        )
    if parameter not in ("velocity", "spin"):
        raise InvalidInput(f"unknown sweep parameter {parameter!r}", parameter="parameter")
    lo, hi = float(value_range[0]), float(value_range[1])
    check_range(lo, hi, "velocity_range" if parameter == "velocity" else "spin_range")
    if points < 2:
        raise InvalidInput("points must be >= 2", parameter="points")
    if not 0 <= min_confidence <= 1:
        raise InvalidInput("min_confidence must be in [0, 1]", parameter="min_confidence")
    cap = max_points if max_points is not None else MAX_REFINEMENT_FACTOR * points
    if cap < points:
        raise BudgetExceeded("max_points must be >= points", parameter="max_points")
    model = build_model(pipe, modes)
    warnings: list[str] = []
    if parameter == "velocity":

        def matrices(p: FloatArray) -> FloatArray:
            return state_matrices(model, p, fixed)

        if lo < 0:
            warnings.append(REVERSE_FLOW_CAVEAT)
    else:

        def matrices(p: FloatArray) -> FloatArray:
            return state_matrices(model, fixed, p)

        if fixed < 0:
            warnings.append(REVERSE_FLOW_CAVEAT)
    if progress is not None:
        progress(0.0)
    br = follow(
        matrices,
        np.linspace(lo, hi, points),
        watch=lambda w0: order_lowest(w0, tracked, pipe.damped),
        min_confidence=min_confidence,
        max_points=cap,
        progress=progress,
        damped=pipe.damped,
    )
    chosen = order_lowest(br.xi[0], tracked, pipe.damped)
    xi = br.xi[:, chosen]
    xi = xi.real + 1j * np.abs(xi.imag)
    conf = br.confidence[:, chosen]
    low = int(np.sum(np.min(conf, axis=1) < min_confidence))
    if low:
        warnings.append(
            f"{low} points keep a tracking confidence below {min_confidence} after refinement "
            "(eigenvalues coalescing, e.g. a mode passing through the real axis, or the "
            "point cap was reached): branch identities there are uncertain"
        )
    orders = tuple(float(n) for n in orders) if parameter == "spin" else ()
    excitation = excitation_crossings(br, chosen.tolist(), orders)
    zeros = zero_crossings(br, chosen.tolist())
    stable, how, boundary, intervals = pipe_stability(br, matrices)
    if progress is not None:
        progress(1.0)
    return Sweep(
        pipe=pipe,
        modes=modes,
        parameter=parameter,
        fixed=float(fixed),
        values=br.p,
        xi=xi,
        confidence=conf,
        mode=br.mode[chosen],
        inserted=br.inserted,
        warnings=warnings,
        orders=orders,
        excitation=excitation,
        zero_crossings=zeros,
        stable_at_start=stable,
        instability_at_start=how,
        boundary=boundary,
        stable_intervals=intervals,
    )
