"""POST /v1/sweeps: Argand/Campbell sweeps, stability maps and Floquet analyses, as jobs.

The body is one of the :data:`pipeflow.stability_spec.SweepSpec` kinds, told apart by
``kind``; each kind is a job kind of its own (:data:`service.kinds.SWEEPS`), computed by
:func:`pipeflow.stability_spec.run_sweep`.  Sweeps and maps can be large, so they always run
as jobs (202, ``Location: /v1/jobs/{key}``) through the same queue, cache and progress
reporting as simulations; the result is then at ``GET /v1/results/{key}``.  A sweep already
computed answers 202 with a job that has already ``succeeded``, so small or repeated sweeps
cost one extra GET, and one response shape per operation keeps generated clients simple.
"""

from __future__ import annotations

from typing import Annotated, Any

from fastapi import APIRouter, Body
from fastapi.responses import JSONResponse

from pipeflow.stability_spec import PAPER_PIPE_JSON, SweepSpec
from service.compute import JOB_ACCEPTED, Refresh, accept_job
from service.deps import RunnerDep, StoreDep
from service.kinds import SWEEPS
from service.problems import responses
from service.schemas import JobStatus

router = APIRouter(prefix="/v1/sweeps", tags=["sweeps"])

PAPER = PAPER_PIPE_JSON
EXAMPLES: dict[str, dict[str, Any]] = {
    "argand": {
        "summary": "Argand diagram: the paper's pipe, v from 0 to 60 m/s at w0 = 100 rad/s",
        "value": {
            "kind": "argand",
            "pipe": PAPER,
            "rotation": {"omega0": {"kind": "constant", "value": 100.0}},
            "modes": 10,
            "tracked_modes": 4,
            "velocity_range": [0.0, 60.0],
            "points": 201,
        },
    },
    "campbell": {
        "summary": "Campbell diagram: the paper's pipe, w0 from 0 to 2000 rad/s at v = 10 m/s",
        "value": {
            "kind": "campbell",
            "pipe": PAPER,
            "flow": {"velocity": {"kind": "constant", "value": 10.0}},
            "modes": 10,
            "tracked_modes": 4,
            "spin_range": [0.0, 2000.0],
        },
    },
    "spin_map": {
        "summary": "Critical velocity against spin: 100 x 100 (v, w0) map of the paper's pipe",
        "value": {
            "kind": "spin_map",
            "pipe": PAPER,
            "modes": 10,
            "velocity_range": [0.0, 60.0],
            "spin_range": [0.0, 2000.0],
            "velocity_points": 100,
            "spin_points": 100,
        },
    },
    "beta_map": {
        "summary": "u_cr(beta) at gamma = 0 (Paidoussis' stability curve with its S-shapes)",
        "value": {
            "kind": "beta_map",
            "modes": 10,
            "beta_range": [0.05, 0.95],
            "u_range": [0.0, 20.0],
            "beta_points": 50,
        },
    },
    "resonance_chart": {
        "summary": "Parametric resonance of pulsating flow v = 10 + a sin(Omega t) m/s",
        "value": {
            "kind": "resonance_chart",
            "pipe": PAPER,
            "modes": 4,
            "mean_velocity": 10.0,
            "amplitude_range": [0.0, 8.0],
            "frequency_range": [100.0, 4000.0],
        },
    },
    "floquet": {
        "summary": "Floquet multipliers: the paper's pipe with v = 10 + 5 sin(1000 t) m/s",
        "value": {
            "kind": "floquet",
            "pipe": PAPER,
            "modes": 6,
            "flow": {
                "velocity": {
                    "kind": "harmonic",
                    "mean": 10.0,
                    "amplitude": 5.0,
                    "frequency": 1000.0,
                }
            },
            "rotation": {"omega0": {"kind": "constant", "value": 100.0}},
        },
    },
}

SweepBody = Annotated[SweepSpec, Body(openapi_examples=EXAMPLES)]


@router.post(
    "",
    operation_id="submitSweep",
    summary="Submit a sweep, stability map or Floquet analysis as a job",
    status_code=202,
    response_model=JobStatus,
    responses={**JOB_ACCEPTED, **responses(413, 422, 503)},
)
async def submit_sweep(
    spec: SweepBody, runner: RunnerDep, store: StoreDep, refresh: Refresh = False
) -> JSONResponse:
    """Accept the computation named by ``kind`` and answer at once with its job (202,
    ``Location: /v1/jobs/{key}``; the job's ``kind`` is the spec's):

    - ``argand``: eigenvalues sigma [1/s] + i omega [rad/s] against flow velocity [m/s] at
      constant spin, modes tracked by left/right eigenvector overlap (optimal assignment),
      with a per-point confidence and refinement where it drops;
    - ``campbell``: the same against spin w0 [rad/s] (also in Hz and rpm) at constant v;
    - ``spin_map``: growth rate over (w0, v) and the critical velocity [m/s] at each spin;
    - ``beta_map``: u_cr(beta) in non-dimensional form, every crossing (S-shaped segments);
    - ``resonance_chart``: Floquet chart of pulsating flow over amplitude [m/s] and
      frequency [rad/s];
    - ``floquet``: multipliers, exponents and a verdict for one harmonic flow and/or spin.

    Poll ``GET /v1/jobs/{key}`` (status, progress 0..1), then fetch
    ``GET /v1/results/{key}``; its ``plots`` name the figures at
    ``/v1/results/{key}/plots/{name}.png``.  Resubmitting is idempotent."""
    return await accept_job(runner, store, SWEEPS[spec.kind], spec, refresh)
