"""Galerkin model of the rotating pipe conveying fluid (physics notes, section 1).

The PDE, for the transverse displacement u(x, t) [m] of a pipe clamped at x = 0 and free
at x = L, spinning at w0(t) [rad/s] and conveying fluid at v(t) [m/s]::

    (M1+M2) u_tt + 2 M2 v u_xt - (M1+M2) w0^2 u + (M2 v_t + M1 w0^2 x) u_x
        + [M2 v^2 - 1/2 M1 w0^2 (L^2 - x^2)] u_xx + EI u_xxxx = -(M1+M2) w0_t x

is projected onto ``n`` cantilever modes (eq. 2-3).  The result is

    M d'' + C(t) d' + K(t) d = F(t),
    C = v C_v,  K = K_0 + v' K_vdot + v^2 K_v2 + w0^2 K_w2,  F = w0' F_wdot,

with constant matrices.  Beyond the paper (issue 14; derivation in ``docs/model.md``):
Kelvin-Voigt and viscous damping (a constant C_0 in S_0), a tip mass and rotary inertia
(in M, K_w2 and F_wdot), a hub radius (K_w2, F_wdot) and out-of-plane motion (no
-(M1+M2) w0^2 u, no forcing); all off by default.

We project the PDE itself: the paper's eq. (7) has the w0^2 integrals with factors 1/2
and 1/4 where eq. (1) gives 1 and 1/2, and only the eq. (1)
projection reproduces the rotating-beam tables (Wright et al. 1982).

State form (eq. 13-14) in *balanced* coordinates
------------------------------------------------
The paper's state is y = (d', d).  Its eigenvector matrix has condition number of the
order of the highest modal frequency (8e4 rad/s for 10 modes of the paper's pipe), which
costs digits in ``Y diag(e^xi) Y^-1``.  We work with z = (d'_j / w_j, d_j), w_j the
non-rotating, no-flow natural frequencies: a diagonal similarity y = T z that leaves
every eigenvalue, and the method, unchanged, and makes the v = 0 state matrix
skew-symmetric (perfectly conditioned eigenvectors).
"""

from __future__ import annotations

import dataclasses
import math
import sys
from collections.abc import Callable
from dataclasses import dataclass, field
from functools import cached_property, lru_cache

import numpy as np
import scipy.linalg
from numpy.typing import ArrayLike, NDArray

from pipeflow._types import FloatArray
from pipeflow.basis import (
    cantilever_roots,
    paper_scale,
)
from pipeflow.beam_modes import BasisKey, rigid_lines, support_basis
from pipeflow.errors import InvalidInput
from pipeflow.integrals import ModeIntegrals, axial_matrix, basis_shapes, mode_integrals
from pipeflow.loading import Coefficients, Integrals
from pipeflow.supports import (
    CANTILEVER,
    PointSupport,
    Supports,
    basis_key,
    check_mounting,
    effective_pressure,
    pressure_force_per_pascal,
    spin_axial_force,
    static_axial_force,
)

#: the planes of motion: "in-plane" (the paper's eq. (1), chordwise) or "out-of-plane" (flapwise)
PLANES = ("in-plane", "out-of-plane")
#: the numeric fields beyond the paper's model (SI units, see :class:`Pipe`), all >= 0
EXTENSION_FIELDS = ("kelvin_voigt", "viscous", "tip_mass", "tip_inertia", "hub_radius")


