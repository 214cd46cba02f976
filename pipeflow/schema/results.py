"""Response models: the JSON of every computation's result, as the service serves it.

One model per result shape (:data:`pipeflow.computations.registry.COMPUTATIONS` names each
computation's), nested models for its parts.  They are the one definition of each
document's keys: :mod:`pipeflow.computations.documents` writes the library's results with
:func:`document`, which takes a model and the values by field name and refuses a name the
model lacks or a required field left out, on every call; the tests check that every field
of every model is written by some real result.  The service adds ``key``, ``cached`` and ``plots``
(:data:`SERVICE_FIELDS`), and :meth:`pipeflow.computations.registry.Computation.execute` puts
``kind`` first.  The client (:mod:`pipeflow_client`) validates what it receives with the
same models.  Every float is finite: where the library has no number (e.g. no critical
velocity) the field is null.
"""

from __future__ import annotations

from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field

# re-exported: the one namespace of the response models (pipeflow.schema.results)
from pipeflow.schema.result_base import (  # noqa: F401
    GROUP_NAMES,
    PLOTS_DESCRIPTION,
    SERVICE_FIELDS,
    _names,
    document,
)
from pipeflow.schema.result_base import Result as _Result
from pipeflow.schema.simulation import LoadSpec
from pipeflow.schema.stability_results import (  # noqa: F401
    MECHANISMS,
    BetaCrossing,
    BetaMapResponse,
    Crossing,
    Excitation,
    ExcitationCrossing,
    Exponents,
    FloquetResponse,
    MapCrossing,
    Mechanisms,
    Multipliers,
    ResonanceChartResponse,
    ResonanceRegion,
    ReverseFlow,
    SpinMapResponse,
    StabilityDimensionless,
    StabilityResponse,
    SweepAxis,
    SweepBoundaryCrossing,
    SweepBranch,
    SweepResponse,
    ZeroCrossing,
)

# -- POST /v1/simulations and /v1/compare ---------------------------------------------


class Trace(BaseModel):
    mode: int = Field(description="Mode number, 1 = lowest frequency at t = 0.")
    sigma: list[float] = Field(description="Real part of xi = sigma + i omega: damping [1/s].")
    omega: list[float] = Field(description="Imaginary part: frequency [rad/s].")
    confidence: list[float] = Field(
        description="Tracking confidence in [0, 1] [-] of the link to the previous time: "
        "1 - d1/d2 (> 0.99) where the eigenvalues alone decided (the nearest eigenvalue d1 "
        "much nearer than the second nearest d2), else the eigenvector correlation."
    )
    least_stable: bool | None = Field(
        None,
        description="Frozen spectrum only: this is the least stable branch of the whole "
        "spectrum (largest sigma over time), traced whether or not it is among the lowest.",
    )


class Spectrum(BaseModel):
    t: list[float] = Field(description="Times of the eigenvalues [s].")
    modes: list[Trace]


class Fundamental(BaseModel):
    sigma: list[float] = Field(description="Damping of the first branch [1/s].")
    omega: list[float] = Field(description="Frequency of the first branch [rad/s].")


class Station(BaseModel):
    x: float = Field(description="Station along the pipe [m].")
    u: list[float] = Field(description="Displacement u(x, t) [m].")


class Modal(BaseModel):
    d: list[list[float]] = Field(description="Modal coordinates d(t), shape (samples, modes) [m].")
    ddot: list[list[float]] = Field(description="Their rates d'(t) [m/s].")


class ShapeTrace(BaseModel):
    mode: int = Field(description="Branch number, as in `eigenvalues`.")
    sigma: list[float] = Field(description="Damping of the branch at each time [1/s].")
    omega: list[float] = Field(description="Frequency of the branch at each time [rad/s].")
    real: list[list[float]] = Field(
        description="Re Phi(x) [-] per time, then per station (max |Phi| = 1, 1 + 0i at its peak)."
    )
    imag: list[list[float]] = Field(description="Im Phi(x) [-] per time, then per station.")


