"""End supports, springs and intermediate supports of the pipe (issue 31; ``docs/model.md`` 9).

An end support is one of the four classical conditions or an elastic end:

==========  ==================================  =======================================
kind        conditions at the end               rigid-body motion left free
==========  ==================================  =======================================
clamped     w = 0, w' = 0                       none
pinned      w = 0, EI w'' = 0                   rotation about the pin
sliding     w' = 0, EI w''' = 0                 translation
free        EI w'' = 0, EI w''' = 0             translation and rotation
elastic     EI w'' = -/+ k_r w', EI w''' = +/- k_t w  (signs: x = L / x = 0)
==========  ==================================  =======================================

``Support(kind="elastic", translational=k_t [N/m], rotational=k_r [N m/rad])``.  On the
non-dimensional coordinate xi = x / L the springs enter as K_t = k_t L^3 / EI and
K_r = k_r L / EI [-] (:meth:`Support.nondimensional`), the numbers the basis depends on.

An intermediate support at 0 < x < L is a translational spring k [N/m] or a rigid pin
(w(x) = 0): :class:`PointSupport`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Protocol

from pipeflow.beam_modes import BasisKey, rigid_lines
from pipeflow.integrals import AxialForce

KINDS = ("clamped", "pinned", "sliding", "free", "elastic")
#: the most intermediate supports a pipe may have
MAX_INTERMEDIATE = 8


@dataclass(frozen=True)
class Support:
    """One end's support: ``kind`` in :data:`KINDS`; for ``"elastic"`` the translational
    spring ``translational`` [N/m] and the rotational spring ``rotational`` [N m/rad]
    (both >= 0, finite; a missing part is 0)."""

    kind: str = "clamped"
    translational: float = 0.0
    rotational: float = 0.0

    def __post_init__(self) -> None:
        if self.kind not in KINDS:
            raise ValueError(f"unknown support {self.kind!r}; use one of {', '.join(KINDS)}")
        for name in ("translational", "rotational"):
            val = getattr(self, name)
            if not (math.isfinite(val) and val >= 0):
                raise ValueError(f"support {name} stiffness must be finite and >= 0, got {val}")
            if val and self.kind != "elastic":
                raise ValueError(f"a {self.kind} support has no {name} spring")

    @property
    def fixes_deflection(self) -> bool:
        """w = 0 at this end (clamped or pinned)."""
        return self.kind in ("clamped", "pinned")

    def nondimensional(self, EI: float, L: float) -> tuple[str, float, float]:
        """``(kind, K_t, K_r)`` with K_t = k_t L^3 / EI and K_r = k_r L / EI [-]."""
        return (self.kind, self.translational * L**3 / EI, self.rotational * L / EI)

    def describe(self) -> str:
        if self.kind != "elastic":
            return self.kind
        return f"elastic (k_t = {self.translational:g} N/m, k_r = {self.rotational:g} N m/rad)"


CLAMPED = Support("clamped")
FREE = Support("free")


@dataclass(frozen=True)
class Supports:
    """The two end supports: ``x0`` at x = 0 (the hub end) and ``xL`` at x = L."""

    x0: Support = CLAMPED
    xL: Support = FREE

    @property
    def is_cantilever(self) -> bool:
        """Clamped at x = 0 and free at x = L: the paper's pipe."""
        return self.x0 == CLAMPED and self.xL == FREE

    @property
    def discharges_freely(self) -> bool:
        """The downstream end x = L is free: the fluid leaves as a free jet at ambient
        pressure, which cancels the pressurisation term (``docs/model.md`` 9)."""
        return self.xL.kind == "free"

    def describe(self) -> str:
        return f"x = 0 {self.x0.describe()}, x = L {self.xL.describe()}"


CANTILEVER = Supports()


@dataclass(frozen=True)
class PointSupport:
    """An intermediate support at ``position`` [m] (0 < x < L): a translational spring of
    stiffness ``translational`` [N/m], or a rigid pin (``pinned=True``: w(x) = 0)."""

    position: float
    translational: float = 0.0
    pinned: bool = False

    def __post_init__(self) -> None:
        if not math.isfinite(self.position):
            raise ValueError(f"intermediate support position must be finite, got {self.position}")
        if not (math.isfinite(self.translational) and self.translational >= 0):
            raise ValueError(
                f"intermediate support stiffness must be finite and >= 0, got {self.translational}"
            )
        if self.pinned and self.translational:
            raise ValueError("a pinned intermediate support has no spring stiffness")