@dataclass(frozen=True)
class Pipe:
    """Pipe and fluid properties.

    Parameters
    ----------
    E : Young's modulus of the pipe wall [Pa].
    I : second moment of area of the pipe cross-section [m^4].
    L : length of the pipe [m].
    M1 : mass of the pipe per unit length [kg/m].
    M2 : mass of the fluid per unit length [kg/m].
    kelvin_voigt : internal (Kelvin-Voigt) damping alpha [s]: E -> E (1 + alpha d/dt).
    viscous : external viscous damping c per unit length [N s/m^2].
    tip_mass : point mass m_t at the free end [kg] (a nozzle, a fitting).
    tip_inertia : rotary inertia J_t of the tip body about the bending axis through the
        tip [kg m^2].
    hub_radius : distance R of the clamped end from the rotation axis [m].
    plane : "in-plane" (the paper's eq. (1): chordwise, with the -(M1+M2) w0^2 u softening
        and the angular-acceleration forcing) or "out-of-plane" (flapwise: neither term).

    supports : the end supports (:class:`~pipeflow.supports.Supports`; default clamped at
        x = 0, free at x = L).
    intermediate_supports : up to 8 point supports 0 < x < L (springs [N/m] or pins).
    tension : axial pre-tension T [N] (negative: compression).
    pressure : internal gauge pressure p [Pa] (cancelled by a free, discharging end).
    flow_area : flow cross-section A [m^2] (needed with a pressure).
    poisson : Poisson's ratio nu of the wall [-].
    axially_restrained : both ends axially fixed (delta = 1 in p A (1 - 2 nu delta); the
        axial body forces, centrifugal and gravity, are then shared by both ends).
    gravity : component of gravity along +x [m/s^2]: +g hanging from x = 0, -g standing on it.

    The fields after ``plane`` describe the pipe as mounted (damping, tip body, hub, supports,
    axial loads); all default to the paper's model, which they then reproduce bit for bit
    (``docs/model.md``).
    """

    E: float
    I: float
    L: float
    M1: float
    M2: float
    kelvin_voigt: float = 0.0
    viscous: float = 0.0
    tip_mass: float = 0.0
    tip_inertia: float = 0.0
    hub_radius: float = 0.0
    plane: str = "in-plane"
    supports: Supports = CANTILEVER
    intermediate_supports: tuple[PointSupport, ...] = ()
    tension: float = 0.0
    pressure: float = 0.0
    flow_area: float = 0.0
    poisson: float = 0.3
    axially_restrained: bool = False
    gravity: float = 0.0

    def __post_init__(self) -> None:
        for name in ("E", "I", "L"):
            val = getattr(self, name)
            if not (math.isfinite(val) and val > 0):
                raise ValueError(f"pipe.{name} must be finite and > 0, got {val}")
        for name in ("M1", "M2"):
            val = getattr(self, name)
            if not (math.isfinite(val) and val >= 0):
                raise ValueError(f"pipe.{name} must be finite and >= 0, got {val}")
        if self.M1 + self.M2 <= 0:
            raise ValueError("pipe.M1 + pipe.M2 must be > 0")
        for name in EXTENSION_FIELDS:
            val = getattr(self, name)
            if not (math.isfinite(val) and val >= 0):
                raise ValueError(f"pipe.{name} must be finite and >= 0, got {val}")
        if self.plane not in PLANES:
            raise ValueError(f"unknown plane {self.plane!r}; use one of {', '.join(PLANES)}")
        check_stiffness(self.E, self.I)
        check_mounting(self)

    @property
    def in_plane(self) -> bool:
        """True for the in-plane (chordwise) motion of the paper's eq. (1)."""
        return self.plane == "in-plane"

    @property
    def damped(self) -> bool:
        """True with any damping: modes are then ordered by natural frequency (an over-damped
        mode's two real roots are one mode, :func:`pipeflow.spectra.damped_modes`)."""
        return bool(self.kelvin_voigt or self.viscous)

    @property
    def basis_key(self) -> BasisKey | None:
        """The support set on the unit interval (None: the cantilever's own basis)."""
        return basis_key(self)

    @property
    def first_bending_frequency(self) -> float:
        """w1 = lambda_1^2 sqrt(EI / ((M1 + M2) L^4)) [rad/s]: the first non-zero bending
        frequency of the bare pipe on its own supports and springs, at rest, without flow,
        spin, axial load or tip body (lambda_1 = 1.8751 for the cantilever; a rigid-body
        mode of a pinned-free pipe is skipped)."""
        key = self.basis_key
        if key is None:
            lam4 = cantilever_roots(1)[0] ** 4
        else:
            values = support_basis(2, *key).lam4
            lam4 = float(values[values > 1e-9][0])
        return math.sqrt(lam4 * self.EI / (self.mass * self.L**4))

    @property
    def rotates_rigidly(self) -> bool:
        """True when the pipe can rotate as a rigid body about one support (a zero
        eigenvalue at every velocity): a pinned end, or an elastic one without rotational
        spring, opposite a free end; or a free-free pipe on one intermediate support.  (A
        pipe free to translate is refused by :func:`~pipeflow.supports.check_mounting`, so
        the one rigid line left is this rotation.)"""
        key = self.basis_key
        return key is not None and bool(rigid_lines(*key))

    @property
    def has_static_axial_force(self) -> bool:
        """Tension, pressure (not cancelled) or gravity act at rest."""
        return bool(self.tension or self.gravity or effective_pressure(self))

    @property
    def is_paper_model(self) -> bool:
        """No damping, no tip body, no hub, in-plane, the cantilever without axial loads:
        exactly the paper's model."""
        mounted = self.basis_key is not None or self.has_static_axial_force
        return self.in_plane and not mounted and not any(getattr(self, n) for n in EXTENSION_FIELDS)

    def dimensionless_groups(self) -> dict[str, float]:
        """The extended model's groups [-], ``{name: value}`` in the order and with the
        definitions of :data:`DIMENSIONLESS_GROUPS` (each is one field over its scale)."""
        return {g.name: getattr(self, g.field) / g.scale(self) for g in DIMENSIONLESS_GROUPS}

    @property
    def EI(self) -> float:
        """Bending stiffness [N m^2]."""
        return self.E * self.I

    @property
    def mass(self) -> float:
        """Total mass per unit length M1 + M2 [kg/m]."""
        return self.M1 + self.M2

    @property
    def beta(self) -> float:
        """Mass ratio M2 / (M1 + M2) [-]."""
        return self.M2 / self.mass

    @property
    def time_scale(self) -> float:
        """sqrt((M1+M2) L^4 / EI) [s]: tau = t / time_scale."""
        return math.sqrt(self.mass * self.L**4 / self.EI)

    def flow_number(self, v: ArrayLike) -> FloatArray:
        """Non-dimensional flow velocity u = v L sqrt(M2/EI) [-]."""
        return np.asarray(v, dtype=float) * self.L * math.sqrt(self.M2 / self.EI)

    def velocity_from_flow_number(self, u: ArrayLike) -> FloatArray:
        """Inverse of :meth:`flow_number`: v [m/s] for a non-dimensional u (needs M2 > 0)."""
        if self.M2 == 0:
            raise ValueError("flow number is undefined for M2 = 0")
        return np.asarray(u, dtype=float) / (self.L * math.sqrt(self.M2 / self.EI))

    def spin_number(self, w0: ArrayLike) -> FloatArray:
        """Non-dimensional spin gamma = w0 L^2 sqrt((M1+M2)/EI) [-]."""
        return np.asarray(w0, dtype=float) * self.L**2 * math.sqrt(self.mass / self.EI)

    def spin_from_number(self, gamma: ArrayLike) -> FloatArray:
        """Inverse of :meth:`spin_number`: w0 [rad/s]."""
        return np.asarray(gamma, dtype=float) / (self.L**2 * math.sqrt(self.mass / self.EI))


