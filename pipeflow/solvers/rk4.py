"""Classical fixed-step fourth-order Runge-Kutta (the paper's comparison, section 4).

RK4 multiplies each eigen-component by R(h lambda) per step, with
R(z) = 1 + z + z^2/2 + z^3/6 + z^4/24 (eq. 32 without its stray "f").  A step is stable
when |R(h lambda)| <= max(1, |e^(h lambda)|) for every eigenvalue of the frozen state
matrix over the run: never amplifying a mode more than the exact flow does.  On the
imaginary axis that is h |lambda| <= 2 sqrt(2); with 10 modes of the paper's pipe the
fastest mode has |lambda| ~ 8e4 1/s, hence the tiny steps and the paper's long CPU times.
"""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np
from numpy.typing import NDArray

from pipeflow._types import FloatArray
from pipeflow.errors import UnstableStep
from pipeflow.solvers.base import (
    Problem,
    Solver,
    SolverOutput,
    SolverStats,
    frozen_eigenvalues,
    given_step,
    load_step_cap,
    step_budget,
    step_counts,
)

#: default fraction of the largest stable step used when the user gives none
SAFETY = 0.9
_BLOCK_ENTRIES = 4_000_000  # stage-matrix entries formed at once (~32 MB)


def rk4_amplification(z: NDArray[np.complex128]) -> NDArray[np.complex128]:
    """R(z) = 1 + z + z^2/2 + z^3/6 + z^4/24, the RK4 amplification factor."""
    return np.asarray(1 + z * (1 + z * (1 / 2 + z * (1 / 6 + z / 24))), dtype=complex)


def _unstable(hl: NDArray[np.complex128]) -> NDArray[np.bool_]:
    bound = np.maximum(1.0, np.exp(hl.real))
    return np.abs(rk4_amplification(hl)) > bound * (1 + 1e-12)


def largest_stable_step(eigenvalues: NDArray[np.complex128]) -> float:
    """Largest h [s] with |R(h lambda)| <= max(1, |e^(h lambda)|) for all given lambda [1/s].

    Scans h |lambda| on (0, 4] (RK4's region lies inside |z| < 2.79 off the imaginary
    axis and |z| <= 2 sqrt(2) on it), then bisects each boundary to 1e-12 relative.
    """
    lam = np.asarray(eigenvalues, dtype=complex).ravel()
    lam = lam[np.abs(lam) > 0]
    if lam.size == 0:
        return float("inf")
    direction = lam / np.abs(lam)
    r = np.linspace(0.0, 4.0, 4001)[1:]
    bad = _unstable(r[None, :] * direction[:, None])
    first = np.where(bad.any(axis=1), bad.argmax(axis=1), r.size)
    lo = np.where(first > 0, r[np.maximum(first - 1, 0)], 0.0)
    hi = np.where(first < r.size, r[np.minimum(first, r.size - 1)], 4.0)
    for _ in range(45):
        mid = 0.5 * (lo + hi)
        unstable = _unstable(mid * direction)
        hi = np.where(unstable, mid, hi)
        lo = np.where(unstable, lo, mid)
    return float(np.min(lo / np.abs(lam)))


