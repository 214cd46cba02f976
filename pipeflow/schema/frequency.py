"""Request model of a frequency response (``POST /v1/frequency-responses``, issue 18).

:class:`FrequencyResponseSpec` is the body: the pipe (every field of the simulation and
stability schemas: damping, tip body, hub radius, plane), one operating point (constant
``flow.velocity`` [m/s] and ``rotation.omega0`` [rad/s], as in the stability requests) or a
list of them (``operating_points``), the ``load`` (a point force or the clamp's
acceleration), the ``response`` wanted (positions [m] and quantity) and the ``frequencies``
[rad/s] (a range, to which the resonances are added, or an explicit list answered at exactly
those values).  What runs it (:func:`pipeflow.frequency.frequency_response` at each
operating point) and writes its document is :mod:`pipeflow.computations.frequency`.

Same conventions as :mod:`pipeflow.schema.stability`: strict models, units in every
description, bounds on everything a request can spend (:data:`MAX_FRF_VALUES`),
:meth:`FrequencyResponseSpec.canonical` for the cache key (one shape: the operating points
as a list, a range's or a list's fields only), refusals naming the request field.
"""

from __future__ import annotations

from typing import Annotated, Any, Literal

from pydantic import ConfigDict, Field, model_validator

from pipeflow.errors import InvalidField
from pipeflow.frequency import (
    MAX_FREQUENCIES,
    MAX_GRID_POINTS,
    MAX_LOAD_VECTORS,
    MAX_OPERATING_POINTS,
    QUANTITIES,
    UNITS,
    BaseAcceleration,
    Load,
    PointForce,
)
from pipeflow.paper import PAPER_PIPE_JSON
from pipeflow.schema.simulation import Cost, PipeSpec, StrictModel
from pipeflow.schema.stability import (
    MAX_SPEED,
    MAX_SPIN,
    ConstantFlow,
    ConstantRotation,
    Modes,
    _Mounted,
)
from pipeflow.schema.supports import mounting_canonical

#: the most output positions of one request
MAX_FRF_POSITIONS = 64
#: the most numbers H of one answer: positions x frequencies x operating points
MAX_FRF_VALUES = 1_000_000
#: the highest frequency a request may ask for [rad/s]
MAX_FREQUENCY = 1e7
#: points a resonance adds to a range (its damped frequency and two half-power points)
POINTS_PER_RESONANCE = 3

#: library parameter -> request field (pipeflow.frequency's names)
FREQUENCY_FIELDS: dict[str, str] = {
    "pipe": "pipe",
    "E": "pipe.E",
    "I": "pipe.I",
    "tip_mass": "pipe.tip_mass",
    "tip_inertia": "pipe.tip_inertia",
    "velocity": "operating_points",
    "omega0": "operating_points",
    "modes": "modes",
    "load": "load.position",
    "positions": "response.positions",
    "quantity": "response.quantity",
    "frequencies": "frequencies",
    "w_min": "frequencies.min",
    "count": "frequencies.count",
    "spacing": "frequencies.spacing",
}

Frequency = Annotated[float, Field(ge=0, le=MAX_FREQUENCY)]


class HarmonicPointForce(StrictModel):
    """A transverse harmonic point force F e^(i W t); H is per unit force [N]."""

    kind: Literal["point_force"] = "point_force"
    position: float = Field(
        gt=0,
        le=1e4,
        description="Where the force acts, x [m] in (0, L]; at L it acts on the tip body "
        "(a hammer test at the tip).",
        examples=[0.025],
    )

    def to_load(self) -> Load:
        return PointForce(self.position)


class HarmonicBaseAcceleration(StrictModel):
    """A transverse harmonic acceleration A e^(i W t) [m/s^2] of the clamp (shaker test); H
    is per unit base acceleration and the response is relative to the clamp."""

    kind: Literal["base_acceleration"] = "base_acceleration"

    def to_load(self) -> Load:
        return BaseAcceleration()


LoadSpec = Annotated[
    HarmonicPointForce | HarmonicBaseAcceleration,
    Field(
        discriminator="kind",
        description="The harmonic load: 'point_force' at a position [m] (H per newton) or "
        "'base_acceleration' of the clamp (H per m/s^2, motion relative to the clamp).",
    ),
]


