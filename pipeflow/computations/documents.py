"""The JSON documents of the library's results, built from the results themselves.

The numerical library (:mod:`pipeflow.simulation`, :mod:`pipeflow.compare`,
:mod:`pipeflow.stability`, ...) returns dataclasses and imports nothing of the schema; this
module turns each of them into its response document (:mod:`pipeflow.schema.results`),
one function per result type, every object written with :func:`~pipeflow.schema.results.
document` (which refuses a name the model lacks and a required field left out), so a key
exists only as a field of a model.  The values are JSON-ready lists and numbers, every float
finite (a simulation's non-finite value is an internal error; elsewhere a missing number is
None), in the order of the bytes the service sends.

- :func:`simulation` (:class:`~pipeflow.simulation.Result`) and :func:`mode_shapes`;
- :func:`compare` (:class:`~pipeflow.compare.Comparison`);
- :func:`critical_velocities` (with :func:`crossing` and :func:`stability_dimensionless`);
- :func:`sweep` (with :func:`excitation_crossing` and :func:`zero_crossing`);
- :func:`spin_map`, :func:`beta_map`;
- :func:`floquet`, :func:`resonance_chart` (with :func:`resonance_regions`);
- :func:`frequency_response` (with :func:`frequency_point`), :func:`state_space`.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from pipeflow.compare import Comparison
from pipeflow.diagnostics import summary
from pipeflow.frequency import FrequencyResponse
from pipeflow.io.json import json_safe
from pipeflow.loads import load_to_dict
from pipeflow.modeshapes import ModeShapes
from pipeflow.schema import results as r
from pipeflow.simulation import Result
from pipeflow.spectra import Traces
from pipeflow.stability.core import damping_ratio, stable_intervals
from pipeflow.stability.critical import CriticalVelocity, Crossing
from pipeflow.stability.floquet import Floquet, ResonanceChart
from pipeflow.stability.maps import BetaMap, SpinMap
from pipeflow.stability.sweeps import RPM, ExcitationCrossing, Sweep, ZeroCrossing
from pipeflow.state_space import StateSpace

# -- one simulation ------------------------------------------------------------------------


def _finite(a: Any) -> Any:
    arr = np.asarray(a, dtype=float)
    if not np.all(np.isfinite(arr)):
        raise ValueError("internal error: non-finite value reached the output")
    return arr.tolist()


def simulation(result: Result, include_modal: bool | None = None) -> dict[str, Any]:
    """:class:`~pipeflow.schema.results.SimulationResponse` of ``result``: lists of floats,
    every number finite; the modal coordinates when ``include_modal`` (default: as the
    simulation asked, ``Simulation.include_modal``).  The CMA exponents are computed here
    on first use (:attr:`pipeflow.simulation.Result.exponents`)."""
    modal = result.simulation.include_modal if include_modal is None else include_modal

    def traces(tr: Traces, flagged: bool = False) -> list[dict[str, Any]]:
        return [
            r.document(
                r.Trace,
                mode=tr.mode_number(j),
                sigma=_finite(tr.sigma[:, j]),
                omega=_finite(tr.omega[:, j]),
                confidence=_finite(tr.confidence[:, j]),
                **({"least_stable": tr.least_stable == j} if flagged else {}),
            )
            for j in range(tr.xi.shape[1])
        ]

    optional: dict[str, Any] = {}
    if result.mode_shapes is not None:
        optional["mode_shapes"] = json_safe(mode_shapes(result.mode_shapes))
    if result.simulation.loads:  # the inputs echoed: only when there are loads
        L = result.simulation.pipe.L
        optional["loads"] = [load_to_dict(load, L) for load in result.simulation.loads]
    if modal:
        optional["modal"] = r.document(r.Modal, d=_finite(result.d), ddot=_finite(result.ddot))
    return r.document(
        r.SimulationResponse,
        status=str(result.status),
        method=result.simulation.method,
        method_used=result.method_used,
        method_reason=result.method_reason,
        first_unstable_time=result.first_unstable_time,
        t=_finite(result.t),
        tip_displacement=_finite(result.tip_displacement),
        initial_tip_displacement=result.initial_tip_displacement,
        divergence_time=result.divergence_time,
        divergence_bound=result.divergence_bound,
        divergence_growth_rate=result.divergence_growth_rate,
        displacements=[
            r.document(r.Station, x=x, u=_finite(result.displacements[i]))
            for i, x in enumerate(result.simulation.positions)
        ],
        eigenvalues=r.document(
            r.Spectrum, t=_finite(result.eigen_t), modes=traces(result.frozen, True)
        ),
        fundamental=r.document(
            r.Fundamental,
            sigma=_finite(result.frozen.sigma[:, 0]),
            omega=_finite(result.frozen.omega[:, 0]),
        ),
        cma_exponents=r.document(
            r.Spectrum, t=_finite(result.eigen_t), modes=traces(result.exponents)
        ),
        dimensionless=result.dimensionless,
        diagnostics=json_safe(result.diagnostics),
        warnings=list(result.warnings),
        **optional,
    )


def mode_shapes(shapes: ModeShapes) -> dict[str, Any]:
    """:class:`~pipeflow.schema.results.ModeShapesBlock`: ``{"t", "x", "modes": [{"mode",
    "sigma", "omega", "real", "imag"}]}`` with ``real``/``imag`` nested as [time][station]."""
    return r.document(
        r.ModeShapesBlock,
        t=shapes.t.tolist(),
        x=shapes.x.tolist(),
        modes=[
            r.document(
                r.ShapeTrace,
                mode=int(shapes.mode[j]) if shapes.mode is not None else j + 1,
                sigma=shapes.xi[:, j].real.tolist(),
                omega=shapes.xi[:, j].imag.tolist(),
                real=shapes.shapes[:, j].real.tolist(),
                imag=shapes.shapes[:, j].imag.tolist(),
            )
            for j in range(shapes.xi.shape[1])
        ],
    )


def compare(comparison: Comparison) -> dict[str, Any]:
    """:class:`~pipeflow.schema.results.CompareResponse` of :func:`pipeflow.compare.compare`:
    each method's times [s], its speed-up over the slowest (None when a solve took no
    measurable time), its claimed error (None when it claims none) and its differences from
    the baseline; its diagnostics summarised (:func:`pipeflow.diagnostics.summary`)."""
    sim = comparison.simulation
    slowest = max(run.solve_seconds for run in comparison.runs)
    rows = []
    for run in comparison.runs:
        result, solve_s, acc = run.result, run.solve_seconds, run.estimated_relative_error
        rows.append(
            r.document(
                r.MethodComparison,
                method=result.simulation.method,
                method_used=result.method_used,
                status=str(result.status),
                solve_seconds=solve_s,
                wall_seconds=run.wall_seconds,
                speedup_vs_slowest=slowest / solve_s if solve_s > 0 else None,
                estimated_relative_error=acc if math.isfinite(acc) else None,
                difference_from_baseline=run.difference_from_baseline,
                tip_difference_from_baseline=run.tip_difference_from_baseline,
                compared_samples=run.compared_samples,
                warnings=list(result.warnings),
                diagnostics=summary(simulation(result)["diagnostics"]),
            )
        )
    return r.document(
        r.CompareResponse,
        baseline=comparison.baseline.simulation.method,
        methods=rows,
        samples=sim.samples,
        modes=sim.modes,
        t_end=sim.t_end,
    )


# -- stability -----------------------------------------------------------------------------


def crossing(c: Crossing) -> dict[str, Any]:
    """:class:`~pipeflow.schema.results.Crossing` (a critical-velocity crossing)."""
    return r.document(
        r.Crossing,
        velocity=c.velocity,
        frequency=c.frequency,
        frequency_hz=c.frequency / (2 * math.pi),
        mode=c.mode,
        kind=c.kind,
        direction=c.direction,
        boundary=c.boundary,
        flow_number=c.flow_number,
        dimensionless_frequency=c.dimensionless_frequency,
    )


def stability_dimensionless(result: CriticalVelocity) -> dict[str, Any]:
    """Paidoussis' groups: :class:`~pipeflow.schema.results.StabilityDimensionless`."""
    p = result.pipe
    return r.document(
        r.StabilityDimensionless,
        beta=p.beta,
        gamma=float(p.spin_number(result.omega0)),
        u_cr=result.u_cr,
        u_range=(None if p.M2 == 0 else [float(p.flow_number(x)) for x in result.velocity_range]),
        time_scale=p.time_scale,
        **p.dimensionless_groups(),
    )


