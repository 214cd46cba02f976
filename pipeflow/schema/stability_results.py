"""Response models of the stability analyses: critical velocities (``stability``), the
sweeps (``argand``, ``campbell``), the maps (``spin_map``, ``beta_map``), the resonance
chart and Floquet analysis.  Part of :mod:`pipeflow.schema.results`, which re-exports
every name here (kept apart to keep each module short)."""

from __future__ import annotations

from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field

from pipeflow.model import GROUPS
from pipeflow.schema.result_base import GROUP_NAMES, Result

# -- POST /v1/stability ----------------------------------------------------------------------


class Crossing(BaseModel):
    """One branch crossing sigma = 0 as the flow velocity increases."""

    velocity: float = Field(description="Flow velocity at the crossing [m/s].")
    frequency: float = Field(
        description="Frequency omega of the branch there [rad/s] (0: divergence)."
    )
    frequency_hz: float = Field(description="The same frequency [Hz].")
    mode: int = Field(description="Mode number of the branch (1 = lowest frequency at v = 0).")
    kind: Literal["flutter", "divergence"] = Field(
        description="flutter (complex pair crosses, omega > 0) or divergence (real eigenvalue "
        "through 0)."
    )
    direction: Literal["loss", "gain"] = Field(
        description="loss: the mode becomes unstable; gain: it becomes stable again."
    )
    boundary: bool = Field(
        description="True when the pipe as a whole changes stability here (no other mode is "
        "unstable on either side)."
    )
    flow_number: float | None = Field(
        description="u = v L sqrt(M2/EI) at the crossing [-] (null when M2 = 0)."
    )
    dimensionless_frequency: float = Field(
        description="omega sqrt((M1+M2) L^4/EI) at the crossing [-]."
    )


class StabilityDimensionless(BaseModel):
    beta: float = Field(description="Mass ratio M2/(M1+M2) [-].")
    gamma: float = Field(description="Spin number w0 L^2 sqrt((M1+M2)/EI) [-].")
    u_cr: float | None = Field(
        description="Critical flow number u_cr = v_cr L sqrt(M2/EI) [-], or null."
    )
    u_range: list[float] | None = Field(
        description="The velocity range as flow numbers [-] (null when M2 = 0)."
    )
    time_scale: float = Field(description="L^2 sqrt((M1+M2)/EI) [s].")
    alpha: float = Field(description=GROUPS["alpha"].description)
    viscous_ratio: float = Field(
        description=GROUPS["viscous_ratio"].description + " Named 'sigma' in earlier versions."
    )
    tip_mass_ratio: float = Field(description=GROUPS["tip_mass_ratio"].description)
    tip_inertia_ratio: float = Field(description=GROUPS["tip_inertia_ratio"].description)
    hub_ratio: float = Field(description=GROUPS["hub_ratio"].description)


class ReverseFlow(BaseModel):
    """The aspirating-pipe caveat for the v < 0 part of the range (no threshold is given)."""

    model_config = ConfigDict(extra="allow")

    velocity_range: list[float] = Field(description="The v < 0 part of the range [m/s].")
    predicted_unstable: bool = Field(
        description="Whether this undamped model predicts growth there (it does for any v < 0)."
    )
    growth_rate_at_v_min: float | None = Field(
        description="Largest sigma at v_min [1/s] (positive: growing in the model)."
    )
    caveat: str = Field(description="Why no critical velocity is reported for reverse flow.")


#: how the pipe is unstable at the start of a range: each mechanism once, fastest first
Mechanisms = list[Literal["flutter", "divergence"]]
MECHANISMS = (
    "How the pipe is unstable at the start of the range: 'divergence' (a real eigenvalue > 0, "
    "e.g. by fast spin at v = 0) and/or 'flutter' (a complex pair with sigma > 0), the "
    "fastest-growing first; empty when it is stable there."
)


