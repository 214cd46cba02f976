"""Request models of the stability analyses (what runs them: computations.stability).

- ``POST /v1/stability``: :class:`StabilitySpec` (critical flow velocity at constant spin:
  every crossing of the stability boundary).
- ``POST /v1/sweeps``: one of the :data:`SweepModel` kinds, told apart by ``kind``:
  ``argand`` (eigenvalues against flow velocity), ``campbell`` (against spin),
  ``spin_map`` (critical velocity against spin), ``beta_map`` (u_cr(beta), non-dimensional),
  ``resonance_chart`` (Floquet chart of pulsating flow) and ``floquet`` (one periodic case).

Same conventions as :mod:`pipeflow.schema.simulation`: strict pydantic models with units in
every description, bounds on everything a request can spend, :meth:`canonical` (defaults
filled in) for the cache key.  How each runs (the plain library call and its document) is
:mod:`pipeflow.computations.stability`.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Annotated, Any, Literal, Self

import numpy as np
from pydantic import AliasChoices, ConfigDict, Field, Strict, model_validator

from pipeflow.basis import MAX_MODES
from pipeflow.errors import InvalidField
from pipeflow.model import GROUPS, Pipe
from pipeflow.paper import PAPER_PIPE_JSON
from pipeflow.schema.simulation import (
    ConstantProfile,
    Cost,
    HarmonicProfile,
    HubRadius,
    PipeSpec,
    Plane,
    StrictModel,
    library_check,
)
from pipeflow.schema.supports import FlowPressure, GravityField, check_pressure
from pipeflow.stability.floquet import (
    MAX_CHART_WORK,
    chart_work,
    period_of,
)
from pipeflow.stability.maps import MAX_MAP_WORK

#: the paper's section-5 pipe, for the schema examples
#: (E, I, L, M1, M2 only: the paper's pipe needs none of the fields beyond its model)
MAX_SWEEP_POINTS = 2001
MAX_MAP_SIDE = 200
MAX_CHART_SIDE = 101
MAX_CHART_MODES = 12
MAX_FLOQUET_MODES = 20
#: |v| [m/s] and |w0| [rad/s] bounds (far beyond any physical pipe; they keep numbers finite)
MAX_SPEED = 1e6
MAX_SPIN = 1e7


#: library parameter -> request field where they differ (the stability specs otherwise use
#: the library's names: modes, velocity_range, points, tolerance...)
STABILITY_FIELDS: dict[str, str] = {
    "flow": "flow.velocity",
    "tip_mass": "pipe.tip_mass",
    "tip_inertia": "pipe.tip_inertia",
    "spin": "rotation.omega0",
    "omega0": "rotation.omega0",
    "E": "pipe.E",
    "I": "pipe.I",
}


def spectrum_cost(points: int, modes: int, fields: tuple[str, ...], what: str) -> Cost:
    """``points`` eigenvalue problems of size 2 ``modes``: points x (2 modes)^3 against
    :data:`~pipeflow.stability.maps.MAX_MAP_WORK` (every sweep, map and critical-velocity
    analysis), naming ``fields[0]`` and the most points that fit."""
    unit = (2 * modes) ** 3
    return Cost(
        units=points * unit,
        bound=int(MAX_MAP_WORK),
        unit="units",
        fields=fields,
        terms=f"{what} = {points} points x (2 x {modes} modes)^3",
        budget="spectrum budget",
        advice=f"use fewer points or modes: at most {int(MAX_MAP_WORK) // unit} points with "
        f"{modes} modes",
    )


def chart_cost(pipe: Pipe, modes: int, points: int, lowest_frequency: float, field: str) -> Cost:
    """``points`` monodromy matrices over the period of ``lowest_frequency`` [rad/s]
    (:func:`~pipeflow.stability.floquet.chart_work`) against
    :data:`~pipeflow.stability.floquet.MAX_CHART_WORK`; a pipe whose magnitudes overflow
    the model is refused naming ``pipe``."""
    try:
        units = chart_work(pipe, modes, points, lowest_frequency)
    except (ArithmeticError, np.linalg.LinAlgError) as exc:
        raise _out_of_range(exc) from None
    per_point = max(1, units // points)
    return Cost(
        units=units,
        bound=int(MAX_CHART_WORK),
        unit="units",
        fields=(field, "modes"),
        terms=f"{points} points x Magnus steps over the longest period x (2 x {modes} modes)^3",
        budget="monodromy budget",
        advice=f"at most {int(MAX_CHART_WORK) // per_point} points with these modes and "
        "lowest frequency (or fewer modes, or a higher lowest frequency)",
    )


def _check_range(value: tuple[float, float], name: str, bound: float, unit: str) -> None:
    lo, hi = value
    if not lo < hi:
        raise InvalidField(f"{name} must be increasing: got [{lo}, {hi}] {unit}", name)
    if max(abs(lo), abs(hi)) > bound:
        raise InvalidField(f"{name} must lie within +-{bound:g} {unit}", name)


class Hub(StrictModel):
    """Where the pipe is mounted on the rotating hub (for analyses that sweep the spin)."""

    hub_radius: HubRadius = 0.0


class ConstantRotation(Hub):
    omega0: ConstantProfile = Field(
        default_factory=ConstantProfile, description="Constant spin w0 of the hub [rad/s]."
    )


class _Mounted(GravityField):
    """A request with a pipe, a hub radius (``rotation.hub_radius``) and a ``plane``."""

    pipe: PipeSpec
    rotation: Hub = Field(default_factory=Hub)
    plane: Plane = "in-plane"

    flow: FlowPressure = Field(
        default_factory=FlowPressure,
        exclude_if=lambda v: v == FlowPressure(),
        description="The flow's internal pressure (the velocity is the analysis' range).",
    )

    @model_validator(mode="after")
    def _pressure(self) -> Self:
        check_pressure(self.pipe, self.flow)
        return self

    def mounted_pipe(self) -> Pipe:
        """The library's pipe with this request's hub radius, plane, gravity and pressure."""
        return self.pipe.to_pipe(
            self.rotation.hub_radius, self.plane, self.gravity_along_x(), self.flow.pressure
        )


class ConstantFlow(FlowPressure):
    velocity: ConstantProfile = Field(
        default_factory=ConstantProfile,
        description="Constant flow velocity v [m/s]; v > 0 flows from the clamped end to the tip.",
    )


StrictFloat = Annotated[float, Strict()]
#: [lo, hi]: a JSON array of two numbers (lax only in accepting an array for the tuple)
Pair = Annotated[tuple[StrictFloat, StrictFloat], Field(strict=False)]

VelocityRange = Annotated[
    Pair,
    Field(description="[v_min, v_max] flow velocities [m/s], increasing; v < 0 is reverse flow."),
]
SpinRange = Annotated[Pair, Field(description="[w_min, w_max] spins w0 [rad/s], increasing.")]
Modes = Annotated[
    int,
    Field(
        ge=1,
        le=MAX_MODES,
        description="Galerkin modes n: the beam eigenfunctions of the pipe's own supports "
        "and springs (the cantilever modes by default).",
    ),
]


class StabilitySpec(_Mounted):
    """Critical flow velocity of a pipe at constant spin over a velocity range."""

    model_config = ConfigDict(
        json_schema_extra={
            "examples": [
                {
                    "pipe": PAPER_PIPE_JSON,
                    "rotation": {"omega0": {"kind": "constant", "value": 100.0}},
                    "modes": 10,
                    "velocity_range": [0.0, 60.0],
                }
            ]
        },
    )

    pipe: PipeSpec
    rotation: ConstantRotation = Field(default_factory=ConstantRotation)
    modes: Modes = 10
    velocity_range: VelocityRange
    points: int = Field(
        401,
        ge=11,
        le=MAX_SWEEP_POINTS,
        description="Grid points from 0 to v_max on which branches are followed [-] (crossings "
        "are then located by root-finding to 1e-10 relative).",
    )

    @model_validator(mode="after")
    def _ranges(self) -> StabilitySpec:
        _check_range(self.velocity_range, "velocity_range", MAX_SPEED, "m/s")
        if abs(self.rotation.omega0.value) > MAX_SPIN:
            raise InvalidField(
                f"rotation.omega0.value must lie within +-{MAX_SPIN:g} rad/s",
                "rotation.omega0.value",
            )
        return self.within_budget()

    def cost(self) -> Cost:
        """One frozen spectrum per grid point (:func:`spectrum_cost`)."""
        return spectrum_cost(self.points, self.modes, ("points", "modes"), "points")


class _TrackedSweep(_Mounted):
    modes: Modes = 10
    points: int = Field(201, ge=2, le=MAX_SWEEP_POINTS, description="Evenly spaced points [-].")
    tracked_modes: int = Field(
        4, ge=1, le=MAX_MODES, description="Lowest modes reported (<= modes) [-]."
    )
    min_confidence: float = Field(
        0.9,
        ge=0,
        le=1,
        description="Insert points where the eigenvector-overlap tracking confidence falls "
        "below this [-]; 0 disables refinement.",
    )
    max_points: int | None = Field(
        None,
        ge=2,
        le=4 * MAX_SWEEP_POINTS,
        description="Cap on points after refinement [-] (default 4 x points).",
    )

    @model_validator(mode="after")
    def _tracked(self) -> _TrackedSweep:
        if self.tracked_modes > self.modes:
            raise InvalidField("tracked_modes cannot exceed modes", "tracked_modes")
        if self.max_points is not None and self.max_points < self.points:
            raise InvalidField("max_points must be >= points", "max_points")
        return self

    def cost(self) -> Cost:
        """One frozen spectrum per point after refinement (max_points, default 4 x points:
        :func:`spectrum_cost`)."""
        most = self.max_points if self.max_points is not None else 4 * self.points
        field = "max_points" if self.max_points is not None else "points"
        return spectrum_cost(most, self.modes, (field, "modes"), "points after refinement")


class ArgandSweep(_TrackedSweep):
    """Eigenvalues against flow velocity at constant spin (Argand diagram)."""

    kind: Literal["argand"] = "argand"
    rotation: ConstantRotation = Field(default_factory=ConstantRotation)
    velocity_range: VelocityRange

    @model_validator(mode="after")
    def _ranges(self) -> ArgandSweep:
        _check_range(self.velocity_range, "velocity_range", MAX_SPEED, "m/s")
        return self.within_budget()


class CampbellSweep(_TrackedSweep):
    """Eigenvalues against spin at constant flow velocity (Campbell diagram)."""

    kind: Literal["campbell"] = "campbell"
    flow: ConstantFlow = Field(default_factory=ConstantFlow)
    spin_range: SpinRange
    orders: list[Annotated[float, Field(gt=0, le=100)]] = Field(
        [1.0, 2.0],
        max_length=8,
        description="Excitation orders n [-]: the lines omega = n w0 (1x synchronous, 2x, "
        "0.5x, ...) whose crossings with the tracked branches are located and reported.",
    )

    @model_validator(mode="after")
    def _ranges(self) -> CampbellSweep:
        _check_range(self.spin_range, "spin_range", MAX_SPIN, "rad/s")
        return self.within_budget()


class SpinMapSweep(_Mounted):
    """Growth-rate map over (spin, flow velocity) and the critical velocity at each spin."""

    kind: Literal["spin_map"] = "spin_map"
    pipe: PipeSpec
    modes: Modes = 10
    velocity_range: VelocityRange
    spin_range: SpinRange
    velocity_points: int = Field(100, ge=3, le=MAX_MAP_SIDE, description="Velocity samples [-].")
    spin_points: int = Field(100, ge=1, le=MAX_MAP_SIDE, description="Spin samples [-].")

    @model_validator(mode="after")
    def _ranges(self) -> SpinMapSweep:
        _check_range(self.velocity_range, "velocity_range", MAX_SPEED, "m/s")
        _check_range(self.spin_range, "spin_range", MAX_SPIN, "rad/s")
        return self.within_budget()

    def cost(self) -> Cost:
        """One frozen spectrum per (v, w0) point (:func:`spectrum_cost`)."""
        points = self.velocity_points * self.spin_points
        return spectrum_cost(
            points,
            self.modes,
            ("spin_points", "velocity_points", "modes"),
            f"{self.velocity_points} velocity_points x {self.spin_points} spin_points",
        )


class BetaMapSweep(StrictModel):
    """u_cr(beta) in Paidoussis' non-dimensional form, all crossings per beta (S-shapes)."""

    kind: Literal["beta_map"] = "beta_map"
    modes: Modes = 10
    beta_range: Pair = Field(
        (0.05, 0.95), description="[beta_min, beta_max] mass ratios M2/(M1+M2) in (0, 1) [-]."
    )
    u_range: Pair = Field(
        (0.0, 20.0), description="[u_min, u_max] flow numbers v L sqrt(M2/EI) >= 0 [-]."
    )
    gamma: float = Field(0.0, ge=0, le=1e3, description="Spin number w0 L^2 sqrt((M1+M2)/EI) [-].")
    beta_points: int = Field(50, ge=1, le=400, description="Mass-ratio samples [-].")
    u_points: int = Field(201, ge=3, le=MAX_SWEEP_POINTS, description="Flow-number samples [-].")
    alpha: float = Field(
        0.0, ge=0, le=1e3, description=GROUPS["alpha"].description + " 0: undamped."
    )
    viscous_ratio: float = Field(
        0.0,
        ge=0,
        le=1e6,
        validation_alias=AliasChoices("viscous_ratio", "sigma"),
        description=GROUPS["viscous_ratio"].description
        + " The former name 'sigma' is still accepted.",
    )
    tip_mass_ratio: float = Field(
        0.0, ge=0, le=1e6, description=GROUPS["tip_mass_ratio"].description
    )
    tip_inertia_ratio: float = Field(
        0.0, ge=0, le=1e6, description=GROUPS["tip_inertia_ratio"].description
    )
    hub_ratio: float = Field(0.0, ge=0, le=1e5, description=GROUPS["hub_ratio"].description)
    plane: Plane = "in-plane"

    @model_validator(mode="after")
    def _ranges(self) -> BetaMapSweep:
        _check_range(self.beta_range, "beta_range", 1.0, "")
        if not (self.beta_range[0] > 0 and self.beta_range[1] < 1):
            raise InvalidField("beta_range must lie inside (0, 1)", "beta_range")
        _check_range(self.u_range, "u_range", 1e3, "")
        if self.u_range[0] < 0:
            raise InvalidField(
                "u_range must be >= 0 (reverse flow has no critical velocity)", "u_range"
            )
        return self.within_budget()

    def cost(self) -> Cost:
        """One frozen spectrum per (beta, u) point (:func:`spectrum_cost`)."""
        return spectrum_cost(
            self.beta_points * self.u_points,
            self.modes,
            ("u_points", "beta_points", "modes"),
            f"{self.beta_points} beta_points x {self.u_points} u_points",
        )