def critical_velocities(result: CriticalVelocity) -> dict[str, Any]:
    """:class:`~pipeflow.schema.results.StabilityResponse` (``kind`` aside) of
    :func:`pipeflow.stability.critical_velocities`."""
    reverse = result.reverse_flow
    return r.document(
        r.StabilityResponse,
        critical_velocity=result.critical_velocity,
        mechanism=result.mechanism,
        stable_throughout=result.stable_throughout,
        stable_at_start=result.stable_at_start,
        instability_at_start=list(result.instability_at_start),
        stable_intervals=result.stable_intervals,
        crossings=[crossing(c) for c in result.crossings],
        dimensionless=stability_dimensionless(result),
        omega0=result.omega0,
        modes=result.modes,
        velocity_range=list(result.velocity_range),
        reverse_flow=None if reverse is None else r.document(r.ReverseFlow, **reverse),
        warnings=list(result.warnings),
        diagnostics=dict(result.diagnostics),
    )


def excitation_crossing(c: ExcitationCrossing) -> dict[str, Any]:
    """:class:`~pipeflow.schema.results.ExcitationCrossing` (a Campbell diagram's)."""
    mag = math.hypot(c.sigma, c.frequency)
    return r.document(
        r.ExcitationCrossing,
        order=c.order,
        mode=c.mode,
        spin=c.spin,
        spin_rpm=c.spin * RPM,
        frequency=c.frequency,
        frequency_hz=c.frequency / (2 * math.pi),
        sigma=c.sigma,
        damping_ratio=-c.sigma / mag if mag > 0 else 0.0,
    )