class ResponseSpec(StrictModel):
    """Where and what: the response at each position, as displacement, velocity or
    acceleration per unit load."""

    positions: list[Annotated[float, Field(gt=0, le=1e4)]] = Field(
        min_length=1,
        max_length=MAX_FRF_POSITIONS,
        description="Positions x along the pipe [m], each in (0, L], in the order wanted. "
        "Many positions along the pipe give the operating deflection shape (amplitude and "
        "phase along the pipe at each frequency; plot 'deflection_shape').",
        examples=[[0.025]],
    )
    quantity: Literal[tuple(QUANTITIES)] = Field(  # type: ignore[valid-type]
        "displacement",
        description="'displacement' (receptance [m/N]; per unit base acceleration [s^2]), "
        "'velocity' (mobility i W H [m/(N s)]; [s]) or 'acceleration' (accelerance -W^2 H "
        "[1/kg]; [-]), per unit load.",
    )


class FrequencySpec(StrictModel):
    """The excitation frequencies W [rad/s]: either a range (``min``, ``max``, ``count``,
    ``spacing``; the operating points' resonances inside it are added, each with its two
    half-power points, so that no peak falls between grid points) or an explicit list
    (``values``, answered at exactly those values)."""

    min: float | None = Field(
        None,
        ge=0,
        le=MAX_FREQUENCY,
        description="Lowest frequency of the range [rad/s] (> 0 for a log spacing).",
    )
    max: float | None = Field(
        None, gt=0, le=MAX_FREQUENCY, description="Highest frequency of the range [rad/s]."
    )
    count: int = Field(
        1000,
        ge=2,
        le=MAX_GRID_POINTS,
        description="Points of the range [-], before the resonances are added.",
    )
    spacing: Literal["linear", "log"] = Field(
        "linear", description="'linear' or 'log' (logarithmic) spacing of the range."
    )
    values: list[Frequency] | None = Field(
        None,
        min_length=1,
        max_length=MAX_GRID_POINTS,
        description="Explicit frequencies [rad/s] >= 0, answered at exactly these values in "
        "this order (instead of min, max, count and spacing).",
    )

    @model_validator(mode="after")
    def _one_form(self) -> FrequencySpec:
        given = self.model_fields_set & {"min", "max", "count", "spacing"}
        if self.values is not None:
            if given:
                raise InvalidField(
                    f"give either values or a range (min, max, count, spacing), not both "
                    f"(got values and {', '.join(sorted(given))})",
                    "values",
                )
            return self
        if self.min is None or self.max is None:
            missing = "min" if self.min is None else "max"
            raise InvalidField(
                "give a range (min and max [rad/s], count, spacing) or a list of values",
                missing,
            )
        if not self.min < self.max:
            raise InvalidField(
                f"min must be below max: got min = {self.min} >= max = {self.max} rad/s", "min"
            )
        if self.spacing == "log" and self.min <= 0:
            raise InvalidField("a log spacing needs min > 0 rad/s", "min")
        return self

    def canonical(self) -> dict[str, Any]:
        """Only the fields of the form given (the range's, or the values)."""
        if self.values is not None:
            return {"values": list(self.values)}
        return {"min": self.min, "max": self.max, "count": self.count, "spacing": self.spacing}


class OperatingPoint(StrictModel):
    """One frozen operating point: constant flow velocity and spin."""

    velocity: float = Field(
        ge=-MAX_SPEED,
        le=MAX_SPEED,
        description="Constant flow velocity v [m/s]; v > 0 flows from the clamped end to the "
        "tip (v < 0: reverse flow, answered with the aspirating-pipe caveat).",
    )
    omega0: float = Field(ge=-MAX_SPIN, le=MAX_SPIN, description="Constant spin w0 [rad/s].")


#: the paper's pipe, a hammer test at the tip at w0 = 100 rad/s and v = 5 m/s (README)
HAMMER_EXAMPLE: dict[str, Any] = {
    "pipe": dict(PAPER_PIPE_JSON),
    "flow": {"velocity": {"kind": "constant", "value": 5.0}},
    "rotation": {"omega0": {"kind": "constant", "value": 100.0}},
    "modes": 10,
    "load": {"kind": "point_force", "position": 0.025},
    "response": {"positions": [0.025], "quantity": "displacement"},
    "frequencies": {"min": 10.0, "max": 8000.0, "count": 2000, "spacing": "log"},
}

#: the same pipe and load at four flow velocities (a waterfall of operating points)
WATERFALL_EXAMPLE: dict[str, Any] = {
    "pipe": dict(PAPER_PIPE_JSON),
    "operating_points": [{"velocity": v, "omega0": 100.0} for v in (0.0, 5.0, 10.0, 20.0)],
    "modes": 10,
    "load": {"kind": "point_force", "position": 0.025},
    "response": {"positions": [0.025]},
    "frequencies": {"min": 10.0, "max": 8000.0, "count": 1000, "spacing": "log"},
}

