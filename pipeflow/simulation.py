"""One simulation: inputs, the solver run, and everything reported about it.

``simulate(Simulation(...))`` is the library's main entry point; the HTTP service and the
command line build a :class:`Simulation` from their JSON spec and call it.
"""

from __future__ import annotations

import dataclasses
import enum
import functools
import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from pipeflow._types import FloatArray, Progress
from pipeflow.basis import MAX_MODES
from pipeflow.diagnostics import add_error_estimate
from pipeflow.divergence import default_bound, divergence
from pipeflow.divergence import message as divergence_message
from pipeflow.errors import InvalidInput
from pipeflow.loading import Loading
from pipeflow.loads import Load, held_note, load_notes, project_loads, validate_loads
from pipeflow.model import REVERSE_FLOW_CAVEAT, Pipe, PipeModel, basis_caveats, build_model
from pipeflow.modeshapes import (
    DEFAULT_SHAPE_POINTS,
    MAX_SHAPE_POINTS,
    MAX_SHAPE_TIMES,
    MAX_SHAPE_VALUES,
    ModeShapes,
    frozen_mode_shapes,
)
from pipeflow.profiles import Constant, Profile
from pipeflow.solvers import SOLVERS, Options, Problem
from pipeflow.solvers.checkpoint import current_checkpoints
from pipeflow.spectra import Traces, max_growth_rates, select, spectrum
from pipeflow.statics import statics_cover
from pipeflow.supports import pressure_force_per_pascal


class SimulationStatus(enum.StrEnum):
    """How a run ended (the ``status`` of a result; JSON carries the value)."""

    OK = "ok"
    #: a frozen growth rate is positive at the end, the deflection still within the bound
    DIVERGING = "diverging"
    #: the deflection passed the divergence bound (the linear model's range): the history
    #: stops at that sample (:mod:`pipeflow.divergence`)
    DIVERGED = "diverged"
    #: the response overflowed double precision (the samples after it are omitted)
    OVERFLOW = "overflow"


@dataclass(frozen=True)
class Simulation:
    """Everything that defines a run (SI units).

    pipe : pipe and fluid properties.
    flow : flow velocity profile v(t) [m/s] (v > 0 from the clamped end to the tip).
    spin : spin profile w0(t) [rad/s].
    u0, du0 : initial amplitude [m] and velocity amplitude [m/s] of the initial shape.
    initial_shape : "paper" (eq. 3's phi_1, tip value 2.7244 u0) or "tip" (u0 is the tip).
    modes : number of Galerkin modes n (1..MAX_MODES = 40).
    t_end : simulated duration [s]; samples : number of output times (incl. 0 and t_end).
    method : solver name (see ``pipeflow.solvers.SOLVERS``); "auto" (the default) runs
        "cma" for constant flow and spin, where it is exact, and "magnus" otherwise;
        options : its options.
    positions : extra stations x [m] (0..L) whose displacement is reported.
    eigen_modes : how many of the lowest eigenvalue branches to trace (at most ``modes``);
        the least stable branch of the whole frozen spectrum is traced too, and flagged.
    eigen_samples : number of times at which frozen eigenvalues are computed, evenly from 0
        to t_end, or to the end of the history when the run stopped early (status
        "diverged" or "overflow": the traces, the growth diagnostics and the status stop
        where the history does; at most one per output time kept).
    include_modal : also return the modal coordinates d [m] and d' [m/s].
    mode_acceleration : add to the tip and station displacements the quasi-static response
        of the modes left out to the loads (:func:`mode_acceleration`; constant flow and
        spin, end supports only, point forces, impulses or clamp accelerations).
    divergence_bound : the linear model's range, a bound [m] on |u| at the tip and at every
        output station: the run stops at the first output time past it, status "diverged"
        (:mod:`pipeflow.divergence`; None, the default: 0.1 L, or twice the initial
        deflection when that is larger).
    quadrature_order : Gauss-Legendre points for the Galerkin integrals (None: automatic).
    mode_shape_times : times [s] (0..t_end) at which the complex mode shapes of the frozen
        spectrum are returned (:mod:`pipeflow.modeshapes`); empty: none.
    mode_shape_points : stations from x = 0 to L at which each mode shape is evaluated.
    pressure : internal gauge pressure p(t) [Pa] varying in time (a profile; its force
        p A (1 - 2 nu delta) enters S(t) as a sixth piece, ``PipeModel.with_pressure_piece``),
        or None (the default): the pipe's constant ``pressure``.  Give one or the other; a
        constant profile is the pipe's constant pressure.
    loads : external loads (:mod:`pipeflow.loads`: :class:`~pipeflow.loads.PointForce`,
        :class:`~pipeflow.loads.DistributedForce`, :class:`~pipeflow.loads.BaseAcceleration`;
        at most 16), each with its time history; every method honours them.  Empty (the
        default): the free vibration, computed exactly as without the field.  With a base
        acceleration the displacements are relative to the clamp.
    """

    pipe: Pipe
    flow: Profile = field(default_factory=lambda: Constant(0.0))
    spin: Profile = field(default_factory=lambda: Constant(0.0))
    u0: float = 0.001
    du0: float = 0.0
    initial_shape: str = "paper"
    modes: int = 10
    t_end: float = 1.0
    samples: int = 2001
    method: str = "auto"
    options: Options = field(default_factory=Options)
    positions: tuple[float, ...] = ()
    eigen_modes: int = 3
    eigen_samples: int = 201
    include_modal: bool = False
    divergence_bound: float | None = None
    quadrature_order: int | None = None
    mode_shape_times: tuple[float, ...] = ()
    mode_shape_points: int = DEFAULT_SHAPE_POINTS
    loads: tuple[Load, ...] = ()
    pressure: Profile | None = None
    mode_acceleration: bool = False