def zero_crossing(c: ZeroCrossing) -> dict[str, Any]:
    """:class:`~pipeflow.schema.results.ZeroCrossing` (a sweep's sigma = 0)."""
    return r.document(
        r.ZeroCrossing,
        mode=c.mode,
        value=c.value,
        frequency=c.frequency,
        direction=c.direction,
    )


def sweep(s: Sweep) -> dict[str, Any]:
    """:class:`~pipeflow.schema.results.SweepResponse` of :func:`pipeflow.stability.sweep`
    (``kind`` ``argand`` or ``campbell``)."""
    p = s.pipe
    spin = s.parameter == "spin"
    axis: dict[str, Any] = {}
    if spin:
        axis["values_hz"] = (s.values / (2 * math.pi)).tolist()
        axis["values_rpm"] = (s.values * RPM).tolist()
        axis["gamma"] = p.spin_number(s.values).tolist()
    elif p.M2 > 0:
        axis["flow_number"] = p.flow_number(s.values).tolist()
    zeta = damping_ratio(s.xi)
    branches = [
        r.document(
            r.SweepBranch,
            mode=int(s.mode[j]),
            sigma=s.sigma[:, j].tolist(),
            omega=s.omega[:, j].tolist(),
            frequency_hz=(s.omega[:, j] / (2 * math.pi)).tolist(),
            damping_ratio=zeta[:, j].tolist(),
            confidence=s.confidence[:, j].tolist(),
            **({"frequency_rpm": (s.omega[:, j] * RPM).tolist()} if spin else {}),
        )
        for j in range(s.xi.shape[1])
    ]
    fixed_name = "velocity" if spin else "omega0"
    return r.document(
        r.SweepResponse,
        kind="campbell" if spin else "argand",
        parameter=r.document(
            r.SweepAxis,
            name=s.parameter,
            unit="rad/s" if spin else "m/s",
            values=s.values.tolist(),
            **axis,
        ),
        fixed={fixed_name: s.fixed},
        inserted=s.inserted.tolist(),
        modes=branches,
        dimensionless={
            "beta": p.beta,
            "time_scale": p.time_scale,
            **p.dimensionless_groups(),
            **({"flow_number": float(p.flow_number(s.fixed))} if spin and p.M2 > 0 else {}),
            **({} if spin else {"gamma": float(p.spin_number(s.fixed))}),
        },
        excitation=(
            r.document(
                r.Excitation,
                orders=list(s.orders),
                crossings=[excitation_crossing(c) for c in s.excitation],
            )
            if spin
            else None
        ),
        zero_crossings=[zero_crossing(c) for c in s.zero_crossings],
        stable_at_start=s.stable_at_start,
        instability_at_start=list(s.instability_at_start),
        boundary=[
            r.document(
                r.SweepBoundaryCrossing,
                value=c.value,
                direction=c.direction,
                kind=c.kind,
                frequency=c.frequency,
            )
            for c in s.boundary
        ],
        stable_intervals=s.stable_intervals,
        warnings=list(s.warnings),
        diagnostics={
            "points": int(s.values.size),
            "inserted_points": int(s.inserted.sum()),
            "min_confidence": float(np.min(s.confidence)),
            "galerkin_modes": s.modes,
        },
    )