@dataclass(frozen=True)
class DimensionlessGroup:
    """One dimensionless group of the extended model: ``name`` = ``pipe.<field>`` / scale.

    ``definition`` is the formula in the :class:`Pipe` field names, ``source`` where the
    group comes from; :meth:`Pipe.dimensionless_groups` evaluates it, the request and
    result schemas take their names and descriptions from it, and on the unit pipe of
    :func:`pipeflow.stability.core.nondimensional_pipe` (E = I = L = M1 + M2 = 1) every
    scale is 1, so there group and field are equal.
    """

    name: str
    field: str
    definition: str
    source: str
    scale: Callable[[Pipe], float]

    @property
    def description(self) -> str:
        """``definition [-] (source)``, the text of the schema fields that carry the group."""
        return f"{self.definition} [-] ({self.source})."


#: THE definitions of the groups beyond beta, gamma and u (docs/model.md section 6), m = M1 + M2
DIMENSIONLESS_GROUPS: tuple[DimensionlessGroup, ...] = (
    DimensionlessGroup(
        "alpha",
        "kelvin_voigt",
        "Kelvin-Voigt damping kelvin_voigt sqrt(EI/m) / L^2 = kelvin_voigt / time_scale",
        "Paidoussis 1998, eq. (3.71): alpha = [I/(E(M+m))]^(1/2) E*/L^2, E* = E kelvin_voigt",
        lambda p: p.time_scale,
    ),
    DimensionlessGroup(
        "viscous_ratio",
        "viscous",
        "Viscous damping viscous L^2 / sqrt(EI m)",
        "Paidoussis 1998, eq. (3.71), where it is called sigma; renamed because sigma is the "
        "growth rate [1/s] of every result",
        lambda p: math.sqrt(p.EI * p.mass) / p.L**2,
    ),
    DimensionlessGroup(
        "tip_mass_ratio",
        "tip_mass",
        "Tip mass over pipe-and-fluid mass, tip_mass / (m L)",
        "the mu of the end-mass frequency equation, Blevins 1979",
        lambda p: p.mass * p.L,
    ),
    DimensionlessGroup(
        "tip_inertia_ratio",
        "tip_inertia",
        "Tip rotary inertia tip_inertia / (m L^3)",
        "the rotary-inertia counterpart of tip_mass_ratio",
        lambda p: p.mass * p.L**3,
    ),
    DimensionlessGroup(
        "hub_ratio",
        "hub_radius",
        "Hub radius over length, delta = hub_radius / L",
        "Hodges & Rutkowski 1981; Banerjee 2000",
        lambda p: p.L,
    ),
)
#: the groups by name
GROUPS = {g.name: g for g in DIMENSIONLESS_GROUPS}


