"""Request models of a simulation and of a method comparison: one schema for the service,
the CLI and files.

pydantic models with units in every description and bounds on every cost a request can
ask for.  Inputs are strict: a boolean or a string where a number belongs is refused
(``"E": true`` is not 1 Pa).  :meth:`SimulationSpec.to_simulation` turns a validated spec
into the library's :class:`~pipeflow.simulation.Simulation` (plain arguments);
:meth:`SimulationSpec.canonical` gives the normalised form (defaults filled, options the
method does not read dropped) that the service's cache key is computed from.
"""

from __future__ import annotations

import dataclasses
from typing import Annotated, Any, Literal

from pydantic import (
    ConfigDict,
    Field,
    GetJsonSchemaHandler,
    ValidationError,
    field_validator,
    model_validator,
)
from pydantic.json_schema import JsonSchemaValue
from pydantic_core import CoreSchema

from pipeflow import paper
from pipeflow.basis import MAX_MODES
from pipeflow.compare import MAX_METHODS, default_methods
from pipeflow.errors import InvalidField, InvalidInput, PipeflowError
from pipeflow.loads import (
    MAX_LOADS,
)
from pipeflow.model import Pipe, check_stiffness
from pipeflow.modeshapes import (
    DEFAULT_SHAPE_POINTS,
    MAX_SHAPE_POINTS,
    MAX_SHAPE_TIMES,
    MAX_SHAPE_VALUES,
)
from pipeflow.schema import messages, units

# the base of every request model, re-exported (``X as X``): importers of these names from
# this module, where they were defined before pipeflow.schema.base, keep working
from pipeflow.schema.base import Cost as Cost
from pipeflow.schema.base import StrictModel as StrictModel
from pipeflow.schema.base import costs_unchecked as costs_unchecked
from pipeflow.schema.base import library_check as library_check
from pipeflow.schema.base import request_field as request_field
from pipeflow.schema.base import request_fields as request_fields
from pipeflow.schema.drawing import (
    DRAWING_FIELDS,
    FluidName,
    MaterialName,
    drawing_field,
    from_drawing,
)
from pipeflow.schema.loads import BaseAccelerationLoad as BaseAccelerationLoad
from pipeflow.schema.loads import DistributedForceLoad as DistributedForceLoad
from pipeflow.schema.loads import LoadSpec as LoadSpec
from pipeflow.schema.loads import PointForceLoad as PointForceLoad
from pipeflow.schema.loads import PointImpulseLoad as PointImpulseLoad
from pipeflow.schema.profiles import MAX_COEFFICIENT as MAX_COEFFICIENT
from pipeflow.schema.profiles import MAX_POLY_DEGREE as MAX_POLY_DEGREE
from pipeflow.schema.profiles import MAX_PROFILE_VALUE as MAX_PROFILE_VALUE
from pipeflow.schema.profiles import MAX_TABLE_POINTS as MAX_TABLE_POINTS
from pipeflow.schema.profiles import BoundedValue as BoundedValue
from pipeflow.schema.profiles import ConstantProfile as ConstantProfile
from pipeflow.schema.profiles import HalfSineProfile as HalfSineProfile
from pipeflow.schema.profiles import HarmonicProfile as HarmonicProfile
from pipeflow.schema.profiles import PolynomialProfile as PolynomialProfile
from pipeflow.schema.profiles import ProfileSpec as ProfileSpec
from pipeflow.schema.profiles import TableProfile as TableProfile
from pipeflow.schema.supports import (
    FlowPressureProfile,
    GravityField,
    MountingFields,
    check_pipe,
    check_pressure,
)
from pipeflow.simulation import Simulation, check_mode_acceleration
from pipeflow.solvers import SOLVERS, Options
from pipeflow.solvers.base import MAX_STEPS_CEILING

