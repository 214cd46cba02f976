"""External loads on the pipe (issue 18) and their projection onto the Galerkin model.

Three kinds, each with a time history given by any :class:`~pipeflow.profiles.Profile`:

- :class:`PointForce`: a transverse force F(t) [N] at x = ``position`` [m], 0 < x <= L, in
  the plane of motion;
- :class:`DistributedForce`: a uniform transverse load q(t) [N/m] on [``start``, ``end``]
  [m] (the whole pipe by default);
- :class:`BaseAcceleration`: the clamp's transverse acceleration a(t) [m/s^2].  In the
  frame of the clamp it is the inertial load -(M1 + M2) a(t) per unit length plus
  -m_t a(t) on the tip body (a rigid translation: the tip's rotary inertia does not see
  it); displacements then stay **relative to the clamp**.

Projection (physics notes, section 5): the generalised force of mode j is
f_j(t) = sum over loads of b_j p(t), with

    b_j = phi_j(x)                                   point force at x,
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
from typing import Any, Literal

import numpy as np
from numpy.typing import ArrayLike

from pipeflow._types import FloatArray
from pipeflow.basis import gauss_legendre_unit
from pipeflow.errors import InvalidInput
from pipeflow.model import PipeModel, mode_integrals
from pipeflow.profiles import Constant, Harmonic, Polynomial, Profile, Table

#: at most this many loads per simulation
MAX_LOADS = 16

#: what a result with a base acceleration says about its displacements
BASE_ACCELERATION_NOTE = (
    "base_acceleration: displacements are relative to the clamp (the clamp's own transverse "
    "motion, the double integral of the acceleration, is not included)"
)


@dataclass(frozen=True)
class PointForce:
    """Transverse force ``force`` F(t) [N] at x = ``position`` [m] (0 < x <= L)."""

    position: float
    force: Profile
    kind: Literal["point_force"] = "point_force"

    @property
    def profile(self) -> Profile:
        return self.force


@dataclass(frozen=True)
class DistributedForce:
    """Uniform transverse load ``intensity`` q(t) [N/m] on [``start``, ``end``] [m]
    (``end`` None: the tip, x = L)."""

    intensity: Profile
    start: float = 0.0
    end: float | None = None
    kind: Literal["distributed_force"] = "distributed_force"

    @property
    def profile(self) -> Profile:
        return self.intensity


@dataclass(frozen=True)
class BaseAcceleration:
    """Transverse acceleration a(t) [m/s^2] of the clamp; displacements are relative to it."""

    acceleration: Profile
    kind: Literal["base_acceleration"] = "base_acceleration"

    @property
    def profile(self) -> Profile:
        return self.acceleration


Load = PointForce | DistributedForce | BaseAcceleration


def validate_loads(loads: tuple[Load, ...], L: float, t_end: float) -> None:
    """Raise :class:`InvalidInput` naming ``loads.<i>.<field>`` when a load cannot be applied."""
    if len(loads) > MAX_LOADS:
        raise InvalidInput(f"at most {MAX_LOADS} loads, got {len(loads)}", parameter="loads")
    for i, load in enumerate(loads):
        if isinstance(load, PointForce):
            x = load.position
            if not (math.isfinite(x) and 0.0 < x <= L):
                raise InvalidInput(
                    f"loads.{i}.position: {x} m is outside (0, L], L = {L} m",
                    parameter=f"loads.{i}.position",
                )
            name = "force"
        elif isinstance(load, DistributedForce):
            end = L if load.end is None else load.end
            if not (math.isfinite(load.start) and 0.0 <= load.start < L):
                raise InvalidInput(
                    f"loads.{i}.start: {load.start} m is outside [0, L), L = {L} m",
                    parameter=f"loads.{i}.start",
                )
            if not (math.isfinite(end) and load.start < end <= L):
                raise InvalidInput(
                    f"loads.{i}.end: {end} m must be in (start, L], start = {load.start} m, "
                    f"L = {L} m",
                    parameter=f"loads.{i}.end",
                )
            name = "intensity"
        elif isinstance(load, BaseAcceleration):
            name = "acceleration"
        else:
            raise InvalidInput(f"loads.{i}: unknown load {load!r}", parameter=f"loads.{i}")
        if load.profile.domain_end() < t_end:
            raise InvalidInput(
                f"loads.{i}.{name}: the table ends at {load.profile.domain_end()} s, before "
                f"t_end = {t_end} s",
                parameter=f"loads.{i}.{name}",
            )


def generalized_force(load: Load, model: PipeModel) -> FloatArray:
    """b_j of ``load``: the generalised force of each mode per unit of its profile, shape
    ``(n,)`` ([-] for a point force, [m] for a distributed one, [kg] for an acceleration)."""
    pipe, n = model.pipe, model.n
    L = pipe.L
    if isinstance(load, PointForce):
        return np.asarray(model.shapes(np.array([load.position / L]))[:, 0])
    g = mode_integrals(n, model.quadrature_order, pipe.basis_key)
    if isinstance(load, DistributedForce):
        end = L if load.end is None else load.end
        if load.start == 0.0 and end == L:
            return np.asarray(L * g.f)
        # the model's rule mapped onto [x0, x1]: integrand smooth, exact to rounding
        xi, w = gauss_legendre_unit(g.quadrature_order)
        a, b = load.start / L, end / L
        shapes = model.shapes(a + (b - a) * xi)
        return np.asarray(L * (b - a) * (shapes @ w))
    if isinstance(load, BaseAcceleration):
        out = -pipe.mass * L * g.f
        if pipe.tip_mass:
            out = out - pipe.tip_mass * g.tip
        return np.asarray(out)
    raise TypeError(f"unknown load {load!r}")


def profile_rate(profile: Profile) -> float:
    """A rate [rad/s] at which ``profile`` varies, for quadrature step sizes: the frequency
    of a harmonic, 0 for constants, polynomials and tables (piecewise polynomials: their
    knots are breakpoints, :meth:`ExternalForcing.knots`)."""
    if isinstance(profile, Harmonic) and not profile.is_constant:
        return abs(float(profile.frequency))
    return 0.0


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

    @property
    def rate(self) -> float:
        """The fastest variation of the loads [rad/s] (:func:`profile_rate`)."""
        return max((profile_rate(p) for p in self.profiles), default=0.0)

    def knots(self, t_end: float) -> FloatArray:
        """Break points of the table profiles inside (0, t_end) [s]: each piece between
        them is a polynomial (the profiles are smooth between)."""
        pts = [np.asarray(p.times, dtype=float) for p in self.profiles if isinstance(p, Table)]
        if not pts:
            return np.zeros(0)
        k = np.unique(np.concatenate(pts))
        return k[(k > 0.0) & (k < t_end)]

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
    if isinstance(profile, Constant):
        return {"kind": "constant", "value": profile.val}
    if isinstance(profile, Polynomial):
        return {"kind": "polynomial", "coefficients": list(profile.coefficients)}
    if isinstance(profile, Harmonic):
        return {
            "kind": "harmonic",
            "mean": profile.mean,
            "amplitude": profile.amplitude,
            "frequency": profile.frequency,
            "phase": profile.phase,
        }
    if isinstance(profile, Table):
        return {
            "kind": "table",
            "t": list(profile.times),
            "values": list(profile.values),
            "interpolation": profile.interpolation,
        }
    raise TypeError(f"no JSON form for {profile!r}")


def load_to_dict(load: Load, L: float) -> dict[str, Any]:
    """The request JSON of a load (its echo in a result)."""
    if isinstance(load, PointForce):
        return {"kind": load.kind, "position": load.position, "force": profile_to_dict(load.force)}
    if isinstance(load, DistributedForce):
        return {
            "kind": load.kind,
            "intensity": profile_to_dict(load.intensity),
            "start": load.start,
            "end": L if load.end is None else load.end,
        }
    return {"kind": load.kind, "acceleration": profile_to_dict(load.acceleration)}
