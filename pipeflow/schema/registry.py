"""The registry of computations: every kind of request pipeflow answers, in one table.

An entry (:class:`Computation`) names the request model, the response model, the function
that runs it (a plain library call: validated request in, JSON-ready dict out), its cost
bound, its plots and CSV tables, its OpenAPI examples, and where library parameter names
land in the request (:attr:`Computation.fields`).  Everything else is derived from
:data:`COMPUTATIONS`: the service's routes and job kinds, the union of result documents,
the OpenAPI examples and the command line's kinds.

Adding a computation is one :func:`register` call here plus its function.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Annotated, Any, Union

from pydantic import BaseModel, Field, TypeAdapter

from pipeflow._types import Progress
from pipeflow.compare import MAX_METHODS, compare
from pipeflow.errors import PipeflowError
from pipeflow.io.export import SIMULATION_TABLES
from pipeflow.io.json import json_safe
from pipeflow.io.plots import available_plots
from pipeflow.schema import results as r
from pipeflow.schema import stability as s
from pipeflow.schema.simulation import (
    PAPER_EXAMPLE,
    SIMULATION_FIELDS,
    CompareSpec,
    SimulationSpec,
    request_field,
)
from pipeflow.schema.simulation import run_simulation as simulate_request
from pipeflow.schema.stability import STABILITY_FIELDS
from pipeflow.schema.study import MAX_CASES, STABILITY_STUDY_EXAMPLE, STUDY_EXAMPLE, StudySpec
from pipeflow.stability.floquet import MAX_CHART_WORK, MAX_STEPS
from pipeflow.stability.maps import MAX_MAP_WORK
from pipeflow.study import run_study

Run = Callable[[Any, Progress | None], dict[str, Any]]


@dataclass(frozen=True)
class Endpoint:
    """Where a group of computations is asked for: ``POST /v1/<path>`` and its job form.

    Several computations share one endpoint when their request models are told apart by
    ``kind`` (``/v1/sweeps``).  ``run_operation`` is None for endpoints that always answer
    with a job (202); the operation ids are stable so the OpenAPI document only changes
    when the API does.
    """

    path: str
    tag: str
    summary: str
    description: str
    run_operation: str | None
    job_operation: str
    job_summary: str
    #: extra paths accepting the job form (``/v1/jobs`` for simulations), with operation ids
    job_aliases: tuple[tuple[str, str], ...] = ()


@dataclass(frozen=True)
class Computation:
    """One kind of computation (see the module docstring)."""

    name: str
    request: type[BaseModel]
    response: type[BaseModel]
    run: Run
    endpoint: Endpoint | None
    #: what bounds a request's work beyond the request model's own bounds (library budgets)
    budget: str
    plots: tuple[str, ...] = ()
    tables: tuple[str, ...] = ()
    examples: Mapping[str, dict[str, Any]] = field(default_factory=dict)
    #: library parameter name -> request field (JSON path); unnamed ones map to themselves
    fields: Mapping[str, str] = field(default_factory=dict)
    #: validation too costly for model validation (run by :func:`parse`, in a thread by the
    #: service before it accepts the request; raises ValidationError naming the field)
    check: Callable[[Any], None] | None = None

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
        the names of its figures in ``plots``.

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


def computations_at(endpoint: Endpoint) -> list[Computation]:
    """The computations asked for at ``endpoint``, in registration order."""
    return [c for c in COMPUTATIONS.values() if c.endpoint is endpoint]


def endpoints() -> list[Endpoint]:
    """Every endpoint of the registered computations, in registration order."""
    out: list[Endpoint] = []
    for c in COMPUTATIONS.values():
        if c.endpoint is not None and c.endpoint not in out:
            out.append(c.endpoint)
    return out


def request_type(endpoint: Endpoint) -> Any:
    """The body type of ``endpoint``: its one request model, or their union by ``kind``."""
    models = [c.request for c in computations_at(endpoint)]
    if len(models) == 1:
        return models[0]
    return Annotated[Union[tuple(models)], Field(discriminator="kind")]  # noqa: UP007


def response_type(endpoint: Endpoint) -> Any:
    """The result document of ``endpoint`` (a union where it has several computations)."""
    models = list(dict.fromkeys(c.response for c in computations_at(endpoint)))
    return models[0] if len(models) == 1 else Union[tuple(models)]  # noqa: UP007


def parse(endpoint: Endpoint, data: Any) -> BaseModel:
    """Validate a JSON body (already decoded) for ``endpoint``, including its computation's
    :attr:`Computation.check` (raises ValidationError)."""
    model: BaseModel = TypeAdapter(request_type(endpoint)).validate_python(data)
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

SIMULATIONS = Endpoint(
    path="simulations",
    tag="simulations",
    summary="Run one simulation (or serve it from the cache)",
    description="Validate the spec, then answer with the result: cached if an equivalent "
    "request (same key) was computed before, otherwise computed in a worker process.  "
    "Identical concurrent requests share one computation.",
    run_operation="runSimulation",
    job_operation="submitSimulationJob",
    job_summary="Submit a simulation as a job",
    job_aliases=(("/v1/jobs", "submitJob"),),
)


def run_simulation(spec: SimulationSpec, progress: Progress | None) -> dict[str, Any]:
    """:func:`pipeflow.simulation.simulate` (see :meth:`~pipeflow.simulation.Result.to_dict`)."""
    return simulate_request(spec, progress).to_dict()


SIMULATION = register(
    Computation(
        name="simulation",
        request=SimulationSpec,
        response=r.SimulationResponse,
        run=run_simulation,
        endpoint=SIMULATIONS,
        budget="the solver refuses runs over options.max_steps steps",
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
    )
)

COMPARE_ENDPOINT = Endpoint(
    path="compare",
    tag="compare",
    summary="Run one case with several methods; wall times and differences",
    description="Run ``simulation`` with each of ``methods``; for each, the solve and wall "
    "time [s], the speed-up against the slowest, its estimated relative error [-] and its "
    "relative difference from the most accurate method (``baseline``) on the modal state and "
    "on the tip displacement [-].  Cached like simulations (the timings are those of the run "
    "that filled the cache: ``X-Cache`` says which).",
    run_operation="compareMethods",
    job_operation="submitCompareJob",
    job_summary="Submit a method comparison as a job",
)


def run_compare(spec: CompareSpec, progress: Progress | None) -> dict[str, Any]:
    """:func:`pipeflow.compare.compare` of the request's simulation and methods."""
    return compare(spec.simulation.to_simulation(), spec.methods, progress)


