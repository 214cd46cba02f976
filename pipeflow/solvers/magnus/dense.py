"""Dense output of a Magnus solve: on a uniform grid of many samples the step control runs
on a coarse subset of the output times and the samples between are filled afterwards (the
method: :mod:`pipeflow.solvers.magnus`).  :class:`DenseOutput` is that output as an object,
as scipy's ``DenseOutput`` is its solvers' (the control asks it for the coarse times, has it
refine them, then fill the samples)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from pipeflow._types import FloatArray
from pipeflow.parallel import charge
from pipeflow.solvers.magnus.generator import LOCAL_SAMPLES, MagnusGenerator
from pipeflow.solvers.magnus.metering import step_seconds

#: ~25 ms beyond the fill's 2,136 exponentials, ~1.4 us each against a step's ~15 us
FILL_SAMPLE_SHARE = 0.125
#: times refined to 11,000) [-]
DENSE_STEPS = 2000
#: estimate leaves less) before the fill is redone by the next, costlier form [-]
FILL_SHARE = 0.1
#: pulsating flow, 2.3x when they were only spread over the run) [-]
FILL_MARGIN = 1.5
#: matrix entries of the step exponentials one batch of a checking march holds [-]
_MARCH_ENTRIES = 1_000_000


def dense_selection(t: FloatArray, h0: float) -> NDArray[np.int64] | None:
    """Indices of the output times the step control runs on when ``t`` is a dense grid:
    uniform, with intervals at most half of min(``h0``, t_end / :data:`DENSE_STEPS`) [s];
    every m-th time (m the intervals of that length) and the last.  None otherwise."""
    K = t.size - 1
    d = float(t[1] - t[0])
    m = int(min(h0, float(t[-1] - t[0]) / DENSE_STEPS) / d * (1 + 1e-9))
    if m < 2 or not np.allclose(np.diff(t), d, rtol=1e-9, atol=0.0):
        return None
    sel = np.arange(0, K + 1, m)
    return sel if sel[-1] == K else np.append(sel, K)


def dense_refine(
    sel: NDArray[np.int64], counts: NDArray[np.int64]
) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """A refinement on a dense grid: coarse interval k (between output times ``sel[k]``
    and ``sel[k + 1]``) was to take ``counts[k]`` steps; it is split at output times
    into min(counts[k], its samples) nearly equal coarse intervals (one step each), or,
    where it has fewer samples than that, into all of them with equal sub-steps.  Returns
    the new coarse times (a superset of ``sel``) and the sub-steps of their intervals."""
    m = np.diff(sel)
    p = np.minimum(counts, m)
    q = np.where(counts > m, -(-counts // m), 1)
    owner = np.repeat(np.arange(m.size), p)
    i = np.arange(owner.size) - np.repeat(np.cumsum(p) - p, p)
    # round(i m / p) past the interval's start
    new = sel[owner] + (2 * i * m[owner] + p[owner]) // (2 * p[owner])
    return np.append(new, sel[-1]), np.repeat(q, p).astype(np.int64)


@dataclass
class DenseFill:
    """The dense output of :func:`dense_fill`: augmented states ``Z`` at every output
    time, the fill's own estimated relative error [-], the exponentials it took, how the
    samples were filled, and on how many coarse intervals its error was measured."""

    Z: FloatArray
    estimate: float
    exponentials: int
    method: str
    checked: int


def _march(
    gen: MagnusGenerator,
    starts: FloatArray,
    h: float,
    steps: int,
    z0: FloatArray,
    order: int = 4,
) -> FloatArray:
    """Magnus steps of ``order`` and length ``h`` [s] from each of ``starts`` [s] (exact
    exponentials, batched over the starts), from the augmented states ``z0``: the states
    after each step, shape (starts, steps, size)."""
    S, n = z0.shape
    out = np.empty((S, steps, n))
    chunk = max(1, _MARCH_ENTRIES // (S * gen.exponent_size**2))
    z = z0
    for c in range(0, steps, chunk):
        j = np.arange(c, min(steps, c + chunk))
        st = (starts[:, None] + j[None, :] * h).ravel()
        P = gen.propagators(gen.omega(st, np.full(st.size, h), order)).reshape(S, j.size, n, n)
        for i in range(j.size):
            z = np.matmul(P[:, i], z[:, :, None])[:, :, 0]
            out[:, c + i] = z
    return out


def _poly_march(C: list[FloatArray], z0: FloatArray, m: int, sigma: FloatArray) -> FloatArray:
    """A march z_{j+1} = sum_q sigma_j^q C_q z_j over j = 0 .. m - 1 for k coarse
    intervals at once: ``C`` the monomial coefficients (k, n, n) of the sample-step
    propagator in sigma, ``sigma`` (k, m) its variable at each sample step, ``z0`` (k, n)
    the augmented states at the intervals' left ends.  One batched matrix-vector product of
    size (len(C) n) x n per sample; returns the states after each step, (k, m, n)."""
    k, n = z0.shape
    G = np.concatenate(C, axis=1)  # (k, len(C) n, n)
    out = np.empty((m, k, n))  # sample-major: each step writes one contiguous block
    w = np.empty((k, len(C) * n, 1))
    z = z0
    for j in range(m):
        np.matmul(G, z[:, :, None], out=w)
        s = sigma[:, j, None]
        z = out[j]
        np.multiply(w[:, n : 2 * n, 0], s, out=z)
        z += w[:, :n, 0]
        for q in range(2, len(C)):
            z += s**q * w[:, q * n : (q + 1) * n, 0]
    return out.transpose(1, 0, 2)


#: the fills :func:`dense_fill` tries in turn: the degree of the sample-step propagator
#: as a polynomial in the sample, then (None) one exact exponential per sample step
FILL_METHODS: dict[int | None, str] = {
    1: "propagator linear in the sample",
    2: "propagator quadratic in the sample",
    None: "exponential per sample",
}


def dense_fill(
    gen: MagnusGenerator, t: FloatArray, sel: NDArray[np.int64], Zc: FloatArray, allowance: float
) -> DenseFill:
    """The augmented states at every output time ``t`` [s] (uniform, spacing d) from those
    at the coarse times ``t[sel]`` (``Zc``, one Magnus step per coarse interval of several
    samples), filled from the left end of each coarse interval (module docstring).

    Inside a coarse interval of m samples, Magnus-4 steps of length d from sample to
    sample, the step from sample j to j + 1 (j = 0 .. m - 1) with a propagator P(j) that
    is a polynomial in j through exact exponentials of sample steps at nodes: linear
    through the steps centred on the interval's two coarse times (j = -1/2 and m - 1/2;
    the first interval's left node is the step from t_0, j = 0), each shared with the
    neighbouring interval (one exponential per coarse interval, two matrix-vector
    products per sample); quadratic with the step centred between them added (one more
    exponential, one more product); then one exact exponential per sample step.  Per
    sample count m all coarse intervals at once (:func:`_poly_march`); the first fill
    whose estimated error is within ``allowance`` (relative [-]) is kept.  The
    error is measured on about :data:`LOCAL_SAMPLES` coarse intervals (spread over the
    run, those where the exponent varies most between the nodes and those where the first
    fill's march ends farthest from the next coarse state) against a march of exact
    Magnus-6 exponentials of the sample steps: the estimate is :data:`FILL_MARGIN`
    times the largest difference at a sample, relative to the largest coarse state.
    """
    n, N = gen.size, gen.model.size
    d = float(t[-1] - t[0]) / (t.size - 1)
    Z = np.empty((t.size, n))
    Z[sel] = Zc
    counts = np.diff(sel)
    scale = float(np.max(np.linalg.norm(Zc[:, :N], axis=1)))
    filled = np.flatnonzero(counts > 1)
    # the end nodes: the sample steps centred on the coarse times (from t_0 at the start)
    nodes = np.unique(np.concatenate([filled, filled + 1]))
    starts = t[sel[nodes]] - 0.5 * d
    starts[nodes == 0] = t[0]
    # a metered caller (the fast lane) is charged each stage of the fill before it is
    # paid, as :func:`propagate` charges the steps: exponentials at one step's cost, a
    # sample of the polynomial march at FILL_SAMPLE_SHARE of it
    step = step_seconds(gen.exponent_size)
    charge(
        (nodes.size + FILL_SAMPLE_SHARE * (t.size - sel.size)) * step,
        f"the dense fill of {t.size - sel.size} samples ({nodes.size} exponentials)",
    )
    omega = gen.omega(starts, np.full(starts.size, d))
    P_nodes = gen.propagators(omega)
    exps, checked, estimate = int(nodes.size), 0, 0.0
    methods: list[str] = []
    for value in np.unique(counts[filled]):
        m = int(value)
        ks = np.flatnonzero(counts == m)
        T = t[sel[ks]]
        left, right = np.searchsorted(nodes, ks), np.searchsorted(nodes, ks + 1)
        a = np.where(ks == 0, 0.0, -0.5)  # the left node's j
        mid, half = 0.5 * (a + m - 0.5), 0.5 * (m - 0.5 - a)
        sigma = (np.arange(m)[None, :] - mid[:, None]) / half[:, None]
        PL, PR = P_nodes[left], P_nodes[right]
        variation = np.einsum("kij,kij->k", *(2 * [omega[right] - omega[left]]))
        picks = np.empty(0, dtype=np.int64)
        for degree in FILL_METHODS:
            if degree == 1:
                states = _poly_march([0.5 * (PL + PR), 0.5 * (PR - PL)], Zc[ks], m, sigma)
            elif degree == 2:
                charge(ks.size * step, f"the dense fill's quadratic form ({ks.size} exponentials)")
                PM = gen.propagators(gen.omega(T + mid * d, np.full(ks.size, d)))
                exps += ks.size
                C = [PM, 0.5 * (PR - PL), 0.5 * (PR + PL) - PM]
                states = _poly_march(C, Zc[ks], m, sigma)
            else:
                charge(ks.size * m * step, f"the dense fill by {ks.size * m} exponentials")
                states = _march(gen, T, d, m, Zc[ks])
                exps += ks.size * m
            if not picks.size:
                # checked: spread over the run, where the exponent varies most, and where
                # the march ends farthest from the coarse state (its own error there, or
                # the coarse step's)
                end = np.linalg.norm(states[:, -1, :N] - Zc[ks + 1, :N], axis=-1)
                part = LOCAL_SAMPLES // 4
                spread = np.linspace(0, ks.size - 1, min(ks.size, 2 * part)).round()
                picks = np.unique(
                    np.concatenate(
                        [
                            spread.astype(np.int64),
                            np.argsort(variation)[-part:],
                            np.argsort(end)[-part:],
                        ]
                    )
                )
                charge(picks.size * (m - 1) * step, "the dense fill's check")
                ref = _march(gen, T[picks], d, m - 1, Zc[ks[picks]], 6)[..., :N]
                exps += picks.size * (m - 1)
                checked += picks.size
            states = states[:, : m - 1]
            diff = float(np.max(np.linalg.norm(states[picks, :, :N] - ref, axis=-1)))
            err = FILL_MARGIN * diff / scale if scale > 0 else (0.0 if diff == 0 else math.inf)
            if err <= allowance:
                break
        Z[sel[ks][:, None] + np.arange(1, m)[None, :]] = states
        if not err <= estimate:  # (not max(): a nan, an overflowed fill, is kept)
            estimate = err
        methods.append(FILL_METHODS[degree])
    method = ", ".join(dict.fromkeys(methods)) or "none: every sample is a coarse time"
    return DenseFill(Z, estimate, exps, method, checked)


class DenseOutput:
    """The dense output of one solve on the uniform output times ``t`` [s]: the step control
    runs on the coarse times ``t[sel]`` (:func:`dense_selection`), refines them by splitting
    coarse intervals at samples (:meth:`refine`) and, after its last attempt, has the samples
    between filled from the coarse states (:meth:`fill`)."""

    def __init__(self, t: FloatArray, sel: NDArray[np.int64]) -> None:
        self.t = t
        self.sel = sel

    @classmethod
    def on(cls, t: FloatArray, h0: float) -> DenseOutput | None:
        """The dense output of the output times ``t`` [s] for a first step ``h0`` [s], or None
        when ``t`` is not a dense grid (the control runs on every output time)."""
        sel = dense_selection(t, h0)
        return None if sel is None else cls(t, sel)

    @property
    def times(self) -> FloatArray:
        """The coarse times the control runs on [s]."""
        return self.t[self.sel]

    def refine(self, counts: NDArray[np.int64]) -> tuple[FloatArray, NDArray[np.int64]]:
        """Split the coarse intervals that were to take ``counts`` steps
        (:func:`dense_refine`): the new coarse times [s] and their intervals' sub-steps."""
        self.sel, substeps = dense_refine(self.sel, counts)
        return self.times, substeps

    def at(self, Z: FloatArray, sel: NDArray[np.int64]) -> FloatArray:
        """The rows of ``Z`` (states at the current coarse times) at the earlier coarse
        times ``sel`` (a subset of the current ones)."""
        return Z[np.searchsorted(self.sel, sel)]

    def fill(
        self, gen: MagnusGenerator, Zc: FloatArray, tolerance: float, estimate: float
    ) -> DenseFill:
        """Every sample from the coarse states ``Zc`` (:func:`dense_fill`): the fill may add
        what the coarse ``estimate`` leaves of the ``tolerance`` (relative [-]), at most
        :data:`FILL_SHARE` of it (and that share when the coarse run is above it)."""
        left = tolerance - estimate
        allowance = FILL_SHARE * tolerance
        return dense_fill(
            gen, self.t, self.sel, Zc, allowance if left <= 0 else min(allowance, left)
        )

    def diagnostics(self, fill: DenseFill, steps: int) -> dict[str, Any]:
        """What the result says of the dense output (``steps``: the coarse run's)."""
        return {
            "steps": steps,
            "coarse_times": int(self.sel.size),
            "samples_filled": int(self.t.size - self.sel.size),
            "method": fill.method,
            "fill_estimated_relative_error": fill.estimate,
            "fill_exponentials": fill.exponentials,
        }

    @staticmethod
    def note(fill: DenseFill) -> str:
        """How the fill's share of the error estimate was measured (empty: not measured)."""
        if not fill.checked:
            return ""
        return (
            f"; dense output: plus {FILL_MARGIN:g} times the fill's largest difference "
            f"from a march of sixth-order Magnus steps between samples on {fill.checked} "
            "coarse intervals"
        )