def pressure_loading(sim: Simulation) -> tuple[Pipe, Profile | None]:
    """The pipe and the pressure profile a run uses: a constant profile becomes the pipe's
    constant ``pressure`` (in K_0, exactly as that field); a profile with no effect (a free,
    discharging end cancels the pressure) is dropped; a time-varying one is returned for
    :class:`~pipeflow.loading.Loading` (the pipe's pressure is then 0)."""
    p = sim.pressure
    if p is None:
        return sim.pipe, None
    if p.is_constant:
        return dataclasses.replace(sim.pipe, pressure=float(p.value(np.zeros(1))[0])), None
    if pressure_force_per_pascal(sim.pipe) == 0.0:
        return sim.pipe, None
    return sim.pipe, p


def model_and_loading(sim: Simulation) -> tuple[PipeModel, Loading]:
    """The Galerkin model and the time dependence of ``sim`` (one rule for every caller)."""
    pipe, pressure = pressure_loading(sim)
    model = build_model(pipe, sim.modes, sim.quadrature_order)
    if pressure is not None:
        model = model.with_pressure_piece()
    return model, Loading(sim.flow, sim.spin, pressure)


def check_mode_acceleration(sim: Simulation) -> None:
    """The mode-acceleration method's domain (its static correction is of one operating
    point of the clamped-free pipe, and of loads whose static response is known)."""
    why = None
    steady = sim.pressure is None or sim.pressure.is_constant
    if not (sim.flow.is_constant and sim.spin.is_constant and steady):
        why = "needs constant flow, spin and pressure (its static correction is of one point)"
    elif not statics_cover(sim.pipe):
        why = "needs the static solution, which a pipe free to rotate as a rigid body does not have"
    elif any(load.kind == "distributed_force" for load in sim.loads):
        why = "takes point forces, impulses and clamp accelerations, not distributed loads"
    if why is not None:
        raise InvalidInput(f"mode_acceleration {why}", parameter="mode_acceleration")


def mode_acceleration(
    sim: Simulation, model: PipeModel, xs: FloatArray, t: FloatArray
) -> FloatArray | None:
    """The mode-acceleration correction [m] at stations ``xs`` [m], shape (len(xs), len(t)):
    for each load the static response of the modes left out per unit load
    (:func:`pipeflow.statics.truncation_residual`) times the load's value at ``t`` (an
    impulse has none); None where the static problem is singular (divergence)."""
    from pipeflow.statics import truncation_residual

    pipe = pressure_loading(sim)[0]  # a constant pressure profile is the pipe's pressure
    v = float(sim.flow.value(np.zeros(1))[0])
    w0 = float(sim.spin.value(np.zeros(1))[0])
    K = model.K_0 + v * v * model.K_v2 + w0 * w0 * model.K_w2
    shapes = model.shapes(xs / sim.pipe.L).T
    out = np.zeros((xs.size, t.size))
    for load in sim.loads:
        if load.kind == "impulse":
            continue
        at = getattr(load, "position", None)
        r = truncation_residual(
            pipe, v, w0, xs, force_at=at, K=K, f=load.generalized_force(model), shapes=shapes
        )
        if r is None:
            return None
        out += r[:, None] * load.profile.value(t)[None, :]
    return out


