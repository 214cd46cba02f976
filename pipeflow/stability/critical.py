"""Critical flow velocity: every crossing of the stability boundary over a velocity range.

For constant spin w0 [rad/s], each eigenvalue branch xi_j(v) = sigma_j + i omega_j of the
frozen state matrix is followed from v = 0 to ``v_max`` (left/right eigenvector
assignment, :func:`pipeflow.stability.core.follow`).  Wherever a branch's sigma_j changes
sign the crossing is located by Brent's method on sigma_j(v) of that tracked branch, to a
relative tolerance ``rtol`` (1e-10 by default, far inside the 1e-6 asked for).  A
*flutter* crossing is a complex pair passing sigma = 0 with omega > 0, a *divergence* a real
eigenvalue passing through 0.  Narrow windows that fall between two grid points (the
S-shaped parts of the u_cr(beta) curve) are caught by maximising sigma_j wherever it has a
local maximum (or, inside an unstable stretch, a local minimum) close to zero.

Reverse flow (v < 0) is answered with :data:`~pipeflow.stability.core.REVERSE_FLOW_CAVEAT`
and no threshold.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass, field
from functools import partial
from typing import Any, Literal

import numpy as np
from scipy.optimize import brentq

from pipeflow._types import ComplexArray, FloatArray, Progress
from pipeflow.errors import InvalidInput
from pipeflow.model import REVERSE_FLOW_CAVEAT, Pipe, PipeModel, basis_caveats, build_model
from pipeflow.spectra import Branches, follow, rounding_level
from pipeflow.stability.core import (
    check_modes,
    check_range,
    growth_rate,
    mechanisms,
    sign_changes,
    stable_intervals,
    state_matrices,
)

Kind = Literal["flutter", "divergence"]
Direction = Literal["loss", "gain"]


@dataclass(frozen=True)
class Crossing:
    """One branch crossing sigma = 0 as the flow velocity increases.

    velocity : flow velocity at the crossing [m/s].
    frequency : omega of the crossing branch there [rad/s] (0 for divergence).
    mode : mode number (1 = lowest frequency at v = 0).
    kind : "flutter" (complex pair, omega > 0) or "divergence" (real eigenvalue through 0).
    direction : "loss" (the mode becomes unstable) or "gain" (it becomes stable again).
    boundary : True when the pipe as a whole changes stability here (no other mode is
        unstable on either side); a crossing while another mode is unstable is False.
    flow_number : u = v L sqrt(M2/EI) [-] (None if M2 = 0).
    dimensionless_frequency : omega sqrt((M1+M2) L^4 / EI) [-].

    JSON form: :func:`pipeflow.computations.documents.crossing`.
    """

    velocity: float
    frequency: float
    mode: int
    kind: Kind
    direction: Direction
    boundary: bool
    flow_number: float | None
    dimensionless_frequency: float


@dataclass
class CriticalVelocity:
    """Result of :func:`critical_velocities` (SI units; JSON form:
    :func:`pipeflow.computations.documents.critical_velocities`).

    critical_velocity : first loss of stability in the range [m/s] (v >= 0 part), or None
        when there is none.  If the pipe is already unstable at the start of the range
        (``stable_at_start`` False, e.g. divergence by fast spin at v = 0), this is the first
        loss after stability is regained; ``stable_intervals`` gives the whole picture.
    stable_intervals : [[v_a, v_b], ...] [m/s] where the pipe is stable (v >= 0 part).
    crossings : every branch crossing of sigma = 0 in the v >= 0 part, by velocity.
    stable_at_start : stability at max(v_min, 0) (None when the whole range is v < 0).
    instability_at_start : how the pipe is unstable there: "divergence" and/or "flutter",
        the fastest-growing first (empty when stable there).
    reverse_flow : the aspirating-pipe caveat when the range reaches v < 0, else None.
    """

    pipe: Pipe
    omega0: float
    modes: int
    velocity_range: tuple[float, float]
    critical_velocity: float | None
    crossings: list[Crossing]
    stable_at_start: bool | None
    reverse_flow: dict[str, Any] | None
    stable_intervals: list[list[float]] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)
    diagnostics: dict[str, Any] = field(default_factory=dict)
    instability_at_start: list[str] = field(default_factory=list)
    #: how the pipe loses stability at critical_velocity: "divergence" (a frequency reaching
    #: zero, supported pipes) or "flutter" (a complex pair, the cantilever); None without one
    mechanism: Kind | None = None

    @property
    def stable_throughout(self) -> bool:
        return bool(self.stable_at_start) and not any(
            c.boundary and c.direction == "loss" for c in self.crossings
        )

    @property
    def u_cr(self) -> float | None:
        """The critical flow number u_cr = v_cr L sqrt(M2/EI) [-] (None without a critical
        velocity or when M2 = 0)."""
        p = self.pipe
        if self.critical_velocity is None or p.M2 == 0:
            return None
        return float(p.flow_number(self.critical_velocity))


def _static_zeros(model: PipeModel, omega0: float, grid: FloatArray) -> list[float]:
    """Velocities [m/s] where K(v) = K_0 + v^2 K_v2 + w0^2 K_w2 is singular: there S has a
    zero eigenvalue (det S = det(M^-1 K)), a divergence or a restabilisation.  Found on the
    sweep's grid by the sign of det(K D) (D = diag(K_bend)^-1 scales it to O(1)) and Brent's
    method: independent of the branch tracking, which cannot tell a pair meeting at 0 from
    a swap (sigma ~ sqrt(v - v_d) there)."""
    Kb = model.K_0 if model.K_bend is None else model.K_bend
    if np.any(np.diag(Kb) <= 0):
        return []  # a rigid-body mode (a pinned-free pipe's rotation): det K = 0 throughout
    scale = 1.0 / np.abs(np.diag(Kb))
    base = model.K_0 + omega0 * omega0 * model.K_w2

    def det(v: float | FloatArray) -> FloatArray:
        vv = np.atleast_1d(np.asarray(v, dtype=float))
        K = base[None] + (vv * vv)[:, None, None] * model.K_v2[None]
        return np.asarray(np.linalg.det(K * scale[None, None, :]))

    vals = det(grid)
    out: list[float] = []
    for a, b, fa, fb in zip(grid[:-1], grid[1:], vals[:-1], vals[1:], strict=True):
        if fa * fb < 0:
            out.append(float(brentq(lambda v: float(det(v)[0]), a, b, xtol=1e-14 * b, rtol=1e-13)))
    return out


def _with_divergence(
    model: PipeModel,
    omega0: float,
    br: Branches,
    crossings: list[Crossing],
    lo: float,
    hi: float,
    tol: float,
) -> list[Crossing]:
    """Every change of the number of unstable eigenvalues in [lo, hi] [m/s], as crossings.

    Candidates: the tracker's crossings, every zero of det K (:func:`_static_zeros`, exact
    divergence velocities that replace a tracker crossing within 1e-4 relative: the tracker
    locates a pair meeting at 0 only to ~sqrt(rtol)), and any change of the whole spectrum's
    stability between two grid points that no candidate explains (located on the largest
    sigma, continuous in v).  Each is kept only if the count of eigenvalues with sigma > tol
    differs between v (1 - 1e-6) and v (1 + 1e-6) (so a tracking swap is no crossing), with
    its direction, whether the pipe as a whole changes stability (``boundary``), and its kind
    from the eigenvalue that changes side (real: divergence; complex: flutter)."""
    pipe = model.pipe
    grid = np.asarray(br.p[(br.p >= lo) & (br.p <= hi)], dtype=float)
    zeros = _static_zeros(model, omega0, grid) if grid.size > 1 else []
    step = 1e-6

    def spectrum(v: float) -> ComplexArray:
        return np.asarray(np.linalg.eigvals(state_matrices(model, np.array([v]), omega0)[0]))

    def growth(v: float) -> float:
        return float(spectrum(v).real.max())

    candidates: list[tuple[float, Crossing | None]] = []
    used: set[float] = set()
    for c in crossings:
        hit = [z for z in zeros if abs(c.velocity - z) <= 1e-4 * abs(z)]
        if hit:
            used.add(hit[0])
            candidates.append((hit[0], None))
        else:
            candidates.append((c.velocity, c))
    candidates += [(z, None) for z in zeros if z not in used]

    def classify(v: float, old: Crossing | None) -> Crossing | None:
        below, above = spectrum(max(v * (1 - step), 0.0)), spectrum(v * (1 + step))
        n_below, n_above = int(np.sum(below.real > tol)), int(np.sum(above.real > tol))
        if n_below == n_above:
            return None
        side = above if n_above > n_below else below
        unstable = side[side.real > tol]
        new = unstable[np.argmin(unstable.real)]  # the one that just crossed
        divergence = old is None and any(abs(v - z) <= 1e-12 * abs(z) for z in zeros)
        divergence = divergence or abs(new.imag) <= 1e-3 * max(abs(new), 1e-300)
        freq = 0.0 if divergence else abs(float(new.imag))
        if old is not None:
            mode = old.mode
        else:
            k = int(np.clip(np.searchsorted(br.p, v), 0, br.p.size - 1))
            mode = int(br.mode[int(np.argmin(np.abs(br.xi[k] - new)))])
        return Crossing(
            velocity=v,
            frequency=freq,
            mode=mode,
            kind="divergence" if divergence else "flutter",
            direction="loss" if n_above > n_below else "gain",
            boundary=(n_below == 0) != (n_above == 0),
            flow_number=None if pipe.M2 == 0 else float(pipe.flow_number(v)),
            dimensionless_frequency=freq * pipe.time_scale,
        )

    found = [classify(v, old) for v, old in candidates]
    out = [c for c in found if c is not None]
    sig = br.xi.real.max(axis=1)
    inside = np.flatnonzero((br.p >= lo) & (br.p <= hi))
    for a_i, b_i in itertools.pairwise(inside):
        a, b = float(br.p[a_i]), float(br.p[b_i])
        if (sig[a_i] > tol) == (sig[b_i] > tol):
            continue
        if any(c.boundary and a * (1 - 1e-3) <= c.velocity <= b * (1 + 1e-3) for c in out):
            continue
        v = float(brentq(lambda x: growth(x) - tol, a, b, xtol=1e-14 * b))
        extra = classify(v, None)
        if extra is not None:
            out.append(extra)
    return sorted(out, key=lambda c: c.velocity)


def _branch_sigma(br: Branches, j: int, x: float, k: int) -> float:
    return br.branch_at(j, k, x).real


def critical_velocities(
    pipe: Pipe,
    omega0: float = 0.0,
    velocity_range: tuple[float, float] = (0.0, 1.0),
    modes: int = 10,
    points: int = 401,
    rtol: float = 1e-10,
    progress: Progress | None = None,
) -> CriticalVelocity:
    """Every crossing of the stability boundary for v in ``velocity_range`` [m/s].

    Parameters
    ----------
    pipe : pipe and fluid properties.
    omega0 : constant spin w0 [rad/s].
    velocity_range : (v_min, v_max) [m/s]; the v < 0 part gets the reverse-flow caveat.
    modes : Galerkin modes n.
    points : grid points of the branch-following sweep over [0, v_max] (refined where
        the tracking confidence drops); crossings are then located by root-finding.
    rtol : relative tolerance of each crossing velocity [-].
    progress : called with a fraction in [0, 1]; may raise ``Cancelled`` to stop.
    """
    check_modes(modes)
    v_min, v_max = float(velocity_range[0]), float(velocity_range[1])
    check_range(v_min, v_max, "velocity_range")
    if points < 3:
        raise InvalidInput("points must be >= 3", parameter="points")
    model = build_model(pipe, modes)
    warnings: list[str] = basis_caveats(pipe)
    reverse: dict[str, Any] | None = None
    if v_min < 0:
        rate = float(growth_rate(model, v_min, omega0)[0])
        reverse = {
            "velocity_range": [v_min, min(v_max, 0.0)],
            "predicted_unstable": rate > 0,
            "growth_rate_at_v_min": rate,
            "caveat": REVERSE_FLOW_CAVEAT,
        }
        warnings.append(
            "the range reaches reverse flow (v < 0): this model predicts flutter for any "
            "v < 0, which experiments do not show; see reverse_flow.caveat"
        )
    result = CriticalVelocity(
        pipe=pipe,
        omega0=float(omega0),
        modes=modes,
        velocity_range=(v_min, v_max),
        critical_velocity=None,
        crossings=[],
        stable_at_start=None,
        reverse_flow=reverse,
        warnings=warnings,
    )
    if v_max <= 0:
        return result
    if pipe.M2 == 0:
        warnings.append("M2 = 0: no fluid, the flow velocity does not enter the model")
    lo = max(v_min, 0.0)
    # follow from v = 0 so that mode numbers are those of the v = 0 (rotating-beam) modes
    head = np.linspace(0.0, lo, max(2, points // 4), endpoint=False) if lo > 0 else np.empty(0)
    grid = np.concatenate([head, np.linspace(lo, v_max, points)])

    def matrices(v: FloatArray) -> FloatArray:
        return state_matrices(model, v, omega0)

    if progress is not None:
        progress(0.0)
    br = follow(
        matrices, grid, min_confidence=0.5, max_points=2 * grid.size, max_levels=4,
        progress=progress, damped=pipe.damped,
    )  # fmt: skip
    tol = rounding_level(br.xi)
    start = int(np.searchsorted(br.p, lo))
    radius = float(np.max(np.abs(br.xi)))
    found: list[tuple[float, int, int, bool]] = []
    m = br.xi.shape[1]
    for j in range(m):
        sigma_j = partial(_branch_sigma, br, j)
        for v, k, loss in sign_changes(br.p, br.xi[:, j].real, tol, sigma_j, start, rtol):
            found.append((v, j, k, loss))
        if progress is not None:
            progress(0.5 + 0.5 * (j + 1) / m)

    unstable0 = br.xi[start].real > tol[start]
    count = sum(1 for j in range(m) if unstable0[j] and br.upper(j, start))
    crossings: list[Crossing] = []
    swaps = 0
    for v, j, k, loss in sorted(found):
        xi = br.branch_at(j, k, v)
        if abs(xi.real) > 1e-6 * max(abs(xi), 1e-9 * radius) and abs(xi) > 1e-5 * radius:
            # sigma jumps instead of passing zero: the grid tracking swapped two branches
            # there (confidence too low); the pipe's stability does not change at a swap.
            # (A divergence, a pair meeting at xi = 0, has sigma ~ sqrt(v - v_d): there the
            # located root leaves |xi| ~ sqrt(rtol) radius, which is a crossing, not a swap.)
            swaps += 1
            continue
        if xi.imag < -1e-9 * max(abs(xi), 1e-9 * radius):
            continue  # the conjugate of a reported flutter crossing
        was = count > 0
        count += 1 if loss else -1
        divergence = abs(xi.imag) <= 1e-7 * radius
        crossings.append(
            Crossing(
                velocity=v,
                frequency=0.0 if divergence else abs(xi.imag),
                mode=int(br.mode[j]),
                kind="divergence" if divergence else "flutter",
                direction="loss" if loss else "gain",
                boundary=was != (count > 0),
                flow_number=None if pipe.M2 == 0 else float(pipe.flow_number(v)),
                dimensionless_frequency=(0.0 if divergence else abs(xi.imag)) * pipe.time_scale,
            )
        )
    crossings = _with_divergence(model, omega0, br, crossings, lo, v_max, float(np.max(tol)))
    result.crossings = crossings
    result.stable_at_start = not any(unstable0[j] and br.upper(j, start) for j in range(m))
    if not result.stable_at_start:
        result.instability_at_start = mechanisms(br.xi[start], float(tol[start]), radius)
    first = [c for c in crossings if c.boundary and c.direction == "loss"]
    if first:
        result.critical_velocity = first[0].velocity
        result.mechanism = first[0].kind
    result.stable_intervals = stable_intervals(
        lo,
        v_max,
        result.stable_at_start,
        [(c.velocity, c.direction == "loss") for c in crossings if c.boundary],
    )
    if not result.stable_at_start:
        warnings.append(
            f"already unstable at v = {lo:.6g} m/s (below the range, or by divergence under "
            "spin at v = 0); critical_velocity is the first loss after stability is regained, "
            "see stable_intervals"
        )
    result.diagnostics = {
        "grid_points": int(br.p.size),
        "inserted_points": int(br.inserted.sum()),
        "min_tracking_confidence": float(np.min(br.confidence[start:])),
        "tracking_swaps_ignored": swaps,
        "rtol": rtol,
    }
    if progress is not None:
        progress(1.0)
    return result
