"""The request fields of a pipe's supports and axial loads (issue 31): ``pipe.supports``,
``pipe.intermediate_supports``, ``pipe.tension``, ``pipe.flow_area``, ``pipe.poisson`` and
``pipe.axially_restrained`` (library: :mod:`pipeflow.supports`, ``docs/supports.md``).

:class:`MountingFields` is a base of :class:`~pipeflow.schema.simulation.PipeSpec`, so every
computation kind that takes a pipe takes them.  Left at their defaults they are dropped from
the serialised pipe, so the canonical form (and the cache key) of a request that leaves them
out is the one it had before they existed.
"""

from __future__ import annotations

from typing import Annotated, Any, Literal

from pydantic import Field, field_validator, model_validator

from pipeflow.errors import InvalidField
from pipeflow.schema.base import StrictModel
from pipeflow.schema.profiles import (
    MAX_TABLE_POINTS,
    ConstantProfile,
    HalfSineProfile,
    HarmonicProfile,
    PolynomialProfile,
    TableProfile,
)
from pipeflow.supports import MAX_INTERMEDIATE, PointSupport, Support, Supports

#: the largest spring stiffness accepted [N/m or N m/rad]: far stiffer than any support
#: (the basis treats K = k L^3/EI above ~1e12 as rigid to rounding)
MAX_SPRING = 1e15
#: the largest |tension| [N]
MAX_TENSION = 1e12

Kind = Literal["clamped", "pinned", "sliding", "free"]


class ElasticSupport(StrictModel):
    """An elastic end: translational and rotational springs (a missing part is 0)."""

    translational: float = Field(
        0.0, ge=0, le=MAX_SPRING, description="Translational spring k_t [N/m] (0: none)."
    )
    rotational: float = Field(
        0.0, ge=0, le=MAX_SPRING, description="Rotational spring k_r [N m/rad] (0: none)."
    )


EndSupport = Kind | ElasticSupport
END_DESCRIPTION = (
    "'clamped' (w = w' = 0), 'pinned' (w = 0, no moment), 'sliding' (w' = 0, no shear), "
    "'free', or {'translational': k_t [N/m], 'rotational': k_r [N m/rad]} (elastic)."
)


class SupportsSpec(StrictModel):
    """The end supports: x0 at x = 0 (the hub end), xL at x = L."""

    x0: EndSupport = Field("clamped", description="Support at x = 0: " + END_DESCRIPTION)
    xL: EndSupport = Field("free", description="Support at x = L: " + END_DESCRIPTION)

    def to_supports(self) -> Supports:
        def one(s: EndSupport) -> Support:
            if isinstance(s, ElasticSupport):
                return Support("elastic", s.translational, s.rotational)
            return Support(s)

        return Supports(one(self.x0), one(self.xL))


class IntermediateSupportSpec(StrictModel):
    """A point support inside the span: a translational spring or a rigid pin."""

    position: float = Field(gt=0, le=1e4, description="Position x, 0 < x < L [m].")
    translational: float | None = Field(
        None,
        ge=0,
        le=MAX_SPRING,
        description="Spring stiffness k [N/m] (or give kind); k L^3 / EI >= 1e10 is computed "
        "as a rigid pin (its frequencies differ from the pin's by under 1e-8).",
    )
    kind: Literal["pinned"] | None = Field(
        None, description="'pinned': a rigid point support w(x) = 0 (or give translational)."
    )

    @model_validator(mode="after")
    def _one(self) -> IntermediateSupportSpec:
        if (self.translational is None) == (self.kind is None):
            raise InvalidField("give exactly one of translational [N/m] or kind 'pinned'", ())
        return self

    def to_point(self) -> PointSupport:
        if self.kind == "pinned":
            return PointSupport(self.position, pinned=True)
        return PointSupport(self.position, translational=float(self.translational or 0.0))