#: What every result with reverse flow says (physics notes sec. 4; one text for all analyses).
REVERSE_FLOW_CAVEAT = (
    "reverse flow (v < 0, the aspirating pipe): in this undamped model reversing the flow is "
    "time reversal, so the spectrum at -v is the spectrum at +v reflected through the "
    "imaginary axis (xi -> -conj(xi)); every mode that is damped at +v grows at -v and the "
    "model predicts flutter for any v < 0. Experiments do not show this flutter (Paidoussis "
    "& Luu 1985), so no critical velocity is given for v < 0."
)


def basis_caveats(pipe: Pipe) -> list[str]:
    """What a result must say about the cantilever-mode basis for this pipe (one text for
    all analyses): the tip body's rotary inertia converges only like 1/modes; a support set
    with a rigid-body mode (a pinned or elastic end without rotational spring opposite a free
    one) keeps a neutral zero eigenvalue."""
    out = []
    if pipe.tip_inertia:
        out.append(
            "pipe.tip_inertia: the cantilever modes lack the tip curvature its boundary "
            "condition needs, so eigenvalues converge only like 1/modes (about 1e-2 relative "
            "for the third mode at 40 modes when J_t/(m L^3) = 0.01, docs/model.md sec. 5); "
            "use many modes"
        )
    if pipe.rotates_rigidly:
        out.append(
            "pipe.supports: the pipe can rotate as a rigid body (a zero eigenvalue at every "
            "velocity); where another eigenvalue passes zero the Galerkin model shows a "
            "narrow divergence window that shrinks with modes (pinned-free, beta = 0.2, "
            "near u = 2 pi: growth 1.7e-3 at 10 modes, 4e-5 at 16): check with more modes"
        )
    return out


#: evaluations of the supports' basis a model keeps (:meth:`PipeModel.shapes`)
SHAPE_MEMO = 16


