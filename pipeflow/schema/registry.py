"""The registry of computations: every kind of request pipeflow answers, in one table.

An entry (:class:`Computation`) names the request model, the response model, the function
that runs it (a plain library call: validated request in, the JSON-ready dict of the
response model out, written by :mod:`pipeflow.schema.documents`), its cost
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
from pipeflow.batch import eligible, summaries
from pipeflow.compare import MAX_METHODS, compare
from pipeflow.errors import PipeflowError
from pipeflow.frequency import MAX_FREQUENCIES
from pipeflow.io.export import FREQUENCY_TABLES, SIMULATION_TABLES
from pipeflow.io.json import json_safe
from pipeflow.io.plots import available_plots
from pipeflow.schema import documents
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
from pipeflow.schema.simulation import run_simulation as simulate_request
from pipeflow.schema.stability import STABILITY_FIELDS
from pipeflow.schema.study import (
    MAX_CASES,
    MAX_STUDY_REQUESTS,
    STABILITY_STUDY_EXAMPLE,
    STUDY_EXAMPLE,
    StudySpec,
)
from pipeflow.schema.study_runner import Column, run_study
from pipeflow.simulation import Simulation
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
        (:mod:`pipeflow.schema.documents` writes it with
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


def _peak(values: Sequence[float | None]) -> float | None:
    finite = [abs(v) for v in values if v is not None]
    return max(finite) if finite else None


def _last(values: Sequence[float | None]) -> float | None:
    return values[-1] if values else None


def run_simulation(spec: SimulationSpec, progress: Progress | None) -> dict[str, Any]:
    """:func:`pipeflow.simulation.simulate`, its document
    (:func:`pipeflow.schema.documents.simulation`)."""
    return documents.simulation(simulate_request(spec, progress))


#: run time of the closed-form (constant coefficients) simulation, measured on one core of
#: the 2-core reference machine: 1.9-2.1 ms at 5 modes, 2.1-3.7 ms at 10, 2.9-6.1 ms at 20
#: modes over 501-2001 samples; fixed part [s] and part per sample and squared mode [s]
LTI_FIXED_S = 2e-3
LTI_PER_SAMPLE_MODE2_S = 1e-8


def run_time_simulation(spec: SimulationSpec) -> float | None:
    """:attr:`Computation.run_time` of a simulation: only the closed form has one (constant
    flow and spin, ``auto`` or ``cma``: one eigen-decomposition, then one matrix product
    per sample); a time-variant run's cost depends on the step control (the paper's
    example: 37 ms to 6.4 s over 5-20 modes, 501-2001 samples, 1-4 s; fewer samples can
    cost more), so it has none."""
    constant = all(
        profile.kind == "constant" for profile in (spec.flow.velocity, spec.rotation.omega0)
    )
    if not constant or spec.method not in ("auto", "cma") or spec.loads:
        return None  # a forced run's convolution costs with its loads' time scales
    samples = spec.time.samples + spec.output.eigen_samples
    return LTI_FIXED_S + LTI_PER_SAMPLE_MODE2_S * samples * spec.modes**2


#: run time of one frozen eigenvalue stack entry (``numpy.linalg.eigvals`` of an n x n
#: state matrix, n = 2 x modes) on one core of the 2-core reference machine, fixed + per n^3
#: [s]: measured 12, 47, 208 and 1,720 us at n = 10, 20, 40, 80 (this gives 10, 45, 325 and
#: 2,565 us); a time-variant run computes two stacks of ``output.eigen_samples`` (the traced
#: spectrum and the CMA exponents)
EIGVALS_FIXED_S = 5e-6
EIGVALS_PER_N3_S = 5e-9


def metered_run_time_simulation(spec: SimulationSpec) -> float | None:
    """:attr:`Computation.metered_run_time` of a simulation: a time-variant run of
    ``magnus`` (``auto``'s choice there) without loads meters its propagations
    (:func:`pipeflow.solvers.magnus.propagate`); the rest is the closed form's output
    work (:data:`LTI_FIXED_S`, :data:`LTI_PER_SAMPLE_MODE2_S`) and two eigenvalue stacks
    (the paper's example: 22 ms estimated, 21 ms measured beside 38 ms of propagations)."""
    if spec.method not in ("auto", "magnus") or spec.loads:
        return None  # other solvers do not meter; a forced run's cost follows its loads
    n = 2 * spec.modes
    stack = max(2, min(spec.output.eigen_samples, spec.time.samples))  # as simulate() does
    samples = spec.time.samples + stack
    eigen = 2 * stack * (EIGVALS_FIXED_S + EIGVALS_PER_N3_S * n**3)
    return LTI_FIXED_S + LTI_PER_SAMPLE_MODE2_S * samples * spec.modes**2 + eigen


#: a simulation's row in a design study
SIMULATION_SUMMARY = (
    Column("peak_tip_displacement", "m", "max |u(L, t)| over the output times."),
    Column(
        "final_sigma_1",
        "1/s",
        "Damping sigma of the fundamental (branch 1 of the "
        "frozen spectrum) at the last output time t_end; > 0: growing.",
    ),
    Column("final_omega_1", "rad/s", "Frequency omega of the fundamental at t_end."),
    Column("method_used", "", "The solver that ran (what 'auto' chose)."),
    Column("result_status", "", "The simulation's status: ok, diverging, diverged or overflow."),
)


def summarize_simulation(result: dict[str, Any]) -> dict[str, Any]:
    """A simulation result (JSON) reduced to :data:`SIMULATION_SUMMARY`."""
    fundamental = result["fundamental"]
    return {
        "peak_tip_displacement": _peak(result["tip_displacement"]),
        "final_sigma_1": _last(fundamental["sigma"]),
        "final_omega_1": _last(fundamental["omega"]),
        "method_used": result["method_used"],
        "result_status": result["status"],
    }


def summarize_simulations(requests: Sequence[SimulationSpec]) -> list[dict[str, Any] | None]:
    """The study rows of the constant-coefficient and time-variant cases among ``requests``
    by stacked computations (:func:`pipeflow.batch.summaries`, equal to
    :func:`summarize_simulation` of each one's result); None for the others."""
    sims: list[Simulation | None] = []
    for spec in requests:
        try:
            sims.append(spec.to_simulation())
        except Exception:  # the single run reports it
            sims.append(None)
    found = iter(summaries([s for s in sims if s is not None]))
    out: list[dict[str, Any] | None] = []
    for sim in sims:
        row = next(found) if sim is not None else None
        out.append(None if row is None else {"status": "ok", **vars(row)})
    return out


def simulation_batchable(spec: SimulationSpec) -> bool:
    """Whether :func:`summarize_simulations` computes ``spec`` itself
    (:func:`pipeflow.batch.eligible`)."""
    try:
        return eligible(spec.to_simulation())
    except Exception:
        return False


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


def run_compare(spec: CompareSpec, progress: Progress | None) -> dict[str, Any]:
    """:func:`pipeflow.compare.compare` of the request's simulation and methods, its
    document (:func:`pipeflow.schema.documents.compare`)."""
    return documents.compare(compare(spec.simulation.to_simulation(), spec.methods, progress))


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


def run_analysis(
    spec: s.StabilitySpec | s.SweepModel | f.FrequencyResponseSpec | ssp.StateSpaceSpec,
    progress: Progress | None,
) -> dict[str, Any]:
    """A stability analysis, sweep or frequency response: its model's ``run`` (the plain
    library call)."""
    return spec.run(progress)


#: the paper's pipe (beta = 0.467) at w0 = 100 rad/s: flutter of mode 3 at v = 27.69 m/s
PAPER_STABILITY: dict[str, Any] = {
    "pipe": s.PAPER_PIPE_JSON,
    "rotation": {"omega0": {"kind": "constant", "value": 100.0}},
    "modes": 10,
    "velocity_range": [0.0, 60.0],
}

#: a critical-velocity analysis's row in a design study
STABILITY_SUMMARY = (
    Column(
        "critical_velocity",
        "m/s",
        "First loss of stability from the start of the range, where the pipe is stable "
        "(null: none; or already unstable at the start, see stable_at_start).",
    ),
    Column("critical_mode", "-", "The mode that loses stability there."),
    Column("critical_kind", "", "flutter or divergence."),
    Column(
        "critical_frequency",
        "rad/s",
        "Frequency omega of the branch that loses stability, at the critical velocity (0 for "
        "divergence).",
    ),
    Column("stable_at_start", "", "Stable at the start of the v >= 0 part of the range."),
    Column("stable_throughout", "", "Stable over the whole v >= 0 part of the range."),
)


def summarize_stability(result: dict[str, Any]) -> dict[str, Any]:
    """A critical-velocity result (JSON) reduced to :data:`STABILITY_SUMMARY`.  A pipe
    already unstable at the start of its range has no critical velocity here (the result's
    ``critical_velocity`` is then a loss after stability is regained: not a threshold from
    rest to be compared, averaged or ranked)."""
    critical = result["critical_velocity"] if result["stable_at_start"] else None
    first = next(
        (c for c in result["crossings"] if c["direction"] == "loss" and c["velocity"] == critical),
        None,
    )
    return {
        "critical_velocity": critical,
        "critical_mode": first["mode"] if first else None,
        "critical_kind": first["kind"] if first else None,
        "critical_frequency": first["frequency"] if first else None,
        "stable_at_start": result["stable_at_start"],
        "stable_throughout": result["stable_throughout"],
    }


STABILITY = register(
    Computation(
        name="stability",
        request=s.StabilitySpec,
        response=r.StabilityResponse,
        run=run_analysis,
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
            run=run_analysis,
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
        run=run_analysis,
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
        run=run_analysis,
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
    """:func:`pipeflow.schema.study_runner.run_study` with the base computation of the
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
