"""Floquet analysis of periodic coefficients: pulsating flow and oscillating spin.

For v(t) and w0(t) periodic with period T [s], the homogeneous state equation
z' = S(t) z (the forcing by dw0/dt moves the response but not its stability) has solutions
z(t + T) = Phi z(t) with the monodromy matrix Phi = Z(T), Z' = S Z, Z(0) = I.  Its
eigenvalues are the Floquet multipliers lambda; the exponents are mu = log(lambda) / T
[1/s] (imaginary parts defined modulo 2 pi / T).  The pipe is stable when every
|lambda| <= 1.

Phi is the product of fourth-order Magnus steps with two Gauss points (Blanes, Casas,
Oteo & Ros, Physics Reports 470, 2009, eq. 253)::

    Omega_k = h/2 (A_1 + A_2) + sqrt(3) h^2 / 12 [A_2, A_1],   Phi = prod_k exp(Omega_k),

batched: all exponentials of a period (and, for a chart, of all amplitudes) are one
:func:`~pipeflow.linalg.expm_stack` call, and the product is taken pairwise
(:func:`~pipeflow.linalg.product_of_steps`); the step itself is
:func:`~pipeflow.linalg.magnus4_omega`, shared with the Magnus solver.  The
number of steps per period is doubled until two successive monodromy matrices agree to
``tolerance`` (relative, 2-norm); that difference is reported as the error estimate.  With zero
pulsation amplitude S is constant, Omega = h S and Phi = exp(S T) to rounding.
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy import ndimage

from pipeflow import parallel
from pipeflow._types import ComplexArray, FloatArray, Progress
from pipeflow.errors import BudgetExceeded, InvalidInput
from pipeflow.linalg import GAUSS_NODES, expm_stack, magnus4_omega, product_of_steps
from pipeflow.loading import Loading
from pipeflow.model import REVERSE_FLOW_CAVEAT, Pipe, PipeModel, build_model
from pipeflow.profiles import Constant, Harmonic, Profile
from pipeflow.stability.core import check_modes, check_range, eigenvalues


class Verdict(enum.StrEnum):
    """The stability verdict of a Floquet analysis (JSON carries the value)."""

    #: every |lambda| < 1 beyond the error band
    STABLE = "stable"
    #: max |lambda| > 1 beyond the error band
    UNSTABLE = "unstable"
    #: max |lambda| = 1 within the error band
    MARGINAL = "marginal"


MIN_STEPS = 16
#: ceiling on Magnus steps per period
MAX_STEPS = 65_536
#: ceiling on (grid points) x (steps per period) x (2n)^3 for one chart
MAX_CHART_WORK = 2e11


def _monodromy_steps(
    model: PipeModel,
    coefficients: Any,
    period: float,
    steps: int,
) -> FloatArray:
    """Monodromy matrices for a batch: ``coefficients(t)`` -> (v, vdot, w2), each (B, len(t))."""
    h = period / steps
    t0 = np.arange(steps) * h
    # (B, N, m, m) at each Gauss point
    A1, A2 = (model.frozen_state_matrix(*coefficients(t0 + g * h)) for g in GAUSS_NODES)
    return product_of_steps(expm_stack(magnus4_omega(A1, A2, h)))


def _converged_monodromy(
    model: PipeModel,
    coefficients: Any,
    period: float,
    tolerance: float,
    start: int,
) -> tuple[FloatArray, int, float]:
    """Double the steps until successive monodromy matrices agree to ``tolerance``.

    Agreement is measured on the batch member that changes most. Returns (Phi, steps,
    error estimate).
    """
    steps = max(MIN_STEPS, start)
    prev = _monodromy_steps(model, coefficients, period, steps)
    while True:
        if 2 * steps > MAX_STEPS:
            raise BudgetExceeded(
                f"the monodromy matrix did not converge to {tolerance:g} within {MAX_STEPS} "
                "steps per period; loosen the tolerance or use fewer modes",
                parameter="tolerance",
            )
        steps *= 2
        cur = _monodromy_steps(model, coefficients, period, steps)
        diff = np.linalg.norm(cur - prev, 2, axis=(-2, -1)) / np.linalg.norm(cur, 2, axis=(-2, -1))
        err = float(np.max(diff)) / 15.0  # order 4: the finer result is ~16x more accurate
        if err <= tolerance:
            return cur, steps, err
        prev = cur


def check_chart_work(
    pipe: Pipe, modes: int, amplitude_points: int, frequency_points: int, lowest_frequency: float
) -> None:
    """Raise :class:`BudgetExceeded` when a resonance chart would cost too much.

    The cost is points x Magnus steps over the longest period (lowest frequency [rad/s])
    x (2 modes)^3; cheap to evaluate, so request validation can refuse early.
    """
    work = chart_work(pipe, modes, amplitude_points * frequency_points, lowest_frequency)
    if work > MAX_CHART_WORK:
        raise BudgetExceeded(
            f"the chart would cost about {work:.3g} units > {MAX_CHART_WORK:.3g}; use fewer "
            "points or modes, or a higher lowest frequency",
            parameter="frequency_points",
        )


def chart_work(pipe: Pipe, modes: int, points: int, lowest_frequency: float) -> int:
    """The cost of ``points`` monodromy matrices over the period of ``lowest_frequency``
    [rad/s]: points x Magnus steps x (2 modes)^3 (the units of :data:`MAX_CHART_WORK`)."""
    model = build_model(pipe, modes)
    steps = _initial_steps(model, 2 * math.pi / lowest_frequency)
    return int(points * steps * model.size**3)


def _initial_steps(model: PipeModel, period: float) -> int:
    # a handful of steps per period of the fastest retained mode keeps h |S| of order 1
    rho = float(np.max(model.omega_ref))
    return int(min(MAX_STEPS // 4, max(MIN_STEPS, math.ceil(rho * period / 4.0))))


@dataclass
class Floquet:
    """Floquet analysis of one periodic case (SI units; JSON form:
    :func:`pipeflow.computations.documents.floquet`).

    period : T [s]; monodromy : Phi (balanced coordinates); multipliers : lambda, sorted by
    decreasing modulus; exponents : mu = log(lambda)/T [1/s]; steps : Magnus steps per
    period; error_estimate : relative accuracy of Phi; verdict : "stable" (all |lambda| < 1
    beyond the error band), "unstable", or "marginal" (max |lambda| = 1 within it).
    frozen_mean : eigenvalues of S at the mean flow and spin [1/s], for reference.
    """

    pipe: Pipe
    modes: int
    period: float
    monodromy: FloatArray
    multipliers: ComplexArray
    exponents: ComplexArray
    steps: int
    error_estimate: float
    verdict: Verdict
    frozen_mean: ComplexArray
    warnings: list[str] = field(default_factory=list)

    @property
    def max_multiplier(self) -> float:
        return float(np.abs(self.multipliers[0]))

    @property
    def growth_rate(self) -> float:
        """log(max |lambda|) / T [1/s]: the growth rate of the worst solution."""
        return math.log(self.max_multiplier) / self.period


def _verdict(max_mod: float, err: float) -> Verdict:
    band = max(1e-9, 100.0 * err)
    if max_mod > 1.0 + band:
        return Verdict.UNSTABLE
    if max_mod < 1.0 - band:
        return Verdict.STABLE
    return Verdict.MARGINAL


def _mean(profile: Profile) -> float:
    if isinstance(profile, Harmonic):
        return float(profile.mean)
    if isinstance(profile, Constant):
        return float(profile.val)
    raise InvalidInput("periodic profiles must be constant or harmonic", parameter="profile")


def period_of(flow: Profile, spin: Profile) -> float:
    """Common period T = 2 pi / frequency [s] of harmonic flow and/or spin."""
    harmonic = [p for p in (flow, spin) if isinstance(p, Harmonic) and p.frequency > 0]
    # a zero-amplitude harmonic still sets the period (the check against exp(S T))
    freqs = [p.frequency for p in harmonic if p.amplitude != 0] or [
        p.frequency for p in harmonic[:1]
    ]
    for name, p in (("flow", flow), ("spin", spin)):
        if not isinstance(p, Harmonic | Constant):
            raise InvalidInput(
                "Floquet analysis needs constant or harmonic profiles", parameter=name
            )
    if not freqs:
        raise InvalidInput(
            "Floquet analysis needs a harmonic flow or spin with frequency > 0 (for "
            "constant coefficients use the critical-velocity analysis)",
            parameter="flow",
        )
    if len(freqs) == 2 and not math.isclose(freqs[0], freqs[1], rel_tol=1e-12):
        raise InvalidInput(
            "harmonic flow and spin must share one frequency for a common period",
            parameter="spin",
        )
    return 2.0 * math.pi / freqs[0]


def floquet(
    pipe: Pipe,
    flow: Profile,
    spin: Profile | None = None,
    modes: int = 6,
    tolerance: float = 1e-8,
    progress: Progress | None = None,
) -> Floquet:
    """Floquet multipliers of the pipe under harmonic flow v(t) [m/s] and/or spin w0(t) [rad/s].

    ``tolerance`` is the relative accuracy asked of the monodromy matrix [-].
    """
    check_modes(modes)
    spin = spin if spin is not None else Constant(0.0)
    period = period_of(flow, spin)
    model = build_model(pipe, modes)
    loading = Loading(flow, spin)

    def coefficients(t: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
        c = loading.coefficients(t)
        return c.v[None], c.vdot[None], c.w2[None]

    if progress is not None:
        progress(0.0)
    Phi, steps, err = _converged_monodromy(
        model, coefficients, period, tolerance, _initial_steps(model, period)
    )
    Phi = Phi[0]
    lam = np.linalg.eigvals(Phi)
    lam = lam[np.argsort(-np.abs(lam), kind="stable")]
    with np.errstate(divide="ignore"):
        mu = np.log(lam.astype(complex)) / period
    warnings = []
    t = np.linspace(0.0, period, 64)
    if np.any(flow.value(t) < 0):
        warnings.append("the flow reverses during the period: " + REVERSE_FLOW_CAVEAT)
    if progress is not None:
        progress(1.0)
    return Floquet(
        pipe=pipe,
        modes=modes,
        period=period,
        monodromy=Phi,
        multipliers=lam,
        exponents=mu,
        steps=steps,
        error_estimate=err,
        verdict=_verdict(float(np.abs(lam[0])), err),
        frozen_mean=eigenvalues(model, _mean(flow), _mean(spin))[0],
        warnings=warnings,
    )


@dataclass(frozen=True)
class UnstableRegion:
    """A connected unstable region of a :class:`ResonanceChart` (SI units).

    frequency_range : its lowest and highest pulsation frequency [rad/s]; min_amplitude :
    its lowest amplitude [m/s]; tip_amplitude, tip_frequency : the point of the tongue's
    tip [m/s, rad/s]; max_growth_rate : the largest growth rate in it [1/s]; points : the
    chart points it covers; nearest_condition, nearest_frequency : the classical resonance
    condition nearest to the tip (:meth:`ResonanceChart.resonances`; "" and NaN when there
    is none) and its frequency [rad/s].
    """

    frequency_range: tuple[float, float]
    min_amplitude: float
    tip_amplitude: float
    tip_frequency: float
    max_growth_rate: float
    points: int
    nearest_condition: str
    nearest_frequency: float


@dataclass
class ResonanceChart:
    """Parametric-resonance chart of pulsating flow v = mean + a sin(Omega t) (SI units).

    amplitudes : a [m/s]; frequencies : Omega [rad/s]; max_multiplier[i, j] : max |lambda| at
    (amplitudes[i], frequencies[j]); growth_rate = log(max |lambda|)/T [1/s]; unstable :
    max |lambda| > 1 beyond the error band; :meth:`unstable_regions` : the connected unstable
    regions with the frozen-frequency resonance condition nearest to each tongue's tip.
    JSON form: :func:`pipeflow.computations.documents.resonance_chart`.
    """

    pipe: Pipe
    modes: int
    mean_velocity: float
    omega0: float
    amplitudes: FloatArray
    frequencies: FloatArray
    max_multiplier: FloatArray
    growth_rate: FloatArray
    unstable: Any
    steps: list[int]
    error_estimate: float
    frozen_mean: ComplexArray
    warnings: list[str] = field(default_factory=list)

    def natural_frequencies(self) -> FloatArray:
        """Frozen frequencies omega_j at the mean flow and spin [rad/s], ascending (> 0)."""
        w = self.frozen_mean
        return np.sort(w.imag[w.imag > 1e-9 * np.max(np.abs(w))])

    def resonances(self) -> list[tuple[str, float]]:
        """Classical resonance conditions: Omega = 2 omega_j / k (k = 1, 2, 3) and
        omega_i +- omega_j (combination resonances) [rad/s]."""
        om = self.natural_frequencies()
        out = []
        for j, w in enumerate(om, start=1):
            for k in (1, 2, 3):
                out.append((f"2*omega_{j}/{k}" if k > 1 else f"2*omega_{j}", 2 * w / k))
        for i in range(om.size):
            for j in range(i + 1, om.size):
                out.append((f"omega_{i + 1}+omega_{j + 1}", om[i] + om[j]))
                out.append((f"omega_{j + 1}-omega_{i + 1}", om[j] - om[i]))
        return out

    def unstable_regions(self) -> list[UnstableRegion]:
        """The connected unstable regions of the chart, by lowest amplitude (then the
        largest first), each with the resonance condition nearest to its tip."""
        labels, count = ndimage.label(self.unstable)
        cands = self.resonances()
        out: list[UnstableRegion] = []
        for label in range(1, count + 1):
            ii, jj = np.nonzero(labels == label)
            tip = np.argmin(self.amplitudes[ii] * 1e6 + np.abs(jj - jj.mean()))
            tip_freq = float(self.frequencies[jj[tip]])
            worst = np.argmax(self.growth_rate[ii, jj])
            near = min(cands, key=lambda c: abs(c[1] - tip_freq)) if cands else ("", math.nan)
            out.append(
                UnstableRegion(
                    frequency_range=(
                        float(self.frequencies[jj.min()]),
                        float(self.frequencies[jj.max()]),
                    ),
                    min_amplitude=float(self.amplitudes[ii].min()),
                    tip_amplitude=float(self.amplitudes[ii[tip]]),
                    tip_frequency=tip_freq,
                    max_growth_rate=float(self.growth_rate[ii[worst], jj[worst]]),
                    points=int(ii.size),
                    nearest_condition=near[0],
                    nearest_frequency=float(near[1]),
                )
            )
        out.sort(key=lambda region: (region.min_amplitude, -region.points))
        return out


#: frequencies of a resonance chart computed by one piece, at most (progress between pieces)
MAX_CHART_PIECE = 4


@dataclass(frozen=True)
class _ChartColumns:
    """A piece of a resonance chart: the columns of pulsation frequencies ``frequencies``
    [rad/s] over all amplitudes ``amplitudes`` [m/s] (picklable)."""

    pipe: Pipe
    modes: int
    mean_velocity: float
    omega0: float
    amplitudes: FloatArray
    frequencies: FloatArray
    tolerance: float


def _chart_columns(piece: _ChartColumns) -> tuple[FloatArray, list[int], list[float]]:
    """Max |lambda| (amplitudes x frequencies of ``piece``), the Magnus steps per period
    and the error estimate of each column: the steps are set by step doubling on the largest
    amplitude (the hardest case), then all amplitudes are propagated in one batch."""
    model = build_model(piece.pipe, piece.modes)
    amps = piece.amplitudes
    w2 = piece.omega0 * piece.omega0
    mean_velocity = piece.mean_velocity
    mod = np.empty((amps.size, piece.frequencies.size))
    steps_used: list[int] = []
    errors: list[float] = []
    for j, Om in enumerate(piece.frequencies):
        Om = float(Om)
        period = 2 * math.pi / Om

        def coeffs(
            t: FloatArray, a: FloatArray, Om: float = Om
        ) -> tuple[FloatArray, FloatArray, FloatArray]:
            s, c = np.sin(Om * t), np.cos(Om * t)
            v = mean_velocity + a[:, None] * s[None]
            vdot = a[:, None] * Om * c[None]
            return v, vdot, np.full_like(v, w2)

        _, steps, err = _converged_monodromy(
            model,
            lambda t, coeffs=coeffs: coeffs(t, amps[-1:]),
            period,
            piece.tolerance,
            _initial_steps(model, period),
        )
        Phi = _monodromy_steps(model, lambda t, coeffs=coeffs: coeffs(t, amps), period, steps)
        mod[:, j] = np.max(np.abs(np.linalg.eigvals(Phi)), axis=-1)
        steps_used.append(steps)
        errors.append(err)
    return mod, steps_used, errors


def resonance_chart(
    pipe: Pipe,
    mean_velocity: float,
    amplitude_range: tuple[float, float],
    frequency_range: tuple[float, float],
    omega0: float = 0.0,
    modes: int = 4,
    amplitude_points: int = 21,
    frequency_points: int = 41,
    tolerance: float = 1e-6,
    progress: Progress | None = None,
) -> ResonanceChart:
    """Max Floquet multiplier over (pulsation amplitude a [m/s], frequency Omega [rad/s]).

    Flow v(t) = mean_velocity + a sin(Omega t) [m/s], constant spin omega0 [rad/s].  For
    each Omega the steps per period are set by step doubling on the largest amplitude
    (the hardest case), then all amplitudes are propagated in one batch.  The frequencies
    are cut into pieces (:func:`pipeflow.parallel.split`) that run on the installed host and
    are merged by index; ``progress`` is called after each piece.
    """
    check_modes(modes)
    check_range(*amplitude_range, parameter="amplitude_range")
    check_range(*frequency_range, parameter="frequency_range")
    if amplitude_range[0] < 0 or frequency_range[0] <= 0:
        raise InvalidInput(
            "amplitudes must be >= 0 m/s and frequencies > 0 rad/s", parameter="frequency_range"
        )
    if amplitude_points < 1 or frequency_points < 1:
        raise InvalidInput("need >= 1 point on each axis", parameter="amplitude_points")
    check_chart_work(pipe, modes, amplitude_points, frequency_points, frequency_range[0])
    model = build_model(pipe, modes)
    amps = np.linspace(*amplitude_range, amplitude_points)
    freqs = np.linspace(*frequency_range, frequency_points)
    # as many pieces as split() makes, but strided: the cost grows with the period, so
    # every piece gets low and high frequencies alike (at most MAX_CHART_PIECE each)
    count = len(parallel.split(freqs.size, max_size=MAX_CHART_PIECE))
    columns = [list(range(k, freqs.size, count)) for k in range(count)]
    pieces = [
        _ChartColumns(pipe, modes, mean_velocity, omega0, amps, freqs[c], tolerance)
        for c in columns
    ]
    parts = parallel.gather(_chart_columns, pieces, progress, [len(c) for c in columns])
    mod = np.empty((amps.size, freqs.size))
    steps_used = [0] * freqs.size
    err_max = 0.0
    for c, (m, steps, err) in zip(columns, parts, strict=True):
        mod[:, c] = m
        for j, n in zip(c, steps, strict=True):
            steps_used[j] = n
        err_max = max([err_max, *err])
    band = max(1e-9, 100.0 * err_max)
    warnings = []
    if mean_velocity - amplitude_range[1] < 0:
        warnings.append("the flow reverses during part of the period: " + REVERSE_FLOW_CAVEAT)
    return ResonanceChart(
        pipe=pipe,
        modes=modes,
        mean_velocity=float(mean_velocity),
        omega0=float(omega0),
        amplitudes=amps,
        frequencies=freqs,
        max_multiplier=mod,
        growth_rate=np.log(mod) * freqs[None, :] / (2 * math.pi),
        unstable=mod > 1.0 + band,
        steps=steps_used,
        error_estimate=err_max,
        frozen_mean=eigenvalues(model, mean_velocity, omega0)[0],
        warnings=warnings,
    )
