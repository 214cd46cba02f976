"""Job kinds: what the job runner can compute.

A kind is a name, a validated spec model (pydantic, with a ``canonical()`` method giving
its normalised JSON form for the cache key) and a pure function in pipeflow's terms,
``function(spec, progress) -> JSON-able dict``, where ``progress(fraction)`` may raise
:class:`pipeflow.errors.Cancelled`.  Function and model are pickled by reference into the
worker processes, so both must be importable module-level names.

To add a kind: write the function, ``register(JobKind("compare", CompareSpec, compare))``
below, and add a route that calls :func:`service.compute.run_sync` or
:func:`service.compute.submit_job` with it.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from pydantic import BaseModel

from pipeflow.compare import CompareSpec, run_compare
from pipeflow.plots import available_plots
from pipeflow.solvers.base import ProgressCallback
from pipeflow.spec import SimulationSpec, hash_canonical, run_simulation
from pipeflow.stability_spec import (
    ArgandSweep,
    BetaMapSweep,
    CampbellSweep,
    FloquetSweep,
    ResonanceChartSweep,
    SpinMapSweep,
    StabilitySpec,
    run_stability,
    run_sweep,
)


@dataclass(frozen=True)
class JobKind:
    name: str
    spec: type[BaseModel]
    function: Callable[[Any, ProgressCallback], dict[str, Any]]

    def canonical(self, spec: BaseModel) -> dict[str, Any]:
        canon = getattr(spec, "canonical", None)
        return canon() if callable(canon) else spec.model_dump(mode="json")

    def key(self, spec: BaseModel) -> str:
        """The parameter hash: :func:`pipeflow.spec.cache_key` salted with this kind."""
        return hash_canonical(self.canonical(spec), self.name)


KINDS: dict[str, JobKind] = {}


def register(kind: JobKind) -> JobKind:
    KINDS[kind.name] = kind
    return kind


def run_simulation_job(spec: SimulationSpec, progress: ProgressCallback) -> dict[str, Any]:
    """One simulation as JSON (see :meth:`pipeflow.simulation.Result.to_dict`), with the
    names of its figures (``plots``, see ``GET /v1/results/{key}/plots/{name}.png``)."""
    result = run_simulation(spec, progress).to_dict()
    result["plots"] = available_plots(result)
    return result


SIMULATION = register(JobKind("simulation", SimulationSpec, run_simulation_job))
COMPARE = register(JobKind("compare", CompareSpec, run_compare))


def run_stability_analysis(spec: StabilitySpec, progress: ProgressCallback) -> dict[str, Any]:
    """Critical flow velocities (:func:`pipeflow.stability_spec.run_stability`) with ``plots``."""
    result = run_stability(spec, progress)
    result["plots"] = available_plots(result)
    return result


def run_sweep_analysis(spec: Any, progress: ProgressCallback) -> dict[str, Any]:
    """A sweep or map (:func:`pipeflow.stability_spec.run_sweep`, any kind) with ``plots``."""
    result = run_sweep(spec, progress)
    result["plots"] = available_plots(result)
    return result


STABILITY = register(JobKind("stability", StabilitySpec, run_stability_analysis))
#: one job kind per sweep kind, named as the spec's ``kind`` (so the key is
#: :func:`pipeflow.stability_spec.cache_key` ``(spec, spec.kind)``)
SWEEPS: dict[str, JobKind] = {
    name: register(JobKind(name, model, run_sweep_analysis))
    for model in (
        ArgandSweep,
        CampbellSweep,
        SpinMapSweep,
        BetaMapSweep,
        ResonanceChartSweep,
        FloquetSweep,
    )
    for name in (str(model.model_fields["kind"].default),)
}
