"""Request models of the time functions of a request, v(t), w0(t) and a load's F(t):
constant, polynomial, harmonic, a half-sine pulse or tabulated (re-exported by
:mod:`pipeflow.schema.simulation`, where they were defined before).  Each model's
:meth:`to_profile` gives the library's :class:`~pipeflow.profiles.Profile`."""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import Field, model_validator

from pipeflow import profiles
from pipeflow.errors import InvalidField
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
        # absent from the normal form when absent from the request: the cache keys of the
        # tables sent before the field existed stay what they were
        exclude_if=lambda after: after is None,
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
