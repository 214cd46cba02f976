"""The registry of computations: every kind of request pipeflow answers, in one table.

An entry (:class:`Computation`) names the request model, the response model, the function
that runs it (a plain library call: validated request in, the JSON-ready dict of the
response model out, written by :mod:`pipeflow.computations.documents`), its cost
bound, its plots and CSV tables, its examples, where library parameter names land in the
request (:attr:`Computation.fields`) and, for the computations a design study can vary,
its study summary (:attr:`Computation.summary_columns`, :attr:`Computation.summarize`).
Everything else is derived from :data:`COMPUTATIONS`: the job kinds, the union of result
documents, the examples and the command line's and the clients' kinds.

The registry names computations only; it knows nothing of HTTP.  Where each one is asked
for (URL path, tag, operation ids) is the service's table
(:mod:`service.routes.endpoints`, keyed by the computation's name).

Adding a computation is one :func:`register` call here plus its function (and, to serve
it, one line of the service's table).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Annotated, Any, Union

from pydantic import BaseModel, Field, TypeAdapter

from pipeflow._types import Progress
from pipeflow.compare import MAX_METHODS
from pipeflow.computations import stability as stability_runs
from pipeflow.computations.frequency import run_frequency_response, run_state_space
from pipeflow.computations.simulation import SIMULATION_SUMMARY as SIMULATION_SUMMARY
from pipeflow.computations.simulation import (
    metered_run_time_simulation as metered_run_time_simulation,
)
from pipeflow.computations.simulation import run_compare as run_compare
from pipeflow.computations.simulation import run_simulation as run_simulation
from pipeflow.computations.simulation import run_time_simulation as run_time_simulation
from pipeflow.computations.simulation import simulation_batchable as simulation_batchable
from pipeflow.computations.simulation import summarize_simulation as summarize_simulation
from pipeflow.computations.simulation import summarize_simulations as summarize_simulations
from pipeflow.computations.stability import STABILITY_SUMMARY as STABILITY_SUMMARY
from pipeflow.computations.stability import summarize_stability as summarize_stability
from pipeflow.computations.study_runner import Column, run_study
from pipeflow.errors import PipeflowError
from pipeflow.frequency import MAX_FREQUENCIES
from pipeflow.io.export import FREQUENCY_TABLES, SIMULATION_TABLES
from pipeflow.io.json import json_safe
from pipeflow.io.plots import available_plots
from pipeflow.schema import frequency as f
from pipeflow.schema import results as r
from pipeflow.schema import stability as s
from pipeflow.schema import state_space as ssp
from pipeflow.schema.simulation import (
    MAX_OUTPUT_VALUES,
    PAPER_EXAMPLE,
    SIMULATION_FIELDS,
    CompareSpec,
    Cost,
    SimulationSpec,
    request_field,
)
from pipeflow.schema.stability import STABILITY_FIELDS
from pipeflow.schema.study import (
    MAX_CASES,
    MAX_STUDY_REQUESTS,
    STABILITY_STUDY_EXAMPLE,
    STUDY_EXAMPLE,
    StudySpec,
)
from pipeflow.stability.floquet import MAX_CHART_WORK, MAX_STEPS
from pipeflow.stability.maps import MAX_MAP_WORK

Run = Callable[[Any, Progress | None], dict[str, Any]]


@dataclass(frozen=True)
class Computation:
    """One kind of computation (see the module docstring)."""

    name: str
    request: type[BaseModel]
    response: type[BaseModel]
    run: Run
    #: what bounds a request's work beyond the request model's own bounds (library budgets)
    budget: str
    plots: tuple[str, ...] = ()
    tables: tuple[str, ...] = ()
    examples: Mapping[str, dict[str, Any]] = field(default_factory=dict)
    #: library parameter name -> request field (JSON path); unnamed ones map to themselves
    fields: Mapping[str, str] = field(default_factory=dict)
    #: the request's estimated cost against its bound (units, bound, the fields that set
    #: it: :class:`~pipeflow.schema.simulation.Cost`), the request model's own
    #: :meth:`~pipeflow.schema.simulation.StrictModel.cost`; the model's validation refuses
    #: a request over it (:meth:`~pipeflow.schema.simulation.StrictModel.within_budget`), so
    #: the library call, the command line and the service refuse it alike
    estimate: Callable[[Any], Cost | None] | None = None
    #: validation too costly for model validation (run by :func:`parse`, in a thread by the
    #: service before it accepts the request; raises ValidationError naming the field)
    check: Callable[[Any], None] | None = None
    #: the columns a design study gives each case of this computation (empty: a study
    #: cannot vary it) and the function reducing the JSON of :meth:`execute` to them
    summary_columns: tuple[Column, ...] = ()
    summarize: Callable[[dict[str, Any]], dict[str, Any]] | None = None
    #: optional: the summaries of a chunk of validated requests at once (``{"status": "ok",
    #: **summary}``, equal to :attr:`summarize` of :meth:`execute`), None for the requests
    #: it leaves to :meth:`execute` (the study runner gives it each chunk first)
    summarize_many: Callable[[Sequence[Any]], list[dict[str, Any] | None]] | None = None
    #: whether :attr:`summarize_many` takes a request of this kind (a study whose base it
    #: takes runs in larger chunks)
    batchable: Callable[[Any], bool] | None = None
    #: a validated request's estimated run time on one core [s] (execute + encode), or
    #: None where it cannot be told cheaply (not its cost bound: :attr:`estimate`); the
    #: service runs a request estimated below
    #: its ``fast_lane_max_s`` in the API process instead of a worker
    run_time: Callable[[Any], float | None] | None = None
    #: for a request whose work of unknown cost is metered (it calls
    #: :func:`pipeflow.parallel.charge` before each part: magnus's propagations), the
    #: estimated run time of the rest on one core [s]; None: not metered.  The service
    #: runs such a request estimated below its ``fast_lane_max_s`` in the API process under
    #: an allowance of ``fast_lane_max_metered_s`` and hands it to a worker at the first
    #: part that would pass it
    metered_run_time: Callable[[Any], float | None] | None = None

    @property
    def cost(self) -> str:
        """The cost bound: the request model's upper bounds on counts, then :attr:`budget`."""
        return "; ".join([*count_bounds(self.request), self.budget])

    def request_field(self, parameter: str | None) -> str | None:
        """The request field (dotted JSON path) of the library's ``parameter``."""
        if parameter is None:
            return None
        return self.fields.get(parameter, parameter)

    def execute(self, request: BaseModel, progress: Progress | None = None) -> dict[str, Any]:
        """Run a validated request: the JSON-ready result (every float finite or null) with
        ``kind`` first where :attr:`response` has one and the names of its figures in
        ``plots``.  The run's dict is already a document of :attr:`response`
        (:mod:`pipeflow.computations.documents` writes it with
        :func:`pipeflow.schema.results.document`); it is not validated
        again here (a design study runs this per case).

        A :class:`~pipeflow.errors.PipeflowError` leaves with ``field`` set to the request
        field of the library parameter it names (:meth:`request_field`).
        """
        try:
            result = self.run(request, progress)
        except PipeflowError as exc:
            request_field(exc, self.fields)  # the one mapping: library name -> request field
            raise
        if "kind" in self.response.model_fields:  # analyses echo their kind first
            result = {"kind": self.name, **result}
        result = dict(json_safe(result))
        result["plots"] = [p for p in available_plots(result) if p in self.plots]
        return result


