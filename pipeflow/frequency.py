"""Frequency response functions of the pipe at a frozen operating point (issue 18).

Linearised about a constant flow velocity v [m/s] and spin w0 [rad/s], the Galerkin model
(:mod:`pipeflow.model`) is, with every field of :class:`~pipeflow.model.Pipe` (damping, tip
body, hub radius, plane)::

    M q'' + C q' + K q = f(t),   C = C_0 + v C_v,   K = K_0 + v^2 K_v2 + w0^2 K_w2

(the K_vdot term vanishes at constant v; the model has no spin gyroscopic term: the
Coriolis coupling with the axial motion is neglected, ``docs/model.md`` sec. 1).  For a
harmonic load f e^(i W t) the steady state is q e^(i W t) with

    (K - W^2 M + i W C) q = f,            u(x) = sum_j q_j phi_j(x/L).

Method: modal superposition over the complex modes of the first-order form.  The model's
state matrix A = S(v, w0) acts on the *balanced* state z = (q'_j / w_j, q_j)
(``PipeModel.state_matrix``; y = (q', q) = T z with T = diag(omega_ref, 1)), so a load
enters as b = (M^-1 f / omega_ref, 0) and the displacement is the lower half of z.  One
eigen-decomposition A = V diag(xi) V^-1 then gives every frequency at once::

    H(W) = Phi_out V_low diag(1 / (i W - xi)) V^-1 b

a (positions x 2n) @ (2n x frequencies) product (physics notes sec. 5).  Each response
carries a check: the direct solve of (K - W^2 M + i W C) q = f, from the second-order
arrays (not the state matrix), at a few frequencies (:class:`Diagnostics`).  Where the
eigenvectors are ill-conditioned (coalescing eigenvalues: flutter onset, critical damping)
and the two disagree, the response falls back to direct solves at every frequency.

Loads (physics notes sec. 5) are :class:`PointForce` (f_j = F phi_j(a)) and
:class:`BaseAcceleration` of the clamp (f_j = -(M1+M2) A int_0^L phi_j dx - m_t A phi_j(L);
the response is then the motion *relative to the clamp*).  Quantities: ``"displacement"``
(receptance), ``"velocity"`` (mobility, i W H) and ``"acceleration"`` (accelerance,
-W^2 H), per unit load; units in :data:`UNITS`.

Past the critical velocity some Re xi > 0: there is no steady state and H is only a
formal quantity; the response says so (``stable``, ``warnings``).

Residual flexibility (issue 32): the static response of the modes left out, u_static(x) -
Phi_out K^-1 f with u_static the static deflection of the continuous pipe
(:mod:`pipeflow.statics`), is added to H where it is measured better (no flow, no tip
rotary inertia, a stable point; ``residual``): the bare cantilever's drive-point
receptance then converges to ~1e-11 at 40 modes instead of like n^-3
(``docs/frequency-response.md`` has the tables, and why not with flow).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any, ClassVar, cast

import numpy as np
from numpy.typing import ArrayLike, NDArray

from pipeflow import loads
from pipeflow.basis import MAX_MODES
from pipeflow.errors import InvalidInput
from pipeflow.frequency_operator import Operator, enriched_operator, operator_at
from pipeflow.model import (
    REVERSE_FLOW_CAVEAT,
    Pipe,
    PipeModel,
    basis_caveats,
)
from pipeflow.profiles import Constant
from pipeflow.spectra import max_growth_rates, mode_numbers, rounding_level
from pipeflow.statics import statics_cover, truncation_residual

FloatArray = NDArray[np.float64]
ComplexArray = NDArray[np.complex128]

#: the response quantities and their units per unit load: (point force, base acceleration)
UNITS: dict[str, tuple[str, str]] = {
    "displacement": ("m/N", "s^2"),
    "velocity": ("m/(N s)", "s"),
    "acceleration": ("1/kg", "-"),
}
QUANTITIES = tuple(UNITS)
#: the largest ``count`` of :func:`frequency_grid`
MAX_GRID_POINTS = 20_000
#: the most frequencies one response takes: a full grid plus 3 points per resonance
MAX_FREQUENCIES = MAX_GRID_POINTS + 3 * MAX_MODES
#: the most output positions of one response
MAX_POSITIONS = 1_000
#: load-dependent Ritz vectors a response may add to its modes (:mod:`pipeflow.enrichment`)
MAX_LOAD_VECTORS = 3
#: the most operating points of :func:`frequency_responses`
MAX_OPERATING_POINTS = 64
#: frequencies [-] at which :class:`Diagnostics` checks the modal sum by direct solves
DIAGNOSTIC_POINTS = 5
#: modal sum vs direct solve: above this relative difference the direct solves are used
FALLBACK_RTOL = 1e-6


# -- loads ------------------------------------------------------------------------------
@dataclass(frozen=True)
class PointForce:
    """A transverse harmonic point force F e^(i W t) at ``position`` a [m], 0 < a <= L.

    H is per unit force [N]; at a = L the force acts on the tip body, if any.  Like the
    time-domain loads (:mod:`pipeflow.loads`, whose generalised force it uses), it carries
    its own behaviour: ``stations`` (where it acts [m]), ``force_at`` (the static problem's
    load point [m]), ``unit_index`` (the column of :data:`UNITS`: per N), ``input_name`` and
    ``input_unit`` (the state space's input), ``checked``, ``generalized_force``,
    ``to_dict``.
    """

    position: float
    kind: ClassVar[str] = "point_force"
    unit_index: ClassVar[int] = 0
    input_unit: ClassVar[str] = "N"

    @property
    def stations(self) -> list[float]:
        return [self.position]

    @property
    def force_at(self) -> float | None:
        return self.position

    @property
    def input_name(self) -> str:
        return f"F(x={self.position!r})"

    def checked(self, pipe: Pipe) -> PointForce:
        a = float(self.position)
        if not (math.isfinite(a) and 0.0 < a <= pipe.L * (1 + 1e-12)):
            raise InvalidInput(f"load.position = {a} m is outside (0, L = {pipe.L} m]", "load")
        return PointForce(min(a, pipe.L))

    def generalized_force(self, model: PipeModel) -> FloatArray:
        return loads.PointForce(self.position, Constant(1.0)).generalized_force(model)

    def to_dict(self) -> dict[str, Any]:
        return {"kind": self.kind, "position": self.position}


@dataclass(frozen=True)
class BaseAcceleration:
    """A transverse harmonic acceleration A e^(i W t) [m/s^2] of the clamp.

    H is per unit base acceleration; the response is relative to the clamp (the absolute
    acceleration is 1 + H for ``quantity="acceleration"``).  In the Galerkin equations it is
    the inertial load -(M1+M2) A per unit length and -m_t A on the tip mass.
    """

    kind: ClassVar[str] = "base_acceleration"
    unit_index: ClassVar[int] = 1  # per m/s^2
    input_unit: ClassVar[str] = "m/s^2"
    input_name: ClassVar[str] = "clamp_acceleration"

    @property
    def stations(self) -> list[float]:
        return []

    @property
    def force_at(self) -> float | None:
        """None: the static problem of a unit acceleration of the supports."""
        return None

    def checked(self, pipe: Pipe) -> BaseAcceleration:
        return self

    def generalized_force(self, model: PipeModel) -> FloatArray:
        return loads.BaseAcceleration(Constant(1.0)).generalized_force(model)

    def to_dict(self) -> dict[str, Any]:
        return {"kind": self.kind}


Load = PointForce | BaseAcceleration


# -- results ----------------------------------------------------------------------------
@dataclass(frozen=True)
class Resonance:
    """One mode of the frozen state matrix at the operating point.

    ``xi`` = sigma + i omega [1/s] the eigenvalue (omega >= 0); ``frequency`` [rad/s] the
    damped natural frequency omega = Im xi (where |H| peaks for light damping);
    ``natural_frequency`` [rad/s] |xi|; ``damping_ratio`` [-] zeta = -Re xi / |xi|
    (negative for a growing mode); ``mode`` [-] the mode number
    (:func:`pipeflow.spectra.mode_numbers`).
    """

    xi: complex
    frequency: float
    natural_frequency: float
    damping_ratio: float
    mode: int

    @property
    def half_power(self) -> tuple[float, float]:
        """omega -+ zeta |xi| [rad/s], the half-power points of a lightly damped peak."""
        bw = self.damping_ratio * self.natural_frequency
        return self.frequency - bw, self.frequency + bw


@dataclass(frozen=True)
class Peak:
    """A resonance inside the frequency range of a response.

    ``frequency`` [rad/s] = Im xi, ``natural_frequency`` [rad/s] = |xi|, ``damping_ratio``
    [-], ``mode`` [-] as in :class:`Resonance`; ``magnitude`` |H| at ``frequency`` at each
    output position, in the response's unit (inf for an undamped mode: the response is
    unbounded there).
    """

    frequency: float
    natural_frequency: float
    damping_ratio: float
    mode: int
    magnitude: tuple[float, ...]


@dataclass(frozen=True)
class Diagnostics:
    """The check of a response against direct solves of (K - W^2 M + i W C) q = f.

    ``check_frequencies`` [rad/s]: where it was made (spread over the range, one near the
    first peak); ``max_relative_difference`` [-]: the largest ||H_modal - H_direct|| /
    ||H_direct|| over them (norms over the positions); ``eigenvector_condition`` [-] the
    1-norm condition number of V (unit columns), LAPACK's estimate (``zgecon``: exact or
    within a small factor); ``method``: ``"modal"``, or ``"direct"``
    when the modal sum disagreed by more than :data:`FALLBACK_RTOL` and every frequency
    was solved directly.
    """

    check_frequencies: tuple[float, ...]
    max_relative_difference: float
    eigenvector_condition: float
    method: str


@dataclass(frozen=True, eq=False)
class FrequencyResponse:
    """Frequency response at one operating point.

    ``frequencies`` [rad/s] W; ``positions`` [m] where the response is given; ``H``
    complex, shape ``(len(positions), len(frequencies))``, per unit load in ``unit``
    (:data:`UNITS`: receptance m/N, mobility m/(N s), accelerance 1/kg; per unit base
    acceleration s^2, s, -); ``velocity`` [m/s] and ``omega0`` [rad/s] the operating point;
    ``eigenvalues`` [1/s] every xi of the frozen state matrix; ``peaks`` the resonances
    within the range; ``stable`` False when some Re xi > 0 (no steady state: H is formal),
    ``max_growth_rate`` [1/s] the largest Re xi (0 within rounding); ``warnings`` plain text;
    ``residual`` True when the residual flexibility of the truncated modes is included;
    ``load_vectors`` the load-dependent Ritz vectors added to the modes (then ``eigenvalues``
    are the modes', the vectors' own left out).
    """

    frequencies: FloatArray
    positions: FloatArray
    H: ComplexArray
    quantity: str
    unit: str
    load: Load
    velocity: float
    omega0: float
    modes: int
    eigenvalues: ComplexArray = field(repr=False)
    peaks: tuple[Peak, ...]
    stable: bool
    max_growth_rate: float
    diagnostics: Diagnostics
    warnings: tuple[str, ...]
    residual: bool = False
    load_vectors: int = 0

    @property
    def magnitude(self) -> FloatArray:
        """|H| in ``unit``."""
        return np.abs(self.H)

    @property
    def phase(self) -> FloatArray:
        """arg H [rad] in (-pi, pi]: the response lags the load by -phase."""
        return np.angle(self.H)


@dataclass(frozen=True, eq=False)
class DeflectionShape:
    """Operating deflection shape: the response along the pipe at one frequency.

    ``positions`` [m], ``frequency`` [rad/s], ``response`` complex H at each position (unit
    of the quantity per unit load), ``amplitude`` = |H|, ``phase`` [rad] = arg H; the
    physical motion is ``amplitude cos(W t + phase)`` per unit load amplitude.
    """

    positions: FloatArray
    frequency: float
    response: ComplexArray
    amplitude: FloatArray
    phase: FloatArray
    quantity: str
    unit: str


# -- validation -------------------------------------------------------------------------
def _check_operating_point(velocity: float, omega0: float) -> tuple[float, float]:
    v, w0 = float(velocity), float(omega0)
    if not math.isfinite(v):
        raise InvalidInput(f"velocity must be finite, got {velocity} m/s", parameter="velocity")
    if not math.isfinite(w0):
        raise InvalidInput(f"omega0 must be finite, got {omega0} rad/s", parameter="omega0")
    return v, w0


def _check_modes(modes: int) -> int:
    if int(modes) != modes or not 1 <= modes <= MAX_MODES:
        raise InvalidInput(f"modes must be an integer between 1 and {MAX_MODES}", "modes")
    return int(modes)


def _check_positions(pipe: Pipe, positions: ArrayLike, name: str = "positions") -> FloatArray:
    x = np.atleast_1d(np.asarray(positions, dtype=float))
    if x.ndim != 1 or x.size == 0:
        raise InvalidInput(f"{name} must be a non-empty list of positions [m]", name)
    if x.size > MAX_POSITIONS:
        raise InvalidInput(f"at most {MAX_POSITIONS} {name}, got {x.size}", name)
    bad = np.flatnonzero(~(np.isfinite(x) & (x > 0.0) & (x <= pipe.L * (1 + 1e-12))))
    if bad.size:
        i = int(bad[0])
        raise InvalidInput(f"{name}[{i}] = {x[i]} m is outside (0, L = {pipe.L} m]", name)
    return np.minimum(x, pipe.L)


def _check_load(pipe: Pipe, load: object) -> Load:
    checked = getattr(load, "checked", None)
    if checked is None:
        raise InvalidInput("load must be a PointForce or a BaseAcceleration", "load")
    return cast(Load, checked(pipe))


def _check_frequencies(frequencies: ArrayLike) -> FloatArray:
    W = np.atleast_1d(np.array(frequencies, dtype=float))  # a copy: returned read-only
    if W.ndim != 1 or W.size == 0:
        raise InvalidInput("frequencies must be a non-empty list [rad/s]", "frequencies")
    if W.size > MAX_FREQUENCIES:
        raise InvalidInput(f"at most {MAX_FREQUENCIES} frequencies, got {W.size}", "frequencies")
    if not np.all(np.isfinite(W)) or np.any(W < 0):
        raise InvalidInput("frequencies must be finite and >= 0 rad/s", "frequencies")
    return W


def _check_quantity(quantity: str) -> str:
    if quantity not in UNITS:
        raise InvalidInput(
            f"unknown quantity {quantity!r}; use one of {', '.join(QUANTITIES)}", "quantity"
        )
    return quantity


# -- the operating point: pipeflow.frequency_operator --------------------------------------


def _generalised_force(model: PipeModel, load: Load, shape: FloatArray | None = None) -> FloatArray:
    """f_j per unit load: [N/N] for a point force, [kg] per unit base acceleration.
    ``shape``: phi_j(a) when already evaluated."""
    return shape if shape is not None else load.generalized_force(model)


def _quantity_factor(quantity: str, W: FloatArray) -> ComplexArray:
    """1, i W or -W^2 [1, 1/s, 1/s^2]: displacement to the quantity."""
    iw = np.asarray(1j * W, dtype=np.complex128)
    if quantity == "displacement":
        return np.ones_like(iw)
    return iw if quantity == "velocity" else iw * iw


def resonances(pipe: Pipe, velocity: float, omega0: float, *, modes: int = 10) -> list[Resonance]:
    """The modes of the frozen state matrix at v = ``velocity`` [m/s], w0 = ``omega0``
    [rad/s], in mode order: one per conjugate pair (omega > 0); over-damped real roots
    have no resonance and are left out.  For :func:`frequency_grid`."""
    v, w0 = _check_operating_point(velocity, omega0)
    op = operator_at(pipe, v, w0, _check_modes(modes))
    return _resonances(op.xi, pipe.damped)


def _resonances(xi: ComplexArray, damped: bool) -> list[Resonance]:
    tol = 1e-9 * float(np.max(np.abs(xi)))
    numbers = mode_numbers(xi, damped)
    level = float(rounding_level(xi))
    idx = np.flatnonzero(xi.imag > tol)
    poles = xi[idx]
    mags = np.abs(poles)
    zetas = np.where(np.abs(poles.real) <= level, 0.0, -poles.real / mags)
    out = [
        Resonance(x, x.imag, mag, zeta, mode)
        for x, mag, zeta, mode in zip(
            poles.tolist(), mags.tolist(), zetas.tolist(), numbers[idx].tolist(), strict=True
        )
    ]
    return sorted(out, key=lambda r: (r.mode, r.frequency))


# -- frequency grids --------------------------------------------------------------------
def frequency_grid(
    w_min: float,
    w_max: float,
    count: int,
    spacing: str = "linear",
    resonances: Sequence[float | Resonance] = (),
) -> FloatArray:
    """Frequencies [rad/s] from ``w_min`` to ``w_max``, ``count`` points (2 .. 20,000),
    ``spacing`` "linear" or "log" (then w_min > 0), sorted and without duplicates.

    ``resonances`` (frequencies [rad/s] or :class:`Resonance` objects, e.g. from
    :func:`resonances`) inside the range are added so that no peak falls between two grid
    points: a :class:`Resonance` adds its damped frequency Im xi and its two half-power
    points; an undamped one (zeta = 0) adds nothing, its response being unbounded there.
    At most ``count + 3 * len(resonances)`` points.
    """
    lo, hi = float(w_min), float(w_max)
    if not (math.isfinite(lo) and math.isfinite(hi) and 0.0 <= lo < hi):
        raise InvalidInput(f"need 0 <= w_min < w_max, got {w_min}, {w_max} rad/s", "w_min")
    if int(count) != count or not 2 <= count <= MAX_GRID_POINTS:
        raise InvalidInput(f"count must be an integer in 2 .. {MAX_GRID_POINTS}", "count")
    if spacing == "linear":
        grid = np.linspace(lo, hi, int(count))
    elif spacing == "log":
        if lo <= 0:
            raise InvalidInput("a log grid needs w_min > 0 rad/s", "w_min")
        grid = np.geomspace(lo, hi, int(count))
    else:
        raise InvalidInput(f"unknown spacing {spacing!r}; use 'linear' or 'log'", "spacing")
    extra: list[float] = []
    for r in resonances:
        if isinstance(r, Resonance):
            if r.damping_ratio > 0:
                extra += [r.frequency, *r.half_power]
        else:
            extra.append(float(r))
    pts = np.array([w for w in extra if math.isfinite(w) and lo <= w <= hi])
    return np.unique(np.concatenate([grid, pts]))


# -- responses --------------------------------------------------------------------------
def _residual_flexibility(
    op: Operator, load: Load, x: FloatArray, out: FloatArray, f: FloatArray, v: float, w0: float
) -> FloatArray | None:
    """u_static(x) - Phi_out K^-1 f [m per unit load]: the static response of the modes left
    out (:func:`pipeflow.statics.truncation_residual`), None where the static problem is
    singular (divergence)."""
    return truncation_residual(
        op.model.pipe, v, w0, x, force_at=load.force_at, K=op.K, f=f, shapes=out
    )


def residual_part(
    op: Operator,
    load: Load,
    x: FloatArray,
    out: FloatArray,
    f: FloatArray,
    v: float,
    w0: float,
    stable: bool,
    residual: bool | None,
    warnings: list[str],
) -> FloatArray | None:
    """The residual flexibility [m per unit load] at ``x`` to add, or None: ``residual``
    True/False, or None for the default (on without flow, tip inertia or instability, where
    :mod:`pipeflow.statics` has the static solution,
    :func:`~pipeflow.statics.statics_cover`); a request it cannot serve says why in
    ``warnings``.  One rule for the frequency response and the state space."""
    pipe = op.model.pipe
    covered = statics_cover(pipe)
    if residual is None:
        residual = v == 0.0 and pipe.tip_inertia == 0.0 and stable and covered
    if residual and not covered:
        warnings.append(
            "the residual flexibility of the truncated modes needs the static solution of "
            "the continuous pipe, which a pipe free to rotate as a rigid body does not have, "
            "so it is left out here"
        )
        return None
    R = _residual_flexibility(op, load, x, out, f, v, w0) if residual else None
    if residual and R is None:
        warnings.append(
            "the static problem is singular at this operating point (divergence), so the "
            "residual flexibility of the truncated modes is left out"
        )
    return R


def _residual_factor(pipe: Pipe, W: FloatArray) -> ComplexArray:
    """1 / (1 + i W alpha) [-]: the modes left out are stiffness-dominated, so Kelvin-Voigt
    damping scales their static response as it scales EI (viscous damping and inertia are
    negligible against their stiffness)."""
    return np.asarray(1.0 / (1.0 + 1j * W * pipe.kelvin_voigt), dtype=np.complex128)


def _check_points(W: FloatArray, peaks: list[Resonance]) -> FloatArray:
    """Up to five of the (sorted, pole-free) frequencies ``W`` spread over them, one of them
    the nearest to the first peak inside (0.1 % above it when undamped)."""
    if W.size == 0:
        return W
    idx = set(np.linspace(0, W.size - 1, min(DIAGNOSTIC_POINTS - 1, W.size)).astype(int))
    inside = [r for r in peaks if W[0] <= r.frequency <= W[-1]]
    if inside:
        r = inside[0]
        near = r.frequency * (1.0 + (1e-3 if r.damping_ratio == 0.0 else 0.0))
        idx.add(int(np.argmin(np.abs(W - near))))
    return np.sort(W[sorted(idx)])


def frequency_response(
    pipe: Pipe,
    velocity: float,
    omega0: float,
    *,
    load: Load,
    positions: ArrayLike,
    frequencies: ArrayLike,
    quantity: str = "displacement",
    modes: int = 10,
    residual: bool | None = None,
    load_vectors: int = 0,
) -> FrequencyResponse:
    """Frequency response of ``pipe`` at constant flow ``velocity`` v [m/s] and spin
    ``omega0`` w0 [rad/s] (the pipe's damping, tip body, hub radius and plane included).

    Parameters
    ----------
    load : :class:`PointForce` (per unit force [N]) or :class:`BaseAcceleration` (per unit
        clamp acceleration [m/s^2]).
    positions : where the response is wanted, x [m] in (0, L].
    frequencies : W [rad/s] >= 0, answered at exactly these values (see
        :func:`frequency_grid`; at most :data:`MAX_FREQUENCIES`).
    quantity : "displacement" (receptance), "velocity" (mobility i W H) or "acceleration"
        (accelerance -W^2 H), relative to the clamp; units in :data:`UNITS`.
    modes : Galerkin modes n, 1 .. 40 (the beam eigenfunctions of the supports).
    residual : add the residual flexibility of the modes left out: the static deflection
        of the continuous pipe under the load (:mod:`pipeflow.statics`) minus its part in
        the n modes, a frequency-independent displacement added to the modal sum (the
        static correction of the mode-acceleration method).  It makes H exact at W = 0 and,
        without flow, removes the truncation error below the highest retained mode (the
        drive-point receptance of the bare cantilever at 3 w_1: 4.8e-4 -> 2e-8 at 10
        modes, 7.6e-6 -> 3e-12 at 40).  With flow the Galerkin error is mostly that of the
        retained modes themselves (their eigenvalues converge like n^-2), which the static
        correction does not touch: above the first resonance it then makes H worse
        (``docs/frequency-response.md``).  ``None`` (default): applied where it is measured
        better, without flow (v = 0), without a tip rotary inertia (whose own 1/n
        convergence dominates) and at a stable operating point; True or False force it.
    load_vectors : 0 .. :data:`MAX_LOAD_VECTORS` load-dependent Ritz vectors added to the
        modes (:mod:`pipeflow.enrichment`: the continuous pipe's static response to the
        load, then to that response's inertia), the remedy with flow: exact at W = 0 and a
        tip force at 10 modes from 7e-3 to 1e-5 at the first resonances (v = 10 m/s,
        w0 = 100 rad/s on the paper's pipe).  It takes the place of ``residual`` (True is
        refused with it); it costs two static solves and an eigen-decomposition two sizes
        up (about 1.3 ms at 10 modes).  Where the static problem has no solution (a rigid
        rotation, divergence) the modes alone answer, with a warning.

    Returns a :class:`FrequencyResponse`, H of shape (positions, frequencies).
    """
    v, w0 = _check_operating_point(velocity, omega0)
    n = _check_modes(modes)
    load = _check_load(pipe, load)
    x = _check_positions(pipe, positions)
    W = _check_frequencies(frequencies)
    quantity = _check_quantity(quantity)
    count = _check_load_vectors(load_vectors, residual)

    warnings: list[str] = []
    enriched = enriched_operator(pipe, v, w0, n, load.force_at, count) if count else None
    if count and enriched is None:
        warnings.append(
            "the static problem has no solution at this operating point (a rigid rotation "
            "or divergence), so no load vectors were added: the modes alone answer"
        )
    if enriched is not None:
        op, basis, f = enriched
        out = basis.shapes(x / pipe.L).T  # (p, n + vectors)
    else:
        op = operator_at(pipe, v, w0, n)
        a = load.stations
        shapes = op.model.shapes(np.concatenate([x, a]) / pipe.L)  # (n, p [+ 1])
        out = shapes[:, : x.size].T  # (p, n)
        f = _generalised_force(op.model, load, shapes[:, -1] if a else None)
    added = op.M.shape[0] - n  # the load vectors kept (an independent part each)
    b = np.concatenate([np.linalg.solve(op.M, f) / op.omega_ref, np.zeros(op.M.shape[0])])
    b = b.astype(complex)
    # frequencies on an undamped pole (|i W - xi| at rounding): H is unbounded there
    on_pole = np.zeros(W.size, dtype=bool)
    level = float(rounding_level(op.xi))
    for pole in op.xi[np.abs(op.xi.real) <= level]:
        on_pole |= np.abs(W - pole.imag) <= max(level, 1e-12 * abs(pole))
    xi = _modes_of(op, added, W, warnings)
    res = _resonances(xi, pipe.damped)
    pole_free = W[~on_pole]
    if pole_free.size > 1 and np.any(pole_free[1:] < pole_free[:-1]):
        pole_free.sort()  # (a grid in increasing order, the usual, is not sorted again)
    checks = _check_points(pole_free, sorted(res, key=lambda r: r.frequency))
    w_lo, w_hi = float(W.min()), float(W.max())
    inside = [r for r in res if w_lo <= r.frequency <= w_hi]
    Wp = np.array([r.frequency for r in inside if r.damping_ratio != 0.0])
    # one modal sum for the answer, the check frequencies and the peaks
    H_all = op.modal_sum(out, b, np.concatenate([W, checks, Wp]))
    H = H_all[:, : W.size]
    Hd = op.direct(out, f, checks)
    with np.errstate(all="ignore"):
        diff = np.linalg.norm(H_all[:, W.size : W.size + checks.size] - Hd, axis=0)
        rel = diff / np.linalg.norm(Hd, axis=0)
    # both zero (a load on a held point: the support takes it) is no difference
    rel = np.where(diff == 0.0, 0.0, np.where(np.isfinite(rel), rel, np.inf))
    if loads.moves_nothing(f):
        warnings.append(loads.held_note("load") + " (the response is zero)")
    max_rel = float(rel.max()) if rel.size else 0.0
    method = "modal"
    if not max_rel <= FALLBACK_RTOL:
        method = "direct"
        H[:, ~on_pole] = op.direct(out, f, W[~on_pole])
        why = (
            "the pipe's rigid rotation about its support: a double zero eigenvalue with a "
            "single eigenvector, which no modal sum represents"
            if pipe.rotates_rigidly
            else "coalescing eigenvalues"
        )
        warnings.append(
            f"the modal sum differed from direct solves by {max_rel:.2g} (relative; eigenvector "
            f"condition number {op.condition:.2g}: {why}), so every frequency was solved "
            "directly"
        )
    growth = float(max_growth_rates(op.xi[None])[0])
    stable = growth <= 0.0
    R = None if count else residual_part(op, load, x, out, f, v, w0, stable, residual, warnings)
    if R is not None:
        H = H + R[:, None] * _residual_factor(pipe, W)[None, :]
    H[:, on_pole] = 0.0
    if quantity != "displacement":
        H = H * _quantity_factor(quantity, W)[None, :]
    if on_pole.any():
        H[:, on_pole] = complex(math.inf, 0.0)
        warnings.append(
            f"{int(on_pole.sum())} frequencies (the first {W[on_pole][0]:.6g} rad/s) fall on "
            "an undamped resonance, where the response is unbounded: H is inf there"
        )

    if not stable:
        warnings.append(
            f"unstable operating point: the largest growth rate Re xi is {growth:.4g} 1/s > 0 "
            f"(v = {v} m/s, w0 = {w0} rad/s beyond the critical velocity), so there is no "
            "steady state; H is a formal quantity only"
        )
    if v < 0:
        warnings.append(REVERSE_FLOW_CAVEAT)
    warnings += basis_caveats(pipe)

    hp = H_all[:, W.size + checks.size :] if method == "modal" else op.direct(out, f, Wp)
    if R is not None:
        hp = hp + R[:, None] * _residual_factor(pipe, Wp)[None, :]
    hp = np.abs(hp * _quantity_factor(quantity, Wp)[None, :])
    columns = iter(hp.T.tolist())
    undamped = tuple(math.inf for _ in x)
    peaks = [
        Peak(r.frequency, r.natural_frequency, r.damping_ratio, r.mode,
             undamped if r.damping_ratio == 0.0 else tuple(next(columns)))
        for r in inside
    ]  # fmt: skip

    unit = UNITS[quantity][load.unit_index]
    for arr in (W, x, H, xi):
        arr.setflags(write=False)
    return FrequencyResponse(
        frequencies=W,
        positions=x,
        H=H,
        quantity=quantity,
        unit=unit,
        load=load,
        velocity=v,
        omega0=w0,
        modes=n,
        eigenvalues=xi,
        peaks=tuple(peaks),
        stable=stable,
        max_growth_rate=growth,
        diagnostics=Diagnostics(tuple(float(c) for c in checks), max_rel, op.condition, method),
        warnings=tuple(warnings),
        residual=R is not None,
        load_vectors=added,
    )


def _check_load_vectors(count: int, residual: bool | None) -> int:
    if int(count) != count or not 0 <= count <= MAX_LOAD_VECTORS:
        raise InvalidInput(
            f"load_vectors must be an integer in 0 .. {MAX_LOAD_VECTORS}, got {count}",
            "load_vectors",
        )
    if count and residual:
        raise InvalidInput(
            "load_vectors and the residual flexibility exclude each other: the first load "
            "vector is the static response the residual flexibility adds",
            "load_vectors",
        )
    return int(count)


def _modes_of(op: Operator, added: int, W: FloatArray, warnings: list[str]) -> ComplexArray:
    """The eigenvalues of the modes: all of ``op.xi`` but, with ``added`` load vectors, the
    2 x added whose eigenvectors lie most on the vectors' coordinates (the vectors' own: not
    simply the largest, which with Kelvin-Voigt damping are the modes' overdamped roots); a
    warning where one of those lies in the frequency range (the response there is not
    resolved by the modes)."""
    xi = op.xi
    if not added:
        return xi
    q = np.abs(op.V_low) ** 2
    order = np.argsort(q[-added:].sum(axis=0) / q.sum(axis=0))
    own = xi[order[-2 * added :]]
    inside = [abs(w.imag) for w in own if W.min() <= abs(w.imag) <= W.max()]
    if inside:
        warnings.append(
            f"the load vectors' own resonance at {min(inside):.6g} rad/s lies in the frequency "
            "range: the response near and above it is beyond the modes; use more modes"
        )
    return np.asarray(xi[np.sort(order[: -2 * added])])


def frequency_responses(
    pipe: Pipe,
    velocity: ArrayLike,
    omega0: ArrayLike,
    *,
    load: Load,
    positions: ArrayLike,
    frequencies: ArrayLike,
    quantity: str = "displacement",
    modes: int = 10,
    residual: bool | None = None,
    load_vectors: int = 0,
) -> tuple[FrequencyResponse, ...]:
    """:func:`frequency_response` at several operating points: ``velocity`` [m/s] and
    ``omega0`` [rad/s] broadcast together (at most :data:`MAX_OPERATING_POINTS` points),
    one response per point in broadcast (C) order, all at the same ``frequencies`` [rad/s].
    ``np.stack([r.H for r in ...])`` gives H with a leading operating-point axis."""
    try:
        v, w = np.broadcast_arrays(np.asarray(velocity, float), np.asarray(omega0, float))
    except ValueError as exc:
        raise InvalidInput(f"velocity and omega0 do not broadcast: {exc}", "omega0") from exc
    if v.size > MAX_OPERATING_POINTS:
        raise InvalidInput(
            f"at most {MAX_OPERATING_POINTS} operating points, got {v.size}", "velocity"
        )
    return tuple(
        frequency_response(
            pipe,
            float(vi),
            float(wi),
            load=load,
            positions=positions,
            frequencies=frequencies,
            quantity=quantity,
            modes=modes,
            residual=residual,
            load_vectors=load_vectors,
        )
        for vi, wi in zip(v.ravel(), w.ravel(), strict=True)
    )


def deflection_shape(
    pipe: Pipe,
    velocity: float,
    omega0: float,
    *,
    load: Load,
    frequency: float,
    positions: ArrayLike | None = None,
    quantity: str = "displacement",
    modes: int = 10,
    residual: bool | None = None,
) -> DeflectionShape:
    """Operating deflection shape at one ``frequency`` W [rad/s]: the response along the
    pipe (``positions`` x [m] in (0, L]; default 100 points from L/100 to L) to ``load`` at
    v = ``velocity`` [m/s], w0 = ``omega0`` [rad/s], as amplitude and phase [rad]."""
    x = np.linspace(pipe.L / 100, pipe.L, 100) if positions is None else positions
    r = frequency_response(
        pipe,
        velocity,
        omega0,
        load=load,
        positions=x,
        frequencies=[frequency],
        quantity=quantity,
        modes=modes,
        residual=residual,
    )
    h = np.asarray(r.H[:, 0])
    return DeflectionShape(
        r.positions, float(r.frequencies[0]), h, np.abs(h), np.angle(h), quantity, r.unit
    )