class StabilityResponse(Result):
    """Critical flow velocities of a pipe at constant spin (every crossing of sigma = 0)."""

    kind: Literal["stability"] = Field(description="Result kind.")
    critical_velocity: float | None = Field(
        description="First loss of stability in the v >= 0 part of the range [m/s], or null "
        "when there is none.  When the range starts unstable (stable_at_start false) this is "
        "the first loss after stability is regained, not a critical velocity from rest: read "
        "stable_intervals and crossings."
    )
    mechanism: Literal["flutter", "divergence"] | None = Field(
        None,
        description="How the pipe loses stability at critical_velocity: 'divergence' (a "
        "frequency reaching zero: supported pipes, conservative ends) or 'flutter' (a complex "
        "pair with growing amplitude: the cantilever, or coupled-mode flutter of a supported "
        "pipe at higher velocity); null without a critical velocity.  Every crossing names its "
        "own in 'kind'.",
    )
    stable_throughout: bool = Field(description="Stable over the whole v >= 0 part of the range.")
    stable_at_start: bool | None = Field(
        description="Stable at max(v_min, 0) (null when the whole range is v < 0)."
    )
    instability_at_start: Mechanisms = Field(description=MECHANISMS)
    stable_intervals: list[list[float]] = Field(
        description="[[v_a, v_b], ...]: velocity intervals where the pipe is stable [m/s]."
    )
    crossings: list[Crossing] = Field(
        description="Every branch crossing of sigma = 0 for v >= 0, by increasing velocity, "
        "each located to 1e-10 relative."
    )
    dimensionless: StabilityDimensionless = Field(
        description="Paidoussis' groups: beta, gamma, u_cr, time scale, and the extended "
        f"model's {GROUP_NAMES}."
    )
    omega0: float = Field(description="Spin w0 [rad/s].")
    modes: int = Field(description="Galerkin modes used [-].")
    velocity_range: list[float] = Field(description="[v_min, v_max] [m/s].")
    reverse_flow: ReverseFlow | None = Field(
        description="The aspirating-pipe caveat when the range reaches v < 0, else null."
    )
    diagnostics: dict[str, Any] = Field(description="Grid points, refinement, tolerances.")


# -- POST /v1/sweeps: argand and campbell ----------------------------------------------------


class SweepAxis(BaseModel):
    name: Literal["velocity", "spin"] = Field(
        description="velocity (Argand: flow velocity swept) or spin (Campbell: w0 swept)."
    )
    unit: Literal["m/s", "rad/s"] = Field(description="Unit of values.")
    values: list[float] = Field(
        description="Swept parameter at each point, refined points included [m/s or rad/s]."
    )
    values_hz: list[float] | None = Field(None, description="Campbell: spin [Hz].")
    values_rpm: list[float] | None = Field(None, description="Campbell: spin [rpm].")
    gamma: list[float] | None = Field(None, description="Campbell: spin number [-].")
    flow_number: list[float] | None = Field(
        None, description="Argand: flow number u = v L sqrt(M2/EI) [-] (absent when M2 = 0)."
    )


class SweepBranch(BaseModel):
    mode: int = Field(description="Mode number (1 = lowest frequency at the first point).")
    sigma: list[float | None] = Field(description="Damping sigma per point [1/s] (> 0: unstable).")
    omega: list[float | None] = Field(description="Frequency omega per point [rad/s].")
    frequency_hz: list[float | None] = Field(description="Frequency per point [Hz].")
    damping_ratio: list[float | None] = Field(
        description="zeta = -sigma/|xi| per point [-] (0 where |xi| = 0; < 0: growing)."
    )
    confidence: list[float] = Field(
        description="Tracking confidence in [0, 1]: left/right eigenvector overlap with the "
        "previous point after the optimal assignment."
    )
    frequency_rpm: list[float | None] | None = Field(
        None, description="Campbell: frequency per point [rpm]."
    )