def count_bounds(model: type[BaseModel], prefix: str = "") -> list[str]:
    """``"field <= bound"`` for every integer field of ``model`` (nested models included)
    with an upper bound: what a request can ask for, read from its one definition."""
    out = []
    for name, info in model.model_fields.items():
        ann = info.annotation
        if isinstance(ann, type) and issubclass(ann, BaseModel):
            out += count_bounds(ann, f"{prefix}{name}.")
            continue
        bound = next((m.le for m in info.metadata if getattr(m, "le", None) is not None), None)
        if ann is int and bound is not None:
            out.append(f"{prefix}{name} <= {bound}")
    return out


COMPUTATIONS: dict[str, Computation] = {}


def register(computation: Computation) -> Computation:
    """Add ``computation`` to :data:`COMPUTATIONS` (its name is the job kind)."""
    COMPUTATIONS[computation.name] = computation
    return computation


def _named(kinds: str | Sequence[str]) -> list[Computation]:
    names = [kinds] if isinstance(kinds, str) else list(kinds)
    unknown = [n for n in names if n not in COMPUTATIONS]
    if unknown or not names:
        raise KeyError(
            f"unknown computation {', '.join(map(repr, unknown)) or '(none given)'}; "
            f"the computations are: {', '.join(COMPUTATIONS)}"
        )
    return [COMPUTATIONS[n] for n in names]