# -- the model's view of the supports and axial loads (docs/model.md 9) ----------------------


class Mounted(Protocol):
    """What the functions below read of a pipe (:class:`pipeflow.model.Pipe` has it): its
    supports, stiffness, masses and axial loads, in the units of ``Pipe``'s fields."""

    @property
    def supports(self) -> Supports: ...
    @property
    def intermediate_supports(self) -> tuple[PointSupport, ...]: ...
    @property
    def E(self) -> float: ...
    @property
    def I(self) -> float: ...  # noqa: E743 (the second moment of area, as Pipe names it)
    @property
    def L(self) -> float: ...
    @property
    def M1(self) -> float: ...
    @property
    def M2(self) -> float: ...
    @property
    def hub_radius(self) -> float: ...
    @property
    def tip_mass(self) -> float: ...
    @property
    def tip_inertia(self) -> float: ...
    @property
    def tension(self) -> float: ...
    @property
    def pressure(self) -> float: ...
    @property
    def gravity(self) -> float: ...
    @property
    def flow_area(self) -> float: ...
    @property
    def poisson(self) -> float: ...
    @property
    def axially_restrained(self) -> bool: ...


#: an intermediate spring with K = k L^3 / EI at or above this is a rigid (pinned) point
#: support.  Its effect on the frequencies differs from the pin's by O(1/K) (below 1e-8 of
#: them here), while the spring's Ritz eigenproblem diag(lambda^4) + K phi phi^T loses
#: eps K / lambda_1^4 of the low eigenvalues to rounding (1.6e-7 at K = 1e12, 7e-5 at 1e14,
#: 58 % at 1e18 on a pinned-pinned pipe with a midspan spring): above 1e10 the pin is the
#: more accurate answer (docs/supports.md).
RIGID_POINT_SPRING = 1e10


def _point_stiffness(p: PointSupport, EI: float, L: float) -> float:
    """K = k L^3 / EI [-] of an intermediate support; inf for a pin or a rigid spring
    (:data:`RIGID_POINT_SPRING`)."""
    K = p.translational * L**3 / EI
    return math.inf if p.pinned or K >= RIGID_POINT_SPRING else K


def basis_key(pipe: Mounted) -> BasisKey | None:
    """The pipe's supports on the unit interval; None for the cantilever without
    intermediate supports (the model then keeps the cantilever modes of pipeflow.basis)."""
    s = pipe.supports
    if s.is_cantilever and not pipe.intermediate_supports:
        return None
    EI, L = pipe.E * pipe.I, pipe.L
    points = tuple(
        sorted((p.position / L, _point_stiffness(p, EI, L)) for p in pipe.intermediate_supports)
    )
    return (s.x0.nondimensional(EI, L), s.xL.nondimensional(EI, L), points)