class ExcitationCrossing(BaseModel):
    order: float = Field(description="Order n of the excitation line omega = n w0 [-].")
    mode: int = Field(description="Mode number of the crossing branch.")
    spin: float = Field(description="Spin w0 at the crossing [rad/s].")
    spin_rpm: float = Field(description="The same [rpm].")
    frequency: float = Field(description="Frequency there, n w0 [rad/s].")
    frequency_hz: float = Field(description="The same [Hz].")
    sigma: float = Field(description="Damping of the branch there [1/s] (> 0: unstable).")
    damping_ratio: float = Field(description="zeta = -sigma/|xi| there [-].")


class Excitation(BaseModel):
    orders: list[float] = Field(description="The excitation orders n requested [-].")
    crossings: list[ExcitationCrossing] = Field(
        description="Every crossing of a tracked branch with a line omega = n w0, by order then "
        "spin, located by root-finding on the frozen spectrum to 1e-12 relative."
    )


class ZeroCrossing(BaseModel):
    mode: int = Field(description="Mode number of the crossing branch.")
    value: float = Field(description="Swept parameter at sigma = 0 [m/s or rad/s].")
    frequency: float = Field(description="|omega| there [rad/s] (0: divergence).")
    direction: Literal["loss", "gain"] = Field(
        description="loss: unstable beyond, with increasing parameter; gain: stable again."
    )


class SweepBoundaryCrossing(BaseModel):
    value: float = Field(description="Swept parameter there [m/s or rad/s].")
    direction: Literal["loss", "gain"] = Field(description="Stability lost or regained.")
    kind: Literal["flutter", "divergence"] = Field(description="Flutter or divergence.")
    frequency: float = Field(description="|omega| of the crossing eigenvalue [rad/s].")


class SweepResponse(Result):
    """Tracked eigenvalues xi = sigma + i omega against flow velocity or spin."""

    kind: Literal["argand", "campbell"] = Field(description="Result kind.")
    parameter: SweepAxis = Field(description="The swept parameter.")
    fixed: dict[str, float] = Field(
        description="The parameter held constant: omega0 [rad/s] (argand) or velocity [m/s] "
        "(campbell)."
    )
    inserted: list[bool] = Field(description="Per point: added by refinement.")
    modes: list[SweepBranch] = Field(description="The tracked branches, lowest first.")
    excitation: Excitation | None = Field(
        None, description="Campbell: the excitation lines' crossings with the tracked branches."
    )
    zero_crossings: list[ZeroCrossing] = Field(
        default_factory=list,
        description="Where a tracked branch crosses sigma = 0 (Argand: the critical points).",
    )
    stable_at_start: bool = Field(
        description="The pipe (every eigenvalue, not only the tracked branches) is stable at "
        "the first point of the sweep."
    )
    instability_at_start: Mechanisms = Field(description=MECHANISMS)
    boundary: list[SweepBoundaryCrossing] = Field(
        description="Every change of the pipe's stability along the sweep (every eigenvalue, "
        "tracked or not), by increasing parameter, each located to 1e-12 relative."
    )
    stable_intervals: list[list[float]] = Field(
        description="[[a, b], ...]: intervals of the swept parameter where the pipe is stable "
        "[m/s or rad/s, the parameter's unit]."
    )
    dimensionless: dict[str, float] = Field(
        description="beta [-], time_scale [s], and gamma (argand) or flow_number (campbell) "
        f"[-]; the extended model's {GROUP_NAMES} [-]."
    )
    diagnostics: dict[str, Any] = Field(
        description="points, inserted_points, min_confidence, galerkin_modes."
    )


# -- spin_map and beta_map -------------------------------------------------------------------


class MapCrossing(BaseModel):
    velocity: float = Field(description="Flow velocity of the boundary crossing [m/s].")
    direction: Literal["loss", "gain"] = Field(description="Stability lost or regained.")
    kind: Literal["flutter", "divergence"] = Field(description="Flutter or divergence.")
    frequency: float = Field(description="Frequency of the crossing branch [rad/s].")
    frequency_hz: float = Field(description="The same [Hz].")