class ResonanceChartSweep(_Mounted):
    """Floquet chart of pulsating flow v = mean + a sin(Omega t) over (a, Omega)."""

    kind: Literal["resonance_chart"] = "resonance_chart"
    pipe: PipeSpec
    modes: int = Field(4, ge=1, le=MAX_CHART_MODES, description="Galerkin modes n [-].")
    rotation: ConstantRotation = Field(default_factory=ConstantRotation)
    mean_velocity: float = Field(
        ge=-MAX_SPEED, le=MAX_SPEED, description="Mean flow velocity [m/s]."
    )
    amplitude_range: Pair = Field(description="[a_min, a_max] pulsation amplitudes >= 0 [m/s].")
    frequency_range: Pair = Field(
        description="[Omega_min, Omega_max] pulsation frequencies > 0 [rad/s]."
    )
    amplitude_points: int = Field(21, ge=1, le=MAX_CHART_SIDE, description="Amplitude samples.")
    frequency_points: int = Field(41, ge=1, le=MAX_CHART_SIDE, description="Frequency samples.")
    tolerance: float = Field(
        1e-5, ge=1e-12, le=1e-2, description="Relative accuracy of each monodromy matrix [-]."
    )

    @model_validator(mode="after")
    def _ranges(self) -> ResonanceChartSweep:
        _check_range(self.amplitude_range, "amplitude_range", MAX_SPEED, "m/s")
        _check_range(self.frequency_range, "frequency_range", 1e7, "rad/s")
        if self.amplitude_range[0] < 0:
            raise InvalidField("amplitude_range must be >= 0 m/s", "amplitude_range")
        if self.frequency_range[0] <= 0:
            raise InvalidField("frequency_range must be > 0 rad/s", "frequency_range")
        return self.within_budget()

    def cost(self) -> Cost:
        """amplitude_points x frequency_points monodromy matrices (:func:`chart_cost`)."""
        return chart_cost(
            self.mounted_pipe(),
            self.modes,
            self.amplitude_points * self.frequency_points,
            self.frequency_range[0],
            "frequency_points",
        )