def check_mounting(pipe: Mounted) -> None:
    """Refuse supports and axial loads that do not describe a pipe (ValueError naming the
    field, as :class:`pipeflow.model.Pipe` does for its other fields)."""
    s = pipe.supports
    if not isinstance(s, Supports):
        raise ValueError(f"pipe.supports must be a Supports, got {type(s).__name__}")
    pts = pipe.intermediate_supports
    if len(pts) > MAX_INTERMEDIATE:
        raise ValueError(f"pipe.intermediate_supports: at most {MAX_INTERMEDIATE}, got {len(pts)}")
    seen: set[float] = set()
    for i, p in enumerate(pts):
        if not 0.0 < p.position < pipe.L:
            raise ValueError(
                f"pipe.intermediate_supports.{i}.position: {p.position} m is not inside the "
                f"pipe (0, L = {pipe.L} m)"
            )
        if p.position in seen:
            raise ValueError(f"pipe.intermediate_supports.{i}.position: {p.position} m repeated")
        seen.add(p.position)
    key = basis_key(pipe)
    # the rigid lines the supports leave free (as the basis counts them: springs below
    # SPRING_FLOOR are none, so a 0 N/m point support holds nothing): a translation
    # (1, 0) among them is a pipe that nothing holds; a rotation about one support is allowed
    if key is not None and (1.0, 0.0) in rigid_lines(*key):
        raise ValueError(
            f"pipe.supports: nothing holds the pipe transversely ({s.describe()}"
            f"{'; its intermediate springs hold nothing' if pts else ''}): it would translate "
            "freely; clamp, pin or spring (translational) one end, or add a pinned or sprung "
            "intermediate support"
        )
    for name in ("tension", "pressure", "gravity"):
        val = getattr(pipe, name)
        if not math.isfinite(val):
            raise ValueError(f"pipe.{name} must be finite, got {val}")
    if not (math.isfinite(pipe.flow_area) and pipe.flow_area >= 0):
        raise ValueError(f"pipe.flow_area must be finite and >= 0, got {pipe.flow_area}")
    if pipe.pressure and not pipe.flow_area:
        raise ValueError(
            "pipe.flow_area: a pressure needs the flow area A [m^2] (p A is the force)"
        )
    if not -1.0 < pipe.poisson <= 0.5:
        raise ValueError(f"pipe.poisson must be in (-1, 0.5], got {pipe.poisson}")
    if pipe.axially_restrained and "free" in (s.x0.kind, s.xL.kind):
        raise ValueError(
            "pipe.axially_restrained: a free end cannot be axially fixed "
            f"(supports: {s.describe()})"
        )
    if (pipe.tip_mass or pipe.tip_inertia) and s.xL.kind not in ("free", "elastic"):
        raise ValueError(
            f"pipe.tip_mass: a tip body needs a free or elastic end at x = L, not {s.xL.kind}"
        )


def pressure_force_per_pascal(pipe: Mounted) -> float:
    """A (1 - 2 nu delta) [m^2]: the pressurisation's compressive force per pascal of
    internal pressure; 0 when the pipe discharges freely at x = L (the jet leaves at ambient
    pressure, and the axial balance of the fluid cancels p A against the wall's tension:
    Paidoussis vol. 1, sec. 3.2.2)."""
    if pipe.supports.discharges_freely:
        return 0.0
    delta = 1.0 if pipe.axially_restrained else 0.0
    return pipe.flow_area * (1.0 - 2.0 * pipe.poisson * delta)


def effective_pressure(pipe: Mounted) -> float:
    """p A (1 - 2 nu delta) [N], the pressurisation's compressive force of the pipe's
    constant pressure (:func:`pressure_force_per_pascal`)."""
    if not pipe.pressure:
        return 0.0
    return pipe.pressure * pressure_force_per_pascal(pipe)


def _restrained(pipe: Mounted, a: AxialForce) -> AxialForce:
    """Both ends axially fixed: the ends share the body force, N - mean(N) (the axial strain
    of an extensible pipe integrates to zero)."""
    if not pipe.axially_restrained:
        return a
    mean = a[0] + a[1] / 2 + a[2] / 3
    return (a[0] - mean, a[1], a[2])


def static_axial_force(pipe: Mounted) -> AxialForce:
    """N(xi) [N] at rest: T - p A (1 - 2 nu delta) + gravity's (m (L - x) + m_t) g_x."""
    m, L = pipe.M1 + pipe.M2, pipe.L
    grav = _restrained(pipe, (pipe.gravity * (m * L + pipe.tip_mass), -pipe.gravity * m * L, 0.0))
    return (pipe.tension - effective_pressure(pipe) + grav[0], grav[1], grav[2])


def spin_axial_force(pipe: Mounted) -> AxialForce:
    """N(xi) per w0^2 [N s^2]: M1 [R (L - x) + (L^2 - x^2)/2] + m_t (R + L) (the paper's
    convention: the pipe mass carries the centrifugal tension), free to slide at x = L, or
    shared by both ends when axially restrained."""
    M1, L, R, mt = pipe.M1, pipe.L, pipe.hub_radius, pipe.tip_mass
    a = (M1 * (R * L + L * L / 2) + mt * (R + L), -M1 * R * L, -M1 * L * L / 2)
    return _restrained(pipe, a)