@dataclass
class Result:
    """Outputs of :func:`simulate` (SI units).

    Its JSON form (the service's document) is :func:`pipeflow.computations.documents.simulation`;
    in a notebook, the functions of :mod:`pipeflow.io.notebook` take this result or that
    JSON form (xarray/pandas are the ``notebook`` extra).
    """

    simulation: Simulation
    t: FloatArray  # [s]
    tip_displacement: FloatArray  # u(L, t) [m]
    displacements: FloatArray  # (len(positions), N) [m]
    d: FloatArray  # (N, n) modal coordinates [m]
    ddot: FloatArray  # (N, n) [m/s]
    eigen_t: FloatArray  # [s] from 0 to the history's last time t[-1]
    frozen: Traces  # eigenvalues of S(t) [1/s]
    #: the paper's CMA exponents (:attr:`exponents`), or how to compute them on first use
    cma_exponents: Traces | Callable[[], Traces] = field(repr=False)
    dimensionless: dict[str, Any]
    diagnostics: dict[str, Any]
    warnings: list[str]
    status: SimulationStatus
    initial_tip_displacement: float  # [m]
    divergence_time: float | None  # [s] when the deflection passed divergence_bound (stopped)
    divergence_bound: float  # [m] the bound on |u| that applied (pipeflow.divergence)
    divergence_growth_rate: float | None  # [1/s] largest frozen sigma at divergence_time
    method_used: str = ""  # the solver that ran ("auto" resolves to "cma" or "magnus")
    method_reason: str = ""  # one line: why that solver
    first_unstable_time: float | None = None  # [s] first output time with a frozen sigma > 0
    mode_shapes: ModeShapes | None = None  # when ``simulation.mode_shape_times`` asks

    @property
    def exponents(self) -> Traces:
        """Eigenvalues of P(t)/t [1/s], the exponents the paper's CMA applies, traced on the
        branches of :attr:`frozen` (:func:`cma_exponents`).  Nothing in :func:`simulate`
        needs them (status, diagnostics and growth come from the frozen spectrum), so with
        time-varying coefficients their decompositions are deferred to the first use here
        (the JSON form, :func:`pipeflow.computations.documents.simulation`, uses them); the value
        is the same either way, and kept."""
        if callable(self.cma_exponents):
            self.cma_exponents = self.cma_exponents()
        return self.cma_exponents

    @property
    def fundamental(self) -> Traces:
        return Traces(self.frozen.xi[:, :1], self.frozen.confidence[:, :1])


