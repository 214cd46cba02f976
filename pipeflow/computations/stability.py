"""How the stability analyses and sweeps run: a validated request model
(:mod:`pipeflow.schema.stability`) in, the plain library call, its document
(:mod:`pipeflow.computations.documents`) out, and a critical-velocity analysis's row in a
design study.  ``progress`` is a callback (fraction in [0, 1]) that may raise
:class:`pipeflow.errors.Cancelled`."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from pipeflow._types import Progress
from pipeflow.computations import documents
from pipeflow.computations.study_runner import Column
from pipeflow.model import GROUPS
from pipeflow.schema import stability as s
from pipeflow.stability.critical import critical_velocities
from pipeflow.stability.floquet import floquet, resonance_chart
from pipeflow.stability.maps import beta_map, spin_map
from pipeflow.stability.sweeps import Parameter, sweep


def run_critical(spec: s.StabilitySpec, progress: Progress | None = None) -> dict[str, Any]:
    """:func:`~pipeflow.stability.critical.critical_velocities`: its document."""
    result = critical_velocities(
        spec.mounted_pipe(),
        omega0=spec.rotation.omega0.value,
        velocity_range=spec.velocity_range,
        modes=spec.modes,
        points=spec.points,
        progress=progress,
    )
    return documents.critical_velocities(result)


def _sweep(
    spec: s.ArgandSweep | s.CampbellSweep,
    parameter: Parameter,
    value_range: tuple[float, float],
    fixed: float,
    progress: Progress | None,
    orders: tuple[float, ...] = (),
) -> dict[str, Any]:
    result = sweep(
        spec.mounted_pipe(),
        parameter,
        value_range,
        fixed=fixed,
        modes=spec.modes,
        tracked=spec.tracked_modes,
        points=spec.points,
        min_confidence=spec.min_confidence,
        max_points=spec.max_points,
        progress=progress,
        orders=orders,
    )
    return documents.sweep(result)


def run_argand(spec: s.ArgandSweep, progress: Progress | None = None) -> dict[str, Any]:
    """:func:`~pipeflow.stability.sweeps.sweep` over flow velocity: its document."""
    return _sweep(spec, "velocity", spec.velocity_range, spec.rotation.omega0.value, progress)


def run_campbell(spec: s.CampbellSweep, progress: Progress | None = None) -> dict[str, Any]:
    """:func:`~pipeflow.stability.sweeps.sweep` over spin: its document."""
    return _sweep(
        spec, "spin", spec.spin_range, spec.flow.velocity.value, progress, tuple(spec.orders)
    )


def run_spin_map(spec: s.SpinMapSweep, progress: Progress | None = None) -> dict[str, Any]:
    """:func:`~pipeflow.stability.maps.spin_map`: its document."""
    result = spin_map(
        spec.mounted_pipe(),
        spec.velocity_range,
        spec.spin_range,
        modes=spec.modes,
        velocity_points=spec.velocity_points,
        spin_points=spec.spin_points,
        progress=progress,
    )
    return documents.spin_map(result)


def run_beta_map(spec: s.BetaMapSweep, progress: Progress | None = None) -> dict[str, Any]:
    """:func:`~pipeflow.stability.maps.beta_map`: its document."""
    result = beta_map(
        spec.beta_range,
        spec.u_range,
        gamma=spec.gamma,
        modes=spec.modes,
        beta_points=spec.beta_points,
        u_points=spec.u_points,
        progress=progress,
        groups={name: getattr(spec, name) for name in GROUPS},
        plane=spec.plane,
    )
    return documents.beta_map(result)


def run_resonance_chart(
    spec: s.ResonanceChartSweep, progress: Progress | None = None
) -> dict[str, Any]:
    """:func:`~pipeflow.stability.floquet.resonance_chart`: its document."""
    result = resonance_chart(
        spec.mounted_pipe(),
        spec.mean_velocity,
        spec.amplitude_range,
        spec.frequency_range,
        omega0=spec.rotation.omega0.value,
        modes=spec.modes,
        amplitude_points=spec.amplitude_points,
        frequency_points=spec.frequency_points,
        tolerance=spec.tolerance,
        progress=progress,
    )
    return documents.resonance_chart(result)


def run_floquet(spec: s.FloquetSweep, progress: Progress | None = None) -> dict[str, Any]:
    """:func:`~pipeflow.stability.floquet.floquet`: its document."""
    result = floquet(
        spec.mounted_pipe(),
        spec.flow.velocity.to_profile(),
        spec.rotation.omega0.to_profile(),
        modes=spec.modes,
        tolerance=spec.tolerance,
        progress=progress,
    )
    return documents.floquet(result)


#: the run of each stability request model
RUNS: dict[type[Any], Callable[[Any, Progress | None], dict[str, Any]]] = {
    s.StabilitySpec: run_critical,
    s.ArgandSweep: run_argand,
    s.CampbellSweep: run_campbell,
    s.SpinMapSweep: run_spin_map,
    s.BetaMapSweep: run_beta_map,
    s.ResonanceChartSweep: run_resonance_chart,
    s.FloquetSweep: run_floquet,
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