class ModeShapesBlock(BaseModel):
    t: list[float] = Field(description="Times of the shapes [s].")
    x: list[float] = Field(description="Stations from the clamped end to the tip [m].")
    modes: list[ShapeTrace]


class SimulationDiagnostics(BaseModel):
    """How a simulation was computed and how far to trust it (the ``diagnostics`` of a
    simulation and of each method of a comparison).  Every field is optional (a method
    reports what applies to it: steps for stepping methods, the integrator's tolerances
    for the reference...); further method-specific entries are kept as extra fields."""

    model_config = ConfigDict(extra="allow")

    method: str | None = Field(None, description="The requested method.")
    method_used: str | None = Field(None, description="The solver that ran.")
    modes: int | None = Field(None, description="Galerkin modes [-].")
    state_size: int | None = Field(None, description="Size of the state vector (2 x modes) [-].")
    samples: int | None = Field(None, description="Output times [-].")
    steps: int | None = Field(None, description="Time steps taken [-].")
    step_min: float | None = Field(None, description="Smallest time step [s].")
    step_max: float | None = Field(None, description="Largest time step [s].")
    step_source: str | None = Field(
        None, description="What chose the step: 'step', 'tolerance' or 'samples'."
    )
    tolerance: float | None = Field(None, description="Requested local error tolerance [-].")
    rtol: float | None = Field(None, description="Reference integrator's relative tolerance [-].")
    atol: float | None = Field(None, description="Reference integrator's absolute tolerance [-].")
    integrator: str | None = Field(None, description="Reference integrator (scipy solve_ivp).")
    rhs_evaluations: int | None = Field(None, description="State-matrix products [-].")
    matrix_exponentials: int | None = Field(None, description="Matrix exponentials [-].")
    eigendecompositions: int | None = Field(None, description="Eigendecompositions [-].")
    quadrature_order: int | None = Field(None, description="Gauss points of the mode integrals.")
    attempts: int | None = Field(None, description="Solver attempts (refinements) [-].")
    time_invariant: bool | None = Field(None, description="Constant flow and spin.")
    max_growth_rate: float | None = Field(
        None, description="Largest real part of the frozen eigenvalues over the run [1/s]."
    )
    largest_stable_step: float | None = Field(None, description="RK4's stability bound [s].")
    stability_margin: float | None = Field(
        None, description="largest_stable_step / step_max (RK4; below 1: unstable) [-]."
    )
    expm_fallbacks: int | None = Field(
        None, description="CMA steps that fell back to a dense matrix exponential [-]."
    )
    steps_order_6: int | None = Field(None, description="Magnus steps of order 6 [-].")
    load_quadrature_nodes: int | None = Field(
        None, description="Quadrature nodes of the load convolution (CMA) [-]."
    )
    load_convolution: str | None = Field(None, description="How the CMA convolved the loads.")
    eigenvector_condition_max: float | None = Field(
        None, description="Largest condition number of the CMA eigenvector matrices [-]."
    )
    estimated_relative_error: float | None = Field(
        None, description="Estimated max relative error of the modal state [-]."
    )
    estimated_tip_relative_error: float | None = Field(
        None, description="The same on the tip displacement u(L, t) [-]."
    )
    error_estimate_method: str | None = Field(None, description="How the estimate was obtained.")
    error_estimate_resolution: float | None = Field(
        None, description="Estimated error of the yardstick run itself [-]."
    )
    error_estimate_seconds: float | None = Field(None, description="Cost of the estimate [s].")
    solve_seconds: float | None = Field(None, description="Time inside the solver [s].")
    wall_seconds: float | None = Field(None, description="Whole run [s].")