def request_type(kinds: str | Sequence[str]) -> Any:
    """The request type of the computation named ``kinds``, or of several (their request
    models told apart by ``kind``)."""
    models = [c.request for c in _named(kinds)]
    if len(models) == 1:
        return models[0]
    return Annotated[Union[tuple(models)], Field(discriminator="kind")]  # noqa: UP007


def response_type(kinds: str | Sequence[str]) -> Any:
    """The result document of the computation(s) ``kinds`` (a union where they differ)."""
    models = list(dict.fromkeys(c.response for c in _named(kinds)))
    return models[0] if len(models) == 1 else Union[tuple(models)]  # noqa: UP007


def parse(kinds: str | Sequence[str], data: Any) -> BaseModel:
    """Validate a JSON body (already decoded) as a request of the computation named
    ``kinds`` (or of one of several, told apart by ``kind``), including its computation's
    :attr:`Computation.check` (raises ValidationError; KeyError for an unknown name)."""
    model: BaseModel = TypeAdapter(request_type(kinds)).validate_python(data)
    check = computation_for(model).check
    if check is not None:
        check(model)
    return model


def computation_for(request: BaseModel) -> Computation:
    """The computation a validated request belongs to (by model and, for sweeps, kind)."""
    kind = getattr(request, "kind", None)
    if isinstance(kind, str) and kind in COMPUTATIONS:
        return COMPUTATIONS[kind]
    for c in COMPUTATIONS.values():
        if type(request) is c.request:
            return c
    raise TypeError(f"no computation takes a {type(request).__name__}")


# -- the computations --------------------------------------------------------------------


SIMULATION = register(
    Computation(
        name="simulation",
        request=SimulationSpec,
        response=r.SimulationResponse,
        run=run_simulation,
        budget=f"time.samples x (2 + output positions + 2 x modes with output.modal) + "
        "eigenvalue times x (4 + 6 x output.eigen_modes) + the mode shapes <= "
        f"{MAX_OUTPUT_VALUES:,} numbers in the answer (about 45 MB of JSON; refused at "
        "validation, naming time.samples and the most samples that fit); the solver refuses "
        "runs over options.max_steps steps",
        estimate=SimulationSpec.cost,
        plots=(
            "tip_displacement",
            "damping",
            "frequency",
            "argand",
            "displacements",
            "mode_shapes",
        ),
        tables=SIMULATION_TABLES,
        examples={
            "paper": {
                "summary": "The paper's section 5: v = 0.4 t m/s, w0 = 100 rad/s, 10 modes, 1 s",
                "value": PAPER_EXAMPLE,
            }
        },
        fields=SIMULATION_FIELDS,
        summary_columns=SIMULATION_SUMMARY,
        summarize=summarize_simulation,
        summarize_many=summarize_simulations,
        batchable=simulation_batchable,
        run_time=run_time_simulation,
        metered_run_time=metered_run_time_simulation,
    )
)


COMPARE = register(
    Computation(
        name="compare",
        request=CompareSpec,
        response=r.CompareResponse,
        run=run_compare,
        budget=f"at most {MAX_METHODS} methods; methods x the simulation's numbers <= "
        f"{MAX_OUTPUT_VALUES:,} (each method's run is held until the comparison is written)",
        estimate=CompareSpec.cost,
        examples={
            "paper": {
                "summary": "The paper's v = 0.4 t case with cma, magnus and rk4",
                "value": {"simulation": PAPER_EXAMPLE, "methods": ["cma", "magnus", "rk4"]},
            }
        },
        fields={
            "methods": "methods",
            **{k: f"simulation.{v}" for k, v in SIMULATION_FIELDS.items()},
            "method": "methods",
        },
    )
)


#: the paper's pipe (beta = 0.467) at w0 = 100 rad/s: flutter of mode 3 at v = 27.69 m/s
PAPER_STABILITY: dict[str, Any] = {
    "pipe": s.PAPER_PIPE_JSON,
    "rotation": {"omega0": {"kind": "constant", "value": 100.0}},
    "modes": 10,
    "velocity_range": [0.0, 60.0],
}