class RK4(Solver):
    name: ClassVar[str] = "rk4"
    description: ClassVar[str] = (
        "Classical fixed-step 4th-order Runge-Kutta; step chosen for stability unless given."
    )
    option_names: ClassVar[tuple[str, ...]] = ("step", "max_steps")
    error_advice: ClassVar[str] = "use a smaller step or method 'magnus'"

    def _solve_impl(self, problem: Problem, stats: SolverStats) -> SolverOutput:
        model, loading, t = problem.model, problem.loading, problem.t
        opts = problem.options
        step = given_step(opts)
        h_stable = largest_stable_step(frozen_eigenvalues(model, loading, float(t[-1])))
        if step is not None:
            if step > h_stable:
                raise UnstableStep(
                    f"RK4 step {step:.6g} s is outside the stability region for this "
                    f"run (largest stable step {h_stable:.6g} s, from the spectral radius "
                    "of the state matrix; paper eq. 32)",
                    parameter="step",
                    largest_stable_step=h_stable,
                )
            h_target = step
        else:
            h_target = min(SAFETY * h_stable, load_step_cap(problem))
        dt = np.diff(t)
        substeps = step_counts(dt, h_target, step_budget(opts), "RK4", step is not None)
        n_steps = int(substeps.sum())
        resumed: dict[str, Any] = {}
        Z = self._integrate(problem, substeps, resumed)
        h_used = dt / substeps
        stats.steps = n_steps
        stats.rhs_evaluations = 4 * n_steps
        diagnostics = {
            "step_max": float(h_used.max()),
            "step_min": float(h_used.min()),
            "largest_stable_step": h_stable,
            "stability_margin": float(h_stable / h_used.max()),
            **resumed,
        }
        return SolverOutput(z=Z, diagnostics=diagnostics)

    def _integrate(
        self, problem: Problem, substeps: NDArray[np.int64], diagnostics: dict[str, Any]
    ) -> FloatArray:
        """States at the output times with ``substeps`` equal steps per interval; with
        ``problem.checkpoints``, a checkpoint (the outputs so far and the state at a
        block boundary) when one is due, and a resume from the stored one (what it
        carried over goes into ``diagnostics``)."""
        model, loading, t = problem.model, problem.loading, problem.t
        A = model.state_pieces
        forced = problem.forced  # varying spin or external loads
        Z = np.empty((t.size, model.size))
        z = problem.z0.astype(float).copy()
        Z[0] = z
        total = int(substeps.sum())
        done = 0
        report_every = max(1, total // 100)

        invariant = loading.is_time_invariant and problem.loads is None
        block = max(16, _BLOCK_ENTRIES // (3 * model.size**2))
        if invariant:
            S_const = model.state_matrix(loading.coefficients(np.zeros(1)))[0]
        cp = problem.checkpointer("rk4")
        k0, b_start = 0, 0  # where to start: output interval, step within it
        snap = cp.restore()
        if snap is not None:
            k0, b_start = int(snap.header["k"]), int(snap.header["step"])
            Z[: k0 + 1] = snap.arrays["outputs"]
            z = snap.arrays["state"].copy()
            done = int(substeps[:k0].sum()) + b_start
            diagnostics.update(
                resumed_from_time=float(
                    t[k0] + (t[k0 + 1] - t[k0]) / substeps[k0] * b_start if b_start else t[k0]
                ),
                resumed_steps=done,
            )
        for k in range(k0, t.size - 1):
            m = int(substeps[k])
            h = (t[k + 1] - t[k]) / m
            for b0 in range(b_start if k == k0 else 0, m, block):
                nb = min(block, m - b0)
                if invariant:
                    for _ in range(nb):
                        k1 = S_const @ z
                        k2 = S_const @ (z + 0.5 * h * k1)
                        k3 = S_const @ (z + 0.5 * h * k2)
                        k4 = S_const @ (z + h * k3)
                        z = z + h / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
                else:
                    starts = t[k] + h * (b0 + np.arange(nb))
                    stage_t = np.concatenate([starts, starts + 0.5 * h, starts + h])
                    c = loading.coefficients(stage_t)
                    cs = c.weights().reshape(3, nb, -1)
                    fs = (
                        problem.forcing(stage_t, c).reshape(3, nb, -1)
                        if forced
                        else np.zeros((3, nb, model.size))
                    )
                    S_all = np.einsum("snc,cij->snij", cs, A)
                    for i in range(nb):
                        S1, S2, S3 = S_all[0, i], S_all[1, i], S_all[2, i]
                        k1 = S1 @ z + fs[0, i]
                        k2 = S2 @ (z + 0.5 * h * k1) + fs[1, i]
                        k3 = S2 @ (z + 0.5 * h * k2) + fs[1, i]
                        k4 = S3 @ (z + h * k3) + fs[2, i]
                        z = z + h / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
                if b0 + nb < m and cp.due():
                    # inside the interval: the state after b0 + nb of its m steps
                    cp.save({"k": k, "step": b0 + nb}, {"outputs": Z[: k + 1], "state": z})
            Z[k + 1] = z
            done += m
            if done % report_every < m:
                problem.report(done / total)
            if k + 2 < t.size and cp.due():
                cp.save({"k": k + 1, "step": 0}, {"outputs": Z[: k + 2], "state": z})
        return Z