def validate(sim: Simulation) -> None:
    """Raise :class:`InvalidInput` naming the field when ``sim`` cannot be run."""
    if sim.method not in SOLVERS:
        raise InvalidInput(
            f"unknown method {sim.method!r}; choose one of {', '.join(sorted(SOLVERS))}",
            parameter="method",
        )
    if not (math.isfinite(sim.t_end) and sim.t_end > 0):
        raise InvalidInput("t_end must be finite and > 0 s", parameter="t_end")
    if sim.samples < 2:
        raise InvalidInput("samples must be >= 2", parameter="samples")
    if sim.divergence_bound is not None and not (
        math.isfinite(sim.divergence_bound) and sim.divergence_bound > 0
    ):
        raise InvalidInput("divergence_bound must be finite and > 0 m", "divergence_bound")
    if not 1 <= sim.modes <= MAX_MODES:
        raise InvalidInput(f"modes must be between 1 and {MAX_MODES}", parameter="modes")
    if sim.initial_shape not in ("paper", "tip"):
        raise InvalidInput(
            f"unknown initial shape {sim.initial_shape!r}; use 'paper' or 'tip'",
            parameter="initial_shape",
        )
    if sim.eigen_modes < 1:
        raise InvalidInput("eigen_modes must be >= 1", parameter="eigen_modes")
    if sim.pressure is not None:
        if sim.pipe.pressure:
            raise InvalidInput(
                "give the pressure once: the pipe's constant pressure or a profile",
                parameter="pressure",
            )
        if not sim.pipe.flow_area:
            raise InvalidInput(
                "a pressure needs pipe.flow_area, the flow cross-section A [m^2]",
                parameter="flow_area",
            )
    profiles = [("flow", sim.flow), ("spin", sim.spin)]
    if sim.pressure is not None:
        profiles.append(("pressure", sim.pressure))
    for name, prof in profiles:
        if prof.domain_end() < sim.t_end:
            raise InvalidInput(
                f"table ends at {prof.domain_end()} s, before t_end = {sim.t_end} s",
                parameter=name,
            )
    validate_loads(tuple(sim.loads), sim.pipe.L, sim.t_end)
    if sim.mode_acceleration:
        check_mode_acceleration(sim)
    for i, x in enumerate(sim.positions):
        if not 0.0 <= x <= sim.pipe.L:
            raise InvalidInput(f"positions[{i}] = {x} m is outside [0, L]", parameter="positions")
    if len(sim.mode_shape_times) > MAX_SHAPE_TIMES:
        raise InvalidInput(f"at most {MAX_SHAPE_TIMES} mode-shape times", "mode_shape_times")
    for i, t in enumerate(sim.mode_shape_times):
        if not 0.0 <= t <= sim.t_end:
            raise InvalidInput(
                f"mode_shape_times[{i}] = {t} s is outside [0, t_end]", "mode_shape_times"
            )
    if not 2 <= sim.mode_shape_points <= MAX_SHAPE_POINTS:
        raise InvalidInput(
            f"mode-shape points must be between 2 and {MAX_SHAPE_POINTS}", "mode_shape_points"
        )
    # the traced branches and the least-stable one (an upper bound: it may be among them)
    values = (
        len(sim.mode_shape_times) * sim.mode_shape_points * (min(sim.eigen_modes, sim.modes) + 1)
    )
    if values > MAX_SHAPE_VALUES:
        raise InvalidInput(
            f"mode shapes: {len(sim.mode_shape_times)} times x {sim.mode_shape_points} points x "
            f"{min(sim.eigen_modes, sim.modes) + 1} branches (eigen_modes + 1) = {values} values, "
            f"more than {MAX_SHAPE_VALUES}; ask fewer points, times or eigen_modes",
            "mode_shape_points",
        )