_FROZEN = (
    "a frequency response is taken at a frozen operating point: give a constant profile "
    "({{'kind': 'constant', 'value': ...}}) or operating_points, not a {kind!r} profile "
    "(time-variant flow or spin: run a simulation)"
)


def refuse_time_variant(data: Any) -> None:
    """A time-variant profile of a frozen-point request is refused by name, not as a tag
    mismatch (the raw body, before validation)."""
    if isinstance(data, dict):
        for group, name in (("flow", "velocity"), ("rotation", "omega0")):
            block = data.get(group)
            prof = block.get(name) if isinstance(block, dict) else None
            kind = prof.get("kind") if isinstance(prof, dict) else None
            if isinstance(kind, str) and kind != "constant":
                raise InvalidField(_FROZEN.format(kind=kind), f"{group}.{name}")


def check_point_and_stations(spec: Any) -> None:
    """The frozen operating point within its bounds (flow.velocity [m/s], rotation.omega0
    [rad/s]) and the response positions and a point load's position on the pipe (0, L] [m],
    each refusal naming its field: one rule for frequency responses and state space."""
    if abs(spec.flow.velocity.value) > MAX_SPEED:
        raise InvalidField(
            f"flow.velocity must lie within +-{MAX_SPEED:g} m/s", "flow.velocity.value"
        )
    if abs(spec.rotation.omega0.value) > MAX_SPIN:
        raise InvalidField(
            f"rotation.omega0 must lie within +-{MAX_SPIN:g} rad/s", "rotation.omega0.value"
        )
    L = spec.pipe.L
    for i, x in enumerate(spec.response.positions):
        if x > L:
            raise InvalidField(
                f"response.positions[{i}] = {x} m is outside (0, L = {L} m]",
                "response.positions",
            )
    if isinstance(spec.load, HarmonicPointForce) and spec.load.position > L:
        raise InvalidField(
            f"load.position = {spec.load.position} m is outside (0, L = {L} m]",
            "load.position",
        )


#: the residual flexibility option of the frequency response and the state space
ResidualFlexibility = Annotated[
    bool | None,
    Field(
        description="Add the static response of the modes left out (the static deflection "
        "of the continuous pipe minus its part in the modes; per unit load, m/N or s^2): "
        "exact at W = 0 and, without flow, the drive-point receptance to ~1e-8 at 10 modes "
        "instead of ~5e-4. null (default): applied without flow, without a tip rotary "
        "inertia and at a stable point, where it is measured better; with flow it is "
        "measured worse above the first resonance (use load_vectors there). "
        "true / false force it on / off. A state space carries it on displacement outputs "
        "only (as the feed-through D, or with Kelvin-Voigt damping one lag state).",
    ),
]