MAX_SAMPLES = 200_001
MAX_POSITIONS = 64
MAX_EIGEN_SAMPLES = 2001
#: the most numbers one simulation's answer may hold (output times x series, eigenvalue
#: traces, mode shapes: :meth:`SimulationSpec.cost`): about 45 MB of JSON (measured: 1.8
#: million numbers, 200,001 samples x 7 positions, were 41 MB, 13 s and a 274 MB peak of
#: the process; 200,001 samples x 145 series, 29 million numbers, had taken 2.7 GB and
#: stored a 299 MB row); a comparison holds one run per method, so its methods share it
MAX_OUTPUT_VALUES = 2_000_000
#: the least total mass per length [kg/m]
MIN_MASS = 1e-15
#: the mounting of the pipe beyond the paper's model (issue 14; docs/model.md): one
#: definition each, used by every simulation and stability request
HubRadius = Annotated[
    float,
    Field(
        ge=0,
        le=1e5,
        description="Distance R of the clamped end from the rotation axis [m]; 0 (default): on "
        "the axis, as in the paper. Adds the centrifugal tension M1 w0^2 R (L - x).",
    ),
]
Plane = Annotated[
    Literal["in-plane", "out-of-plane"],
    Field(
        description="Plane of the vibration: 'in-plane' (default; the paper's eq. (1), "
        "chordwise, with the -(M1+M2) w0^2 u softening and the forcing by the angular "
        "acceleration) or 'out-of-plane' (flapwise, perpendicular to the rotation plane: "
        "neither of those two terms)."
    ),
]


#: library parameter (of :class:`~pipeflow.simulation.Simulation` and
#: :class:`~pipeflow.solvers.Options`) -> the request field of :class:`SimulationSpec` it
#: comes from; the one place where library error names become JSON paths
SIMULATION_FIELDS: dict[str, str] = {
    "pipe": "pipe",
    "E": "pipe.E",
    "I": "pipe.I",
    "tip_mass": "pipe.tip_mass",
    "tip_inertia": "pipe.tip_inertia",
    "flow": "flow.velocity",
    "spin": "rotation.omega0",
    "omega0": "rotation.omega0",
    "pressure": "flow.pressure",
    "flow_area": "pipe.flow_area",
    "u0": "initial.u0",
    "du0": "initial.du0",
    "initial_shape": "initial.shape",
    "modes": "modes",
    "t_end": "time.t_end",
    "samples": "time.samples",
    "method": "method",
    "positions": "output.positions",
    "eigen_modes": "output.eigen_modes",
    "eigen_samples": "output.eigen_samples",
    "include_modal": "output.modal",
    "mode_acceleration": "output.mode_acceleration",
    "divergence_bound": "output.divergence_bound",
    "mode_shape_times": "output.mode_shapes.times",
    "mode_shape_points": "output.mode_shapes.points",
    "loads": "loads",
    **{f.name: f"options.{f.name}" for f in dataclasses.fields(Options)},
}


class DampingSpec(StrictModel):
    """Damping of the pipe (issue 14): internal (Kelvin-Voigt) and external viscous."""

    kelvin_voigt: float = Field(
        0.0,
        ge=0,
        le=1e3,
        description="Internal (Kelvin-Voigt) damping alpha [s]: E -> E (1 + alpha d/dt), a "
        "damping matrix alpha K; 0 (default): none. Dimensionless alpha / time_scale "
        "(Paidoussis 1998, eq. 3.71).",
    )
    viscous: float = Field(
        0.0,
        ge=0,
        le=1e9,
        description="External viscous damping c per unit length [N s/m^2] (force c du/dt per "
        "metre); 0 (default): none. Dimensionless c L^2 / sqrt(EI (M1+M2)).",
    )