@dataclass(frozen=True, eq=False)
class PipeModel:
    """Discretised model: second-order matrices and the balanced state-space form.

    Attributes (SI units, n = number of modes)
    ----------
    M : mass matrix [kg] (our modes are normalised: M = (M1+M2) L I without a tip body).
    C_0 : constant damping matrix [kg/s] (Kelvin-Voigt alpha K_0 plus viscous c L I).
    C_v : gyroscopic matrix per unit flow velocity [kg/m]; C = v C_v [kg/s].
    K_0 : bending stiffness [N/m].
    K_vdot : per unit flow acceleration [kg/m]; multiplied by dv/dt [m/s^2].
    K_v2 : per unit v^2 [kg/m^2]; multiplied by v^2 [m^2/s^2].
    K_w2 : per unit w0^2 [kg]; multiplied by w0^2 [rad^2/s^2].
    F_wdot : generalised force per unit spin acceleration [kg m]; times dw0/dt [rad/s^2].
    omega_ref : natural frequencies without flow or spin [rad/s] (the balancing scales).
    """

    pipe: Pipe
    n: int
    quadrature_order: int
    M: FloatArray = field(repr=False)
    C_0: FloatArray = field(repr=False)
    C_v: FloatArray = field(repr=False)
    K_0: FloatArray = field(repr=False)
    K_vdot: FloatArray = field(repr=False)
    K_v2: FloatArray = field(repr=False)
    K_w2: FloatArray = field(repr=False)
    F_wdot: FloatArray = field(repr=False)
    omega_ref: FloatArray = field(repr=False)
    # balanced state-space pieces: S(t) = S_0 + v S_v + vdot S_vdot + v^2 S_v2 + w0^2 S_w2
    # (the damping C_0 is constant, so it sits in S_0's upper-left block)
    S_0: FloatArray = field(repr=False)
    S_v: FloatArray = field(repr=False)
    S_vdot: FloatArray = field(repr=False)
    S_v2: FloatArray = field(repr=False)
    S_w2: FloatArray = field(repr=False)
    f_wdot: FloatArray = field(repr=False)
    tip: FloatArray = field(repr=False)
    #: the bending stiffness alone (with the support springs) [N/m]; K_0 adds the static
    #: axial forces (tension, pressure, gravity).  None: K_0 itself
    K_bend: FloatArray | None = field(default=None, repr=False)

    @property
    def size(self) -> int:
        """Dimension 2n of the state."""
        return 2 * self.n

    # -- state matrices -------------------------------------------------------------
    #: S_p [1/(s Pa)]: the state piece of a time-varying pressure p(t) (None: constant)
    S_p: FloatArray | None = field(default=None, repr=False)

    @cached_property
    def state_pieces(self) -> FloatArray:
        """(S_0, S_v, S_vdot, S_v2, S_w2) stacked, shape ``(5, 2n, 2n)`` (and S_p, ``(6, 2n,
        2n)``, with a time-varying pressure), read-only: S(t) is
        ``Coefficients.weights() @ state_pieces`` over the first axis."""
        pieces = [self.S_0, self.S_v, self.S_vdot, self.S_v2, self.S_w2]
        if self.S_p is not None:
            pieces.append(self.S_p)
        A = np.stack(pieces)
        A.setflags(write=False)
        return A

    def with_pressure_piece(self) -> PipeModel:
        """This model with S_p, the state piece of a unit internal pressure (1 Pa): its
        compressive force A (1 - 2 nu delta) (:func:`pipeflow.supports.pressure_force_per_pascal`,
        0 at a free discharging end) as an axial force, -(N w')' with N = -A (1 - 2 nu
        delta), the same term the constant pressure adds to K_0.  For a run whose pressure
        varies in time (:class:`Loading` ``pressure``); the pipe's own ``pressure`` must then
        be 0 (no double count)."""
        if self.pipe.pressure:
            raise ValueError("a time-varying pressure replaces the pipe's constant pressure")
        n, L = self.n, self.pipe.L
        g = mode_integrals(n, self.quadrature_order, self.pipe.basis_key)
        K_p = axial_matrix((-pressure_force_per_pascal(self.pipe), 0.0, 0.0), g, L)
        T = np.concatenate([self.omega_ref, np.ones(n)])
        S_p = np.zeros((2 * n, 2 * n))
        S_p[:n, n:] = -np.linalg.solve(self.M, K_p)
        S_p = S_p * (1.0 / T)[:, None] * T[None, :]
        S_p.setflags(write=False)
        return dataclasses.replace(self, S_p=S_p)

    def state_matrix(self, c: Coefficients) -> NDArray[np.float64]:
        """Frozen-time balanced state matrices S(t), shape ``(len(t), 2n, 2n)`` [1/s]."""
        return np.tensordot(c.weights(), self.state_pieces, axes=1)

    def frozen_state_matrix(
        self, v: ArrayLike, vdot: ArrayLike = 0.0, w2: ArrayLike = 0.0
    ) -> FloatArray:
        """S = S_0 + v S_v + vdot S_vdot + v^2 S_v2 + w0^2 S_w2 [1/s] frozen at given values.

        ``v`` [m/s], ``vdot`` [m/s^2] and ``w2`` = w0^2 [rad^2/s^2] broadcast to one shape
        ``B``; the result has shape ``B + (2n, 2n)`` (:meth:`state_matrix` on the flattened
        batch, the forcing not involved).
        """
        vv, aa, ww = np.broadcast_arrays(*(np.asarray(x, dtype=float) for x in (v, vdot, w2)))
        flat = vv.ravel()
        S = self.state_matrix(
            Coefficients(v=flat, vdot=aa.ravel(), w2=ww.ravel(), wdot=np.zeros_like(flat))
        )
        return np.asarray(S.reshape(vv.shape + S.shape[1:]))

    def forcing(self, c: Coefficients) -> FloatArray:
        """Balanced forcing vectors f(t), shape ``(len(t), 2n)`` [1/s]."""
        return c.wdot[:, None] * self.f_wdot[None]

    def integrated_state_matrix(self, g: Integrals) -> FloatArray:
        """P(t) = integral_0^t S, eq. (18), in closed form; shape ``(len(t), 2n, 2n)`` [-]."""
        rows = [g.t, g.v, g.dv, g.v2, g.w2]
        if self.S_p is not None:
            if g.p is None:
                raise ValueError("this model has a pressure piece: give int p (Integrals.p)")
            rows.append(g.p)
        return np.tensordot(np.stack(rows, axis=1), self.state_pieces, axes=1)

    # -- conversions between the paper's state (d', d) and the balanced one --------------
    def to_balanced(self, d: FloatArray, ddot: FloatArray) -> FloatArray:
        return np.concatenate([ddot / self.omega_ref, d], axis=-1)

    def from_balanced(self, z: NDArray[np.float64]) -> tuple[FloatArray, FloatArray]:
        """Return ``(d, d')`` [m-equivalent modal amplitudes, and per second]."""
        n = self.n
        return z[..., n:], z[..., :n] * self.omega_ref

    def shapes(self, xi: ArrayLike, derivative: int = 0) -> FloatArray:
        """The basis functions' ``derivative``-th derivatives d^k phi_j / dxi^k [-] at
        ``xi = x/L``, shape ``(n, len(xi))`` (cantilever modes or the supports' basis).
        The supports' basis (a sum of end-support eigenfunctions, costlier than the
        cantilever's closed form) keeps the last :data:`SHAPE_MEMO` evaluations per model,
        read-only: a simulation's stations and watch points repeat from run to run."""
        xi = np.atleast_1d(np.asarray(xi, dtype=float))
        key = self.pipe.basis_key
        if key is None:
            return basis_shapes(self.n, xi, derivative, None)
        memo = self._shape_memo
        tag = (derivative, xi.tobytes())
        found = memo.get(tag)
        if found is None:
            found = basis_shapes(self.n, xi, derivative, key)
            found.setflags(write=False)
            if len(memo) >= SHAPE_MEMO:
                memo.pop(next(iter(memo)))
            memo[tag] = found
        return found

    @cached_property
    def _shape_memo(self) -> dict[tuple[int, bytes], FloatArray]:
        return {}

    def displacement(self, d: FloatArray, xi: ArrayLike) -> FloatArray:
        """u(x, t) [m] at non-dimensional positions ``xi = x/L`` from modal coordinates."""
        return np.asarray(d @ self.shapes(xi))

    def natural_frequencies(self) -> FloatArray:
        """Undamped no-flow, no-spin natural frequencies [rad/s] (Rao, Table 8.1 roots; with
        a tip body, the Galerkin eigenvalues of (K_0, M)), ascending."""
        p = self.pipe
        if not (p.tip_mass or p.tip_inertia or p.basis_key or p.has_static_axial_force):
            lam = np.asarray(cantilever_roots(self.n))
            return lam**2 * math.sqrt(p.EI / (p.mass * p.L**4))
        # supports, springs and axial loads: the Galerkin eigenvalues; a pipe buckled at
        # rest (a negative omega^2: divergence) reports 0 for those modes
        w2 = scipy.linalg.eigh(self.K_0, self.M, eigvals_only=True)
        return np.sqrt(np.clip(np.sort(w2), 0.0, None))

    @cached_property
    def first_shape_peak(self) -> float:
        """max |phi_1(xi)| [-] over 1001 points of [0, 1] (with supports: the 'paper' initial
        shape's scale; once per model, which build_model caches)."""
        return float(np.max(np.abs(self.shapes(np.linspace(0.0, 1.0, 1001))[0])))

    def initial_state(
        self, u0: float, du0: float, shape: str = "paper"
    ) -> tuple[FloatArray, FloatArray]:
        """Modal initial conditions for u(x,0) = u0 s(x), du/dt(x,0) = du0 s(x) (eq. 9).

        ``shape="paper"``: s is the paper's eq. (3) first mode, whose tip value is 2.7244,
        so the initial tip displacement is 2.7244 u0 [m].
        ``shape="tip"``: s is the first mode scaled to a unit tip value, so u0 is the
        initial tip displacement [m].
        With other supports (``docs/supports.md``) s is the first basis function scaled to a
        largest |s| of 1 for ``"paper"`` (u0 is the largest initial deflection [m]) and to a
        unit tip value for ``"tip"`` (refused where the tip is held: w(L) = 0).
        """
        d0 = np.zeros(self.n)
        v0 = np.zeros(self.n)
        if shape not in ("paper", "tip"):
            raise ValueError(f"unknown initial shape {shape!r} (use 'paper' or 'tip')")
        if self.pipe.basis_key is not None and shape == "paper":
            scale = 1.0 / self.first_shape_peak
        elif self.pipe.basis_key is not None and abs(float(self.tip[0])) < 1e-9:
            raise InvalidInput(
                "the initial shape 'tip' needs a moving tip; with the supports "
                f"({self.pipe.supports.describe()}) use 'paper' (largest deflection u0)",
                "initial_shape",
            )
        elif shape == "paper":
            scale = paper_scale(1)[0]
        elif shape == "tip":
            scale = 1.0 / float(self.tip[0])
        else:
            raise ValueError(f"unknown initial shape {shape!r} (use 'paper' or 'tip')")
        d0[0] = u0 * scale
        v0[0] = du0 * scale
        return d0, v0


