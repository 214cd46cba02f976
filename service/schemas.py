"""Response models of the service (request bodies are pipeflow's own spec models).

These document the JSON the service returns; the simulation result itself is produced by
:meth:`pipeflow.simulation.Result.to_dict`, and a test checks the two agree.
"""

from __future__ import annotations

from datetime import datetime
from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field

from service.problems import Problem

KEY_PATTERN = r"^[0-9a-f]{64}$"


class Trace(BaseModel):
    mode: int = Field(description="Mode number, 1 = lowest frequency at t = 0.")
    sigma: list[float] = Field(description="Real part of xi = sigma + i omega: damping [1/s].")
    omega: list[float] = Field(description="Imaginary part: frequency [rad/s].")
    confidence: list[float] = Field(
        description="Tracking confidence in [0, 1] (eigenvector correlation between steps)."
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


class SimulationResponse(BaseModel):
    """A simulation result with its parameter hash."""

    model_config = ConfigDict(extra="allow")

    key: str = Field(description="Parameter hash (SHA-256 hex) identifying this result.")
    cached: bool = Field(description="True when served from the cache, not computed now.")
    status: Literal["ok", "diverging", "overflow"] = Field(
        description="ok; diverging (a growing mode or the tip passed the divergence bound); "
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
        description="First time the tip passed the divergence bound [s], or null."
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
        description="Paidoussis' groups: beta, flow number u, spin number gamma, time scale [s]."
    )
    diagnostics: dict[str, Any] = Field(description="Solver diagnostics (costs, conditioning).")
    warnings: list[str] = Field(description="What the caller should know about this result.")
    modal: Modal | None = Field(None, description="Present when output.modal is true.")
    mode_shapes: ModeShapesBlock | None = Field(
        None,
        description="Complex mode shapes of the frozen spectrum; present when "
        "output.mode_shapes is given.",
    )
    plots: list[str] = Field(
        default_factory=list,
        description="Figures of this result: GET /v1/results/{key}/plots/{name}.png or .svg.",
    )


class JobStatus(BaseModel):
    """The state of a job; its id is the parameter hash."""

    key: str = Field(description="Job id = parameter hash (SHA-256 hex).")
    kind: str = Field(
        description="What is computed (the job kind): 'simulation', 'stability', or the sweep's "
        "kind ('argand', 'campbell', 'spin_map', 'beta_map', 'resonance_chart', 'floquet')."
    )
    status: Literal["queued", "running", "succeeded", "failed", "cancelled"]
    progress: float = Field(ge=0, le=1, description="Fraction done [-].")
    created: datetime = Field(description="When the job was (last) accepted (UTC).")
    started: datetime | None = Field(description="When its current run started (UTC).")
    finished: datetime | None = Field(description="When it reached its terminal state (UTC).")
    updated: datetime = Field(description="Last change of this record (UTC).")
    error: Problem | dict[str, Any] | None = Field(
        description="Why it failed or was cancelled (an RFC 9457 problem document)."
    )
    result: str | None = Field(description="URL path of the result once succeeded.")


class Health(BaseModel):
    status: Literal["ok"] = "ok"
    version: str = Field(description="pipeflow version.")


class Readiness(BaseModel):
    status: Literal["ready"] = "ready"
    workers: int = Field(description="Worker processes.")
    in_flight: int = Field(description="Computations queued or running.")
    capacity: int = Field(description="Computations accepted before answering 503.")


class MethodComparison(BaseModel):
    method: str = Field(description="Method name.")
    method_used: str = Field(description="Solver that ran ('auto' resolves to cma or magnus).")
    status: str = Field(description="'ok', 'diverging' or 'overflow' (see simulations).")
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
    diagnostics: dict[str, Any] = Field(description="Key solver diagnostics.")


class CompareResponse(BaseModel):
    """Result of ``POST /v1/compare`` (see :func:`pipeflow.compare.compare`)."""

    key: str = Field(description="Parameter hash of the request.")
    cached: bool = Field(description="True when served from the cache.")
    baseline: str = Field(description="The most accurate method, differences refer to it.")
    methods: list[MethodComparison] = Field(description="One entry per method, in order.")
    samples: int = Field(description="Output times per run.")
    modes: int = Field(description="Galerkin modes.")
    t_end: float = Field(description="Simulated duration [s].")