class PipeSpec(MountingFields):
    """Pipe and fluid properties (the paper's section 5 values are the example).

    Given explicitly (E, I, L, M1, M2) or by its drawing: L, outer_diameter with
    inner_diameter or wall_thickness, density or material, fluid_density or fluid, and E
    by value or the material's. The drawing is replaced by the explicit form first
    (I, M1, M2 and E computed from it), so both forms are one request and one cache key;
    a quantity given both ways (I and the diameters, M1 and density) is refused."""

    # upper bounds: every engineering pipe fits with orders of magnitude to spare, and the
    # numerics stay within double precision (1e308 overflowed); vanishing values that still
    # overflow are answered by the service's numerical-range problem
    E: float = Field(gt=0, le=1e13, description="Young's modulus of the pipe wall [Pa].")
    I: float = Field(gt=0, le=10.0, description="Second moment of area of the cross-section [m^4].")
    L: float = Field(gt=0, le=1e4, description="Pipe length, hub (clamped) to free tip [m].")
    M1: float = Field(ge=0, le=1e6, description="Mass of the pipe per unit length [kg/m].")
    M2: float = Field(
        ge=0, le=1e6, description="Mass of the conveyed fluid per unit length [kg/m]."
    )
    damping: DampingSpec = Field(
        default_factory=DampingSpec,
        description="Structural damping; both zero (default) is the paper's undamped pipe.",
    )
    tip_mass: float = Field(
        0.0,
        ge=0,
        le=1e9,
        description="Point mass m_t at the free end, e.g. a nozzle [kg]; 0 (default): none. "
        "Adds its inertia, its centrifugal tension m_t w0^2 (R + L) and, in plane, its "
        "softening and its forcing.",
    )
    tip_inertia: float = Field(
        0.0,
        ge=0,
        le=1e12,
        description="Rotary inertia J_t of the tip body about the bending axis through the "
        "tip [kg m^2]; 0 (default): none. The cantilever-mode Galerkin converges only like "
        "1/modes for it (about 1e-2 relative at 40 modes for J_t/(m L^3) = 0.01).",
    )

    outer_diameter: float | None = drawing_field("outer_diameter")
    inner_diameter: float | None = drawing_field("inner_diameter")
    wall_thickness: float | None = drawing_field("wall_thickness")
    density: float | None = drawing_field("density")
    fluid_density: float | None = drawing_field("fluid_density")
    material: MaterialName | None = drawing_field("material")
    fluid: FluidName | None = drawing_field("fluid")

    @model_validator(mode="before")
    @classmethod
    def _drawing(cls, data: Any) -> Any:
        """The drawing form replaced by the explicit one (:func:`from_drawing`), its
        quantities converted first."""
        if not isinstance(data, dict) or not any(k in data for k in DRAWING_FIELDS):
            return data
        return from_drawing(units.convert_fields(cls, data))

    @classmethod
    def __get_pydantic_json_schema__(
        cls, core_schema: CoreSchema, handler: GetJsonSchemaHandler
    ) -> JsonSchemaValue:
        schema = super().__get_pydantic_json_schema__(core_schema, handler)
        target = handler.resolve_ref_schema(schema)
        if handler.mode == "validation":
            # E, I, M1, M2 may come from the drawing form instead
            target["required"] = [r for r in target.get("required", []) if r == "L"]
        else:  # the drawing form never comes back: an answer holds the explicit form
            for name in DRAWING_FIELDS:
                target.get("properties", {}).pop(name, None)
        return schema

    @model_validator(mode="after")
    def _mass(self) -> PipeSpec:
        if self.M1 + self.M2 < MIN_MASS:
            raise InvalidField(f"M1 + M2 must be >= {MIN_MASS:g} kg/m", "M1")
        try:
            check_stiffness(self.E, self.I)
        except PipeflowError as exc:
            raise InvalidField(exc.message, exc.parameter) from None
        check_pipe(self.to_pipe)  # supports and axial loads (schema/supports.py)
        return self

    def to_pipe(
        self,
        hub_radius: float = 0.0,
        plane: str = "in-plane",
        gravity: float = 0.0,
        pressure: float = 0.0,
    ) -> Pipe:
        """The library's :class:`~pipeflow.model.Pipe`, mounted at ``hub_radius`` [m] and
        vibrating in ``plane`` (both given by the request's rotation and plane fields)."""
        return Pipe(
            E=self.E,
            I=self.I,
            L=self.L,
            M1=self.M1,
            M2=self.M2,
            kelvin_voigt=self.damping.kelvin_voigt,
            viscous=self.damping.viscous,
            tip_mass=self.tip_mass,
            tip_inertia=self.tip_inertia,
            hub_radius=hub_radius,
            plane=plane,
            gravity=gravity,
            pressure=pressure,
            **self.mounting(),
        )