def spin_map(m: SpinMap) -> dict[str, Any]:
    """:class:`~pipeflow.schema.results.SpinMapResponse` of :func:`pipeflow.stability.spin_map`."""
    p = m.pipe
    return r.document(
        r.SpinMapResponse,
        kind="spin_map",
        spins=m.spins.tolist(),
        spins_rpm=(m.spins * 60 / (2 * math.pi)).tolist(),
        velocities=m.velocities.tolist(),
        growth_rate=m.growth.tolist(),
        critical_velocity=m.critical_velocity,
        stable_at_start=m.stable_at_start,
        instability_at_start=[list(k) for k in m.instability_at_start],
        stable_intervals=[
            stable_intervals(
                max(0.0, float(m.velocities[0])),
                float(m.velocities[-1]),
                ok,
                [(c.velocity, c.direction == "loss") for c in line],
            )
            for ok, line in zip(m.stable_at_start, m.crossings, strict=True)
        ],
        crossings=[
            [
                r.document(
                    r.MapCrossing,
                    velocity=c.velocity,
                    direction=c.direction,
                    kind=c.kind,
                    frequency=c.frequency,
                    frequency_hz=c.frequency / (2 * math.pi),
                )
                for c in line
            ]
            for line in m.crossings
        ],
        dimensionless={
            "beta": p.beta,
            "gamma": p.spin_number(m.spins).tolist(),
            "u_cr": [
                None if v is None or p.M2 == 0 else float(p.flow_number(v))
                for v in m.critical_velocity
            ],
            "time_scale": p.time_scale,
            **p.dimensionless_groups(),
        },
        warnings=list(m.warnings),
        diagnostics={"galerkin_modes": m.modes, "points": int(m.growth.size)},
    )


def beta_map(m: BetaMap) -> dict[str, Any]:
    """:class:`~pipeflow.schema.results.BetaMapResponse` of :func:`pipeflow.stability.beta_map`."""
    return r.document(
        r.BetaMapResponse,
        kind="beta_map",
        gamma=m.gamma,
        groups=dict(m.groups),
        plane=m.plane,
        betas=m.betas.tolist(),
        u_range=list(m.u_range),
        u_cr=m.u_cr,
        stable_at_start=m.stable_at_start,
        instability_at_start=[list(k) for k in m.instability_at_start],
        stable_intervals=[
            stable_intervals(
                m.u_range[0], m.u_range[1], ok, [(c.velocity, c.direction == "loss") for c in line]
            )
            for ok, line in zip(m.stable_at_start, m.crossings, strict=True)
        ],
        crossings=[
            [
                r.document(
                    r.BetaCrossing,
                    u=c.velocity,
                    direction=c.direction,
                    kind=c.kind,
                    frequency=c.frequency,
                )
                for c in line
            ]
            for line in m.crossings
        ],
        curve=[
            [float(b), c.velocity]
            for b, line in zip(m.betas, m.crossings, strict=True)
            for c in line
        ],
        multiple_crossings=[
            float(b) for b, line in zip(m.betas, m.crossings, strict=True) if len(line) > 1
        ],
        warnings=list(m.warnings),
        diagnostics={"galerkin_modes": m.modes},
    )


