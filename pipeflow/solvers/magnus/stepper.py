"""One Magnus propagation: the augmented states at the output times following a step plan
(:func:`propagate`), the part of a solve that takes the time."""

from __future__ import annotations

import numpy as np

from pipeflow._types import FloatArray
from pipeflow.linalg import product_of_steps
from pipeflow.solvers.base import Problem
from pipeflow.solvers.magnus.checkpoints import MagnusCheckpoints
from pipeflow.solvers.magnus.generator import MagnusGenerator, StepPlan, augmented_initial_state
from pipeflow.solvers.magnus.metering import charge_steps

#: allocator; larger ones cost page faults (3-5x slower here)
_BLOCK_ENTRIES = 12_000
#: output intervals whose propagators are formed before they are applied (bounds memory)
_WINDOW = 256


def propagate(
    problem: Problem,
    gen: MagnusGenerator,
    t: FloatArray,
    plan: StepPlan,
    checkpoints: MagnusCheckpoints | None = None,
) -> tuple[FloatArray, int]:
    """Augmented states at the times ``t`` [s] following ``plan``, and the exponentials used;
    ``checkpoints``: continue from its stored window, and save one after a window when due.

    A metered caller (:func:`pipeflow.parallel.metered`) is charged the plan's estimated
    cost before any of it is paid (the exact time-invariant path, one exponential, is not)."""
    if not gen.invariant:
        charge_steps(
            plan.steps,
            gen.exponent_size,
            f"a magnus propagation of {plan.steps} steps of size {gen.exponent_size}",
        )
    Zaug = np.empty((t.size, gen.size))
    z = augmented_initial_state(problem, gen)
    Zaug[0] = z
    dt = np.diff(t)
    if gen.invariant:
        # exact: one exponential per distinct interval length (one for a uniform grid)
        if np.allclose(dt, dt[0], rtol=1e-12, atol=0.0):
            lengths, inverse = dt[:1], np.zeros(dt.size, dtype=np.int64)
        else:
            lengths, inverse = np.unique(dt, return_inverse=True)
        E = gen.propagators(gen.omega(np.zeros(lengths.size), lengths.astype(float)))
        for k in range(dt.size):
            z = E[inverse[k]] @ z
            Zaug[k + 1] = z
        return Zaug, int(lengths.size)
    substeps, orders = plan.substeps, plan.order
    # entries of one exponent (with loads: the Jordan-bordered generator), so a batch is one
    # expm_stack block
    per = gen.exponent_size**2
    exps = 0
    k = 0
    if checkpoints is not None:
        k, exps = checkpoints.resume(t, Zaug)
    while k < dt.size:
        # a window of output intervals: the propagators of its intervals are formed in
        # batches of equal sub-step count and order (sized to stay in cache), whether or
        # not those intervals are adjacent, then applied in order
        stop = min(dt.size, k + _WINDOW)
        window = np.arange(k, stop)
        E_win = np.empty((window.size, gen.size, gen.size))
        keys = substeps[window] * 16 + orders[window]
        for key in np.unique(keys):
            m, q = int(key) // 16, int(key) % 16
            members = window[keys == key]
            limit = max(1, _BLOCK_ENTRIES // (per * m))
            # every step of the group at once: start times, lengths and the coefficients at
            # their Gauss nodes (one profile evaluation per group, not per block)
            h_all = np.repeat(dt[members] / m, m)
            starts_all = t[members][:, None] + np.arange(m)[None, :] * (dt[members] / m)[:, None]
            starts_all = starts_all.ravel()
            weights = gen.node_weights(starts_all, h_all, q)
            # order 4: Omega's rows on the pieces, for the group at once; with loads their
            # forcing polynomials too
            coeffs = gen.omega4_coefficients(h_all, weights) if q == 4 else None
            forcing = gen.forcing_coefficients(starts_all, h_all, q) if gen.jordan else None
            for b in range(0, members.size, limit):
                idx = members[b : b + limit]
                rows = slice(b * m, (b + idx.size) * m)
                omega = gen.omega(
                    starts_all[rows],
                    h_all[rows],
                    q,
                    weights[:, rows],
                    None if coeffs is None else coeffs[rows],
                    None if forcing is None else forcing[rows],
                )
                E = gen.propagators(omega)
                exps += E.shape[0]
                E_win[idx - k] = product_of_steps(E.reshape(idx.size, m, gen.size, gen.size))
        # written in place, no temporary per output time; ndarray.dot (BLAS gemv, as
        # matmul) costs half of np.matmul's per-call dispatch on 20 x 20 (~0.7 vs ~1.6 us)
        for E_j, z_j, z_next in zip(E_win, Zaug[k:stop], Zaug[k + 1 : stop + 1], strict=True):
            E_j.dot(z_j, out=z_next)
        k = stop
        problem.report(k / dt.size)
        if checkpoints is not None and checkpoints.due():
            checkpoints.save(t, k, Zaug, exps)
    return Zaug, exps
