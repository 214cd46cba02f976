"""Request and response models of a state-space realisation (``POST /v1/state-space``,
issue 32): the body of a frequency response without its frequencies (one operating
point), answered with the real matrices A, B, C, D of :func:`pipeflow.state_space.state_space`,
the names of the states, input and outputs, and their units.  What runs it is
:mod:`pipeflow.computations.frequency`.
"""

from __future__ import annotations

from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field, model_validator

from pipeflow.schema.frequency import (
    HAMMER_EXAMPLE,
    LoadSpec,
    ResidualFlexibility,
    ResponseSpec,
    check_point_and_stations,
    refuse_time_variant,
)
from pipeflow.schema.result_base import Result
from pipeflow.schema.simulation import Cost, PipeSpec
from pipeflow.schema.stability import (
    ConstantFlow,
    ConstantRotation,
    Modes,
    _Mounted,
)
from pipeflow.schema.supports import mounting_canonical

#: library parameter -> request field
STATE_SPACE_FIELDS: dict[str, str] = {
    "pipe": "pipe",
    "E": "pipe.E",
    "I": "pipe.I",
    "tip_mass": "pipe.tip_mass",
    "tip_inertia": "pipe.tip_inertia",
    "velocity": "flow.velocity.value",
    "omega0": "rotation.omega0.value",
    "modes": "modes",
    "load": "load.position",
    "positions": "response.positions",
    "quantity": "response.quantity",
}

#: the hammer example's body without its frequencies
STATE_SPACE_EXAMPLE: dict[str, Any] = {
    k: v for k, v in HAMMER_EXAMPLE.items() if k not in ("frequencies", "operating_points")
}


class StateSpaceSpec(_Mounted):
    """A state-space realisation z' = A z + B w, y = C z + D w at one frozen operating point."""

    model_config = ConfigDict(json_schema_extra={"examples": [STATE_SPACE_EXAMPLE]})

    pipe: PipeSpec
    flow: ConstantFlow = Field(
        default_factory=ConstantFlow, description="Constant flow velocity v [m/s]."
    )
    rotation: ConstantRotation = Field(
        default_factory=ConstantRotation,
        description="Constant spin w0 [rad/s] and the hub radius [m].",
    )
    modes: Modes = 10
    load: LoadSpec
    response: ResponseSpec
    residual_flexibility: ResidualFlexibility = None

    @model_validator(mode="before")
    @classmethod
    def _constant_profiles(cls, data: Any) -> Any:
        refuse_time_variant(data)
        return data

    @model_validator(mode="after")
    def _consistent(self) -> StateSpaceSpec:
        check_point_and_stations(self)
        return self.within_budget()

    def cost(self) -> Cost | None:
        """None: bounded by its fields (A is at most 80 x 80, C 64 x 80)."""
        return None

    def canonical(self) -> dict[str, Any]:
        """One shape for the cache key (defaults filled in)."""
        out: dict[str, Any] = {
            "pipe": self.pipe.model_dump(mode="json"),
            "rotation": {
                "omega0": {"kind": "constant", "value": self.rotation.omega0.value},
                "hub_radius": self.rotation.hub_radius,
            },
            "flow": {"velocity": {"kind": "constant", "value": self.flow.velocity.value}},
            "plane": self.plane,
            "modes": self.modes,
            "load": self.load.model_dump(mode="json"),
            "response": self.response.model_dump(mode="json"),
        }
        if self.residual_flexibility is not None:  # the default keeps earlier keys
            out["residual_flexibility"] = self.residual_flexibility
        mounting = mounting_canonical(self)
        if "flow" in mounting:
            out["flow"] |= mounting.pop("flow")
        return out | mounting


class StateSpaceUnits(BaseModel):
    time: str = Field(description="Time unit: s.")
    states: str = Field(
        description="Unit of the modal states: m (q'_j / w_j and q_j); a residual_lag state "
        "(residual flexibility with Kelvin-Voigt damping) has the input's unit."
    )
    inputs: str = Field(description="Unit of the input: N (point force) or m/s^2 (clamp).")
    outputs: str = Field(description="Unit of the outputs: m, m/s or m/s^2.")
    A: str = Field(description="Unit of A: 1/s.")
    B: str = Field(description="Unit of B.")
    C: str = Field(description="Unit of C.")
    D: str = Field(description="Unit of D.")


class StateSpaceResponse(Result):
    """z' = A z + B w, y = C z + D w: the modal model at a frozen operating point.  The
    transfer function C (i W I - A)^-1 B + D is the frequency response of the same body
    (the same ``residual_flexibility``, carried on displacement outputs); the eigenvalues
    of A [1/s] are the frozen spectrum (with Kelvin-Voigt damping and residual flexibility,
    and -1/alpha of the lag state)."""

    kind: Literal["state_space"] = Field(description="Result kind.")
    A: list[list[float]] = Field(
        description="State matrix (2n x 2n, one more with a residual_lag state) [1/s]."
    )
    B: list[list[float]] = Field(description="Input matrix (2n x 1) [m/(input unit s)].")
    C: list[list[float]] = Field(description="Output matrix (positions x 2n) [output unit/m].")
    D: list[list[float]] = Field(
        description="Feed-through (positions x 1) [output unit/input unit]: non-zero for "
        "acceleration outputs, and for displacement outputs with residual flexibility "
        "(without Kelvin-Voigt damping)."
    )
    states: list[str] = Field(
        description="State names: qdot_j/w_j (modal velocity over the j-th natural frequency "
        "without flow or spin) then q_j (Galerkin coordinate), all [m]."
    )
    inputs: list[str] = Field(description="Input name: F(x=a) [N] or clamp_acceleration.")
    outputs: list[str] = Field(description="Output names: u(x=...) and its time derivatives.")
    units: StateSpaceUnits = Field(description="Units of the signals and matrices (SI).")
    velocity: float = Field(description="Flow velocity v of the operating point [m/s].")
    omega0: float = Field(description="Spin w0 of the operating point [rad/s].")
    quantity: Literal["displacement", "velocity", "acceleration"] = Field(
        description="What the outputs are."
    )
    positions: list[float] = Field(description="Output positions x [m].")
    natural_frequencies: list[float] = Field(
        description="w_j [rad/s]: the balancing scales of the velocity states."
    )