STABILITY = register(
    Computation(
        name="stability",
        request=s.StabilitySpec,
        response=r.StabilityResponse,
        run=stability_runs.run_critical,
        budget=f"one frozen spectrum per point: points x (2 modes)^3 <= {MAX_MAP_WORK:g} "
        "(spectrum work)",
        estimate=s.StabilitySpec.cost,
        examples={
            "paper": {
                "summary": "The paper's pipe at w0 = 100 rad/s, v from 0 to 60 m/s, 10 modes",
                "description": "Flutter of mode 3 at v = 27.69 m/s (u_cr = 9.15).",
                "value": PAPER_STABILITY,
            },
            "reverse_flow": {
                "summary": "A range reaching reverse flow: answered with the aspirating-pipe "
                "caveat",
                "value": {**PAPER_STABILITY, "velocity_range": [-10.0, 60.0]},
            },
        },
        fields=STABILITY_FIELDS,
        summary_columns=STABILITY_SUMMARY,
        summarize=summarize_stability,
    )
)

_PAPER = s.PAPER_PIPE_JSON


def _sweep(
    model: type[Any],
    response: type[BaseModel],
    budget: str,
    plots: tuple[str, ...],
    summary: str,
    example: dict[str, Any],
) -> Computation:
    name = str(model.model_fields["kind"].default)
    return register(
        Computation(
            name=name,
            request=model,
            response=response,
            run=stability_runs.RUNS[model],
            budget=budget,
            estimate=model.cost,
            plots=plots,
            examples={name: {"summary": summary, "value": {"kind": name, **example}}},
            fields=STABILITY_FIELDS,
        )
    )


ARGAND = _sweep(
    s.ArgandSweep,
    r.SweepResponse,
    "one frozen spectrum per point, at most max_points (4 x points) after refinement: "
    f"max_points x (2 modes)^3 <= {MAX_MAP_WORK:g} (spectrum work)",
    ("argand", "sweep_frequency", "sweep_damping"),
    "Argand diagram: the paper's pipe, v from 0 to 60 m/s at w0 = 100 rad/s",
    {
        "pipe": _PAPER,
        "rotation": {"omega0": {"kind": "constant", "value": 100.0}},
        "modes": 10,
        "tracked_modes": 4,
        "velocity_range": [0.0, 60.0],
        "points": 201,
    },
)
CAMPBELL = _sweep(
    s.CampbellSweep,
    r.SweepResponse,
    "one frozen spectrum per point, at most max_points (4 x points) after refinement: "
    f"max_points x (2 modes)^3 <= {MAX_MAP_WORK:g} (spectrum work)",
    ("argand", "campbell", "sweep_frequency", "sweep_damping"),
    "Campbell diagram: the paper's pipe, w0 from 0 to 2000 rad/s at v = 10 m/s",
    {
        "pipe": _PAPER,
        "flow": {"velocity": {"kind": "constant", "value": 10.0}},
        "modes": 10,
        "tracked_modes": 4,
        "spin_range": [0.0, 2000.0],
    },
)
SPIN_MAP = _sweep(
    s.SpinMapSweep,
    r.SpinMapResponse,
    f"velocity_points x spin_points x (2 modes)^3 <= {MAX_MAP_WORK:g} (map work)",
    ("spin_map",),
    "Critical velocity against spin: 100 x 100 (v, w0) map of the paper's pipe",
    {
        "pipe": _PAPER,
        "modes": 10,
        "velocity_range": [0.0, 60.0],
        "spin_range": [0.0, 2000.0],
        "velocity_points": 100,
        "spin_points": 100,
    },
)
BETA_MAP = _sweep(
    s.BetaMapSweep,
    r.BetaMapResponse,
    f"beta_points x u_points x (2 modes)^3 <= {MAX_MAP_WORK:g} (map work)",
    ("beta_map",),
    "u_cr(beta) at gamma = 0 (Paidoussis' stability curve with its S-shapes)",
    {"modes": 10, "beta_range": [0.05, 0.95], "u_range": [0.0, 20.0], "beta_points": 50},
)
RESONANCE_CHART = _sweep(
    s.ResonanceChartSweep,
    r.ResonanceChartResponse,
    "amplitude_points x frequency_points x Magnus steps x (2 modes)^3 <= "
    f"{MAX_CHART_WORK:g} (chart work)",
    ("resonance_chart",),
    "Parametric resonance of pulsating flow v = 10 + a sin(Omega t) m/s",
    {
        "pipe": _PAPER,
        "modes": 4,
        "mean_velocity": 10.0,
        "amplitude_range": [0.0, 8.0],
        "frequency_range": [100.0, 4000.0],
    },
)
FLOQUET = _sweep(
    s.FloquetSweep,
    r.FloquetResponse,
    "one monodromy matrix over the common period: Magnus steps x (2 modes)^3 <= "
    f"{MAX_CHART_WORK:g} (chart work), at most {MAX_STEPS} steps",
    ("floquet_multipliers",),
    "Floquet multipliers: the paper's pipe with v = 10 + 5 sin(1000 t) m/s",
    {
        "pipe": _PAPER,
        "modes": 6,
        "flow": {
            "velocity": {"kind": "harmonic", "mean": 10.0, "amplitude": 5.0, "frequency": 1000.0}
        },
        "rotation": {"omega0": {"kind": "constant", "value": 100.0}},
    },
)