class SimulationResponse(BaseModel):
    """A simulation result with its parameter hash."""

    model_config = ConfigDict(extra="allow")

    key: str = Field(description="Parameter hash (SHA-256 hex) identifying this result.")
    cached: bool = Field(description="True when served from the cache, not computed now.")
    status: Literal["ok", "diverging", "diverged", "overflow"] = Field(
        description="ok; diverging (a branch of the frozen spectrum grows at t_end, the "
        "deflection still within divergence_bound); diverged (the deflection passed "
        "divergence_bound, the linear model's range: the history stops at divergence_time); "
        "overflow (samples after double-precision overflow are omitted)."
    )
    method: str = Field(description="Method as requested ('auto' by default).")
    method_used: str = Field(description="Solver that ran ('auto' resolves to cma or magnus).")
    method_reason: str = Field(description="One line: why that solver.")
    first_unstable_time: float | None = Field(
        description="First output time [s] at which any branch of the frozen spectrum "
        "has sigma > 0 (beyond rounding), or null if none."
    )
    t: list[float] = Field(description="Output times [s].")
    tip_displacement: list[float] = Field(description="Tip displacement u(L, t) [m].")
    initial_tip_displacement: float = Field(description="u(L, 0) [m].")
    divergence_time: float | None = Field(
        description="First output time [s] at which |u| at the tip or at a station passed "
        "divergence_bound (the last sample of the history), or null."
    )
    divergence_bound: float | None = Field(
        None,
        description="The bound on |u| [m] that applied: output.divergence_bound, or by "
        "default 0.1 L (twice the initial deflection when that is larger).",
    )
    divergence_growth_rate: float | None = Field(
        None,
        description="Largest sigma of the frozen spectrum at divergence_time [1/s], or null.",
    )
    displacements: list[Station] = Field(description="u(x, t) at the requested stations.")
    eigenvalues: Spectrum = Field(
        description="Tracked eigenvalues xi = sigma + i omega of the frozen state matrix S(t)."
    )
    fundamental: Fundamental = Field(description="The first branch of `eigenvalues`.")
    cma_exponents: Spectrum = Field(
        description="Eigenvalues of P(t)/t [1/s]: the exponents the complex modal analysis uses."
    )
    dimensionless: dict[str, Any] = Field(
        description="Paidoussis' groups: beta, flow number u, spin number gamma, time scale "
        f"[s]; the extended model's {GROUP_NAMES} [-]."
    )
    diagnostics: SimulationDiagnostics = Field(
        description="Solver diagnostics (costs, conditioning, error estimate)."
    )
    warnings: list[str] = Field(description="What the caller should know about this result.")
    modal: Modal | None = Field(None, description="Present when output.modal is true.")
    mode_shapes: ModeShapesBlock | None = Field(
        None,
        description="Complex mode shapes of the frozen spectrum; present when "
        "output.mode_shapes is given.",
    )
    loads: list[LoadSpec] | None = Field(
        None,
        description="The request's external loads, echoed (a distributed load's end filled "
        "in); present when the request has loads. With a base_acceleration every "
        "displacement of this result is relative to the clamp.",
    )
    plots: list[str] = Field(
        default_factory=list,
        description="Figures of this result: GET /v1/results/{key}/plots/{name}.png or .svg.",
    )


class MethodComparison(BaseModel):
    method: str = Field(description="Method name.")
    method_used: str = Field(description="Solver that ran ('auto' resolves to cma or magnus).")
    status: str = Field(
        description="'ok', 'diverging', 'diverged' or 'overflow' (see simulations)."
    )
    solve_seconds: float = Field(description="Time inside the solver [s].")
    wall_seconds: float = Field(description="Whole run incl. eigenvalue traces [s].")
    speedup_vs_slowest: float | None = Field(description="Slowest solve time / this one [-].")
    estimated_relative_error: float | None = Field(
        description="The method's own or measured error estimate [-] (null: unknown)."
    )
    difference_from_baseline: float = Field(
        description="max_t |z - z_baseline| / max_t |z_baseline| on the modal state [-]."
    )
    tip_difference_from_baseline: float = Field(
        description="The same on the tip displacement u(L, t) [-]."
    )
    compared_samples: int = Field(description="Output times compared (finite in both).")
    warnings: list[str] = Field(description="The run's warnings (e.g. error above 1e-4).")
    diagnostics: SimulationDiagnostics = Field(description="Key solver diagnostics.")