#: the smallest bending stiffness E I [N m^2] a pipe may have: the smallest normal double.
#: Below it the product underflows (E = I = 1e-200 Pa, m^4 gives 0): the model has no
#: stiffness, and every method, the spectra and the frequency response would divide by zero
MIN_BENDING_STIFFNESS = sys.float_info.min


def check_stiffness(E: float, I: float) -> None:
    """Refuse an ``E`` and ``I`` whose product, the bending stiffness, underflows double
    precision (:data:`MIN_BENDING_STIFFNESS`): the one check every pipe passes (the
    library's :class:`Pipe`, the request's pipe), so every method and analysis refuses it
    alike (:class:`~pipeflow.errors.InvalidInput` naming ``E``)."""
    EI = E * I
    if not EI >= MIN_BENDING_STIFFNESS:
        raise InvalidInput(
            f"E x I = {E:g} Pa x {I:g} m^4 = {EI:g} N m^2 is below {MIN_BENDING_STIFFNESS:.4g} "
            "N m^2, the smallest bending stiffness double precision holds (the product "
            "underflows): raise pipe.E or pipe.I",
            "E",
        )


#: the largest condition number of the mass matrix accepted: the solves with M then keep
#: about 4 of the 16 significant digits (cond x eps = 1e-4)
MASS_COND_MAX = 1e12