def pipe_of_request(body: Any) -> Pipe | None:
    """The library pipe of a request body's ``pipe`` (a method comparison's
    ``simulation.pipe``), for drawing its supports on the figures along x [m]; None when the
    body has no pipe or an invalid one (a figure then draws no supports)."""
    if isinstance(body, dict) and isinstance(body.get("simulation"), dict):
        body = body["simulation"]
    if not isinstance(body, dict) or not isinstance(body.get("pipe"), dict):
        return None
    try:
        return PipeSpec.model_validate(body["pipe"]).to_pipe()
    except (ValidationError, PipeflowError):
        return None


class RotationSpec(StrictModel):
    omega0: ProfileSpec = Field(
        default_factory=ConstantProfile, description="Spin w0(t) of the hub [rad/s]."
    )
    hub_radius: HubRadius = 0.0


class FlowSpec(FlowPressureProfile):
    velocity: ProfileSpec = Field(
        default_factory=ConstantProfile,
        description="Flow velocity v(t) [m/s]; v > 0 flows from the clamped end to the tip.",
    )


class InitialSpec(StrictModel):
    u0: float = Field(
        0.001,
        ge=-1e3,
        le=1e3,
        description="Initial amplitude [m]: u(x,0) = u0 s(x), s chosen by 'shape'.",
    )
    du0: float = Field(
        0.0, ge=-1e6, le=1e6, description="Initial velocity amplitude [m/s]: du/dt(x,0) = du0 s(x)."
    )
    shape: Literal["paper", "tip"] = Field(
        "paper",
        description=(
            "'paper': s is eq. (3)'s phi_1, whose tip value is 2.7244, so the initial tip "
            "displacement is 2.7244 u0 (as in the paper); 'tip': s is the first mode scaled "
            "to a unit tip value, so u0 is the initial tip displacement."
        ),
    )


class TimeSpec(StrictModel):
    t_end: float = Field(1.0, gt=0, le=1e6, description="Simulated duration [s].")
    samples: int = Field(
        2001, ge=2, le=MAX_SAMPLES, description="Output times, evenly spaced incl. 0 and t_end."
    )


#: the library's option defaults (one definition: :class:`pipeflow.solvers.Options`)
_OPTIONS = Options()


class MethodOptions(StrictModel):
    """Solver options (:class:`pipeflow.solvers.Options`, field for field, with bounds and
    units); a method ignores the ones it does not read (and so does the cache key)."""

    step: float | None = Field(
        _OPTIONS.step, gt=0, description="rk4/magnus: time step [s]; null picks one automatically."
    )
    max_steps: int = Field(
        _OPTIONS.max_steps,
        ge=1,
        le=MAX_STEPS_CEILING,
        description="Refuse runs needing more steps.",
    )
    rtol: float = Field(
        _OPTIONS.rtol, ge=1e-14, le=1e-2, description="reference: relative tolerance [-]."
    )
    atol: float = Field(
        _OPTIONS.atol,
        ge=1e-20,
        le=1.0,
        description="reference: absolute tolerance [m of modal amplitude].",
    )
    integrator: Literal["DOP853", "RK45", "RK23", "Radau", "BDF", "LSODA"] = Field(
        _OPTIONS.integrator,  # type: ignore[arg-type]
        description="reference: scipy solve_ivp method.",
    )
    tolerance: float = Field(
        _OPTIONS.tolerance, ge=1e-13, le=1e-1, description="magnus: relative accuracy target [-]."
    )
    condition_limit: float = Field(
        _OPTIONS.condition_limit,
        ge=10,
        le=1e14,
        description="cma: eigenvector 1-norm condition number above which expm is used [-].",
    )