class CompareResponse(BaseModel):
    """Result of ``POST /v1/compare`` (see :func:`pipeflow.compare.compare`)."""

    key: str = Field(description="Parameter hash of the request.")
    cached: bool = Field(description="True when served from the cache.")
    baseline: str = Field(description="The most accurate method, differences refer to it.")
    methods: list[MethodComparison] = Field(description="One entry per method, in order.")
    samples: int = Field(description="Output times per run.")
    modes: int = Field(description="Galerkin modes.")
    t_end: float = Field(description="Simulated duration [s].")
    plots: list[str] = Field(default_factory=list, description=PLOTS_DESCRIPTION)


# -- POST /v1/studies ------------------------------------------------------------------------


class StudyColumn(BaseModel):
    name: str = Field(
        description="Column name: index, key, status, cached, each overridden field's path, "
        "the base kind's summary (simulation: peak_tip_displacement, final_sigma_1, "
        "final_omega_1, method_used, result_status; stability: critical_velocity, "
        "critical_mode, critical_kind, critical_frequency, stable_at_start, "
        "stable_throughout), error_type, error_field, "
        "error_detail."
    )
    unit: str = Field(
        description="SI unit of the column's numbers ('-': dimensionless; '': text or a flag)."
    )
    description: str = Field(description="What the column holds.")


class StudyCounts(BaseModel):
    total: int = Field(description="Cases in the study [-].")
    ok: int = Field(description="Cases that ran [-].")
    failed: int = Field(description="Cases that failed (their rows say why) [-].")
    cached: int = Field(description="Cases whose summary came from the cache [-].")
    computed: int = Field(
        description="Case computations run for this study [-] (cases with equal keys share one)."
    )


class ColumnStatistics(BaseModel):
    """Statistics of one numeric summary column over the study's ok cases that have a value
    in it, in the column's unit (``unit``)."""

    unit: str = Field(description="SI unit of the column (and of every number here but count).")
    count: int = Field(
        description="Cases with a value [-] (ok cases; a null, e.g. no critical velocity in "
        "the range, is left out)."
    )
    mean: float | None = Field(description="Sample mean [unit] (null: no value).")
    std: float | None = Field(
        description="Sample standard deviation, divisor count - 1 [unit] (null below 2 values)."
    )
    min: float | None = Field(description="Smallest value [unit].")
    max: float | None = Field(description="Largest value [unit].")
    quantiles: dict[str, float | None] = Field(
        description="Empirical quantiles [unit] at the probabilities '0.05', '0.5', '0.95' "
        "(linear interpolation between order statistics, numpy's default)."
    )


class StudyInstability(BaseModel):
    """How many cases are unstable, as a proportion with its binomial standard error."""

    criterion: str = Field(description="What makes a case unstable (see `probability`).")
    probability: float | None = Field(
        description="Fraction of the decided cases that are unstable [-]. Simulation bases: "
        "a case is unstable when its result_status is diverging, diverged or overflow: some "
        "branch of its frozen spectrum grows at t_end (sigma above the spectrum's rounding "
        "level, which includes final_sigma_1 > 0), or its deflection passed the divergence bound, "
        "or the solution overflowed. Stability bases (with operating_velocity): a case is "
        "unstable when it is unstable at the start of its range (stable_at_start false) or "
        "its critical_velocity is at or below operating_velocity; a case whose range ends "
        "below operating_velocity with no loss of stability is undecided. Failed cases are "
        "undecided. Null when no case is decided."
    )
    standard_error: float | None = Field(
        description="Binomial standard error sqrt(p (1 - p) / decided) [-] (independent "
        "draws; a quasi-Monte Carlo design is usually more accurate than this)."
    )
    unstable: int = Field(description="Unstable cases [-].")
    decided: int = Field(description="Cases decided stable or unstable [-].")