def simulate(sim: Simulation, progress: Progress | None = None) -> Result:
    """Run one simulation and derive every reported quantity."""
    validate(sim)
    wall0 = time.perf_counter()
    model, loading = model_and_loading(sim)
    t = np.linspace(0.0, sim.t_end, sim.samples)
    d0, v0 = model.initial_state(sim.u0, sim.du0, sim.initial_shape)
    z0 = model.to_balanced(d0, v0)
    forcing = project_loads(model, tuple(sim.loads))  # None without loads
    # the host's checkpoints, if any (pipeflow.solvers.checkpoint.checkpointing)
    problem = Problem(model, loading, z0, t, sim.options, progress, forcing, current_checkpoints())
    solver, reason = SOLVERS[sim.method].choose(problem)
    out = solver.solve(problem)
    add_error_estimate(solver, problem, out)  # how far to trust it (pipeflow.diagnostics)

    Z = out.z
    status = SimulationStatus.OK
    warnings = list(out.warnings)
    finite = np.all(np.isfinite(Z), axis=1)
    overflowed = not finite.all()
    if overflowed:
        # keep the finite prefix: JSON has no Inf or NaN, and nothing after overflow is data
        last = int(np.argmin(finite))
        t, Z = t[:last], Z[:last]
    d, ddot = model.from_balanced(Z)
    tip = d @ model.tip
    xs = np.asarray(sim.positions, dtype=float) / sim.pipe.L
    displacements = model.displacement(d, xs).T if xs.size else np.zeros((0, t.size))
    if sim.mode_acceleration and sim.loads:
        extra = mode_acceleration(sim, model, np.append(xs, 1.0) * sim.pipe.L, t)
        if extra is None:
            warnings.append(
                "the static problem is singular at this operating point (divergence), so "
                "the mode-acceleration correction is left out"
            )
        else:
            tip, displacements = tip + extra[-1], displacements + extra[:-1]
    # the linear model's range (pipeflow.divergence): the history stops at the first
    # sample past the bound, before any overflow
    bound = sim.divergence_bound
    watch, where = displacements, np.asarray(sim.positions, dtype=float)
    if sim.pipe.basis_key is not None:
        # supports: the tip may be held (w(L) = 0), so watch 19 interior stations too
        inner = np.linspace(0.05, 0.95, 19)
        watch = np.vstack([displacements, model.displacement(d, inner).T])
        where = np.concatenate([where, inner * sim.pipe.L])
    if bound is None:
        start = max(abs(float(tip[0])), float(np.max(np.abs(watch[:, 0]), initial=0.0)))
        bound = default_bound(sim.pipe.L, start)
    stop = divergence(t, tip, watch, where, bound, model, loading)
    if stop is not None:
        k = stop.index + 1
        t, d, ddot, tip, displacements = t[:k], d[:k], ddot[:k], tip[:k], displacements[:, :k]
        status = SimulationStatus.DIVERGED
        warnings.append(divergence_message(stop))
    elif overflowed:
        status = SimulationStatus.OVERFLOW
        warnings.append(
            f"the response overflowed double precision after t = {t[-1]:.6g} s; "
            "samples after that are omitted"
        )

    requested_t = trace_times(sim.eigen_samples, problem.t)
    eigen_t = trace_times(sim.eigen_samples, t)  # where the history stops (diverged)
    n_eig = min(sim.eigen_modes, sim.modes)  # more branches than modes do not exist
    spec = frozen_spectrum(model, loading, eigen_t)
    frozen = select(*spec, n_eig, least_stable=True, damped=sim.pipe.damped)
    # the same branches of P(t)/t (P(t)/t -> S(0) at t = 0: the same first point)
    branches = frozen.xi[0]
    exponents: Traces | Callable[[], Traces]
    if loading.is_time_invariant:
        exponents = select(*spec, branches)  # P(t)/t = S: the same spectrum
    else:  # one decomposition per time, only if asked for (Result.exponents)
        exponents = functools.partial(cma_exponents, model, loading, eigen_t, branches.copy())
    # the whole frozen spectrum decides growth, not only the traced branches
    sigma_max = max_growth_rates(spec[0])  # per eigen_t [1/s]
    unstable = np.flatnonzero(sigma_max > 0)
    first_unstable = (
        first_unstable_time(model, loading, eigen_t, int(unstable[0]), problem.t)
        if unstable.size
        else None
    )

    shapes = None
    if sim.mode_shape_times:
        shapes = frozen_mode_shapes(
            model,
            loading,
            np.asarray(sim.mode_shape_times, dtype=float),
            branches,
            sim.mode_shape_points,
            track_times=requested_t,  # shapes may be asked past a divergence time
        )
        shapes = dataclasses.replace(shapes, mode=frozen.mode)

    initial_tip = float(d0 @ model.tip)
    # a growth rate above rounding of the spectrum at the end means a growing mode
    growing = bool(unstable.size and unstable[-1] == eigen_t.size - 1)
    if status == SimulationStatus.OK and growing:
        status = SimulationStatus.DIVERGING
    if np.any(sim.flow.value(eigen_t) < 0):
        warnings.append(REVERSE_FLOW_CAVEAT)
    warnings.extend(basis_caveats(sim.pipe))
    warnings.extend(load_notes(tuple(sim.loads)))
    if forcing is not None:
        warnings.extend(held_note(f"loads.{i}") for i in forcing.held())
    diagnostics = {"method": sim.method, "method_used": solver.name, **out.diagnostics}
    diagnostics.update(
        modes=sim.modes,
        state_size=model.size,
        quadrature_order=model.quadrature_order,
        samples=int(t.size),
        time_invariant=loading.is_time_invariant,
        max_growth_rate=float(np.max(sigma_max)),
        wall_seconds=time.perf_counter() - wall0,
    )
    return Result(
        simulation=sim,
        t=t,
        tip_displacement=tip,
        displacements=displacements,
        d=d,
        ddot=ddot,
        eigen_t=eigen_t,
        frozen=frozen,
        cma_exponents=exponents,
        dimensionless=dimensionless(sim.pipe, loading, requested_t),  # of the input
        diagnostics=diagnostics,
        warnings=warnings,
        status=status,
        initial_tip_displacement=initial_tip,
        divergence_time=stop.time if stop is not None else None,
        divergence_bound=float(bound),
        divergence_growth_rate=stop.growth_rate if stop is not None else None,
        method_used=solver.name,
        method_reason=reason,
        first_unstable_time=first_unstable,
        mode_shapes=shapes,
    )