class PeriodicFlow(FlowPressure):
    velocity: ConstantProfile | HarmonicProfile = Field(
        discriminator="kind", description="Flow velocity v(t) [m/s]: constant or harmonic."
    )


class PeriodicRotation(Hub):
    omega0: ConstantProfile | HarmonicProfile = Field(
        default_factory=ConstantProfile,
        discriminator="kind",
        description="Spin w0(t) [rad/s]: constant or harmonic (same frequency as the flow).",
    )


class FloquetSweep(_Mounted):
    """Floquet multipliers of one case with harmonic flow and/or spin (one period)."""

    kind: Literal["floquet"] = "floquet"
    pipe: PipeSpec
    modes: int = Field(6, ge=1, le=MAX_FLOQUET_MODES, description="Galerkin modes n [-].")
    flow: PeriodicFlow
    rotation: PeriodicRotation = Field(default_factory=PeriodicRotation)
    tolerance: float = Field(
        1e-8, ge=1e-12, le=1e-2, description="Relative accuracy of the monodromy matrix [-]."
    )

    @model_validator(mode="after")
    def _periodic(self) -> FloquetSweep:
        _library_check(
            period_of, self.flow.velocity.to_profile(), self.rotation.omega0.to_profile()
        )
        return self.within_budget()

    def cost(self) -> Cost:
        """One monodromy matrix over the common period (:func:`chart_cost`; the solver
        refuses more than :data:`~pipeflow.stability.floquet.MAX_STEPS` steps)."""
        period = period_of(self.flow.velocity.to_profile(), self.rotation.omega0.to_profile())
        return chart_cost(self.mounted_pipe(), self.modes, 1, 2 * np.pi / period, "flow.velocity")


#: the request models asked for by ``kind`` at ``/v1/sweeps`` (their registry entries
#: are in :mod:`pipeflow.computations.registry`)
SweepModel = (
    ArgandSweep | CampbellSweep | SpinMapSweep | BetaMapSweep | ResonanceChartSweep | FloquetSweep
)


def _library_check(check: Callable[..., object], *args: Any) -> None:
    """:func:`pipeflow.schema.simulation.library_check` with :data:`STABILITY_FIELDS`; a pipe
    whose magnitudes overflow the model there (e.g. L = 5e-324 m: 1/L^3 = inf) is refused
    naming ``pipe``."""
    try:
        library_check(check, STABILITY_FIELDS, *args)
    except (ArithmeticError, np.linalg.LinAlgError) as exc:
        raise _out_of_range(exc) from None


def _out_of_range(exc: Exception) -> InvalidField:
    """The refusal of a pipe whose magnitudes overflow the model, naming ``pipe``."""
    return InvalidField(
        f"pipe: the pipe's magnitudes take the model out of double precision "
        f"({type(exc).__name__}: {exc}); check E, I, L, M1 and M2",
        "pipe",
    )
