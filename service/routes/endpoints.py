"""Where each computation of the registry is asked for: its URL path, tag and operation ids.

The registry (:data:`pipeflow.computations.registry.COMPUTATIONS`) names computations only; this
table (:data:`ENDPOINTS`, keyed by computation name) maps each served one to its
:class:`Endpoint`.  Several computations share one endpoint when their request models are
told apart by ``kind`` (``/v1/sweeps``).  The routes (:mod:`service.routes.computations`),
the job kinds and the result documents are derived from it; a computation missing here
(e.g. the tests' own kinds) is registered but not served.
"""

from __future__ import annotations

from dataclasses import dataclass

from pipeflow.computations.registry import COMPUTATIONS, SWEEP_KINDS, Computation


@dataclass(frozen=True)
class Endpoint:
    """Where a group of computations is asked for: ``POST /v1/<path>`` and its job form.

    ``run_operation`` is None for endpoints that always answer with a job (202); the
    operation ids are stable so the OpenAPI document only changes when the API does.
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


COMPARE = Endpoint(
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


STABILITY = Endpoint(
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
    "Poll ``GET /v1/jobs/{key}`` (status, progress 0..1; ``?wait=<s>``: a long poll, "
    "answered when the job has ended), then fetch "
    "``GET /v1/results/{key}``; its ``plots`` name the figures at "
    "``/v1/results/{key}/plots/{name}.png``.  Resubmitting is idempotent.  Sweeps and maps "
    "can be large, so they always run as jobs; a sweep already computed answers 202 with a "
    "job that has already ``succeeded``.",
    run_operation=None,
    job_operation="submitSweep",
    job_summary="Submit a sweep, stability map or Floquet analysis as a job",
)


STUDIES = Endpoint(
    path="studies",
    tag="studies",
    summary="Submit a design study (many cases of one simulation or stability analysis)",
    description="Accept a study and answer at once with its job (202, "
    "``Location: /v1/jobs/{key}``): a ``base`` simulation or stability request and either "
    "``cases`` (a list of overrides) or ``grid`` (values per field, every combination), "
    "overriding numeric fields by dotted path (``pipe.E`` [Pa], ``pipe.L`` [m], ``pipe.M2`` "
    "[kg/m], ``rotation.omega0.value`` [rad/s], ``flow.velocity.coefficients.1`` [m/s^2], "
    "...).  Every override value is checked against its field's type and bounds in the "
    "base request model before any work (a 422 names the study field: ``cases.3.pipe.E``, "
    "``grid.pipe.L.2``); a case breaking a rule across fields (``output.positions`` beyond "
    "a shortened ``pipe.L``) is a failed row (``invalid-input``, naming the field).  Each "
    "case is cached "
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


FREQUENCY_RESPONSES = Endpoint(
    path="frequency-responses",
    tag="frequency-responses",
    summary="Frequency response functions at frozen operating points (or from the cache)",
    description="The steady harmonic response H(W) of the pipe at constant flow velocity v "
    "[m/s] and spin w0 [rad/s] (``flow.velocity`` and ``rotation.omega0``, or up to 64 "
    "``operating_points``) to a harmonic ``load`` (a point force at a position [m], H per "
    "newton; or the clamp's acceleration, H per m/s^2), at the ``response.positions`` [m] as "
    "displacement, velocity or acceleration (``unit`` in the answer: m/N, m/(N s), 1/kg; s^2, "
    "s, -), over ``frequencies`` [rad/s] (a range with the resonances added, or an explicit "
    "list).  Per operating point: real, imaginary, magnitude and phase [rad] at each position, "
    "the ``peaks`` (frequency [rad/s], damping ratio [-], magnitude, mode), ``stable`` and "
    "``max_growth_rate`` [1/s] (an unstable point is answered, with a warning: H is formal "
    "there) and the check of the modal sum against direct solves (``diagnostics``).  Many "
    "positions give the operating deflection shape.  Figures: bode, nyquist, waterfall (several "
    "points), deflection_shape; tables (CSV, Parquet): frequency_response, peaks.  Cached like "
    "simulations (``X-Cache``, ``?refresh=true``).",
    run_operation="runFrequencyResponse",
    job_operation="submitFrequencyResponseJob",
    job_summary="Submit a frequency response as a job",
)


STATE_SPACE = Endpoint(
    path="state-space",
    tag="frequency-responses",
    summary="A state-space model (A, B, C, D) at a frozen operating point",
    description="The modal model of the pipe at constant flow velocity v [m/s] and spin w0 "
    "[rad/s] as z' = A z + B w, y = C z + D w (real matrices as nested lists): the same body "
    "as a frequency response without ``frequencies`` (pipe, flow, rotation, plane, modes, "
    "load, response).  States: q'_j / w_j and q_j [m] (Galerkin coordinates); input: the "
    "load (a point force [N] or the clamp's acceleration [m/s^2]); outputs: the response "
    "quantity at each position (m, m/s or m/s^2); names and ``units`` in the answer.  "
    "C (i W I - A)^-1 B + D equals the frequency response with ``residual_flexibility: "
    "false``; the eigenvalues of A are the frozen spectrum.  ``GET /v1/results/{key}"
    "?format=mat`` gives it as a MATLAB file (A, B, C, D, states, inputs, outputs).  "
    "Cached like simulations.",
    run_operation="runStateSpace",
    job_operation="submitStateSpaceJob",
    job_summary="Submit a state-space realisation as a job",
)


#: computation name -> its endpoint (every served computation, and only those)
ENDPOINTS: dict[str, Endpoint] = {
    "simulation": SIMULATIONS,
    "compare": COMPARE,
    "stability": STABILITY,
    **{name: SWEEPS for name in SWEEP_KINDS},
    "study": STUDIES,
    "frequency_response": FREQUENCY_RESPONSES,
    "state_space": STATE_SPACE,
}


def served() -> list[Computation]:
    """The computations the service answers, in registration order."""
    return [c for c in COMPUTATIONS.values() if c.name in ENDPOINTS]


def endpoints() -> list[Endpoint]:
    """Every endpoint, in the registration order of their first computation."""
    return list(dict.fromkeys(ENDPOINTS[c.name] for c in served()))


def computations_at(endpoint: Endpoint) -> list[str]:
    """The names of the computations asked for at ``endpoint``, in registration order."""
    return [c.name for c in served() if ENDPOINTS[c.name] is endpoint]
