"""External loads on the pipe (issue 18) and their projection onto the Galerkin model.

Three kinds, each with a time history given by any :class:`~pipeflow.profiles.Profile`:

- :class:`PointForce`: a transverse force F(t) [N] at x = ``position`` [m], 0 < x <= L, in
  the plane of motion;
- :class:`DistributedForce`: a uniform transverse load q(t) [N/m] on [``start``, ``end``]
  [m] (the whole pipe by default);
- :class:`BaseAcceleration`: the clamp's transverse acceleration a(t) [m/s^2].  In the
  frame of the clamp it is the inertial load -(M1 + M2) a(t) per unit length plus
  -m_t a(t) on the tip body (a rigid translation: the tip's rotary inertia does not see
  it); displacements then stay **relative to the clamp**;

and :class:`PointImpulse`, a blow J [N s] at x = ``position`` at t0 = ``time`` [s]: the
profile J delta(t - t0) of a point force, a jump of the modal velocities at t0 (solvers
apply it as a jump of the state, :attr:`ExternalForcing.impulsive`).

Projection (physics notes, section 5): the generalised force of mode j is
f_j(t) = sum over loads of b_j p(t), with

    b_j = phi_j(x)                                   point force or impulse at x,
    b_j = integral_{x0}^{x1} phi_j dx                distributed load on [x0, x1],
    b_j = -(M1+M2) integral_0^L phi_j dx - m_t phi_j(L)   base acceleration,

phi_j the basis module's normalised cantilever modes; the integrals use the Gauss-Legendre
rule of the model (:func:`pipeflow.model.mode_integrals`: its ``f`` vector over the whole
pipe, the same order mapped onto [x0, x1] for part of it), exact to rounding for these
smooth integrands.  In the balanced state z = (d'/omega_ref, d) of :mod:`pipeflow.model`
each load is a column g = ((M^-1 b) / omega_ref, 0), exactly like the spin-up load
``f_wdot``, and the state equation becomes

    z' = S(t) z + f_wdot dw0/dt + sum_k g_k p_k(t).

:class:`ExternalForcing` holds the columns g_k and the profiles p_k; every solver reads
it from :attr:`pipeflow.solvers.base.Problem.loads`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, ClassVar, Literal, cast

import numpy as np
from numpy.typing import ArrayLike

from pipeflow._types import FloatArray
from pipeflow.basis import gauss_legendre_unit
from pipeflow.errors import InvalidInput
from pipeflow.integrals import mode_integrals
from pipeflow.model import PipeModel
from pipeflow.profiles import Impulse, Profile

#: at most this many loads per simulation
MAX_LOADS = 16

#: what a result with a base acceleration says about its displacements
BASE_ACCELERATION_NOTE = (
    "base_acceleration: displacements are relative to the clamp (the clamp's own transverse "
    "motion, the double integral of the acceleration, is not included)"
)


def _out_of_span(i: int, name: str, message: str) -> InvalidInput:
    return InvalidInput(f"loads.{i}.{name}: {message}", parameter=f"loads.{i}.{name}")


def _point_shapes(position: float, model: PipeModel) -> FloatArray:
    return np.asarray(model.shapes(np.array([position / model.pipe.L]))[:, 0])


class _LoadRules:
    """What every load does itself (issue 33: no ``isinstance`` chains elsewhere): its
    generalised force, its checks (one set of rules, used by the library and the schema),
    its JSON form, and what a result should say about it.

    ``profile_field``: the name of the field holding the time history; ``note``: a line a
    result with this load carries (None: nothing to say)."""

    profile_field: ClassVar[str]
    note: ClassVar[str | None] = None
    kind: str

    @property
    def profile(self) -> Profile:
        return cast(Profile, getattr(self, self.profile_field))

    def generalized_force(self, model: PipeModel) -> FloatArray:
        """b_j: the generalised force of each mode per unit of the profile, shape (n,)."""
        raise NotImplementedError

    def check_span(self, i: int, L: float) -> None:
        """Raise :class:`InvalidInput` naming ``loads.<i>.<field>`` when the load does not
        fit on a pipe of length ``L`` [m]."""

    def check(self, i: int, L: float, t_end: float) -> None:
        """The load's rules on a run of ``t_end`` [s] on a pipe of length ``L`` [m]."""
        self.check_span(i, L)
        self.check_onset(i, t_end)
        end = self.profile.domain_end()
        if end < t_end:
            raise _out_of_span(
                i,
                self.profile_field,
                f"the table ends at {end} s, before t_end = {t_end} s (or say what it does "
                "after its last time: after = 'hold' or 'zero')",
            )

    def check_onset(self, i: int, t_end: float) -> None:
        """A load that starts after the run ends would change nothing: refused, naming the
        field of its start (a silent no-op hides a mistyped time)."""
        onset = self.profile.onset
        if onset > t_end:
            field, what = self.onset_field
            raise _out_of_span(
                i,
                field,
                f"{what} at {onset:g} s comes after the run ends (t_end = {t_end:g} s), so it "
                "would change nothing",
            )

    @property
    def onset_field(self) -> tuple[str, str]:
        """(the field holding the load's start, how to name it)."""
        return f"{self.profile_field}.start", "the pulse starts"

    def fields(self, L: float) -> dict[str, Any]:
        """The load's own fields in its request JSON (besides kind and the profile)."""
        return {}

    def to_dict(self, L: float) -> dict[str, Any]:
        """The request JSON of the load (its echo in a result)."""
        return {"kind": self.kind, **self.fields(L), self.profile_field: self.profile.to_dict()}


