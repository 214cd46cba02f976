"""Summaries of many constant-coefficient simulations at once: one stacked computation.

A design study of LTI simulations (constant flow and spin, method ``cma`` or ``auto``, no
external loads) wants five numbers per case, not its histories.  :func:`lti_summaries`
computes exactly those numbers for a list of :class:`~pipeflow.simulation.Simulation`,
the same ones :func:`~pipeflow.simulation.simulate` reports:

- ``peak_tip_displacement`` [m]: max |u(L, t)| over the output times;
- ``final_sigma_1``, ``final_omega_1``: the fundamental's eigenvalue at t_end (mode 1 as
  the single run numbers it, :func:`pipeflow.spectra.order_lowest`; at constant
  coefficients the frozen spectrum is the same at every time);
- ``method_used`` (``cma``: what ``auto`` runs here) and ``result_status`` (``ok``,
  ``diverged``: the tip past the divergence bound, :mod:`pipeflow.divergence`, the peak
  then taken up to that sample as the single run stops there, or ``diverging``: a growth
  rate of the frozen spectrum above rounding, :func:`pipeflow.spectra.max_growth_rates`).

Cases sharing the number of modes and the time grid are one computation: their state
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
from pipeflow.model import Loading, build_model
from pipeflow.simulation import Simulation, SimulationStatus, validate
from pipeflow.solvers.cma import _uniform_step
from pipeflow.spectra import MARGINAL_RTOL, order_lowest

#: the methods whose constant-coefficient run is one eigen-decomposition (``auto`` runs cma)
BATCHED_METHODS = ("auto", "cma")
#: most cases in one stacked computation (bounds the temporaries: 256 cases x 40 modes)
MAX_STACK = 256
#: a state whose bound sum_j |c_j| max_i |V_ij| 2 exp(sigma_j t_end) passes e^LOG_OVERFLOW
#: (double precision ends at e^709.78) may overflow in the single run: left to it
LOG_OVERFLOW = 700.0
#: a status within this relative distance of its threshold is left to the single run
THRESHOLD_RTOL = 1e-8
_BLOCK = 64  # the block of modal_exponentials


@dataclass(frozen=True)
class LTISummary:
    """The study row of one constant-coefficient simulation (see the module docstring)."""

    peak_tip_displacement: float  # [m]
    final_sigma_1: float  # [1/s]
    final_omega_1: float  # [rad/s]
    method_used: str
    result_status: str


def eligible(sim: Simulation) -> bool:
    """Whether :func:`lti_summaries` computes ``sim`` itself: constant flow and spin, method
    ``cma`` or ``auto``, no external loads, no mode shapes and no output stations."""
    return (
        sim.method in BATCHED_METHODS
        and not sim.loads
        and not sim.mode_shape_times
        and not sim.positions  # a station may pass the divergence bound before the tip
        and sim.flow.is_constant
        and sim.spin.is_constant
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


def lti_summaries(sims: Sequence[Simulation]) -> list[LTISummary | None]:
    """The study row of every simulation in ``sims``, or None where the caller must run
    :func:`~pipeflow.simulation.simulate` (see the module docstring)."""
    out: list[LTISummary | None] = [None] * len(sims)
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


def _stack(cases: list[_Case], t: FloatArray) -> list[LTISummary | None]:
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
    out: list[LTISummary | None] = []
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
        out.append(
            LTISummary(float(peak[b]), float(w[b, j].real), float(w[b, j].imag), "cma", str(status))
        )
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