class MountingFields(StrictModel):
    """Supports and axial loads of a pipe (a base of the request's pipe)."""

    supports: SupportsSpec = Field(
        default_factory=SupportsSpec,
        exclude_if=lambda v: v == SupportsSpec(),
        description="End supports {x0, xL}; default clamped at x = 0, free at x = L (the "
        "cantilever). A tip mass needs a free or elastic end at x = L.",
    )
    intermediate_supports: list[IntermediateSupportSpec] = Field(
        default_factory=list,
        exclude_if=lambda v: not v,
        max_length=MAX_INTERMEDIATE,
        description=f"Up to {MAX_INTERMEDIATE} point supports inside the span, each "
        "{position [m], translational [N/m]} or {position [m], kind: 'pinned'}.",
    )
    tension: float = Field(
        0.0,
        exclude_if=lambda v: v == 0.0,
        ge=-MAX_TENSION,
        le=MAX_TENSION,
        description="Axial pre-tension T [N] (negative: compression; beyond buckling the "
        "spectrum says divergence at rest).",
    )
    flow_area: float = Field(
        0.0,
        exclude_if=lambda v: v == 0.0,
        ge=0,
        le=1e4,
        description="Flow cross-section A [m^2]: the internal pressure's force is p A.",
    )
    poisson: float = Field(
        0.3,
        gt=-1,
        le=0.5,
        exclude_if=lambda v: v == 0.3,
        description="Poisson's ratio nu of the pipe wall [-].",
    )
    axially_restrained: bool = Field(
        False,
        exclude_if=lambda v: not v,
        description="Both ends axially fixed (delta = 1 in p A (1 - 2 nu delta)); the "
        "gravity and centrifugal axial forces are then shared by both ends. Not with a free end.",
    )

    def mounting(self) -> dict[str, Any]:
        """The :class:`~pipeflow.model.Pipe` keyword arguments of these fields."""
        return {
            "supports": self.supports.to_supports(),
            "intermediate_supports": tuple(p.to_point() for p in self.intermediate_supports),
            "tension": self.tension,
            "flow_area": self.flow_area,
            "poisson": self.poisson,
            "axially_restrained": self.axially_restrained,
        }


def check_pipe(build: Any) -> None:
    """Build the library pipe (``build()``) and answer its refusal of a mounting as an
    :class:`InvalidField` naming the field (``pipe.tip_mass: ...`` -> ``tip_mass``)."""
    try:
        build()
    except InvalidField:
        raise
    except ValueError as exc:
        text = str(exc)
        head = text.split(":")[0].split(" ")[0]
        loc = head.removeprefix("pipe.") if head.startswith("pipe.") else ()
        raise InvalidField(text, loc) from None


class GravitySpec(StrictModel):
    """Gravity along the pipe's axis (Paidoussis vol. 1, sec. 3.5.3; Gregory & Paidoussis
    1966)."""

    g: float = Field(9.81, gt=0, le=1e3, description="Acceleration of gravity g [m/s^2].")
    orientation: Literal["hanging", "standing"] = Field(
        "hanging",
        description="'hanging': the pipe hangs from x = 0, gravity points from x = 0 to L "
        "(tension (m (L - x) + m_t) g); 'standing': the opposite (compression).",
    )

    def along_x(self) -> float:
        """The component of gravity along +x [m/s^2]."""
        return self.g if self.orientation == "hanging" else -self.g


class GravityField(StrictModel):
    """The top-level ``gravity`` of a request (absent: none; then dropped from the canonical
    form, so requests without it keep their cache key)."""

    gravity: GravitySpec | None = Field(
        None,
        exclude_if=lambda v: v is None,
        description="Gravity along the pipe: {g [m/s^2], orientation 'hanging' | 'standing'}; "
        "absent: none. Acts on pipe and fluid, (M1 + M2) g, and on the tip mass.",
    )

    def gravity_along_x(self) -> float:
        """g_x [m/s^2] for :class:`~pipeflow.model.Pipe` (0 without gravity)."""
        return 0.0 if self.gravity is None else self.gravity.along_x()


#: the largest |internal pressure| [Pa] (1e10: far above any pipe's burst pressure)
MAX_PRESSURE = 1e10


class FlowPressure(StrictModel):
    """The flow block's internal pressure (a base of every request's ``flow``)."""

    pressure: float = Field(
        0.0,
        ge=-MAX_PRESSURE,
        le=MAX_PRESSURE,
        exclude_if=lambda v: v == 0.0,
        description="Internal gauge pressure p [Pa], constant in time (needs pipe.flow_area); "
        "its force p A (1 - 2 nu delta) compresses the pipe like the flow's M v^2, except at "
        "a free, discharging end x = L, where it cancels (docs/model.md 9).",
    )


_PRESSURE_VALUE = Field(
    0.0, ge=-MAX_PRESSURE, le=MAX_PRESSURE, description="Value, internal gauge pressure [Pa]."
)


class PressureConstant(ConstantProfile):
    """p(t) = value [Pa] (the same request as the plain number)."""

    value: float = _PRESSURE_VALUE