def _check_station(i: int, x: float, L: float) -> None:
    if math.isfinite(x) and x > L:
        raise _out_of_span(i, "position", f"{x} m is beyond the tip, L = {L} m")
    if not (math.isfinite(x) and 0.0 < x <= L):
        raise _out_of_span(i, "position", f"{x} m is outside (0, L], L = {L} m")


@dataclass(frozen=True)
class PointForce(_LoadRules):
    """Transverse force ``force`` F(t) [N] at x = ``position`` [m] (0 < x <= L)."""

    position: float
    force: Profile
    kind: Literal["point_force"] = "point_force"
    profile_field: ClassVar[str] = "force"

    def generalized_force(self, model: PipeModel) -> FloatArray:
        return _point_shapes(self.position, model)  # [-]

    def check_span(self, i: int, L: float) -> None:
        _check_station(i, self.position, L)

    def fields(self, L: float) -> dict[str, Any]:
        return {"position": self.position}


@dataclass(frozen=True)
class PointImpulse(_LoadRules):
    """A transverse impulse ``impulse`` J [N s] at x = ``position`` [m] (0 < x <= L) at
    ``time`` t0 [s] >= 0 (a hammer blow): a jump of the modal velocities at t0, the
    response right-continuous (the sample at t0 is after the blow)."""

    position: float
    impulse: float
    time: float
    kind: Literal["impulse"] = "impulse"
    profile_field: ClassVar[str] = "impulse"

    @property
    def profile(self) -> Profile:
        return Impulse(self.impulse, self.time)

    def generalized_force(self, model: PipeModel) -> FloatArray:
        return _point_shapes(self.position, model)  # [-]

    def check_span(self, i: int, L: float) -> None:
        _check_station(i, self.position, L)
        if not math.isfinite(self.impulse):
            raise _out_of_span(i, "impulse", f"{self.impulse} N s is not finite")

    def check(self, i: int, L: float, t_end: float) -> None:
        self.check_span(i, L)
        if not (math.isfinite(self.time) and self.time >= 0.0):
            raise _out_of_span(i, "time", f"{self.time} s must be >= 0")
        self.check_onset(i, t_end)

    @property
    def onset_field(self) -> tuple[str, str]:
        return "time", "the blow"

    def to_dict(self, L: float) -> dict[str, Any]:
        return {
            "kind": self.kind,
            "position": self.position,
            "impulse": self.impulse,
            "time": self.time,
        }