class FrequencyResponseSpec(_Mounted):
    """Frequency response functions of the pipe at one or several frozen operating points."""

    model_config = ConfigDict(json_schema_extra={"examples": [HAMMER_EXAMPLE]})

    pipe: PipeSpec
    flow: ConstantFlow = Field(
        default_factory=ConstantFlow,
        description="Constant flow velocity of the one operating point (or operating_points).",
    )
    rotation: ConstantRotation = Field(
        default_factory=ConstantRotation,
        description="Constant spin w0 [rad/s] of the one operating point (or operating_points) "
        "and the hub radius [m] (which applies to every point).",
    )
    operating_points: list[OperatingPoint] | None = Field(
        None,
        min_length=1,
        max_length=MAX_OPERATING_POINTS,
        description=f"Several operating points (at most {MAX_OPERATING_POINTS}), each "
        "{velocity [m/s], omega0 [rad/s]}, instead of flow.velocity and rotation.omega0; "
        "the answer has one block per point, in this order, all at the same frequencies.",
    )
    modes: Modes = 10
    load: LoadSpec
    response: ResponseSpec
    frequencies: FrequencySpec
    residual_flexibility: ResidualFlexibility = None
    load_vectors: int = Field(
        0,
        ge=0,
        le=MAX_LOAD_VECTORS,
        description="Load-dependent Ritz vectors added to the modes [-]: the continuous "
        "pipe's static response to the load, then to that response's inertia "
        "(pipeflow.enrichment). The remedy with flow, where the modes alone converge slowly "
        "for a force at the free end: 2 vectors at 10 modes bring a tip force at v = 10 m/s "
        "from ~7e-3 to ~1e-5 of the exact response up to the third resonance, exact at W = 0. "
        "Excludes residual_flexibility true (the first vector is that static response); "
        "about 1.5 ms more per operating point (3-4x the plain response at 10-20 modes).",
    )

    @model_validator(mode="before")
    @classmethod
    def _constant_profiles(cls, data: Any) -> Any:
        refuse_time_variant(data)
        return data

    @model_validator(mode="after")
    def _consistent(self) -> FrequencyResponseSpec:
        if self.operating_points is not None:
            # the flow block may still carry the pressure, which applies to every point
            velocity_given = "velocity" in self.flow.model_fields_set
            if velocity_given or "omega0" in self.rotation.model_fields_set:
                raise InvalidField(
                    "give operating_points or flow.velocity and rotation.omega0, not both",
                    "operating_points",
                )
        check_point_and_stations(self)
        self._check_frequencies()
        if self.load_vectors and self.residual_flexibility:
            raise InvalidField(
                "load_vectors and residual_flexibility true exclude each other: the first "
                "load vector is the static response the residual flexibility adds",
                "load_vectors",
            )
        return self.within_budget()

    def points(self) -> list[tuple[float, float]]:
        """The operating points (v [m/s], w0 [rad/s]), in order."""
        if self.operating_points is None:
            return [(self.flow.velocity.value, self.rotation.omega0.value)]
        return [(p.velocity, p.omega0) for p in self.operating_points]

    def frequency_bound(self) -> int:
        """The most frequencies the answer can have: the list's length, or the range's count
        plus 3 points per resonance of every operating point."""
        f = self.frequencies
        if f.values is not None:
            return len(f.values)
        return f.count + POINTS_PER_RESONANCE * self.modes * len(self.points())

    def _check_frequencies(self) -> None:
        f = self.frequencies
        where = "frequencies.values" if f.values is not None else "frequencies.count"
        n_freq = self.frequency_bound()
        if n_freq > MAX_FREQUENCIES:
            raise InvalidField(
                f"count + {POINTS_PER_RESONANCE} x modes x operating points (the resonance "
                f"points added to the range) is {n_freq}, over {MAX_FREQUENCIES}: lower "
                "count, modes or the number of operating points",
                where,
            )

    def cost(self) -> Cost:
        """The numbers H of the answer: positions x frequencies (:meth:`frequency_bound`)
        x operating points against :data:`MAX_FRF_VALUES`, naming the frequencies."""
        f = self.frequencies
        where = "frequencies.values" if f.values is not None else "frequencies.count"
        positions, points = len(self.response.positions), len(self.points())
        n_freq = self.frequency_bound()
        per_frequency = max(1, positions * points)
        if f.values is not None:
            advice = f"at most {MAX_FRF_VALUES // per_frequency} frequencies"
        else:
            extra = POINTS_PER_RESONANCE * self.modes * points
            advice = f"count at most {MAX_FRF_VALUES // per_frequency - extra}"
        return Cost(
            units=positions * n_freq * points,
            bound=MAX_FRF_VALUES,
            unit="values",
            fields=(where, "response.positions", "operating_points"),
            terms=f"{positions} response.positions x {n_freq} frequencies x {points} "
            "operating points",
            budget="response budget",
            advice=f"{advice} with these positions and operating points (or fewer positions "
            "or points)",
        )

    def canonical(self) -> dict[str, Any]:
        """One shape for the cache key: the operating points always as a list, the hub
        radius, and only the frequency form given (defaults filled in)."""
        out = {
            "pipe": self.pipe.model_dump(mode="json"),
            "rotation": {"hub_radius": self.rotation.hub_radius},
            "plane": self.plane,
            "operating_points": [{"velocity": v, "omega0": w} for v, w in self.points()],
            "modes": self.modes,
            "load": self.load.model_dump(mode="json"),
            "response": self.response.model_dump(mode="json"),
            "frequencies": self.frequencies.canonical(),
        }
        if self.residual_flexibility is not None:  # the default keeps earlier keys
            out["residual_flexibility"] = self.residual_flexibility
        if self.load_vectors:  # (none: the key of a request from before the field)
            out["load_vectors"] = self.load_vectors
        out |= mounting_canonical(self)
        return out


__all__ = [
    "FREQUENCY_FIELDS",
    "HAMMER_EXAMPLE",
    "MAX_FRF_POSITIONS",
    "MAX_FRF_VALUES",
    "UNITS",
    "FrequencyResponseSpec",
]