class StudyStatistics(BaseModel):
    """Statistics of the study's summary columns over its ok cases: for a sampled study,
    estimates of each output's distribution; for cases or a grid, plain summaries."""

    ok: int = Field(description="Cases that ran, over which the statistics are taken [-].")
    failed: int = Field(description="Cases that failed, left out [-].")
    columns: dict[str, ColumnStatistics] = Field(
        description="Per numeric summary column (simulation: peak_tip_displacement [m], "
        "final_sigma_1 [1/s], final_omega_1 [rad/s]; stability: critical_velocity [m/s], "
        "critical_mode [-], critical_frequency [rad/s]): its statistics."
    )
    instability: StudyInstability | None = Field(
        description="The probability that a case is unstable (null for a stability base "
        "without operating_velocity)."
    )


class SobolIndices(BaseModel):
    """Sobol' indices of one output with respect to one parameter (SALib.analyze.sobol)."""

    S1: float = Field(
        description="First-order index [-]: the share of the output's variance due to this "
        "parameter alone."
    )
    S1_conf: float = Field(
        description="Half-width of S1's bootstrap confidence interval at conf_level [-]."
    )
    ST: float = Field(
        description="Total index [-]: the share of the variance involving this parameter, "
        "interactions included."
    )
    ST_conf: float = Field(
        description="Half-width of ST's bootstrap confidence interval at conf_level [-]."
    )


class ColumnSensitivity(BaseModel):
    """Sobol' indices of one numeric summary column, per sampled parameter."""

    available: bool = Field(
        description="False when some case has no finite value in the column (a failed case, "
        "or a null such as no critical velocity in the range): the estimators need all."
    )
    reason: str | None = Field(description="Why the indices are not available (else null).")
    parameters: dict[str, SobolIndices] | None = Field(
        description="Parameter path -> its indices (null when not available)."
    )


class StudySensitivity(BaseModel):
    """Global sensitivity of a saltelli study (Sobol' indices by Saltelli's estimators)."""

    method: Literal["saltelli"] = Field(description="The design and estimators used.")
    base_points: int = Field(description="Base points N of the design (N (2 D + 2) cases) [-].")
    conf_level: float = Field(description="Confidence level of the intervals [-].")
    columns: dict[str, ColumnSensitivity] = Field(
        description="Per numeric summary column: its indices per parameter."
    )


class StudyResponse(_Result):
    """A design study: one row of summaries per case (CSV: ``?format=csv&table=study``)."""

    kind: Literal["study"] = Field(description="Result kind.")
    base_kind: Literal["simulation", "stability"] = Field(description="The cases' computation.")
    overrides: list[str] = Field(description="The overridden fields (dotted paths), in order.")
    columns: list[StudyColumn] = Field(description="The table's columns, in row order.")
    rows: list[list[str | int | float | bool | None]] = Field(
        description="One row per case, in case order, values in the columns' units; null "
        "where a case has no value (a field it does not override, a failed case's summary)."
    )
    counts: StudyCounts = Field(description="How many cases ran, failed, came from the cache.")
    statistics: StudyStatistics = Field(
        description="Statistics of the numeric summary columns over the ok cases, and the "
        "probability that a case is unstable."
    )
    sensitivity: StudySensitivity | None = Field(
        description="Sobol' sensitivity indices (studies sampled with method saltelli; null "
        "otherwise)."
    )
    request: dict[str, Any] | None = Field(
        None,
        description="The study's request in its normal form, the one its key is the hash of "
        "(a valid request again: posted, it is the same study): its design (cases, grid or "
        "samples with method, count N and seed) and base. Absent from results stored "
        "before it was echoed.",
    )


# -- POST /v1/frequency-responses ------------------------------------------------------------


class FrfCurve(BaseModel):
    """H at one position over the frequencies, in the answer's ``unit`` per unit load."""

    position: float = Field(description="Position x along the pipe [m].")
    real: list[float | None] = Field(
        description="Re H per frequency [unit] (null where H is unbounded: a frequency on an "
        "undamped resonance)."
    )
    imag: list[float | None] = Field(description="Im H per frequency [unit].")
    magnitude: list[float | None] = Field(description="|H| per frequency [unit].")
    phase: list[float | None] = Field(
        description="arg H per frequency [rad] in (-pi, pi]: the response lags the load by -phase."
    )