COMPARE = register(
    Computation(
        name="compare",
        request=CompareSpec,
        response=r.CompareResponse,
        run=run_compare,
        endpoint=COMPARE_ENDPOINT,
        budget=f"one simulation's bound per method, at most {MAX_METHODS} methods",
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


def run_analysis(spec: s.StabilitySpec | s.SweepModel, progress: Progress | None) -> dict[str, Any]:
    """A stability analysis or sweep: its model's ``run`` (the plain library call)."""
    return spec.run(progress)


STABILITY_ENDPOINT = Endpoint(
    path="stability",
    tag="stability",
    summary="Critical flow velocities at constant spin (or served from the cache)",
    description="Every crossing of the stability boundary (sigma = 0) for flow velocities v "
    "[m/s] in ``velocity_range`` at constant spin w0 [rad/s]: flutter or divergence, loss or "
    "gain, the crossing mode and its frequency [rad/s], each located by root-finding.  "
    "``critical_velocity`` [m/s] is the first loss (null when stable throughout); the "
    "non-dimensional u_cr, beta and gamma are in ``dimensionless``.  The v < 0 part of the "
    "range (reverse flow, the aspirating pipe) gets the caveat in ``reverse_flow`` and no "
    "threshold.  Cached like simulations (``X-Cache``, ``?refresh=true``).",
    run_operation="runStability",
    job_operation="submitStabilityJob",
    job_summary="Submit a critical-velocity analysis as a job",
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
        run=run_analysis,
        endpoint=STABILITY_ENDPOINT,
        budget="one frozen spectrum per point",
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
    )
)

SWEEPS = Endpoint(
    path="sweeps",
    tag="sweeps",
    summary="Submit a sweep, stability map or Floquet analysis as a job",
    description="Accept the computation named by ``kind`` and answer at once with its job "
    "(202, ``Location: /v1/jobs/{key}``; the job's ``kind`` is the spec's):\n\n"
    "- ``argand``: eigenvalues sigma [1/s] + i omega [rad/s] against flow velocity [m/s] at "
    "constant spin, modes tracked by left/right eigenvector overlap (optimal assignment), "
    "with a per-point confidence and refinement where it drops;\n"
    "- ``campbell``: the same against spin w0 [rad/s] (also in Hz and rpm) at constant v;\n"
    "- ``spin_map``: growth rate over (w0, v) and the critical velocity [m/s] at each spin;\n"
    "- ``beta_map``: u_cr(beta) in non-dimensional form, every crossing (S-shaped segments);\n"
    "- ``resonance_chart``: Floquet chart of pulsating flow over amplitude [m/s] and "
    "frequency [rad/s];\n"
    "- ``floquet``: multipliers, exponents and a verdict for one harmonic flow and/or spin.\n\n"
    "Poll ``GET /v1/jobs/{key}`` (status, progress 0..1), then fetch "
    "``GET /v1/results/{key}``; its ``plots`` name the figures at "
    "``/v1/results/{key}/plots/{name}.png``.  Resubmitting is idempotent.  Sweeps and maps "
    "can be large, so they always run as jobs; a sweep already computed answers 202 with a "
    "job that has already ``succeeded``.",
    run_operation=None,
    job_operation="submitSweep",
    job_summary="Submit a sweep, stability map or Floquet analysis as a job",
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
            endpoint=SWEEPS,
            budget=budget,
            plots=plots,
            examples={name: {"summary": summary, "value": {"kind": name, **example}}},
            fields=STABILITY_FIELDS,
        )
    )