def floquet(f: Floquet) -> dict[str, Any]:
    """:class:`~pipeflow.schema.results.FloquetResponse` (``kind`` aside) of
    :func:`pipeflow.stability.floquet`."""
    upper = f.frozen_mean[f.frozen_mean.imag >= 0]
    upper = upper[np.argsort(upper.imag)]
    return r.document(
        r.FloquetResponse,
        period=f.period,
        verdict=str(f.verdict),
        max_multiplier=f.max_multiplier,
        growth_rate=f.growth_rate,
        multipliers=r.document(
            r.Multipliers,
            real=f.multipliers.real.tolist(),
            imag=f.multipliers.imag.tolist(),
            modulus=np.abs(f.multipliers).tolist(),
        ),
        exponents=r.document(
            r.Exponents,
            sigma=f.exponents.real.tolist(),
            omega=f.exponents.imag.tolist(),
        ),
        frozen_mean={"sigma": upper.real.tolist(), "omega": upper.imag.tolist()},
        dimensionless={
            "beta": f.pipe.beta,
            "time_scale": f.pipe.time_scale,
            **f.pipe.dimensionless_groups(),
            "period": f.period / f.pipe.time_scale,
        },
        warnings=list(f.warnings),
        diagnostics={
            "steps_per_period": f.steps,
            "error_estimate": f.error_estimate,
            "galerkin_modes": f.modes,
            "propagator": "magnus4 (2 Gauss points), step doubling",
        },
    )


def resonance_regions(chart: ResonanceChart) -> list[dict[str, Any]]:
    """The connected unstable regions of ``chart``
    (:meth:`~pipeflow.stability.floquet.ResonanceChart.unstable_regions`, the lowest first):
    :class:`~pipeflow.schema.results.ResonanceRegion`."""
    return [
        r.document(
            r.ResonanceRegion,
            frequency_range=list(region.frequency_range),
            min_amplitude=region.min_amplitude,
            tip={"amplitude": region.tip_amplitude, "frequency": region.tip_frequency},
            max_growth_rate=region.max_growth_rate,
            points=region.points,
            nearest_resonance={
                "condition": region.nearest_condition,
                "frequency": region.nearest_frequency,
            },
        )
        for region in chart.unstable_regions()
    ]


def resonance_chart(chart: ResonanceChart) -> dict[str, Any]:
    """:class:`~pipeflow.schema.results.ResonanceChartResponse` of
    :func:`pipeflow.stability.resonance_chart`."""
    p = chart.pipe
    return r.document(
        r.ResonanceChartResponse,
        kind="resonance_chart",
        mean_velocity=chart.mean_velocity,
        omega0=chart.omega0,
        amplitudes=chart.amplitudes.tolist(),
        frequencies=chart.frequencies.tolist(),
        max_multiplier=chart.max_multiplier.tolist(),
        growth_rate=chart.growth_rate.tolist(),
        unstable=np.asarray(chart.unstable).tolist(),
        regions=resonance_regions(chart),
        natural_frequencies=chart.natural_frequencies().tolist(),
        dimensionless={
            "beta": p.beta,
            "time_scale": p.time_scale,
            **p.dimensionless_groups(),
            "u_mean": None if p.M2 == 0 else float(p.flow_number(chart.mean_velocity)),
            "gamma": float(p.spin_number(chart.omega0)),
            "frequencies": (chart.frequencies * p.time_scale).tolist(),
            "amplitude_ratio": (
                (chart.amplitudes / chart.mean_velocity).tolist()
                if chart.mean_velocity != 0
                else None
            ),
        },
        warnings=list(chart.warnings),
        diagnostics={
            "steps_per_period": chart.steps,
            "error_estimate": chart.error_estimate,
            "galerkin_modes": chart.modes,
        },
    )