@dataclass(frozen=True)
class DistributedForce(_LoadRules):
    """Uniform transverse load ``intensity`` q(t) [N/m] on [``start``, ``end``] [m]
    (``end`` None: the tip, x = L)."""

    intensity: Profile
    start: float = 0.0
    end: float | None = None
    kind: Literal["distributed_force"] = "distributed_force"
    profile_field: ClassVar[str] = "intensity"

    def generalized_force(self, model: PipeModel) -> FloatArray:
        L = model.pipe.L
        end = L if self.end is None else self.end
        g = mode_integrals(model.n, model.quadrature_order, model.pipe.basis_key)
        if self.start == 0.0 and end == L:
            return np.asarray(L * g.f)  # [m]
        # the model's rule mapped onto [x0, x1]: integrand smooth, exact to rounding
        xi, w = gauss_legendre_unit(g.quadrature_order)
        a, b = self.start / L, end / L
        shapes = model.shapes(a + (b - a) * xi)
        return np.asarray(L * (b - a) * (shapes @ w))

    def check_span(self, i: int, L: float) -> None:
        end = L if self.end is None else self.end
        if not (math.isfinite(self.start) and 0.0 <= self.start < L):
            raise _out_of_span(i, "start", f"{self.start} m is outside [0, L), L = {L} m")
        if math.isfinite(end) and end > L:
            raise _out_of_span(i, "end", f"{end} m is beyond the tip, L = {L} m")
        if not (math.isfinite(end) and end > 0.0):
            raise _out_of_span(i, "end", f"{end} m must be in (start, L], L = {L} m")
        if self.start >= end:
            raise _out_of_span(i, "start", f"{self.start} m must be below the end, {end} m")

    def fields(self, L: float) -> dict[str, Any]:
        return {"start": self.start, "end": L if self.end is None else self.end}


@dataclass(frozen=True)
class BaseAcceleration(_LoadRules):
    """Transverse acceleration a(t) [m/s^2] of the clamp; displacements are relative to it."""

    acceleration: Profile
    kind: Literal["base_acceleration"] = "base_acceleration"
    profile_field: ClassVar[str] = "acceleration"
    note: ClassVar[str | None] = BASE_ACCELERATION_NOTE

    def generalized_force(self, model: PipeModel) -> FloatArray:
        pipe = model.pipe
        g = mode_integrals(model.n, model.quadrature_order, model.pipe.basis_key)
        out = -pipe.mass * pipe.L * g.f  # [kg]
        if pipe.tip_mass:
            out = out - pipe.tip_mass * g.tip
        return np.asarray(out)


Load = PointForce | PointImpulse | DistributedForce | BaseAcceleration


def validate_loads(loads: tuple[Load, ...], L: float, t_end: float) -> None:
    """Raise :class:`InvalidInput` naming ``loads.<i>.<field>`` when a load cannot be applied."""
    if len(loads) > MAX_LOADS:
        raise InvalidInput(f"at most {MAX_LOADS} loads, got {len(loads)}", parameter="loads")
    for i, load in enumerate(loads):
        if not callable(getattr(load, "check", None)):
            raise InvalidInput(f"loads.{i}: unknown load {load!r}", parameter=f"loads.{i}")
        load.check(i, L, t_end)


def generalized_force(load: Load, model: PipeModel) -> FloatArray:
    """b_j of ``load``: the generalised force of each mode per unit of its profile, shape
    ``(n,)`` ([-] for a point force or impulse, [m] for a distributed one, [kg] for an
    acceleration)."""
    return load.generalized_force(model)


def load_notes(loads: tuple[Load, ...]) -> list[str]:
    """What a result with these loads must say about them (each note once)."""
    return list(dict.fromkeys(load.note for load in loads if load.note))


def moves_nothing(force: ArrayLike) -> bool:
    """Whether a load's generalised force (or its state column) ``force`` is zero: the load
    acts where the pipe is held (a pin, a clamped or pinned end), where every basis function
    vanishes, so the support takes it.  One test for simulate() and the FRF."""
    return not np.any(force)


def held_note(name: str) -> str:
    """What a result says of the load ``name`` when :func:`moves_nothing` holds for it."""
    return f"{name}: it acts where the pipe is held (a support takes it): it moves nothing"


def profile_rate(profile: Profile) -> float:
    """A rate [rad/s] at which ``profile`` varies, for quadrature step sizes: the frequency
    of a harmonic, 0 for constants, polynomials and tables (piecewise polynomials: their
    knots are breakpoints, :meth:`ExternalForcing.knots`)."""
    return profile.rate


