"""Where a run leaves the linear model's range, and stopping it there.

The equation of motion (:mod:`pipeflow.model`) is linear: it holds for small deflections
only (slopes small against 1, no axial shortening, no large-rotation geometry).  A run
past the critical velocity grows as exp(sigma t) without bound (at v = 40 m/s on the
paper's pipe, sigma = 1694 1/s: 1e304 m by t = 0.42 s), so samples beyond a few percent of
the length are not a description of the pipe, only of the linear equation.

:func:`divergence` finds the first output time at which the deflection at the tip or at
any requested station exceeds a stated bound (default :func:`default_bound`: 0.1 L, or
twice the initial deflection when the run starts beyond 0.05 L, as the paper's own
example does at 0.109 L); :func:`pipeflow.simulation.simulate` keeps the history up to
and including that sample and reports the status ``diverged`` with that time and the
growth rate there.  The solvers march (or exponentiate) to t_end regardless: this is the
post-processing of their output, the same for every method.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pipeflow._types import FloatArray
from pipeflow.loading import Loading
from pipeflow.model import PipeModel
from pipeflow.spectra import max_growth_rates

#: default bound on |u(x, t)| as a fraction of the length L [-]
DEFAULT_RANGE = 0.1


def default_bound(L: float, initial_deflection: float) -> float:
    """The default bound on |u| [m]: ``DEFAULT_RANGE`` x L [m], or twice the initial
    deflection [m] when that is larger (a run that starts near or beyond 0.1 L, like the
    paper's u0 = 1 mm on L = 25 mm, is stopped once its deflection has doubled, not at
    t = 0 nor by the beating of its stable modes)."""
    return max(DEFAULT_RANGE * L, 2.0 * initial_deflection)


@dataclass(frozen=True)
class Divergence:
    """The first output sample past the bound.

    index : its index in the output times; time : t there [s]; bound : the bound [m];
    where : "the tip" or the station ("x = 0.0125 m") that passed first; deflection : |u| there [m];
    growth_rate : the largest sigma of the frozen spectrum S(t) at that time [1/s].
    """

    index: int
    time: float
    bound: float
    where: str
    deflection: float
    growth_rate: float


def divergence(
    t: FloatArray,
    tip: FloatArray,
    displacements: FloatArray,
    positions: FloatArray,
    bound: float,
    model: PipeModel,
    loading: Loading,
) -> Divergence | None:
    """The first sample of ``t`` [s] at which |tip| [m] or |u| at a station (rows of
    ``displacements`` [m], at ``positions`` [m]) exceeds ``bound`` [m]; None if none does.
    Where several pass at that sample, the largest names it."""
    series = np.vstack([tip[None, :], displacements]) if displacements.size else tip[None, :]
    over = np.abs(series) > bound
    hit = np.flatnonzero(over.any(axis=0))
    if not hit.size:
        return None
    k = int(hit[0])
    row = int(np.argmax(np.abs(series[:, k])))
    where = "the tip" if row == 0 else f"x = {float(positions[row - 1]):.6g} m"
    return Divergence(
        index=k,
        time=float(t[k]),
        bound=float(bound),
        where=where,
        deflection=float(abs(series[row, k])),
        growth_rate=growth_rate(model, loading, float(t[k])),
    )


def growth_rate(model: PipeModel, loading: Loading, time: float) -> float:
    """The largest sigma [1/s] of the frozen spectrum S(t) at ``time`` [s] (rounding-level
    values reported as 0, :func:`pipeflow.spectra.max_growth_rates`)."""
    S = model.state_matrix(loading.coefficients(np.array([time])))
    return float(max_growth_rates(np.asarray(np.linalg.eigvals(S), dtype=complex))[0])


def message(stop: Divergence) -> str:
    """The result's warning for ``stop``."""
    return (
        f"the deflection at {stop.where} reached {stop.deflection:.3g} m, past the linear "
        f"model's range |u| <= {stop.bound:.3g} m, at t = {stop.time:.6g} s (growth rate "
        f"{stop.growth_rate:.4g} 1/s there): the run is stopped there (status 'diverged'); "
        "the samples after it describe the linear equation, not the pipe"
    )