#: the sweeps, maps and Floquet analyses: computations whose request models carry their
#: name as ``kind`` (one body type, told apart by it; the command line's sweep kinds)
SWEEP_KINDS: tuple[str, ...] = (
    ARGAND.name,
    CAMPBELL.name,
    SPIN_MAP.name,
    BETA_MAP.name,
    RESONANCE_CHART.name,
    FLOQUET.name,
)


FREQUENCY_RESPONSE = register(
    Computation(
        name="frequency_response",
        request=f.FrequencyResponseSpec,
        response=r.FrequencyResponseResponse,
        run=run_frequency_response,
        estimate=f.FrequencyResponseSpec.cost,
        budget=f"response.positions x frequencies x operating points <= {f.MAX_FRF_VALUES:,} "
        f"values, frequencies being the list's length or count + 3 x modes x operating points "
        f"for a range (at most {MAX_FREQUENCIES}); one eigen-decomposition per operating point "
        "and a few direct solves to check it",
        plots=("bode", "nyquist", "waterfall", "deflection_shape"),
        tables=FREQUENCY_TABLES,
        examples={
            "hammer": {
                "summary": "Hammer test at the tip of the paper's pipe, w0 = 100 rad/s, v = 5 m/s",
                "description": "Receptance at the tip, 10 to 8000 rad/s (log), 10 modes: "
                "peaks at 244, 1768 and 5034 rad/s.",
                "value": f.HAMMER_EXAMPLE,
            },
            "waterfall": {
                "summary": "The same hammer test at v = 0, 5, 10 and 20 m/s (a waterfall)",
                "value": f.WATERFALL_EXAMPLE,
            },
        },
        fields=f.FREQUENCY_FIELDS,
    )
)


STATE_SPACE = register(
    Computation(
        name="state_space",
        request=ssp.StateSpaceSpec,
        response=ssp.StateSpaceResponse,
        run=run_state_space,
        estimate=ssp.StateSpaceSpec.cost,
        budget="one state matrix of 2 x modes states, C of positions x 2 x modes numbers",
        examples={
            "hammer": {
                "summary": "The hammer test's pipe, load and tip output as a state-space model",
                "value": ssp.STATE_SPACE_EXAMPLE,
            }
        },
        fields=ssp.STATE_SPACE_FIELDS,
    )
)


def run_study_request(spec: StudySpec, progress: Progress | None) -> dict[str, Any]:
    """:func:`pipeflow.computations.study_runner.run_study` with the base computation of the
    registry (cases fanned out on the current host)."""
    return run_study(spec, COMPUTATIONS[spec.base_kind], progress)


STUDY = register(
    Computation(
        name="study",
        request=StudySpec,
        response=r.StudyResponse,
        run=run_study_request,
        budget=f"at most {MAX_CASES} cases (the list's length or the grid's product), each "
        f"bounded as its base computation is (simulation: {SIMULATION.cost}; stability: "
        f"{STABILITY.cost}); cases x the estimate of the costliest case (the base with each "
        f"overridden count at its largest value) <= {MAX_STUDY_REQUESTS} times the base's "
        "bound",
        estimate=StudySpec.cost,
        tables=("study",),
        plots=("study_histograms", "sobol_indices"),
        check=StudySpec.check,
        examples={
            "simulation_grid": {
                "summary": "The paper's example (4 modes, 0.2 s) over fluid mass x spin, 6 cases",
                "value": STUDY_EXAMPLE,
            },
            "stability_spins": {
                "summary": "Critical velocity of the paper's pipe at four spins",
                "value": STABILITY_STUDY_EXAMPLE,
            },
        },
    )
)
