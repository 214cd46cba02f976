"""Summaries of many simulations at once: stacked computations, never the full documents.

A design study wants five numbers per case, not its histories.  :func:`summaries` computes
exactly those numbers for a list of :class:`~pipeflow.simulation.Simulation`, the same ones
:func:`~pipeflow.simulation.simulate` reports, by two stacked paths:
:func:`lti_summaries` for constant flow and spin (method ``cma`` or ``auto``, no external
loads; below) and :func:`time_variant_summaries` for flow or spin varying in time (method
``magnus`` or ``auto``, no external loads; see that function).  The numbers:

- ``peak_tip_displacement`` [m]: max |u(L, t)| over the output times;
- ``final_sigma_1``, ``final_omega_1``: the fundamental's eigenvalue at the end of its
  trace, t_end or the divergence time where the run stopped (mode 1 as the single run
  numbers it, :func:`pipeflow.spectra.order_lowest`; at constant coefficients the frozen
  spectrum is the same at every time, with varying ones the branch of mode 1 at t = 0
  followed to there as the single run follows it);
- ``method_used`` (``cma`` or ``magnus``: what ``auto`` runs) and ``result_status`` (``ok``,
  ``diverged``: the tip past the divergence bound, :mod:`pipeflow.divergence`, the peak
  then taken up to that sample as the single run stops there, or ``diverging``: a growth
  rate of the frozen spectrum above rounding, :func:`pipeflow.spectra.max_growth_rates`).

Constant coefficients.  Cases sharing the number of modes and the time grid are one
computation: their state
matrices S stacked, one batched ``np.linalg.eig``, and the tip history by broadcasting
z(t) = V exp(Lambda t) V^-1 z0 in the balanced state (z0 from the initial shape as
:func:`~pipeflow.simulation.simulate` builds it), the conjugate pairs taken once with
twice their real part, exp(Lambda t) on a uniform grid by products of two small tables
(:func:`pipeflow.solvers.cma.modal_exponentials`).  Nothing else of a result is formed.

Where the batched numbers could differ from the single run's in more than rounding the
case is answered ``None`` (the caller runs :func:`~pipeflow.simulation.simulate`): cases
that are not eligible (:func:`eligible`), that the library refuses (validation, the model's
assembly), whose eigenvector matrix is ill-conditioned past ``options.condition_limit``
(``cma`` then marches with Pade exponentials), that could overflow double precision (the
single run then reports ``overflow``), or whose status sits within rounding of a threshold
(the tip at the divergence bound, the largest sigma at the rounding level).
"""

from __future__ import annotations

from collections import defaultdict
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from pipeflow._types import FloatArray
from pipeflow.divergence import default_bound
from pipeflow.loading import Loading
from pipeflow.model import PipeModel, build_model
from pipeflow.simulation import Simulation, SimulationStatus, trace_times, validate
from pipeflow.solvers import Problem, SolverOutput
from pipeflow.solvers.convolution import uniform_step as _uniform_step
from pipeflow.solvers.magnus.stack import MAX_RUNS, solve_many
from pipeflow.spectra import MARGINAL_RTOL, assign, decompose, max_growth_rates, order_lowest

#: the methods whose constant-coefficient run is one eigen-decomposition (``auto`` runs cma)
BATCHED_METHODS = ("auto", "cma")
#: the methods whose time-variant run is the tolerance-controlled magnus (``auto`` runs it)
STACKED_METHODS = ("auto", "magnus")
#: most cases in one stacked computation (bounds the temporaries: 256 cases x 40 modes)
MAX_STACK = 256
#: a state whose bound sum_j |c_j| max_i |V_ij| 2 exp(sigma_j t_end) passes e^LOG_OVERFLOW
#: (double precision ends at e^709.78) may overflow in the single run: left to it
LOG_OVERFLOW = 700.0
#: a status within this relative distance of its threshold is left to the single run
THRESHOLD_RTOL = 1e-8
_BLOCK = 64  # the block of modal_exponentials
#: matrix entries of the frozen spectra decomposed at once (time-variant cases) [-]
SPECTRUM_ENTRIES = 400_000
#: bytes of state histories of the time-variant cases stacked at once (a single run of
#: 40 modes at 20,001 samples holds ~40 MB of them) [B]
STACK_BYTES = 128 * 2**20


@dataclass(frozen=True)
class CaseSummary:
    """The study row of one simulation (see the module docstring)."""

    peak_tip_displacement: float  # [m]
    final_sigma_1: float  # [1/s]
    final_omega_1: float  # [rad/s]
    method_used: str
    result_status: str


