"""The request models of time profiles and external loads: the JSON forms of
:mod:`pipeflow.profiles` and :mod:`pipeflow.loads` (``kind``-discriminated unions), each
converting to its library object (``to_profile``, ``to_load``); the rules a load must
follow are the library's (:meth:`pipeflow.loads.PointForce.check`...), run by
:class:`pipeflow.schema.simulation.SimulationSpec`."""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import Field, model_validator

from pipeflow import profiles
from pipeflow.errors import InvalidField
from pipeflow.loads import BaseAcceleration, DistributedForce, Load, PointForce, PointImpulse
from pipeflow.schema.base import StrictModel

MAX_TABLE_POINTS = 10_000
MAX_POLY_DEGREE = 8
#: bounds on profile values (m/s for v, rad/s for w0, N for a force...)
MAX_PROFILE_VALUE = 1e7
MAX_COEFFICIENT = 1e9
BoundedValue = Annotated[float, Field(ge=-MAX_PROFILE_VALUE, le=MAX_PROFILE_VALUE)]


class ConstantProfile(StrictModel):
    """p(t) = value."""

    kind: Literal["constant"] = "constant"
    value: float = Field(
        0.0,
        ge=-MAX_PROFILE_VALUE,
        le=MAX_PROFILE_VALUE,
        description="Value, in the unit of the quantity (m/s or rad/s).",
    )

    def to_profile(self) -> profiles.Profile:
        return profiles.Constant(self.value)


class PolynomialProfile(StrictModel):
    """p(t) = sum_k coefficients[k] t^k with t in seconds (the paper's a, a t, a t^2)."""

    kind: Literal["polynomial"] = "polynomial"
    coefficients: list[Annotated[float, Field(ge=-MAX_COEFFICIENT, le=MAX_COEFFICIENT)]] = Field(
        min_length=1,
        max_length=MAX_POLY_DEGREE + 1,
        description="c_0, c_1, ...: c_k in (unit of the quantity)/s^k, e.g. m/s^(k+1) for v.",
    )

    def to_profile(self) -> profiles.Profile:
        return profiles.Polynomial(tuple(self.coefficients))


class HarmonicProfile(StrictModel):
    """p(t) = mean + amplitude sin(frequency t + phase): pulsating flow, oscillating spin."""

    kind: Literal["harmonic"] = "harmonic"
    mean: float = Field(
        0.0,
        ge=-MAX_PROFILE_VALUE,
        le=MAX_PROFILE_VALUE,
        description="Mean value (m/s for v, rad/s for w0).",
    )
    amplitude: float = Field(
        0.0,
        ge=-MAX_PROFILE_VALUE,
        le=MAX_PROFILE_VALUE,
        description="Amplitude (m/s for v, rad/s for w0).",
    )
    frequency: float = Field(0.0, ge=0, le=1e7, description="Angular frequency [rad/s].")
    phase: float = Field(0.0, ge=-1e3, le=1e3, description="Phase at t = 0 [rad].")

    def to_profile(self) -> profiles.Profile:
        return profiles.Harmonic(self.mean, self.amplitude, self.frequency, self.phase)


class TableProfile(StrictModel):
    """Tabulated values interpolated in time; must start at t <= 0 and cover t_end."""

    kind: Literal["table"] = "table"
    t: list[float] = Field(
        min_length=2, max_length=MAX_TABLE_POINTS, description="Strictly increasing times [s]."
    )
    values: list[BoundedValue] = Field(
        min_length=2, max_length=MAX_TABLE_POINTS, description="Values at those times."
    )
    interpolation: Literal["linear", "cubic", "pchip"] = Field(
        "linear", description="linear, cubic (not-a-knot spline) or pchip (monotone)."
    )
    after: Literal["hold", "zero"] | None = Field(
        None,
        description="What the profile does past its last time: 'hold' (keeps the last "
        "value), 'zero'; null (default): the table must cover the run (t_end).",
    )

    @model_validator(mode="after")
    def _check(self) -> TableProfile:
        if len(self.t) != len(self.values):
            raise InvalidField("t and values must have the same length", "t")
        if any(b <= a for a, b in zip(self.t, self.t[1:], strict=False)):
            raise InvalidField("t must be strictly increasing", "t")
        if self.t[0] > 0:
            raise InvalidField("the table must start at or before t = 0 s")
        return self

    def to_profile(self) -> profiles.Profile:
        return profiles.table(self.t, self.values, self.interpolation, self.after)


class HalfSineProfile(StrictModel):
    """A half-sine pulse: p(t) = peak sin(pi (t - start) / duration) on
    [start, start + duration], zero elsewhere (a hammer blow of finite duration)."""

    kind: Literal["half_sine"] = "half_sine"
    peak: float = Field(
        ge=-MAX_PROFILE_VALUE,
        le=MAX_PROFILE_VALUE,
        description="Peak value, in the unit of the quantity (N for a force).",
    )
    start: float = Field(0.0, ge=0, le=1e6, description="Start of the pulse [s].")
    duration: float = Field(gt=0, le=1e6, description="Duration of the pulse [s].")

    def to_profile(self) -> profiles.Profile:
        return profiles.HalfSine(self.peak, self.start, self.duration)


ProfileSpec = Annotated[
    ConstantProfile | PolynomialProfile | HarmonicProfile | TableProfile | HalfSineProfile,
    Field(discriminator="kind"),
]


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