class PressureHarmonic(HarmonicProfile):
    """p(t) = mean + amplitude sin(frequency t + phase) [Pa]: a pulsating pressure."""

    mean: float = Field(0.0, ge=-MAX_PRESSURE, le=MAX_PRESSURE, description="Mean pressure [Pa].")
    amplitude: float = Field(0.0, ge=-MAX_PRESSURE, le=MAX_PRESSURE, description="Amplitude [Pa].")


class PressureTable(TableProfile):
    """Tabulated pressures [Pa] interpolated in time."""

    values: list[Annotated[float, Field(ge=-MAX_PRESSURE, le=MAX_PRESSURE)]] = Field(
        min_length=2, max_length=MAX_TABLE_POINTS, description="Pressures at those times [Pa]."
    )


class PressureHalfSine(HalfSineProfile):
    """A half-sine pressure pulse [Pa] (a water hammer of finite duration)."""

    peak: float = Field(ge=-MAX_PRESSURE, le=MAX_PRESSURE, description="Peak pressure [Pa].")


#: a time profile of the internal pressure: the profiles of every time function, with the
#: pressure's bounds (|p| <= MAX_PRESSURE) on their values
PressureProfileSpec = Annotated[
    PressureConstant | PolynomialProfile | PressureHarmonic | PressureTable | PressureHalfSine,
    Field(discriminator="kind"),
]


class FlowPressureProfile(StrictModel):
    """The flow block's internal pressure for a run in time: constant or a profile."""

    pressure: Annotated[float, Field(ge=-MAX_PRESSURE, le=MAX_PRESSURE)] | PressureProfileSpec = (
        Field(
            0.0,
            exclude_if=lambda v: v == 0.0,
            description="Internal gauge pressure p(t) [Pa] (needs pipe.flow_area): a number "
            "(constant) or a profile of time like the flow velocity's; its force "
            "p A (1 - 2 nu delta) compresses the pipe like the flow's M v^2, except at a free, "
            "discharging end x = L, where it cancels (docs/model.md 9).",
        )
    )

    @field_validator("pressure", mode="after")
    @classmethod
    def _constant_is_a_number(cls, value: Any) -> Any:
        # a constant profile is the same request as its number (the same key)
        return float(value.value) if isinstance(value, PressureConstant) else value

    @property
    def pressure_profile(self) -> Any:
        """The pressure's profile model when it varies in time, else None."""
        return None if isinstance(self.pressure, float | int) else self.pressure

    @property
    def constant_pressure(self) -> float:
        """The constant pressure [Pa] (0 when it varies in time: the profile carries it)."""
        return float(self.pressure) if isinstance(self.pressure, float | int) else 0.0


def mounting_canonical(spec: Any) -> dict[str, Any]:
    """The top-level ``gravity`` and the flow's ``pressure`` of ``spec`` for a request kind
    whose :meth:`canonical` lists its fields by hand (frequency responses, state space):
    ``{"gravity": {...}, "flow": {"pressure": p}}``, each only when set, so a request
    without them keeps its key and two requests that differ in them never share one."""
    out: dict[str, Any] = {}
    if getattr(spec, "gravity", None) is not None:
        out["gravity"] = spec.gravity.model_dump(mode="json")
    pressure = getattr(getattr(spec, "flow", None), "pressure", 0.0)
    if pressure:
        out["flow"] = {"pressure": pressure}
    return out


def check_pressure(pipe: Any, flow: Any) -> None:
    """Refuse a pressure without the flow area it acts on (names ``pipe.flow_area``)."""
    if getattr(flow, "pressure", 0.0) and not pipe.flow_area:
        raise InvalidField(
            "flow.pressure needs pipe.flow_area, the flow cross-section A [m^2] "
            "(the pressure's force is p A)",
            "pipe.flow_area",
        )


#: the new fields' defaults, which the dump leaves out (exclude_if): a study varies them
MOUNTING_DEFAULTS: dict[str, Any] = {
    "tension": 0.0,
    "flow_area": 0.0,
    "poisson": 0.3,
}


def with_defaults(spec: Any, full: dict[str, Any]) -> dict[str, Any]:
    """``full`` (a request's JSON dump) with the numeric defaults of these fields put back
    (``pipe.tension``, ``pipe.flow_area``, ``pipe.poisson``, ``flow.pressure``), so that a
    study may vary them by path like every numeric field."""
    out = dict(full)
    if isinstance(out.get("pipe"), dict):
        out["pipe"] = {**MOUNTING_DEFAULTS, **out["pipe"]}
    flow = getattr(spec, "flow", None)
    if isinstance(flow, FlowPressure):
        out["flow"] = {"pressure": 0.0, **out.get("flow", {})}
    return out