class SpinMapResponse(Result):
    """Growth rate over (spin, flow velocity) and the critical velocity at each spin."""

    kind: Literal["spin_map"] = Field(description="Result kind.")
    spins: list[float] = Field(description="Spins w0 [rad/s].")
    spins_rpm: list[float] = Field(description="The same [rpm].")
    velocities: list[float] = Field(description="Flow velocities v [m/s].")
    growth_rate: list[list[float | None]] = Field(
        description="Largest sigma at (spins[i], velocities[k]) [1/s] (> 0: unstable)."
    )
    critical_velocity: list[float | None] = Field(
        description="Per spin: first loss of stability for v >= 0 [m/s], or null; at a spin "
        "whose line starts unstable (stable_at_start false), the first loss after stability "
        "is regained, not a critical velocity from rest: read stable_intervals."
    )
    stable_at_start: list[bool] = Field(description="Per spin: stable at max(v_min, 0).")
    instability_at_start: list[Mechanisms] = Field(description="Per spin: " + MECHANISMS)
    stable_intervals: list[list[list[float]]] = Field(
        description="Per spin: [[v_a, v_b], ...] where the pipe is stable [m/s]."
    )
    crossings: list[list[MapCrossing]] = Field(
        description="Per spin: every boundary crossing for v >= 0."
    )
    dimensionless: dict[str, Any] = Field(
        description="beta [-], gamma per spin [-], u_cr per spin [-], time_scale [s]; the "
        f"extended model's {GROUP_NAMES} [-]."
    )
    diagnostics: dict[str, Any] = Field(description="galerkin_modes, points.")


class BetaCrossing(BaseModel):
    u: float = Field(description="Flow number of the boundary crossing [-].")
    direction: Literal["loss", "gain"] = Field(description="Stability lost or regained.")
    kind: Literal["flutter", "divergence"] = Field(description="Flutter or divergence.")
    frequency: float = Field(description="Non-dimensional frequency of the branch [-].")


class BetaMapResponse(Result):
    """u_cr(beta) in non-dimensional form with every crossing (the S-shaped segments)."""

    kind: Literal["beta_map"] = Field(description="Result kind.")
    gamma: float = Field(description="Spin number [-].")
    groups: dict[str, float] = Field(description=f"{GROUP_NAMES} [-] (the same at every beta).")
    plane: Literal["in-plane", "out-of-plane"] = Field(description="Plane of the vibration.")
    betas: list[float] = Field(description="Mass ratios M2/(M1+M2) [-].")
    u_range: list[float] = Field(description="[u_min, u_max] flow numbers [-].")
    u_cr: list[float | None] = Field(
        description="Per beta: first loss of stability [-], or null; where the line starts "
        "unstable (stable_at_start false), the first loss after stability is regained: read "
        "stable_intervals."
    )
    stable_at_start: list[bool] = Field(description="Per beta: stable at u_min.")
    instability_at_start: list[Mechanisms] = Field(description="Per beta: " + MECHANISMS)
    stable_intervals: list[list[list[float]]] = Field(
        description="Per beta: [[u_a, u_b], ...] where the pipe is stable [-]."
    )
    crossings: list[list[BetaCrossing]] = Field(description="Per beta: every boundary crossing.")
    curve: list[list[float]] = Field(
        description="[[beta, u], ...]: every crossing as a point of the stability curve [-]."
    )
    multiple_crossings: list[float] = Field(
        description="Betas with more than one crossing (S-shaped segment) [-]."
    )
    diagnostics: dict[str, Any] = Field(description="galerkin_modes.")


# -- resonance_chart and floquet -------------------------------------------------------------