def eligible(sim: Simulation) -> bool:
    """Whether :func:`lti_summaries` computes ``sim`` itself: constant flow and spin, method
    ``cma`` or ``auto``, no external loads, no mode shapes and no output stations, the
    cantilever's supports."""
    return (
        sim.method in BATCHED_METHODS
        and not sim.loads
        and not sim.mode_shape_times
        and not sim.positions  # a station may pass the divergence bound before the tip
        and sim.flow.is_constant
        and sim.spin.is_constant
        and sim.pressure is None  # a pressure profile: the single run
        # a held tip (supports, issue 31): simulate watches interior stations, these read
        # the tip only, which is rounding there
        and sim.pipe.basis_key is None
    )


@dataclass
class _Case:
    S: FloatArray  # (m, m) [1/s]
    z0: FloatArray  # (m,) balanced initial state
    tip: FloatArray  # (n,) tip values of the modes
    bound: float  # [m]
    limit: float  # eigenvector condition limit
    damped: bool


def _prepare(sim: Simulation) -> _Case | None:
    """The arrays of one case, exactly as :func:`~pipeflow.simulation.simulate` forms them;
    None when the library refuses the case (the single run then reports why)."""
    try:
        validate(sim)
        model = build_model(sim.pipe, sim.modes, sim.quadrature_order)
    except Exception:
        return None
    loading = Loading(sim.flow, sim.spin)
    S = model.state_matrix(loading.coefficients(np.zeros(1)))[0]
    d0, v0 = model.initial_state(sim.u0, sim.du0, sim.initial_shape)
    bound = sim.divergence_bound
    if bound is None:  # as simulate: no stations here (eligible), the tip's start
        bound = default_bound(sim.pipe.L, abs(float(d0 @ model.tip)))
    return _Case(
        S, model.to_balanced(d0, v0), model.tip, float(bound), sim.options.condition_limit,
        sim.pipe.damped,
    )  # fmt: skip


def lti_summaries(sims: Sequence[Simulation]) -> list[CaseSummary | None]:
    """The study row of every simulation in ``sims``, or None where the caller must run
    :func:`~pipeflow.simulation.simulate` (see the module docstring)."""
    out: list[CaseSummary | None] = [None] * len(sims)
    groups: dict[tuple[int, int, float], list[tuple[int, _Case]]] = defaultdict(list)
    for i, sim in enumerate(sims):
        if not eligible(sim):
            continue
        case = _prepare(sim)
        if case is not None:
            groups[(sim.modes, sim.samples, sim.t_end)].append((i, case))
    for (_, samples, t_end), members in groups.items():
        t = np.linspace(0.0, t_end, samples)
        for s0 in range(0, len(members), MAX_STACK):
            part = members[s0 : s0 + MAX_STACK]
            rows = _stack([c for _, c in part], t)
            for (i, _), row in zip(part, rows, strict=True):
                out[i] = row
    return out


def _fundamental(w: NDArray[np.complex128]) -> NDArray[np.intp]:
    """Per row of ``w`` (B, m): the index of mode 1 of an undamped spectrum, as
    :func:`pipeflow.spectra.order_lowest` numbers it (vectorised)."""
    scale = np.maximum(np.abs(w).max(axis=1), 1e-300)[:, None]
    tol = 1e-9 * scale
    real = np.abs(w.imag) <= tol
    lower = w.imag < -tol
    # a decaying real root mirrored by a growing one (+-s): the pair's lower member
    neg = real & (w.real < 0)
    pos = real & (w.real > 0)
    close = np.abs(w.real[:, :, None] + w.real[:, None, :]) <= 1e-6 * scale[:, :, None]
    lower |= neg & np.any(close & pos[:, None, :], axis=2)
    upper = ~lower
    # lowest |omega| among the upper members, ties by sigma, then by position (lexsort)
    a = np.where(upper, np.abs(w.imag), np.inf)
    first = upper & (a == a.min(axis=1, keepdims=True))
    r = np.where(first, w.real, np.inf)
    return np.asarray(np.argmin(r, axis=1))


