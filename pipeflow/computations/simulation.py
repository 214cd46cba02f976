"""How a simulation and a method comparison run: a validated request
(:mod:`pipeflow.schema.simulation`) in, the plain library call, its document
(:mod:`pipeflow.computations.documents`) out; a simulation's estimated run time (what the
service's fast lane is told) and its row in a design study."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from pipeflow._types import Progress
from pipeflow.batch import eligible, summaries
from pipeflow.compare import compare
from pipeflow.computations import documents
from pipeflow.computations.study_runner import Column
from pipeflow.schema import plausibility
from pipeflow.schema.base import request_fields
from pipeflow.schema.simulation import SIMULATION_FIELDS, CompareSpec, SimulationSpec
from pipeflow.simulation import Result, Simulation, simulate


def _peak(values: Sequence[float | None]) -> float | None:
    finite = [abs(v) for v in values if v is not None]
    return max(finite) if finite else None


def _last(values: Sequence[float | None]) -> float | None:
    return values[-1] if values else None


def simulate_spec(spec: SimulationSpec, progress: Progress | None = None) -> Result:
    """:func:`~pipeflow.simulation.simulate` on a validated spec; a library refusal names
    the request field (``exc.field``, from :data:`SIMULATION_FIELDS`), and a value far
    outside the pipe's scales, likely meant in another unit, adds a warning (issue 34,
    item 8)."""
    with request_fields(SIMULATION_FIELDS):
        sim = spec.to_simulation()  # the request's library arguments, built once
        result = simulate(sim, progress=progress)
    result.warnings.extend(plausibility.warnings(spec, sim))
    return result


def run_simulation(spec: SimulationSpec, progress: Progress | None) -> dict[str, Any]:
    """:func:`simulate_spec`, its document (:func:`pipeflow.computations.documents.simulation`)."""
    return documents.simulation(simulate_spec(spec, progress))


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


def run_compare(spec: CompareSpec, progress: Progress | None) -> dict[str, Any]:
    """:func:`pipeflow.compare.compare` of the request's simulation and methods, its
    document (:func:`pipeflow.computations.documents.compare`)."""
    return documents.compare(compare(spec.simulation.to_simulation(), spec.methods, progress))
