"""One simulation: inputs, the solver run, and everything reported about it.

``simulate(Simulation(...))`` is the library's main entry point; the HTTP service and the
command line build a :class:`Simulation` from their JSON spec and call it.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from pipeflow.diagnostics import add_error_estimate
from pipeflow.eigen import Traces, track
from pipeflow.errors import InvalidInput
from pipeflow.model import REVERSE_FLOW_CAVEAT, Loading, Pipe, PipeModel, build_model
from pipeflow.profiles import Constant, Profile
from pipeflow.solvers import SOLVERS, Options, Problem
from pipeflow.solvers.base import ProgressCallback

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class Simulation:
    """Everything that defines a run (SI units).

    pipe : pipe and fluid properties.
    flow : flow velocity profile v(t) [m/s] (v > 0 from the clamped end to the tip).
    spin : spin profile w0(t) [rad/s].
    u0, du0 : initial amplitude [m] and velocity amplitude [m/s] of the initial shape.
    initial_shape : "paper" (eq. 3's phi_1, tip value 2.7244 u0) or "tip" (u0 is the tip).
    modes : number of Galerkin modes n (1..40).
    t_end : simulated duration [s]; samples : number of output times (incl. 0 and t_end).
    method : solver name (see ``pipeflow.solvers.SOLVERS``); options : its options.
    positions : extra stations x [m] (0..L) whose displacement is reported.
    eigen_modes : how many of the lowest eigenvalue branches to trace (at most ``modes``).
    eigen_samples : number of times at which frozen eigenvalues are computed.
    include_modal : also return the modal coordinates d [m] and d' [m/s].
    divergence_bound : tip amplitude [m] beyond which the run is flagged as diverging
        (default: the pipe length, where the linear model has long stopped meaning anything).
    quadrature_order : Gauss-Legendre points for the Galerkin integrals (None: automatic).
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
    method: str = "cma"
    options: Options = field(default_factory=Options)
    positions: tuple[float, ...] = ()
    eigen_modes: int = 3
    eigen_samples: int = 201
    include_modal: bool = False
    divergence_bound: float | None = None
    quadrature_order: int | None = None


@dataclass
class Result:
    """Outputs of :func:`simulate` (SI units; see :meth:`to_dict` for the JSON form)."""

    simulation: Simulation
    t: FloatArray  # [s]
    tip_displacement: FloatArray  # u(L, t) [m]
    displacements: FloatArray  # (len(positions), N) [m]
    d: FloatArray  # (N, n) modal coordinates [m]
    ddot: FloatArray  # (N, n) [m/s]
    eigen_t: FloatArray  # [s]
    frozen: Traces  # eigenvalues of S(t) [1/s]
    exponents: Traces  # eigenvalues of P(t)/t [1/s], the paper's CMA exponents
    dimensionless: dict[str, Any]
    diagnostics: dict[str, Any]
    warnings: list[str]
    status: str  # "ok", "diverging" or "overflow"
    initial_tip_displacement: float  # [m]
    divergence_time: float | None  # [s]

    @property
    def fundamental(self) -> Traces:
        return Traces(self.frozen.xi[:, :1], self.frozen.confidence[:, :1])

    def to_dict(self, include_modal: bool | None = None) -> dict[str, Any]:
        """JSON-ready dictionary: lists of floats, every number finite."""
        modal = self.simulation.include_modal if include_modal is None else include_modal

        def traces(tr: Traces) -> list[dict[str, Any]]:
            return [
                {
                    "mode": j + 1,
                    "sigma": _finite(tr.sigma[:, j]),
                    "omega": _finite(tr.omega[:, j]),
                    "confidence": _finite(tr.confidence[:, j]),
                }
                for j in range(tr.xi.shape[1])
            ]

        out: dict[str, Any] = {
            "status": self.status,
            "method": self.simulation.method,
            "t": _finite(self.t),
            "tip_displacement": _finite(self.tip_displacement),
            "initial_tip_displacement": self.initial_tip_displacement,
            "divergence_time": self.divergence_time,
            "displacements": [
                {"x": x, "u": _finite(self.displacements[i])}
                for i, x in enumerate(self.simulation.positions)
            ],
            "eigenvalues": {"t": _finite(self.eigen_t), "modes": traces(self.frozen)},
            "fundamental": {
                "sigma": _finite(self.frozen.sigma[:, 0]),
                "omega": _finite(self.frozen.omega[:, 0]),
            },
            "cma_exponents": {"t": _finite(self.eigen_t), "modes": traces(self.exponents)},
            "dimensionless": self.dimensionless,
            "diagnostics": json_safe(self.diagnostics),
            "warnings": list(self.warnings),
        }
        if modal:
            out["modal"] = {"d": _finite(self.d), "ddot": _finite(self.ddot)}
        return out


def _finite(a: Any) -> Any:
    arr = np.asarray(a, dtype=float)
    if not np.all(np.isfinite(arr)):
        raise ValueError("internal error: non-finite value reached the output")
    return arr.tolist()


def json_safe(data: Any) -> Any:
    """JSON-ready copy: non-finite floats become null (JSON has no Inf/NaN), numpy scalars
    Python numbers, nested dicts, lists and tuples are walked.  The one rule for every result."""
    if isinstance(data, dict):
        return {k: json_safe(v) for k, v in data.items()}
    if isinstance(data, list | tuple):
        return [json_safe(v) for v in data]
    if hasattr(data, "item") and not isinstance(data, str):
        data = data.item()
    if isinstance(data, float) and not math.isfinite(data):
        return None
    return data


def validate(sim: Simulation) -> None:
    """Raise :class:`InvalidInput` naming the field when ``sim`` cannot be run."""
    if sim.method not in SOLVERS:
        raise InvalidInput(
            f"unknown method {sim.method!r}; choose one of {', '.join(sorted(SOLVERS))}",
            field="method",
        )
    if not (math.isfinite(sim.t_end) and sim.t_end > 0):
        raise InvalidInput("t_end must be finite and > 0 s", field="time.t_end")
    if sim.samples < 2:
        raise InvalidInput("samples must be >= 2", field="time.samples")
    if not 1 <= sim.modes <= 40:
        raise InvalidInput("modes must be between 1 and 40", field="modes")
    if sim.initial_shape not in ("paper", "tip"):
        raise InvalidInput(
            f"unknown initial shape {sim.initial_shape!r}; use 'paper' or 'tip'",
            field="initial.shape",
        )
    if sim.eigen_modes < 1:
        raise InvalidInput("eigen_modes must be >= 1", field="output.eigen_modes")
    for name, prof in (("flow.velocity", sim.flow), ("rotation.omega0", sim.spin)):
        if prof.domain_end() < sim.t_end:
            raise InvalidInput(
                f"table ends at {prof.domain_end()} s, before t_end = {sim.t_end} s",
                field=name,
            )
    for i, x in enumerate(sim.positions):
        if not 0.0 <= x <= sim.pipe.L:
            raise InvalidInput(f"position {x} m is outside [0, L]", field=f"positions.{i}")


def simulate(sim: Simulation, progress: ProgressCallback | None = None) -> Result:
    """Run one simulation and derive every reported quantity."""
    validate(sim)
    wall0 = time.perf_counter()
    model = build_model(sim.pipe, sim.modes, sim.quadrature_order)
    loading = Loading(sim.flow, sim.spin)
    t = np.linspace(0.0, sim.t_end, sim.samples)
    d0, v0 = model.initial_state(sim.u0, sim.du0, sim.initial_shape)
    z0 = model.to_balanced(d0, v0)
    problem = Problem(model, loading, z0, t, sim.options, progress)
    out = SOLVERS[sim.method].solve(problem)
    add_error_estimate(sim.method, problem, out)  # how far to trust it (pipeflow.diagnostics)

    Z = out.z
    status = "ok"
    warnings = list(out.warnings)
    finite = np.all(np.isfinite(Z), axis=1)
    if not finite.all():
        # keep the finite prefix: JSON has no Inf or NaN, and nothing after overflow is data
        last = int(np.argmin(finite))
        t, Z = t[:last], Z[:last]
        status = "overflow"
        warnings.append(
            f"the response overflowed double precision after t = {t[-1]:.6g} s; "
            "samples after that are omitted"
        )
    d, ddot = model.from_balanced(Z)
    tip = d @ model.tip
    xs = np.asarray(sim.positions, dtype=float) / sim.pipe.L
    displacements = model.displacement(d, xs).T if xs.size else np.zeros((0, t.size))

    eigen_t = np.linspace(0.0, sim.t_end, max(2, min(sim.eigen_samples, sim.samples)))
    n_eig = min(sim.eigen_modes, sim.modes)  # more branches than modes do not exist
    frozen = frozen_traces(model, loading, eigen_t, n_eig)
    exponents = cma_exponents(model, loading, eigen_t, n_eig)

    initial_tip = float(d0 @ model.tip)
    bound = sim.divergence_bound if sim.divergence_bound is not None else sim.pipe.L
    over = np.flatnonzero(np.abs(tip) > bound)
    divergence_time = float(t[over[0]]) if over.size else None
    # a growth rate above rounding of the spectrum (1e-9 of |xi|) means a growing mode
    growing = bool(np.any(frozen.sigma[-1] > 1e-9 * np.abs(frozen.xi[-1])))
    if status == "ok" and (divergence_time is not None or growing):
        status = "diverging"
    if divergence_time is not None:
        warnings.append(
            f"tip amplitude passed the divergence bound {bound:.3g} m at t = "
            f"{divergence_time:.6g} s: the linear model no longer describes the pipe"
        )
    if np.any(sim.flow.value(eigen_t) < 0):
        warnings.append(REVERSE_FLOW_CAVEAT)
    diagnostics = {"method": sim.method, **out.diagnostics}
    diagnostics.update(
        modes=sim.modes,
        state_size=model.size,
        quadrature_order=model.quadrature_order,
        samples=int(t.size),
        time_invariant=loading.is_time_invariant,
        max_growth_rate=float(np.max(frozen.sigma)),
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
        exponents=exponents,
        dimensionless=dimensionless(sim.pipe, loading, eigen_t),
        diagnostics=diagnostics,
        warnings=warnings,
        status=status,
        initial_tip_displacement=initial_tip,
        divergence_time=divergence_time,
    )


def frozen_traces(model: PipeModel, loading: Loading, times: FloatArray, modes: int) -> Traces:
    """Tracked eigenvalues of the frozen state matrix S(t) [1/s] at ``times`` [s].

    For constant coefficients S is one matrix: decomposed once, the same at every time."""
    if loading.is_time_invariant:
        return _repeated(track(model.state_matrix(loading.coefficients(times[:1])), modes), times)
    return track(model.state_matrix(loading.coefficients(times)), modes)


def _repeated(one: Traces, times: FloatArray) -> Traces:
    """Traces of one point, repeated at every time (confidence 1: nothing to link)."""
    n = np.asarray(times).size
    return Traces(np.repeat(one.xi, n, axis=0), np.ones((n, one.xi.shape[1])))


def cma_exponents(model: PipeModel, loading: Loading, times: FloatArray, modes: int) -> Traces:
    """Tracked eigenvalues of P(t)/t [1/s], the exponents the paper's CMA applies.

    At t = 0 the limit P(t)/t -> S(0) is used.  For constant coefficients these equal the
    frozen eigenvalues; for varying ones they are the time-averaged spectrum.
    """
    t = np.asarray(times, dtype=float)
    if loading.is_time_invariant:  # P(t)/t = S at every time
        return frozen_traces(model, loading, t, modes)
    mats = np.empty((t.size, model.size, model.size))
    pos = t > 0
    mats[~pos] = model.state_matrix(loading.coefficients(t[~pos]))
    if pos.any():
        mats[pos] = model.integrated_state_matrix(loading.integrals(t[pos])) / t[pos, None, None]
    return track(mats, modes)


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
    }