def _stack(cases: list[_Case], t: FloatArray) -> list[CaseSummary | None]:
    """One stacked computation for cases of one size and time grid."""
    S = np.stack([c.S for c in cases])
    m = S.shape[-1]
    n = m // 2
    w, V = np.linalg.eig(S)
    with np.errstate(all="ignore"):
        try:
            Vinv = np.linalg.inv(V)
        except np.linalg.LinAlgError:  # an exactly singular V somewhere: one at a time
            Vinv = np.stack([_inverse(v) for v in V])
        cond = np.abs(V).sum(axis=1).max(axis=1) * np.abs(Vinv).sum(axis=1).max(axis=1)
        z0 = np.stack([c.z0 for c in cases]).astype(complex)
        coef = np.einsum("bij,bj->bi", Vinv, z0)
        tipv = np.stack([c.tip for c in cases])
        # u(L, t) = sum_j (tip . V[n:, j]) c_j exp(w_j t): one amplitude per eigenvalue
        amp = np.einsum("bi,bij->bj", tipv.astype(complex), V[:, n:, :]) * coef
    # one member of each conjugate pair (omega > 0, twice its real part) and the real ones
    keep = w.imag >= 0
    weight = np.where(w.imag > 0, 2.0, 1.0) * keep
    order = np.argsort(~keep, axis=1, kind="stable")
    k = int(keep.sum(axis=1).max())
    cols = order[:, :k]
    wk = np.take_along_axis(w, cols, axis=1)
    ak = np.take_along_axis(amp * weight, cols, axis=1)
    sigma_max = w.real.max(axis=1)
    with np.errstate(all="ignore"):
        size = np.log(2.0 * np.abs(coef) * np.abs(V).max(axis=1) + 1e-300) + w.real * t[-1]
        top = size.max(axis=1)
        reach = top + np.log(np.exp(size - top[:, None]).sum(axis=1))
    growth_bad = ~(sigma_max * t[-1] <= LOG_OVERFLOW) | ~(reach <= LOG_OVERFLOW)
    wk = np.where(growth_bad[:, None], 0.0, wk)  # those rows are left to the single run
    with np.errstate(all="ignore"):
        tip = _tip_history(wk, ak, t)
    bound = np.array([c.bound for c in cases])
    # simulate stops the history at the first sample past the bound (pipeflow.divergence):
    # the peak is then that sample's |u|, every earlier one being within the bound
    over = np.abs(tip) > bound[:, None]
    diverged = np.asarray(over.any(axis=1))
    first = np.argmax(over, axis=1)
    peak = np.where(diverged, np.abs(tip[np.arange(len(cases)), first]), np.abs(tip).max(axis=1))

    # the status as simulate decides it: the tip past the bound, or growth above rounding
    level = MARGINAL_RTOL * np.abs(w).max(axis=1)
    growing = np.asarray((np.abs(sigma_max) > level) & (sigma_max > 0))
    near = (np.abs(np.abs(sigma_max) - level) <= THRESHOLD_RTOL * level) | np.any(
        np.abs(np.abs(tip) - bound[:, None]) <= THRESHOLD_RTOL * bound[:, None], axis=1
    )
    limit = np.array([c.limit for c in cases])
    fine = (
        np.isfinite(cond)
        & (cond <= limit)
        & ~growth_bad
        & ~near
        & np.isfinite(peak)
        & np.all(np.isfinite(w), axis=1)
    )
    damped = np.array([c.damped for c in cases])
    mode1 = _fundamental(w)
    out: list[CaseSummary | None] = []
    for b in range(len(cases)):
        if not fine[b]:
            out.append(None)
            continue
        j = int(order_lowest(w[b], 1, True)[0]) if damped[b] else int(mode1[b])
        status = (
            SimulationStatus.DIVERGED
            if diverged[b]
            else SimulationStatus.DIVERGING
            if growing[b]
            else SimulationStatus.OK
        )
        xi = complex(w[b, j])
        out.append(CaseSummary(float(peak[b]), xi.real, xi.imag, "cma", str(status)))
    return out


def _inverse(v: NDArray[np.complex128]) -> NDArray[np.complex128]:
    try:
        return np.asarray(np.linalg.inv(v))
    except np.linalg.LinAlgError:
        return np.full_like(v, np.nan)


def _tip_history(w: NDArray[np.complex128], a: NDArray[np.complex128], t: FloatArray) -> FloatArray:
    """Re sum_k a[b, k] exp(w[b, k] t) for every row b [m], shape (B, T): on a uniform
    grid (t_k = k dt) as exp(w t_block) a times exp(w j dt), one batched product."""
    T = t.size
    dt = _uniform_step(t)
    if dt is None or T <= 2 * _BLOCK:
        E = np.exp(w[:, None, :] * t[None, :, None])  # (B, T, K)
        return np.asarray(np.einsum("btk,bk->bt", E, a).real)
    starts = np.exp(w[:, None, :] * (dt * np.arange(0, T, _BLOCK))[None, :, None])  # (B, nb, K)
    offsets = np.exp(w[:, :, None] * (dt * np.arange(_BLOCK))[None, None, :])  # (B, K, 64)
    tip = ((starts * a[:, None, :]) @ offsets).real  # (B, nb, 64)
    return np.asarray(tip.reshape(w.shape[0], -1)[:, :T])