class ModeShapesSpec(StrictModel):
    """Complex mode shapes of the frozen spectrum (pipeflow.modeshapes), one per traced
    eigenvalue branch (output.eigen_modes) at each time, normalised to max |Phi| = 1."""

    times: list[float] = Field(
        min_length=1,
        max_length=MAX_SHAPE_TIMES,
        description="Times t [s] (0 <= t <= time.t_end) at which the shapes are returned.",
    )
    points: int = Field(
        DEFAULT_SHAPE_POINTS,
        ge=2,
        le=MAX_SHAPE_POINTS,
        description="Stations from x = 0 to x = L [m], evenly spaced, at which each shape is "
        f"evaluated. times x points x (output.eigen_modes + 1) is at most {MAX_SHAPE_VALUES}.",
    )


class OutputSpec(StrictModel):
    positions: list[float] = Field(
        default_factory=list,
        max_length=MAX_POSITIONS,
        description="Extra stations x [m] (0 <= x <= L) whose displacement u(x, t) is returned.",
    )
    eigen_modes: int = Field(
        3, ge=1, le=MAX_MODES, description="Lowest eigenvalue branches to trace (capped at modes)."
    )
    eigen_samples: int = Field(
        201, ge=2, le=MAX_EIGEN_SAMPLES, description="Times at which eigenvalues are computed."
    )
    modal: bool = Field(False, description="Also return modal coordinates d [m], d' [m/s].")
    divergence_bound: float | None = Field(
        None,
        gt=0,
        description="The linear model's range: a bound on |u| [m] at the tip and at every "
        "output position. The run stops at the first output time past it (status "
        "'diverged', with divergence_time [s] and divergence_growth_rate [1/s]). null "
        "(default): 0.1 L, or twice the initial deflection when that is larger.",
    )
    mode_shapes: ModeShapesSpec | None = Field(
        None,
        description="Also return the complex mode shapes Phi(x) [-] (real and imaginary parts, "
        "max modulus 1) of the frozen spectrum at these times; null: none.",
    )

    mode_acceleration: bool = Field(
        False,
        exclude_if=lambda v: not v,  # absent from the normal form when off: earlier keys
        description="Add to the displacements (tip and positions) the quasi-static response "
        "of the modes left out to the loads (the mode-acceleration method: the continuous "
        "pipe's static deflection under each load minus its part in the modes, times the "
        "load's value at t; m). It helps loads slow against the first mode left out (a "
        "harmonic force at 50 rad/s on the paper's pipe: 1.5e-5 -> 2.4e-8 of the 40-mode "
        "answer at 10 modes); a step's transient in those modes it cannot give. For "
        "constant flow and spin, any supports but a pipe free to rotate (pinned-free), and "
        "point forces, impulses or clamp accelerations.",
    )

    def mode_shape_arguments(self) -> dict[str, Any]:
        """The :class:`~pipeflow.simulation.Simulation` arguments of ``mode_shapes``."""
        if self.mode_shapes is None:
            return {}
        return {
            "mode_shape_times": tuple(self.mode_shapes.times),
            "mode_shape_points": self.mode_shapes.points,
        }