def frequency_point(fr: FrequencyResponse) -> dict[str, Any]:
    """One operating point's block of a frequency response (numbers as the library gives
    them)."""
    d = fr.diagnostics
    return {
        "velocity": fr.velocity,
        "omega0": fr.omega0,
        "stable": fr.stable,
        "max_growth_rate": fr.max_growth_rate,
        "responses": [
            {
                "position": float(x),
                "real": fr.H[i].real.tolist(),
                "imag": fr.H[i].imag.tolist(),
                "magnitude": fr.magnitude[i].tolist(),
                "phase": fr.phase[i].tolist(),
            }
            for i, x in enumerate(fr.positions)
        ],
        "peaks": [
            {
                "frequency": p.frequency,
                "natural_frequency": p.natural_frequency,
                "damping_ratio": p.damping_ratio,
                "mode": p.mode,
                "magnitude": list(p.magnitude),
            }
            for p in fr.peaks
        ],
        "diagnostics": {
            "check_frequencies": list(d.check_frequencies),
            "max_relative_difference": d.max_relative_difference,
            "eigenvector_condition": d.eigenvector_condition,
            "method": d.method,
            "residual_flexibility": fr.residual,
            "load_vectors": fr.load_vectors,
        },
        "warnings": list(fr.warnings),
    }


def frequency_response(responses: list[FrequencyResponse]) -> dict[str, Any]:
    """The document of the responses at several operating points (same load, positions,
    quantity and frequencies): shared fields once, one block per point.

    The top-level ``warnings`` are every point's, once: a warning every point has as is,
    another prefixed with its operating point."""
    first = responses[0]
    warnings: list[str] = []
    for fr in responses:
        for w in fr.warnings:
            shared = all(w in o.warnings for o in responses)
            text = w if shared else f"at v = {fr.velocity:g} m/s, w0 = {fr.omega0:g} rad/s: {w}"
            if text not in warnings:
                warnings.append(text)
    return {
        "quantity": first.quantity,
        "unit": first.unit,
        "load": first.load.to_dict(),
        "modes": first.modes,
        "positions": first.positions.tolist(),
        "frequencies": first.frequencies.tolist(),
        "stable": all(fr.stable for fr in responses),
        "max_growth_rate": max(fr.max_growth_rate for fr in responses),
        "operating_points": [frequency_point(fr) for fr in responses],
        "warnings": warnings,
    }


def state_space(ss: StateSpace) -> dict[str, Any]:
    """The document of a state-space realisation (the real matrices, the names of the
    states, input and outputs, and their units)."""
    return {
        "A": ss.A.tolist(),
        "B": ss.B.tolist(),
        "C": ss.C.tolist(),
        "D": ss.D.tolist(),
        "states": list(ss.states),
        "inputs": list(ss.inputs),
        "outputs": list(ss.outputs),
        "units": {
            "time": "s",
            "states": "m"
            if "residual_lag" not in ss.states
            else f"m; residual_lag {ss.input_unit}",
            "inputs": ss.input_unit,
            "outputs": ss.output_unit,
            "A": "1/s",
            "B": f"m/({ss.input_unit} s)",
            "C": f"{ss.output_unit}/m",
            "D": f"{ss.output_unit}/{ss.input_unit}",
        },
        "velocity": ss.velocity,
        "omega0": ss.omega0,
        "quantity": ss.quantity,
        "positions": ss.positions.tolist(),
        "natural_frequencies": ss.natural_frequencies.tolist(),
        "warnings": list(ss.warnings),
    }