def _check_mass_conditioning(M: FloatArray, tip_mass_part: float, tip_inertia_part: float) -> None:
    """Refuse a tip body that swamps the pipe's own mass matrix (m_t/(m L) or J_t/(m L^3)
    around 1e11 and more): its inverse would be rounding, not physics.  Names the larger of
    the two tip terms (their sizes in M: m_t |phi(L)|^2 and J_t |phi'(L)|^2 [kg])."""
    cond = float(np.linalg.cond(M))
    if cond <= MASS_COND_MAX:
        return
    name = "tip_mass" if tip_mass_part >= tip_inertia_part else "tip_inertia"
    raise InvalidInput(
        f"{name} is too large for the modal basis: the mass matrix's condition number is "
        f"{cond:.3g} (above {MASS_COND_MAX:.0e}), so the model would be rounding; reduce "
        f"{name} (the tip body against the pipe's mass m L and m L^3)",
        name,
    )


@dataclass(frozen=True)
class SecondOrder:
    """The model's second-order matrices on a set of basis functions (:func:`second_order`):
    M [kg], C_0 [kg/s], C_v [kg/m], K_0 and K_bend [N/m], K_vdot [kg/m], K_v2 [kg/m^2],
    K_w2 [kg], the spin-acceleration force F_wdot [kg m], and the functions' end values
    ``tip`` [-] and slopes ``slope`` [1/m]."""

    M: FloatArray
    C_0: FloatArray
    C_v: FloatArray
    K_0: FloatArray
    K_bend: FloatArray
    K_vdot: FloatArray
    K_v2: FloatArray
    K_w2: FloatArray
    F_wdot: FloatArray
    tip: FloatArray
    slope: FloatArray


def second_order(pipe: Pipe, g: ModeIntegrals) -> SecondOrder:
    """The second-order matrices of ``pipe`` from the Galerkin integrals ``g`` of its basis
    (or of any functions on it: :mod:`pipeflow.enrichment`).

    The terms beyond the paper (damping, tip body, hub radius, out-of-plane) are derived in
    ``docs/model.md``; each is added only when its field is non-zero, so the paper's model
    gives the same arrays, bit for bit, as before they existed.
    """
    n = g.n
    key = pipe.basis_key
    L, m, M1, M2, EI = pipe.L, pipe.mass, pipe.M1, pipe.M2, pipe.EI
    R, mt, Jt = pipe.hub_radius, pipe.tip_mass, pipe.tip_inertia
    # dimensional integrals: dx = L dxi, d/dx = (1/L) d/dxi
    gram = L * g.gram
    M = m * gram
    C_v = 2.0 * M2 * g.b
    K_0 = EI / L**3 * g.k4
    K_vdot = M2 * g.b
    K_v2 = M2 / L * g.c
    # centrifugal tension M1 w0^2 (L^2 - x^2)/2 (strong form), and in-plane the -m w0^2 u term
    K_w2 = (-m * gram + M1 * L * g.xb if pipe.in_plane else M1 * L * g.xb) - 0.5 * M1 * L * g.tc
    F_wdot = -m * L**2 * g.xf if pipe.in_plane else np.zeros(n)
    C_0 = np.zeros((n, n))
    tip = g.tip
    slope = g.tip_slope / L  # d phi_j / dx at x = L [1/m]
    if key is not None or pipe.axially_restrained:
        # any supports: the centrifugal tension in weak form, integral of N phi_i' phi_j' / L,
        # with N(x) following the axial boundary conditions (docs/model.md 9)
        K_w2 = axial_matrix(spin_axial_force(pipe), g, L)
        if pipe.in_plane:
            K_w2 = K_w2 - m * gram
        if pipe.in_plane and R:
            F_wdot = F_wdot - m * R * L * g.f
    elif R:
        # tension M1 w0^2 R (L - x), zero at the tip: weak form = strong form
        K_w2 = K_w2 + M1 * R * (g.d - g.xd)
        if pipe.in_plane:
            F_wdot = F_wdot - m * R * L * g.f
    if mt:
        M = M + mt * np.outer(tip, tip)
        # the tip mass's tension m_t w0^2 (R + L) along the whole pipe (weak form: the
        # natural boundary condition EI u_xxx - T(L) u_x = ... carries its tip part);
        # with other supports it is in spin_axial_force
        if key is None and not pipe.axially_restrained:
            K_w2 = K_w2 + mt * (R + L) / L * g.d
        if pipe.in_plane:
            K_w2 = K_w2 - mt * np.outer(tip, tip)
            F_wdot = F_wdot - mt * (R + L) * tip
    if Jt:
        M = M + Jt * np.outer(slope, slope)
        if pipe.in_plane:
            F_wdot = F_wdot - Jt * slope
    K_bend = K_0
    if pipe.has_static_axial_force:
        # tension, pressure and gravity at rest: K_0 gains integral of N phi_i' phi_j' / L
        K_0 = K_0 + axial_matrix(static_axial_force(pipe), g, L)
    if pipe.kelvin_voigt:
        # the material's damping acts on the beam's strain energy, not on the support
        # springs (external elements): without springs the two are the same matrix
        K_flex = K_bend if g.flex is None else EI / L**3 * g.flex
        C_0 = C_0 + pipe.kelvin_voigt * K_flex
    if pipe.viscous:
        C_0 = C_0 + pipe.viscous * gram

    return SecondOrder(M, C_0, C_v, K_0, K_bend, K_vdot, K_v2, K_w2, F_wdot, tip, slope)