ARGAND = _sweep(
    s.ArgandSweep,
    r.SweepResponse,
    "one frozen spectrum per point, at most max_points (4 x points) after refinement",
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
    "one frozen spectrum per point, at most max_points (4 x points) after refinement",
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
    f"one monodromy matrix over the common period, at most {MAX_STEPS} Magnus steps",
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

#: names of the computations asked for by ``kind`` at ``/v1/sweeps`` (the CLI's sweep kinds)
SWEEP_KINDS: tuple[str, ...] = tuple(c.name for c in computations_at(SWEEPS))

STUDIES = Endpoint(
    path="studies",
    tag="studies",
    summary="Submit a design study (many cases of one simulation or stability analysis)",
    description="Accept a study and answer at once with its job (202, "
    "``Location: /v1/jobs/{key}``): a ``base`` simulation or stability request and either "
    "``cases`` (a list of overrides) or ``grid`` (values per field, every combination), "
    "overriding numeric fields by dotted path (``pipe.E`` [Pa], ``pipe.L`` [m], ``pipe.M2`` "
    "[kg/m], ``rotation.omega0.value`` [rad/s], ``flow.velocity.coefficients.1`` [m/s^2], "
    "...).  Every case is validated by the base request model before any work (a 422 "
    "names the study field: ``cases.3.pipe.E``, ``grid.pipe.L.2``).  Each case is cached "
    "under its own key, the key of the same request sent alone: a study overlapping an "
    "earlier one computes only its new cases.  The job's progress is the fraction of cases "
    "done.  The result (``GET /v1/results/{key}``) is a table, one row per case: its "
    "overrides, its key, ok or failed (with the problem's type, field and detail: one "
    "failing case does not fail the study), and for simulations the peak tip displacement "
    "[m], the damping sigma [1/s] and frequency omega [rad/s] of the fundamental at t_end "
    "and the method used, for stability the critical velocity [m/s] and the mode that loses "
    "stability; ``?format=csv`` gives it as CSV with units in the header.",
    run_operation=None,
    job_operation="submitStudy",
    job_summary="Submit a design study as a job",
)


def run_study_request(spec: StudySpec, progress: Progress | None) -> dict[str, Any]:
    """:func:`pipeflow.study.run_study` (cases fanned out on the current host)."""
    return run_study(spec, progress)


STUDY = register(
    Computation(
        name="study",
        request=StudySpec,
        response=r.StudyResponse,
        run=run_study_request,
        endpoint=STUDIES,
        budget=f"at most {MAX_CASES} cases (the list's length or the grid's product), each "
        f"bounded as its base computation is (simulation: {SIMULATION.cost}; stability: "
        f"{STABILITY.cost}): at most {MAX_CASES} times the base's bound",
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