def trace_times(eigen_samples: int, history: FloatArray) -> FloatArray:
    """The times [s] of a run's eigenvalue traces: ``eigen_samples`` evenly from 0 to the
    last time of ``history`` (the output times [s] the run keeps: to t_end, or to where a
    run stopped, status "diverged" or "overflow"), at most one per output time, at least 2."""
    return np.linspace(0.0, float(history[-1]), max(2, min(eigen_samples, history.size)))


def frozen_spectrum(
    model: PipeModel, loading: Loading, times: FloatArray
) -> tuple[NDArray[np.complex128], FloatArray, NDArray[np.intp]]:
    """Every branch of the frozen state matrix S(t) [1/s] at ``times`` [s], followed
    (:func:`pipeflow.spectra.spectrum`; a damped pipe's modes numbered by natural
    frequency): one decomposition when S is constant."""
    damped = model.pipe.damped
    if loading.is_time_invariant:
        S = model.state_matrix(loading.coefficients(times[:1]))
        xi, conf, mode = spectrum(S, damped)
        return np.repeat(xi, times.size, axis=0), np.repeat(conf, times.size, axis=0), mode
    return spectrum(model.state_matrix(loading.coefficients(times)), damped)


def first_unstable_time(
    model: PipeModel, loading: Loading, eigen_t: FloatArray, k: int, t: FloatArray
) -> float:
    """The first output time [s] (of ``t``) at which the frozen spectrum has a sigma above
    rounding, given that eigenvalue time ``eigen_t[k]`` is the first such one: the output
    times in (eigen_t[k-1], eigen_t[k]] are checked (eigenvalues only), the earliest
    unstable one returned (``eigen_t[k]`` itself if none of them is)."""
    if k == 0:
        return float(t[0])
    inside = t[(t > eigen_t[k - 1]) & (t < eigen_t[k])]
    if inside.size:
        xi = np.asarray(
            np.linalg.eigvals(model.state_matrix(loading.coefficients(inside))), complex
        )
        over = np.flatnonzero(max_growth_rates(xi) > 0)
        if over.size:
            return float(inside[over[0]])
    return float(eigen_t[k])


def frozen_traces(
    model: PipeModel, loading: Loading, times: FloatArray, modes: int, least_stable: bool = False
) -> Traces:
    """Tracked eigenvalues of the frozen state matrix S(t) [1/s] at ``times`` [s]: the
    ``modes`` lowest branches (and the least stable one, flagged)."""
    return select(*frozen_spectrum(model, loading, times), modes, least_stable, model.pipe.damped)


def cma_exponents(
    model: PipeModel, loading: Loading, times: FloatArray, modes: int | NDArray[np.complex128]
) -> Traces:
    """Tracked eigenvalues of P(t)/t [1/s], the exponents the paper's CMA applies.

    At t = 0 the limit P(t)/t -> S(0) is used.  For constant coefficients these equal the
    frozen eigenvalues; for varying ones they are the time-averaged spectrum.  ``modes``:
    how many of the lowest branches, or their eigenvalues at t = 0 (``Traces.xi[0]``).
    """
    t = np.asarray(times, dtype=float)
    if loading.is_time_invariant:  # P(t)/t = S at every time: one decomposition
        return select(*frozen_spectrum(model, loading, t), modes, damped=model.pipe.damped)
    mats = np.empty((t.size, model.size, model.size))
    pos = t > 0
    mats[~pos] = model.state_matrix(loading.coefficients(t[~pos]))
    if pos.any():
        mats[pos] = model.integrated_state_matrix(loading.integrals(t[pos])) / t[pos, None, None]
    return select(*spectrum(mats, model.pipe.damped), modes, damped=model.pipe.damped)


def dimensionless(pipe: Pipe, loading: Loading, times: FloatArray) -> dict[str, Any]:
    """Paidoussis' groups: beta, flow number u, spin number gamma, and the time scale."""
    v = loading.flow.value(times)
    w = loading.spin.value(times)
    u = pipe.flow_number(v)
    g = pipe.spin_number(w)
    return {
        "beta": pipe.beta,
        "u_initial": float(u[0]),
        "u_final": float(u[-1]),
        "u_max_abs": float(np.max(np.abs(u))),
        "gamma_initial": float(g[0]),
        "gamma_final": float(g[-1]),
        "gamma_max_abs": float(np.max(np.abs(g))),
        "time_scale": pipe.time_scale,
        "tau_end": float(times[-1] / pipe.time_scale),
        **pipe.dimensionless_groups(),
    }