class FrfPeak(BaseModel):
    """A resonance of the operating point inside the frequency range."""

    frequency: float = Field(description="Damped natural frequency Im xi [rad/s].")
    natural_frequency: float = Field(description="Undamped natural frequency |xi| [rad/s].")
    damping_ratio: float = Field(
        description="zeta = -Re xi / |xi| [-] (negative for a growing mode)."
    )
    mode: int = Field(description="Mode number [-] (1 = lowest frequency).")
    magnitude: list[float | None] = Field(
        description="|H| at the peak frequency at each position [unit] (null for an undamped "
        "mode: unbounded there)."
    )


class FrfDiagnostics(BaseModel):
    """The modal sum checked against direct solves of (K - W^2 M + i W C) q = f."""

    check_frequencies: list[float] = Field(description="Where the check was made [rad/s].")
    max_relative_difference: float | None = Field(
        description="Largest ||H_modal - H_direct|| / ||H_direct|| over them [-]."
    )
    eigenvector_condition: float | None = Field(
        description="1-norm condition number of the eigenvectors [-], LAPACK's estimate "
        "(large: coalescing eigenvalues)."
    )
    method: Literal["modal", "direct"] = Field(
        description="modal: the modal sum; direct: it disagreed by more than 1e-6, so every "
        "frequency was solved directly."
    )
    residual_flexibility: bool = Field(
        False,
        description="True when the static response of the truncated modes (residual "
        "flexibility, m/N or s^2 per unit load) is included in H.",
    )
    load_vectors: int = Field(
        0,
        description="Load-dependent Ritz vectors added to the modes [-] (the request's "
        "load_vectors, less any that the modes already contain); the eigenvalues are then "
        "the modes', the vectors' own left out.",
    )


class FrfOperatingPoint(BaseModel):
    """The response at one operating point."""

    velocity: float = Field(description="Constant flow velocity v [m/s].")
    omega0: float = Field(description="Constant spin w0 [rad/s].")
    stable: bool = Field(
        description="False when some eigenvalue has Re xi > 0: there is no steady state and H "
        "is a formal quantity (answered, with a warning)."
    )
    max_growth_rate: float = Field(
        description="Largest Re xi of the frozen state matrix [1/s] (0 within rounding)."
    )
    responses: list[FrfCurve] = Field(description="One per requested position, in order.")
    peaks: list[FrfPeak] = Field(description="The resonances inside the range, by mode.")
    diagnostics: FrfDiagnostics = Field(description="Modal sum vs direct solves.")
    warnings: list[str] = Field(description="This point's warnings (e.g. unstable).")


class FrequencyResponseResponse(_Result):
    """Frequency response functions H(W) at one or several frozen operating points."""

    kind: Literal["frequency_response"] = Field(description="Result kind.")
    quantity: Literal["displacement", "velocity", "acceleration"] = Field(
        description="What H gives: displacement, velocity or acceleration per unit load."
    )
    unit: str = Field(
        description="Unit of H: m/N, m/(N s), 1/kg for a point force; s^2, s, - per unit base "
        "acceleration."
    )
    load: dict[str, Any] = Field(
        description="The load: {kind: point_force, position [m]} or {kind: base_acceleration}."
    )
    modes: int = Field(description="Galerkin modes used [-].")
    positions: list[float] = Field(description="The response positions x [m].")
    frequencies: list[float] = Field(
        description="Excitation frequencies W [rad/s] (a range has the resonances added)."
    )
    stable: bool = Field(description="Every operating point is stable.")
    max_growth_rate: float = Field(description="Largest Re xi over the operating points [1/s].")
    operating_points: list[FrfOperatingPoint] = Field(
        description="One block per operating point, in request order (one for a request with "
        "flow.velocity and rotation.omega0)."
    )