class ResonanceRegion(BaseModel):
    model_config = ConfigDict(extra="allow")

    frequency_range: list[float] = Field(
        description="[Omega_a, Omega_b] pulsation frequencies spanned [rad/s]."
    )
    min_amplitude: float = Field(description="Smallest unstable amplitude in the region [m/s].")
    tip: dict[str, float] = Field(description="amplitude [m/s] and frequency [rad/s] of its tip.")
    max_growth_rate: float = Field(description="Largest growth rate in the region [1/s].")
    points: int = Field(description="Unstable chart points in the region [-].")
    nearest_resonance: dict[str, Any] = Field(
        description="condition (e.g. '2*omega_1') and frequency [rad/s] nearest to the tip."
    )


class ResonanceChartResponse(Result):
    """Floquet chart of pulsating flow v = mean + a sin(Omega t) over (a, Omega)."""

    kind: Literal["resonance_chart"] = Field(description="Result kind.")
    mean_velocity: float = Field(description="Mean flow velocity [m/s].")
    omega0: float = Field(description="Spin w0 [rad/s].")
    amplitudes: list[float] = Field(description="Pulsation amplitudes a [m/s].")
    frequencies: list[float] = Field(description="Pulsation frequencies Omega [rad/s].")
    max_multiplier: list[list[float | None]] = Field(
        description="max |lambda| at (amplitudes[i], frequencies[j]) [-]."
    )
    growth_rate: list[list[float | None]] = Field(
        description="log(max |lambda|)/T at (amplitudes[i], frequencies[j]) [1/s]."
    )
    unstable: list[list[bool]] = Field(
        description="max |lambda| > 1 beyond the error band at (amplitudes[i], frequencies[j])."
    )
    regions: list[ResonanceRegion] = Field(description="Connected unstable regions (tongues).")
    natural_frequencies: list[float] = Field(
        description="Frozen frequencies at the mean flow and spin [rad/s], ascending."
    )
    dimensionless: dict[str, Any] = Field(
        description="beta, u_mean, gamma, frequencies Omega*time_scale, amplitude_ratio a/mean "
        f"[-]; time_scale [s]; the extended model's {GROUP_NAMES} [-]."
    )
    diagnostics: dict[str, Any] = Field(
        description="steps_per_period, error_estimate, galerkin_modes."
    )


class Multipliers(BaseModel):
    real: list[float] = Field(description="Re lambda [-], by decreasing modulus.")
    imag: list[float] = Field(description="Im lambda [-].")
    modulus: list[float] = Field(description="|lambda| [-] (> 1: a growing solution).")


class Exponents(BaseModel):
    sigma: list[float] = Field(description="Re mu = log|lambda|/T [1/s].")
    omega: list[float] = Field(description="Im mu = arg(lambda)/T [rad/s] (modulo 2 pi/T).")


class FloquetResponse(Result):
    """Floquet multipliers of one case with harmonic flow and/or spin."""

    kind: Literal["floquet"] = Field(description="Result kind.")
    period: float = Field(description="Period T of the coefficients [s].")
    verdict: Literal["stable", "unstable", "marginal"] = Field(
        description="stable: every |lambda| < 1 beyond the error band; unstable: one > 1; "
        "marginal: max |lambda| = 1 within it."
    )
    max_multiplier: float = Field(description="max |lambda| [-].")
    growth_rate: float = Field(description="log(max |lambda|)/T [1/s].")
    multipliers: Multipliers = Field(
        description="Floquet multipliers lambda (monodromy eigenvalues)."
    )
    exponents: Exponents = Field(description="Floquet exponents mu = log(lambda)/T.")
    frozen_mean: dict[str, list[float]] = Field(
        description="Eigenvalues at the mean flow and spin: sigma [1/s], omega [rad/s]."
    )
    dimensionless: dict[str, float] = Field(
        description="beta [-], time_scale [s], period/time_scale [-]; the extended model's "
        f"{GROUP_NAMES} [-]."
    )
    diagnostics: dict[str, Any] = Field(
        description="steps_per_period, error_estimate, galerkin_modes, propagator."
    )