@lru_cache(maxsize=64)
def build_model(pipe: Pipe, n: int, quadrature_order: int | None = None) -> PipeModel:
    """Assemble the Galerkin model for ``n`` modes (cached per pipe, n and order):
    :func:`second_order` on the basis' integrals, then the balanced state-space form."""
    key = pipe.basis_key
    g = mode_integrals(n, quadrature_order, key)
    L, m, EI = pipe.L, pipe.mass, pipe.EI
    so = second_order(pipe, g)
    M, K_bend = so.M, so.K_bend
    tip_body = (
        pipe.tip_mass * float(so.tip @ so.tip),
        pipe.tip_inertia * float(so.slope @ so.slope),
    )
    _check_mass_conditioning(M, *tip_body)
    # M is diagonal up to rounding without a tip body (n <= 40): one solve for every block
    Minv = np.linalg.solve(M, np.eye(n))
    omega_ref = np.sqrt(np.diag(K_bend) / np.diag(M))
    if key is not None:
        # a rigid-body mode (a free or sliding end) has no bending stiffness: balance it on
        # the beam's frequency scale sqrt(EI / (m L^4)) instead (any positive scale works)
        omega_ref = np.maximum(omega_ref, math.sqrt(EI / (m * L**4)))
    T = np.concatenate([omega_ref, np.ones(n)])  # y = T z

    def balanced(upper_left: FloatArray, upper_right: FloatArray, lower: bool) -> FloatArray:
        S = np.zeros((2 * n, 2 * n))
        S[:n, :n] = upper_left
        S[:n, n:] = upper_right
        if lower:
            S[n:, :n] = np.eye(n)
        return S * (1.0 / T)[:, None] * T[None, :]

    zero = np.zeros((n, n))
    damped = bool(pipe.kelvin_voigt or pipe.viscous)
    S_0 = balanced(-Minv @ so.C_0 if damped else zero, -Minv @ so.K_0, True)
    S_v = balanced(-Minv @ so.C_v, zero, False)
    S_vdot = balanced(zero, -Minv @ so.K_vdot, False)
    S_v2 = balanced(zero, -Minv @ so.K_v2, False)
    S_w2 = balanced(zero, -Minv @ so.K_w2, False)
    f_wdot = np.concatenate([(Minv @ so.F_wdot) / omega_ref, np.zeros(n)])
    arrays = [M, so.C_0, so.C_v, so.K_0, K_bend, so.K_vdot, so.K_v2, so.K_w2, so.F_wdot]
    arrays.append(omega_ref)
    arrays += [S_0, S_v, S_vdot, S_v2, S_w2, f_wdot]
    for a in arrays:
        a.setflags(write=False)
    return PipeModel(
        pipe, n, g.quadrature_order, M, so.C_0, so.C_v, so.K_0, so.K_vdot, so.K_v2, so.K_w2,
        so.F_wdot, omega_ref, S_0, S_v, S_vdot, S_v2, S_w2, f_wdot, so.tip,
        None if K_bend is so.K_0 else K_bend,
    )  # fmt: skip
