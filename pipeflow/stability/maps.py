"""Stability maps: critical flow velocity against spin, and u_cr(beta) in Paidoussis' form.

Both scan a grid with one batched eigenvalue call and then locate every crossing of the
stability boundary along each velocity line by Brent's method on the largest real part
g(v) = max sigma of the whole spectrum (the zero level of g *is* the stability boundary),
including narrow windows between samples (:func:`pipeflow.stability.core.sign_changes`).
Several crossings on one line are the S-shaped segments of the u_cr(beta) curve: the pipe
loses, regains and loses stability again.  Mode numbers need branch following; for one
line use :func:`pipeflow.stability.critical.critical_velocities`.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from pipeflow import parallel
from pipeflow._types import ComplexArray, FloatArray, Progress
from pipeflow.errors import BudgetExceeded, InvalidInput
from pipeflow.model import REVERSE_FLOW_CAVEAT, Pipe, PipeModel, build_model
from pipeflow.spectra import rounding_level
from pipeflow.stability.core import (
    check_modes,
    check_range,
    crossing_kind,
    eigenvalues,
    mechanisms,
    nondimensional_pipe,
    sign_changes,
)

#: eigenvalue problems per batched call (bounds memory: 4096 x 80 x 80 complex ~ 0.4 GB max)
CHUNK = 4096
#: ceiling on grid points x (2n)^3 for one map
MAX_MAP_WORK = 2e10


@dataclass(frozen=True)
class BoundaryCrossing:
    """A crossing of the stability boundary along one velocity line.

    velocity : [m/s] (for the beta map: the flow number u [-]).
    direction : "loss" or "gain" of stability with increasing velocity.
    kind : "flutter" or "divergence"; frequency : omega of the crossing mode [rad/s]
        (for the beta map: non-dimensional, omega times the time scale).
    """

    velocity: float
    direction: str
    kind: str
    frequency: float


def check_map_work(points: int, modes: int, parameter: str) -> None:
    """Raise :class:`BudgetExceeded` when ``points`` eigenproblems of ``2 modes`` cost too much."""
    work = points * (2.0 * modes) ** 3
    if work > MAX_MAP_WORK:
        raise BudgetExceeded(
            f"the map needs {points} eigenvalue problems of size {2 * modes}: "
            f"{work:.3g} > {MAX_MAP_WORK:.3g} units; use fewer points or modes",
            parameter=parameter,
        )


def _spectra(model: PipeModel, v: FloatArray, w0: FloatArray) -> Any:
    """Eigenvalues on the grid ``v`` x ``w0`` (broadcast), in batches of :data:`CHUNK`."""
    vv, ww = np.broadcast_arrays(v, w0)
    shape = vv.shape
    vv, ww = vv.ravel(), ww.ravel()
    out = np.empty((vv.size, model.size), dtype=complex)
    for i in range(0, vv.size, CHUNK):
        out[i : i + CHUNK] = eigenvalues(model, vv[i : i + CHUNK], ww[i : i + CHUNK])
    return out.reshape(*shape, model.size)


def _line(
    model: PipeModel, v: FloatArray, w0: float, xi: Any, rtol: float
) -> list[BoundaryCrossing]:
    """Boundary crossings along one line of constant spin, v >= 0 part only."""
    g = xi.real.max(axis=-1)
    tol = rounding_level(xi)
    start = int(np.searchsorted(v, 0.0))

    def growth(x: float, k: int) -> float:
        return float(eigenvalues(model, x, w0)[0].real.max())

    out = []

    def spectrum(x: float) -> ComplexArray:
        return np.asarray(eigenvalues(model, x, w0)[0])

    for x, _, loss in sign_changes(v, g, tol, growth, start, rtol, spectrum):
        kind, omega = crossing_kind(spectrum, x, loss)
        out.append(
            BoundaryCrossing(
                velocity=x, direction="loss" if loss else "gain", kind=kind, frequency=omega
            )
        )
    return out


def _first_loss(crossings: list[BoundaryCrossing]) -> float | None:
    losses = [c.velocity for c in crossings if c.direction == "loss"]
    return losses[0] if losses else None


@dataclass
class SpinMap:
    """Critical flow velocities against spin (SI units; JSON form:
    :func:`pipeflow.computations.documents.spin_map`).

    spins : w0 [rad/s]; velocities : v grid [m/s]; growth[i, k] : max sigma [1/s] at
    (spins[i], velocities[k]); crossings[i] : the boundary crossings at spins[i] for v >= 0;
    critical_velocity[i] : the first loss [m/s] or None (if the line starts unstable, e.g.
    divergence by fast spin at v = 0, the first loss after stability is regained; see
    stable_at_start and stable_intervals); instability_at_start[i] : how the line is
    unstable at its first v >= 0 ("divergence" and/or "flutter", fastest first; empty
    when stable there).
    """

    pipe: Pipe
    modes: int
    spins: FloatArray
    velocities: FloatArray
    growth: FloatArray
    crossings: list[list[BoundaryCrossing]]
    stable_at_start: list[bool]
    critical_velocity: list[float | None]
    warnings: list[str] = field(default_factory=list)
    instability_at_start: list[list[str]] = field(default_factory=list)


@dataclass(frozen=True)
class _SpinLines:
    """A piece of a spin map: the lines of constant spin ``spins`` [rad/s] over the whole
    velocity grid ``velocities`` [m/s] (picklable: a host may run it elsewhere)."""

    pipe: Pipe
    modes: int
    velocities: FloatArray
    spins: FloatArray
    rtol: float


def _start(xi: Any, start: int) -> tuple[bool, list[str]]:
    """Stability at point ``start`` of a line whose spectra are ``xi`` (points x 2n) and
    how it is unstable there (:func:`~pipeflow.stability.core.mechanisms`)."""
    if start >= len(xi):
        return False, []
    tol = float(rounding_level(xi[start]))
    how = mechanisms(xi[start], tol, float(np.max(np.abs(xi))))
    return bool(xi[start].real.max() <= tol), how


_Lines = tuple[list[list[BoundaryCrossing]], list[bool], list[list[str]]]


def _spin_lines(
    piece: _SpinLines,
) -> tuple[FloatArray, list[list[BoundaryCrossing]], list[bool], list[list[str]]]:
    """Growth rates (spins x velocities) [1/s], boundary crossings, and stability at the
    first v >= 0 of each line of ``piece`` with how it is unstable there: every point and
    line is computed on its own, so the map does not depend on how it is cut."""
    model = build_model(piece.pipe, piece.modes)
    v = piece.velocities
    xi = _spectra(model, v[None, :], piece.spins[:, None])
    start = int(np.searchsorted(v, 0.0))
    crossings, stable, how = [], [], []
    for i, w0 in enumerate(piece.spins):
        line = _line(model, v, float(w0), xi[i], piece.rtol) if start < v.size else []
        ok, kinds = _start(xi[i], start)
        crossings.append(line)
        stable.append(ok)
        how.append(kinds)
    return xi.real.max(axis=-1), crossings, stable, how


def spin_map(
    pipe: Pipe,
    velocity_range: tuple[float, float],
    spin_range: tuple[float, float],
    modes: int = 10,
    velocity_points: int = 100,
    spin_points: int = 100,
    rtol: float = 1e-10,
    progress: Progress | None = None,
) -> SpinMap:
    """Growth-rate map over (w0, v) and the critical velocities at each spin.

    velocity_range [m/s] and spin_range [rad/s] are sampled evenly; crossings are searched
    on the v >= 0 part of each line (v < 0 gets the reverse-flow caveat) and located to
    relative tolerance ``rtol``.  The spins are cut into chunks (:func:`pipeflow.parallel.split`,
    at most :data:`CHUNK` eigenproblems each) that run on the installed host and are merged
    in order; ``progress`` is called after each chunk.
    """
    check_modes(modes)
    check_range(*velocity_range, parameter="velocity_range")
    check_range(*spin_range, parameter="spin_range")
    if velocity_points < 3 or spin_points < 1:
        raise InvalidInput("need >= 3 velocity points and >= 1 spin point", parameter="points")
    check_map_work(velocity_points * spin_points, modes, "spin_points")
    v = np.linspace(*velocity_range, velocity_points)
    if velocity_range[0] < 0 < velocity_range[1]:
        v = np.union1d(v, [0.0])  # the line must pass through the marginal point v = 0
    w = np.linspace(*spin_range, spin_points)
    warnings = [REVERSE_FLOW_CAVEAT] if velocity_range[0] < 0 else []
    chunks = parallel.split(w.size, max_size=max(1, CHUNK // v.size))
    pieces = [_SpinLines(pipe, modes, v, w[c.start : c.stop], rtol) for c in chunks]
    parts = parallel.gather(_spin_lines, pieces, progress, [len(c) for c in chunks])
    crossings = [line for part in parts for line in part[1]]
    return SpinMap(
        pipe=pipe,
        modes=modes,
        spins=w,
        velocities=v,
        growth=np.concatenate([part[0] for part in parts]),
        crossings=crossings,
        stable_at_start=[ok for part in parts for ok in part[2]],
        critical_velocity=[_first_loss(line) for line in crossings],
        warnings=warnings,
        instability_at_start=[kinds for part in parts for kinds in part[3]],
    )


@dataclass
class BetaMap:
    """u_cr(beta) at fixed non-dimensional spin gamma (JSON form:
    :func:`pipeflow.computations.documents.beta_map`).

    For each beta: every crossing of the stability boundary in flow number u [-] (several
    where the curve is S-shaped), the non-dimensional frequency there, and u_cr (first loss).
    """

    modes: int
    gamma: float
    betas: FloatArray
    u_range: tuple[float, float]
    crossings: list[list[BoundaryCrossing]]
    stable_at_start: list[bool]
    warnings: list[str] = field(default_factory=list)
    groups: dict[str, float] = field(default_factory=dict)
    plane: str = "in-plane"
    instability_at_start: list[list[str]] = field(default_factory=list)

    @property
    def u_cr(self) -> list[float | None]:
        return [_first_loss(c) for c in self.crossings]


@dataclass(frozen=True)
class _BetaLines:
    """A piece of a beta map: the lines of constant mass ratio ``betas`` [-] over the flow
    numbers ``u`` [-] at spin number ``gamma`` [-] (picklable)."""

    betas: FloatArray
    u: FloatArray
    gamma: float
    modes: int
    rtol: float
    groups: dict[str, float]
    plane: str


def _beta_lines(piece: _BetaLines) -> _Lines:
    """Boundary crossings in u, stability at the first u of each beta of ``piece`` and
    how it is unstable there."""
    crossings, stable, how = [], [], []
    u = piece.u
    for beta in piece.betas:
        pipe = nondimensional_pipe(float(beta), piece.groups, piece.plane)
        model = build_model(pipe, piece.modes)
        scale = 1.0 / math.sqrt(beta)  # v = u / sqrt(beta)
        xi = eigenvalues(model, u * scale, piece.gamma)
        line = _line(model, u * scale, piece.gamma, xi, piece.rtol)
        crossings.append(
            [BoundaryCrossing(c.velocity / scale, c.direction, c.kind, c.frequency) for c in line]
        )
        ok, kinds = _start(xi, 0)
        stable.append(ok)
        how.append(kinds)
    return crossings, stable, how


def beta_map(
    beta_range: tuple[float, float],
    u_range: tuple[float, float] = (0.0, 20.0),
    gamma: float = 0.0,
    modes: int = 10,
    beta_points: int = 50,
    u_points: int = 201,
    rtol: float = 1e-10,
    progress: Progress | None = None,
    groups: Mapping[str, float] | None = None,
    plane: str = "in-plane",
) -> BetaMap:
    """The u_cr(beta) curve: boundary crossings in u for each beta, gamma fixed.

    Non-dimensional throughout (E = I = L = 1, M1 + M2 = 1: physics notes section 1):
    beta = M2/(M1+M2) in (0, 1), u = v L sqrt(M2/EI) >= 0, gamma = w0 L^2 sqrt((M1+M2)/EI);
    frequencies are omega sqrt((M1+M2) L^4/EI). ``groups`` (by name, as defined in
    :data:`pipeflow.model.DIMENSIONLESS_GROUPS`) and ``plane`` extend the pipe beyond the
    paper's model, the same at every beta.
    """
    nondimensional_pipe(0.5, groups, plane)  # refuse bad groups before any work
    check_modes(modes)
    check_range(*beta_range, parameter="beta_range")
    check_range(*u_range, parameter="u_range")
    if not (0 < beta_range[0] and beta_range[1] < 1):
        raise InvalidInput("beta must lie in (0, 1)", parameter="beta_range")
    if u_range[0] < 0:
        raise InvalidInput(
            "u_range must be >= 0 (" + REVERSE_FLOW_CAVEAT + ")", parameter="u_range"
        )
    if beta_points < 1 or u_points < 3:
        raise InvalidInput("need >= 1 beta point and >= 3 u points", parameter="points")
    check_map_work(beta_points * u_points, modes, "u_points")
    betas = np.linspace(*beta_range, beta_points)
    u = np.linspace(*u_range, u_points)
    chunks = parallel.split(betas.size, max_size=max(1, CHUNK // u.size))
    pieces = [
        _BetaLines(betas[c.start : c.stop], u, float(gamma), modes, rtol, dict(groups or {}), plane)
        for c in chunks
    ]
    parts = parallel.gather(_beta_lines, pieces, progress, [len(c) for c in chunks])
    crossings = [line for part in parts for line in part[0]]
    stable = [ok for part in parts for ok in part[1]]
    return BetaMap(
        modes=modes,
        gamma=float(gamma),
        betas=betas,
        u_range=(float(u_range[0]), float(u_range[1])),
        crossings=crossings,
        stable_at_start=stable,
        groups=nondimensional_pipe(0.5, groups, plane).dimensionless_groups(),
        plane=plane,
        instability_at_start=[kinds for part in parts for kinds in part[2]],
    )