def time_variant(sim: Simulation) -> bool:
    """Whether :func:`time_variant_summaries` computes ``sim`` itself: flow or spin varying
    in time, method ``magnus`` or ``auto``, no external loads, no mode shapes and no output
    stations asked for."""
    return (
        sim.method in STACKED_METHODS
        and not sim.loads
        and not sim.mode_shape_times
        and not sim.positions  # a station may pass the divergence bound before the tip
        and not (sim.flow.is_constant and sim.spin.is_constant)
        and sim.pressure is None  # a pressure profile: the single run
        # a held tip (supports, issue 31): simulate watches interior stations, these read
        # the tip only, which is rounding there
        and sim.pipe.basis_key is None
    )


def summaries(sims: Sequence[Simulation]) -> list[CaseSummary | None]:
    """The study row of every simulation in ``sims`` (:func:`lti_summaries` for the
    constant-coefficient ones, :func:`time_variant_summaries` for the others), or None
    where the caller must run :func:`~pipeflow.simulation.simulate`."""
    out = lti_summaries(sims)
    varying = [i for i, sim in enumerate(sims) if time_variant(sim)]
    for i, row in zip(varying, time_variant_summaries([sims[i] for i in varying]), strict=True):
        out[i] = row
    return out


@dataclass
class _Varying:
    sim: Simulation
    model: PipeModel
    problem: Problem
    kept: int | None = None  # output times the single run keeps (None: all)


def time_variant_summaries(sims: Sequence[Simulation]) -> list[CaseSummary | None]:
    """The study rows of time-variant simulations (:func:`time_variant`), or None where the
    caller must run :func:`~pipeflow.simulation.simulate`.

    In chunks of :data:`~pipeflow.solvers.magnus.stack.MAX_RUNS` cases (fewer where their
    state histories would pass :data:`STACK_BYTES`): the states by
    :func:`~pipeflow.solvers.magnus.stack.solve_many` (the magnus runs of the chunk
    stacked, each with the single run's step control: the same steps, estimate and
    refinements, so the same states to rounding), the tip and its peak from them, and the
    frozen spectra of the chunk at the single run's eigenvalue times in one batched
    decomposition, each case's branches followed as :func:`pipeflow.spectra.spectrum`
    follows them (the fundamental: mode 1 at t = 0, followed to t_end).  None for the
    cases the library refuses (validation, the model, the solver's budget or options: the
    single run reports why), that overflow, or whose status sits within
    :data:`THRESHOLD_RTOL` of a threshold.
    """
    out: list[CaseSummary | None] = [None] * len(sims)
    cases: list[tuple[int, _Varying]] = []
    for i, sim in enumerate(sims):
        if not time_variant(sim):
            continue
        try:
            validate(sim)
            model = build_model(sim.pipe, sim.modes, sim.quadrature_order)
        except Exception:
            continue
        d0, v0 = model.initial_state(sim.u0, sim.du0, sim.initial_shape)
        t = np.linspace(0.0, sim.t_end, sim.samples)
        problem = Problem(
            model, Loading(sim.flow, sim.spin), model.to_balanced(d0, v0), t, sim.options
        )
        cases.append((i, _Varying(sim, model, problem)))
    for part in _chunks(cases):
        solved = solve_many([c.problem for _, c in part])
        tips: list[tuple[FloatArray, float] | None] = [None] * len(part)
        for p, ((_, case), result) in enumerate(zip(part, solved, strict=True)):
            # the overflowed ones are left to the single run (it reports the finite prefix)
            if isinstance(result, SolverOutput) and np.all(np.isfinite(result.z)):
                tips[p] = tip, bound = _tip(case, result)
                over = tip > bound  # the single run's traces stop with its history
                case.kept = int(np.argmax(over)) + 1 if over.any() else None
        finals = _final_fundamentals([c for _, c in part])
        for (i, case), result, final, history in zip(part, solved, finals, tips, strict=True):
            if isinstance(result, SolverOutput) and history is not None:
                out[i] = _varying_row(case, result, final, history)
    return out