class SimulationSpec(GravityField):
    """A simulation request: pipe, loading, initial condition, discretisation and method."""

    model_config = ConfigDict(
        json_schema_extra={
            "examples": [
                {  # the paper's example (pipeflow.paper) as JSON
                    "pipe": dict(paper.PAPER_PIPE_JSON),
                    "rotation": {"omega0": {"kind": "constant", "value": paper.PAPER_OMEGA0}},
                    "flow": {
                        "velocity": {
                            "kind": "polynomial",
                            "coefficients": list(paper.PAPER_FLOW.coefficients),
                        }
                    },
                    "initial": {"u0": paper.PAPER_U0, "du0": 0.0},
                    "modes": paper.PAPER_MODES,
                    "time": {"t_end": paper.PAPER_T_END, "samples": paper.PAPER_SAMPLES},
                    "method": "auto",
                }
            ]
        },
    )

    pipe: PipeSpec
    rotation: RotationSpec = Field(default_factory=RotationSpec)
    plane: Plane = "in-plane"
    flow: FlowSpec = Field(default_factory=FlowSpec)
    initial: InitialSpec = Field(default_factory=InitialSpec)
    modes: int = Field(
        10,
        ge=1,
        le=MAX_MODES,
        description="Number of Galerkin modes n [-]: the beam eigenfunctions of the pipe's own "
        "supports and springs (the cantilever modes by default).",
    )
    time: TimeSpec = Field(default_factory=TimeSpec)
    method: str = Field(
        "auto",
        description="Solver: " + "; ".join(f"'{n}': {s.description}" for n, s in SOLVERS.items()),
        json_schema_extra={"enum": list(sorted(SOLVERS))},
    )
    options: MethodOptions = Field(default_factory=MethodOptions)
    output: OutputSpec = Field(default_factory=OutputSpec)
    loads: list[LoadSpec] = Field(
        default_factory=list,
        max_length=MAX_LOADS,
        description="External loads, each with its time history (any profile kind): "
        "'point_force' (N at position x [m]), 'distributed_force' (N/m on [start, end] [m]) "
        "'base_acceleration' (m/s^2 of the clamp; displacements then stay relative to "
        "the clamp) and 'impulse' (a blow of J [N s] at position x [m] and time t0 [s]). "
        f"At most {MAX_LOADS}; empty (default): free vibration.",
    )

    @field_validator("method")
    @classmethod
    def _known_method(cls, v: str) -> str:
        if v not in SOLVERS:
            hint = messages.did_you_mean(v, sorted(SOLVERS)) or "; choose one of " + ", ".join(
                sorted(SOLVERS)
            )
            raise InvalidField(f"unknown method {v!r}{hint}")
        return v

    @model_validator(mode="after")
    def _consistent(self) -> SimulationSpec:
        check_pressure(self.pipe, self.flow)
        if self.output.eigen_modes > self.modes:
            # normalise: there are only `modes` branches (keeps equivalent requests one key)
            self.output.eigen_modes = self.modes
        for i, x in enumerate(self.output.positions):
            if not 0 <= x <= self.pipe.L:
                raise InvalidField(
                    f"output.positions[{i}] = {x} m is outside [0, L]", "output.positions"
                )
        shapes = self.output.mode_shapes
        for i, t in enumerate(shapes.times if shapes is not None else []):
            if not 0 <= t <= self.time.t_end:
                raise InvalidField(
                    f"output.mode_shapes.times.{i}: {t} s is outside [0, time.t_end]",
                    f"output.mode_shapes.times.{i}",
                )
        if shapes is not None:  # the mode shapes' own bound first: it names their field
            branches = min(self.output.eigen_modes, self.modes) + 1
            values = len(shapes.times) * shapes.points * branches
            if values > MAX_SHAPE_VALUES:
                raise InvalidField(
                    f"output.mode_shapes.points: {len(shapes.times)} times x {shapes.points} "
                    f"points x {branches} branches (eigen_modes + 1) = {values} values, more "
                    f"than {MAX_SHAPE_VALUES}; ask fewer points, times or eigen_modes",
                    "output.mode_shapes.points",
                )
        for name, prof in (
            ("flow.velocity", self.flow.velocity),
            ("rotation.omega0", self.rotation.omega0),
            ("flow.pressure", self.flow.pressure_profile),
        ):
            if (
                isinstance(prof, TableProfile)
                and prof.after is None
                and prof.t[-1] < self.time.t_end
            ):
                raise InvalidField(
                    f"{name}: the table ends at {prof.t[-1]} s, before time.t_end (or say "
                    "what it does after its last time: after = 'hold' or 'zero')",
                    name,
                )
        if self.output.mode_acceleration:
            library_check(check_mode_acceleration, SIMULATION_FIELDS, self.to_simulation())
        self._check_loads()
        return self.within_budget()

    def _check_loads(self) -> None:
        """The library's rules of each load (:meth:`pipeflow.loads.PointForce.check`...:
        stations on the pipe, spans ordered, tables covering t_end); the error names the
        field (``loads.0.position``)."""
        for i, spec in enumerate(self.loads):
            try:
                spec.to_load().check(i, self.pipe.L, self.time.t_end)
            except InvalidInput as exc:
                raise InvalidField(exc.message, exc.parameter or f"loads.{i}") from None

    def output_values(self) -> tuple[int, int, int, str]:
        """The numbers of the answer (:func:`pipeflow.computations.documents.simulation`), an upper
        bound: ``(per output time, eigenvalue and mode-shape numbers, total, terms)``.

        Per output time: t, the tip, each output position and, with ``output.modal``, d and
        d' of each mode.  Per eigenvalue time (``min(eigen_samples, samples)``): t twice,
        the fundamental's sigma and omega, and sigma, omega and confidence of each traced
        branch in the frozen spectrum and in the CMA exponents.  Mode shapes: t, x and per
        branch (eigen_modes + 1 at most) sigma and omega per time and the real and
        imaginary parts per time and station."""
        samples = self.time.samples
        branches = min(self.output.eigen_modes, self.modes)
        per_sample = 2 + len(self.output.positions) + (2 * self.modes if self.output.modal else 0)
        eigen_times = max(2, min(self.output.eigen_samples, samples))
        fixed = eigen_times * (4 + 6 * branches)
        shapes = self.output.mode_shapes
        if shapes is not None:
            times, points = len(shapes.times), shapes.points
            fixed += times + points + (branches + 1) * times * (2 + 2 * points)
        terms = f"{samples} samples x (2 + {len(self.output.positions)} positions"
        if self.output.modal:
            terms += f" + 2 x {self.modes} modes (output.modal)"
        terms += f") + {eigen_times} eigenvalue times x (4 + 6 x {branches} output.eigen_modes)"
        if shapes is not None:
            terms += " + the mode shapes"
        return per_sample, fixed, samples * per_sample + fixed, terms

    def cost(self) -> Cost:
        """The numbers of the answer (:meth:`output_values`) against
        :data:`MAX_OUTPUT_VALUES`, naming ``time.samples`` (and the largest count that fits
        with these outputs)."""
        per_sample, fixed, units, terms = self.output_values()
        return _output_cost(units, per_sample, fixed, terms, 1, "")

    def to_simulation(self) -> Simulation:
        """The library's :class:`~pipeflow.simulation.Simulation` (plain arguments)."""
        varying = self.flow.pressure_profile
        return Simulation(
            pipe=self.pipe.to_pipe(
                self.rotation.hub_radius,
                self.plane,
                self.gravity_along_x(),
                self.flow.constant_pressure,
            ),
            pressure=None if varying is None else varying.to_profile(),
            flow=self.flow.velocity.to_profile(),
            spin=self.rotation.omega0.to_profile(),
            u0=self.initial.u0,
            du0=self.initial.du0,
            initial_shape=self.initial.shape,
            modes=self.modes,
            t_end=self.time.t_end,
            samples=self.time.samples,
            method=self.method,
            options=Options(**self.options.model_dump()),
            positions=tuple(self.output.positions),
            eigen_modes=self.output.eigen_modes,
            eigen_samples=self.output.eigen_samples,
            include_modal=self.output.modal,
            mode_acceleration=self.output.mode_acceleration,
            divergence_bound=self.output.divergence_bound,
            **self.output.mode_shape_arguments(),
            loads=tuple(load.to_load() for load in self.loads),
        )

    def canonical(self) -> dict[str, Any]:
        """Normalised JSON form: every default filled in, unread method options dropped."""
        data = self.model_dump(mode="json")
        used = set(SOLVERS[self.method].option_names)
        data["options"] = {k: v for k, v in data["options"].items() if k in used}
        if data["output"]["mode_shapes"] is None:
            del data["output"]["mode_shapes"]  # requests from before the field keep their key
        if not data["loads"]:
            del data["loads"]  # no loads: the key of a request from before the field
        return data


