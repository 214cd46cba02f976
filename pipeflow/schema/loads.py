"""The request models of external loads: the JSON forms of :mod:`pipeflow.loads`
(a ``kind``-discriminated union), each converting to its library object (``to_load``);
the rules a load must follow are the library's (:meth:`pipeflow.loads.PointForce.check`...),
run by :class:`pipeflow.schema.simulation.SimulationSpec`.  Their time profiles are
:mod:`pipeflow.schema.profiles`."""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import Field

from pipeflow.loads import BaseAcceleration, DistributedForce, Load, PointForce, PointImpulse
from pipeflow.schema.base import StrictModel
from pipeflow.schema.profiles import MAX_PROFILE_VALUE, ProfileSpec


class PointForceLoad(StrictModel):
    """A transverse point force F(t) at x = position, in the plane of motion."""

    kind: Literal["point_force"]
    position: float = Field(
        gt=0,
        le=1e4,
        description="Station x of the force [m], 0 < x <= pipe.L (x = L: at the tip).",
    )
    force: ProfileSpec = Field(
        description="Force F(t) [N] (profile values in N, polynomial coefficients in "
        "N/s^k), transverse, in the plane of motion."
    )

    def to_load(self) -> Load:
        return PointForce(self.position, self.force.to_profile())


class DistributedForceLoad(StrictModel):
    """A uniform transverse load q(t) per unit length on [start, end]."""

    kind: Literal["distributed_force"]
    intensity: ProfileSpec = Field(
        description="Load per unit length q(t) [N/m] (profile values in N/m), transverse, "
        "in the plane of motion, uniform on [start, end]."
    )
    start: float = Field(0.0, ge=0, le=1e4, description="Start x0 of the loaded span [m].")
    end: float | None = Field(
        None,
        gt=0,
        le=1e4,
        description="End x1 of the loaded span [m], start < x1 <= pipe.L; null (default): "
        "the tip, x1 = L.",
    )

    def to_load(self) -> Load:
        return DistributedForce(self.intensity.to_profile(), self.start, self.end)


class BaseAccelerationLoad(StrictModel):
    """The transverse acceleration of the clamp; displacements are relative to it."""

    kind: Literal["base_acceleration"]
    acceleration: ProfileSpec = Field(
        description="Transverse acceleration a(t) of the clamp [m/s^2] (profile values in "
        "m/s^2), in the plane of motion. Acts as the inertial load -(M1 + M2) a(t) per unit "
        "length plus -m_t a(t) on the tip mass; the returned displacements are relative to "
        "the clamp."
    )

    def to_load(self) -> Load:
        return BaseAcceleration(self.acceleration.to_profile())


class PointImpulseLoad(StrictModel):
    """A transverse impulse (hammer blow) J at x = position at time t0."""

    kind: Literal["impulse"]
    position: float = Field(
        gt=0,
        le=1e4,
        description="Station x of the blow [m], 0 < x <= pipe.L (x = L: at the tip).",
    )
    impulse: float = Field(
        ge=-MAX_PROFILE_VALUE,
        le=MAX_PROFILE_VALUE,
        description="Impulse J [N s] (the time integral of the force), transverse, in the "
        "plane of motion: a jump of the modal velocities at t0.",
    )
    time: float = Field(
        0.0,
        ge=0,
        le=1e6,
        description="Time t0 of the blow [s]; samples at t >= t0 include it.",
    )

    def to_load(self) -> Load:
        return PointImpulse(self.position, self.impulse, self.time)


LoadSpec = Annotated[
    PointForceLoad | DistributedForceLoad | BaseAccelerationLoad | PointImpulseLoad,
    Field(discriminator="kind"),
]