def _chunks(cases: list[tuple[int, _Varying]]) -> list[list[tuple[int, _Varying]]]:
    """Consecutive chunks of at most MAX_RUNS cases whose state histories (the states at
    every output time: ~3 of them held per case during the step control) stay within
    :data:`STACK_BYTES`."""
    out: list[list[tuple[int, _Varying]]] = []
    size = 0
    for item in cases:
        problem = item[1].problem
        need = 3 * 8 * problem.t.size * (problem.model.size + 1)
        if not out or len(out[-1]) >= MAX_RUNS or size + need > STACK_BYTES:
            out.append([])
            size = 0
        out[-1].append(item)
        size += need
    return out


def _eigen_times(case: _Varying) -> FloatArray:
    """The single run's eigenvalue times [s] (to where its history stops)."""
    return trace_times(case.sim.eigen_samples, case.problem.t[: case.kept])


def _final_fundamentals(cases: Sequence[_Varying]) -> list[tuple[complex, NDArray[np.complex128]]]:
    """Per case: the fundamental's eigenvalue at the end of its trace [1/s] (mode 1 at
    t = 0 followed as :func:`pipeflow.spectra.spectrum` follows it, to t_end or where the
    run stopped) and the whole spectrum there."""
    out: list[tuple[complex, NDArray[np.complex128]] | None] = [None] * len(cases)
    groups: dict[tuple[int, int], list[int]] = defaultdict(list)
    for c, case in enumerate(cases):
        groups[(case.model.size, _eigen_times(case).size)].append(c)
    for (m, T), group in groups.items():
        # the decompositions of a few cases at a time (complex V and W: 32 bytes an entry)
        per = max(1, SPECTRUM_ENTRIES // (T * m * m))
        for s0 in range(0, len(group), per):
            members = group[s0 : s0 + per]
            _follow(cases, members, m, T, out)
    return [o for o in out if o is not None]


def _follow(
    cases: Sequence[_Varying],
    members: list[int],
    m: int,
    T: int,
    out: list[tuple[complex, NDArray[np.complex128]] | None],
) -> None:
    """:func:`_final_fundamentals` of the cases ``members`` (state size m, T eigenvalue
    times): one batched decomposition, each case's branches followed."""
    S = np.stack(
        [
            cases[c].model.state_matrix(
                cases[c].problem.loading.coefficients(_eigen_times(cases[c]))
            )
            for c in members
        ]
    )
    w, V, W = decompose(S.reshape(-1, m, m))
    w, V, W = (a.reshape(len(members), T, *a.shape[1:]) for a in (w, V, W))
    for g, c in enumerate(members):
        perm, _ = assign(w[g], V[g], W[g])
        j = int(order_lowest(w[g, 0], 1, cases[c].model.pipe.damped)[0])
        out[c] = (complex(w[g, -1, perm[-1, j]]), w[g, -1])


def _varying_row(
    case: _Varying,
    result: SolverOutput,
    final: tuple[complex, NDArray[np.complex128]],
    history: tuple[FloatArray, float],
) -> CaseSummary | None:
    """The row of one solved time-variant case (``history``: its :func:`_tip`), as
    :func:`~pipeflow.simulation.simulate` decides it; None where it sits at a threshold."""
    tip, bound = history
    if np.any(np.abs(tip - bound) <= THRESHOLD_RTOL * bound):
        return None
    over = tip > bound
    xi, last = final
    if over.any():
        peak = float(np.max(tip[: int(np.argmax(over)) + 1]))
        status = SimulationStatus.DIVERGED
    else:
        peak = float(np.max(tip))
        sigma = float(np.max(last.real))
        level = float(MARGINAL_RTOL * np.max(np.abs(last)))
        if abs(abs(sigma) - level) <= THRESHOLD_RTOL * level:
            return None
        growing = bool(max_growth_rates(last) > 0)
        status = SimulationStatus.DIVERGING if growing else SimulationStatus.OK
    return CaseSummary(peak, float(xi.real), float(xi.imag), str(result.method), str(status))


def _tip(case: _Varying, result: SolverOutput) -> tuple[FloatArray, float]:
    """|u(L, t)| [m] of a solved case and the divergence bound [m] that applies to it:
    the linear model's range as simulate applies it (pipeflow.divergence), the history
    stopping at the first sample past it."""
    model, sim = case.model, case.sim
    tip = np.abs(model.from_balanced(result.z)[0] @ model.tip)
    bound = sim.divergence_bound
    if bound is None:
        bound = default_bound(sim.pipe.L, float(tip[0]))
    return tip, float(bound)