def _output_cost(
    units: int, per_sample: int, fixed: int, terms: str, runs: int, prefix: str
) -> Cost:
    """A simulation's (or ``runs`` of them: a comparison's) numbers against
    :data:`MAX_OUTPUT_VALUES`, naming ``{prefix}time.samples`` and the largest count that
    fits (the eigenvalue times counted at their most, so the count fits as stated)."""
    largest = (MAX_OUTPUT_VALUES // runs - fixed) // per_sample
    times = "" if runs == 1 else f" and {runs} methods"
    advice = (
        f"at most {largest} samples with these outputs{times}"
        if largest >= 2
        else "fewer output.eigen_samples, output.eigen_modes or mode shapes first"
    )
    fields = ("time.samples", "output.positions", "output.modal", "output.eigen_samples")
    return Cost(
        units=units,
        bound=MAX_OUTPUT_VALUES,
        unit="values",
        fields=tuple(prefix + f for f in fields),
        terms=terms,
        budget="output budget",
        advice=advice,
    )


#: the paper's section-5 example (:mod:`pipeflow.paper`), v = 0.4 t m/s, w0 = 100 rad/s,
#: 10 modes, 1 s
PAPER_EXAMPLE: dict[str, Any] = SimulationSpec.model_json_schema()["examples"][0]


class CompareSpec(StrictModel):
    """Body of ``POST /v1/compare``: one simulation, several methods."""

    model_config = ConfigDict(
        json_schema_extra={
            "examples": [{"simulation": PAPER_EXAMPLE, "methods": ["cma", "magnus", "rk4"]}]
        },
    )

    simulation: SimulationSpec = Field(
        description="The case to run; its 'method' is ignored, its 'options' apply to every "
        "method that reads them."
    )
    methods: list[Literal[tuple(sorted(SOLVERS))]] = Field(  # type: ignore[valid-type]
        default_factory=default_methods,
        min_length=1,
        max_length=MAX_METHODS,
        description="Distinct method names to run (default: every method but 'reference' "
        "and 'auto').",
        json_schema_extra={"uniqueItems": True},
    )

    @field_validator("methods")
    @classmethod
    def _distinct(cls, v: list[str]) -> list[str]:
        if len(set(v)) != len(v):
            raise InvalidField("methods must be distinct", "methods")
        return v

    @model_validator(mode="after")
    def _budget(self) -> CompareSpec:
        return self.within_budget()

    def cost(self) -> Cost:
        """Each method's run is held until the comparison is written: the methods times one
        simulation's numbers against :data:`MAX_OUTPUT_VALUES`."""
        runs = len(self.methods)
        per_sample, fixed, units, terms = self.simulation.output_values()
        return _output_cost(
            runs * units,
            per_sample,
            fixed,
            f"{runs} methods x ({terms})",
            runs,
            "simulation.",
        )

    def canonical(self) -> dict[str, Any]:
        """Normalised form for the cache key: every option kept (each method reads its own)."""
        data = self.simulation.model_dump(mode="json")
        data.pop("method")
        if not data["loads"]:
            del data["loads"]  # no loads: the key of a request from before the field
        return {"simulation": data, "methods": list(self.methods)}