@dataclass(frozen=True, eq=False)
class ExternalForcing:
    """The loads of a run in the balanced state: z' = S z + ... + ``columns.T @ values(t)``.

    ``columns`` has shape ``(K, 2n)`` [1/s per unit of the profile: the unit of g p is 1/s
    times metres of balanced state]; ``profiles`` the K time histories; ``loads`` the
    library loads they come from.
    """

    loads: tuple[Load, ...]
    columns: FloatArray
    profiles: tuple[Profile, ...]

    @property
    def count(self) -> int:
        return len(self.profiles)

    @property
    def is_constant(self) -> bool:
        """True when every load is constant in time (then z' = S z + const)."""
        return all(p.is_constant for p in self.profiles)

    def held(self) -> list[int]:
        """The indices of the loads that act where the pipe is held (a pin, a clamped or
        pinned end): every basis function vanishes there, so they force nothing."""
        return [i for i, column in enumerate(self.columns) if moves_nothing(column)]

    @property
    def rate(self) -> float:
        """The fastest variation of the loads [rad/s] (:func:`profile_rate`)."""
        return max((profile_rate(p) for p in self.profiles), default=0.0)

    def knots(self, t_end: float) -> FloatArray:
        """Break points of the profiles inside (0, t_end) [s] (table knots, the ends of a
        pulse): the profiles are smooth between them."""
        pts = [np.asarray(p.breaks(), dtype=float) for p in self.profiles]
        if not pts:
            return np.zeros(0)
        k = np.unique(np.concatenate(pts))
        return k[(k > 0.0) & (k < t_end)]

    @property
    def closed_form(self) -> tuple[bool, ...]:
        """Per load: its profile is a sum of exponential-polynomial pieces (its response
        has a closed form, :func:`pipeflow.solvers.convolution.exact_particular`)."""
        return tuple(p.terms() is not None for p in self.profiles)

    @property
    def impulsive(self) -> bool:
        """True when a load is a Dirac impulse (it acts as a jump of the state)."""
        return any(p.impulsive for p in self.profiles)

    def subset(self, which: ArrayLike) -> ExternalForcing | None:
        """The loads selected by the boolean mask ``which`` (None when none is)."""
        mask = np.asarray(which, dtype=bool)
        if not mask.any():
            return None
        idx = np.flatnonzero(mask)
        columns = self.columns[idx]
        return ExternalForcing(
            tuple(self.loads[i] for i in idx), columns, tuple(self.profiles[i] for i in idx)
        )

    def impulses(self) -> list[tuple[float, FloatArray]]:
        """The impulses as ``(time [s], state jump [m of balanced state])``, in time order."""
        out = []
        for column, profile in zip(self.columns, self.profiles, strict=True):
            for term in profile.terms() or ():
                if term.power < 0:
                    out.append((term.start, np.asarray(column * term.coef.real)))
        return sorted(out, key=lambda item: item[0])

    def values(self, t: ArrayLike) -> FloatArray:
        """p_k(t), shape ``(len(t), K)``."""
        t = np.asarray(t, dtype=float)
        return np.stack([p.value(t) for p in self.profiles], axis=-1)

    def vector(self, t: ArrayLike) -> FloatArray:
        """The balanced forcing sum_k g_k p_k(t), shape ``(len(t), 2n)`` [1/s x m]."""
        return np.asarray(self.values(t) @ self.columns)

    def peak(self, t_end: float, samples: int = 257) -> float:
        """A size of the forcing: max over sampled times of |sum_k g_k p_k(t)|_2."""
        ts = np.linspace(0.0, t_end, samples)
        return float(np.max(np.linalg.norm(self.vector(ts), axis=1)))


def project_loads(model: PipeModel, loads: tuple[Load, ...]) -> ExternalForcing | None:
    """The loads as balanced forcing columns of ``model`` (None when there are none)."""
    if not loads:
        return None
    b = np.stack([generalized_force(load, model) for load in loads])  # (K, n)
    upper = np.linalg.solve(model.M, b.T).T / model.omega_ref[None, :]
    columns = np.concatenate([upper, np.zeros_like(upper)], axis=1)
    columns.setflags(write=False)
    return ExternalForcing(tuple(loads), columns, tuple(load.profile for load in loads))


def profile_to_dict(profile: Profile) -> dict[str, Any]:
    """The request JSON of a profile (the schema's ``kind`` forms)."""
    return profile.to_dict()


def load_to_dict(load: Load, L: float) -> dict[str, Any]:
    """The request JSON of a load (its echo in a result)."""
    return load.to_dict(L)
