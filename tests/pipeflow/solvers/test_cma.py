"""The paper's complex modal analysis against the tight-tolerance reference."""

import tracemalloc

import numpy as np
import pytest
from scipy.linalg import expm

from pipeflow.loading import Loading
from pipeflow.model import build_model
from pipeflow.paper import PAPER_PIPE
from pipeflow.profiles import Constant, Harmonic, Profile, polynomial
from pipeflow.simulation import simulate
from pipeflow.solvers import Options, Problem
from pipeflow.solvers.cma import CMA
from tests.pipeflow.cases import PAPER_FLOWS, paper_sim, reference_run


def rel_err(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.max(np.abs(a - b)) / np.max(np.abs(b)))


@pytest.mark.parametrize("case", ["v=0.4", "v=-0.4"])
def test_cma_exact_for_constant_coefficients(case: str) -> None:
    """Issue 2: cma equals reference to 1e-9 relative (tip history) for constant v and w0.

    The reference runs DOP853 at rtol 1e-12; CMA is exact up to the rounding of one
    eigen-decomposition, so the gap is the reference's own error (~1e-10 seen)."""
    ref = reference_run(case)
    cma = simulate(paper_sim(PAPER_FLOWS[case]))
    assert rel_err(cma.tip_displacement, ref.tip_displacement) < 1e-9
    assert cma.diagnostics["eigendecompositions"] == 1
    assert cma.diagnostics["expm_fallbacks"] == 0


def test_cma_matches_expm_for_constant_coefficients_10_modes() -> None:
    """Independent check at the paper's 10 modes: exp(S t) z0 by scipy's Pade expm at a
    few times agrees to 1e-11 relative (the two exponentials' rounding)."""
    sim = paper_sim(Constant(0.3), modes=10, t_end=1.0, samples=2001)
    res = simulate(sim)
    model = build_model(PAPER_PIPE, 10)
    loading = Loading(sim.flow, sim.spin)
    S = model.state_matrix(loading.coefficients(np.zeros(1)))[0]
    d0, v0 = model.initial_state(sim.u0, sim.du0)
    z0 = model.to_balanced(d0, v0)
    for k in (1, 700, 2000):
        z = expm(S * res.t[k]) @ z0
        d, _ = model.from_balanced(z)
        assert abs(d @ model.tip - res.tip_displacement[k]) < 1e-11 * abs(
            res.initial_tip_displacement
        )


@pytest.mark.parametrize(
    ("case", "documented"),
    [("v=0.4t", 7e-4), ("v=0.4t^2", 2e-3), ("v=-0.4t", 4e-2)],
)
def test_cma_approximation_error_is_measured(case: str, documented: float) -> None:
    """Physics notes sec. 2: for time-variant v the paper's CMA is only the first Magnus term.

    On 6 modes and 1 s the notes measured relative tip errors of about 7e-4 (v = 0.4 t),
    2e-3 (v = 0.4 t^2), 4e-2 (v = -0.4 t). Here, on 4 modes and 0.25 s (the first quarter,
    where the commutator terms have had less time to accumulate), we *measure* the error and
    check it is real (> 1e-6: CMA is not exact here) and at most the documented 1 s size.
    Worst errors seen: see the closing note of issue 2.
    """
    ref = reference_run(case)
    cma = simulate(paper_sim(PAPER_FLOWS[case]))
    err = rel_err(cma.tip_displacement, ref.tip_displacement)
    assert 1e-6 < err < documented


@pytest.mark.slow
def test_cma_error_at_paper_size() -> None:
    """The notes' figure for v = 0.4 t on 6 modes and 1 s: about 7e-4 (we see 6.6e-4)."""
    ref = simulate(paper_sim(polynomial(0, 0.4), "reference", modes=6, t_end=1.0, samples=2001))
    cma = simulate(paper_sim(polynomial(0, 0.4), modes=6, t_end=1.0, samples=2001))
    err = rel_err(cma.tip_displacement, ref.tip_displacement)
    assert 5e-4 < err < 9e-4


def test_cma_varying_spin_forcing_matches_reference() -> None:
    """The Duhamel term of notes sec. 2 for the force -(M1+M2) dw0/dt x of a varying spin.

    w0 = 0.5 sin(1000 t) rad/s: dw0/dt reaches 500 rad/s^2 while w0^2 <= 0.25 rad^2/s^2 is
    negligible against omega_1^2 = 8.5e4, so S(t) barely varies, CMA's commutator error is
    tiny (~1e-7 seen) and what is tested is the forcing integral. Starting from rest the
    whole response is forced. Tolerance 1e-6 relative."""
    kw = dict(
        flow=Constant(0.0), spin=Harmonic(0.0, 0.5, 1000.0), modes=3, t_end=0.1, samples=201, u0=0.0
    )
    ref = simulate(paper_sim(method="reference", **kw))  # type: ignore[arg-type]
    cma = simulate(paper_sim(**kw))  # type: ignore[arg-type]
    assert np.max(np.abs(ref.tip_displacement)) > 1e-5  # a real forced response [m]
    assert rel_err(cma.tip_displacement, ref.tip_displacement) < 1e-6


def test_cma_spin_up_error_is_commutator_sized() -> None:
    """A spin-up w0 = 100 + 200 t changes the stiffness by 0.7 %: CMA is then approximate
    (measured 5e-3 relative on 3 modes over 0.1 s); we check it stays below 1e-2."""
    kw = dict(flow=Constant(0.0), spin=polynomial(100.0, 200.0), modes=3, t_end=0.1, samples=201)
    ref = simulate(paper_sim(method="reference", **kw))  # type: ignore[arg-type]
    cma = simulate(paper_sim(**kw))  # type: ignore[arg-type]
    assert rel_err(cma.tip_displacement, ref.tip_displacement) < 1e-2


def test_ill_conditioned_eigenvectors_fall_back_to_expm() -> None:
    """A condition limit below any real condition number forces the Pade fallback of the
    constant-coefficient path (the time-variant one decomposes nothing), which must give
    the same answer (1e-10) and say so in diagnostics and warnings."""
    base = simulate(paper_sim(Constant(0.2), t_end=0.05, samples=51))
    forced = simulate(
        paper_sim(
            Constant(0.2),
            t_end=0.05,
            samples=51,
            options=Options(condition_limit=1.0 + 1e-9),
        )
    )
    assert forced.diagnostics["expm_fallbacks"] > 0
    assert any("ill-conditioned" in w for w in forced.warnings)
    assert rel_err(forced.tip_displacement, base.tip_displacement) < 1e-10


def test_cma_vectorised_over_times_matches_pointwise() -> None:
    """Chunked batched evaluation equals one-time-at-a-time evaluation (exactly the same math)."""
    sim = paper_sim(polynomial(0, 0.4), modes=3, t_end=0.1, samples=1200)
    model = build_model(PAPER_PIPE, 3)
    loading = Loading(sim.flow, sim.spin)
    d0, v0 = model.initial_state(sim.u0, sim.du0)
    z0 = model.to_balanced(d0, v0)
    t = np.linspace(0, 0.1, 1200)
    batched = CMA().solve(Problem(model, loading, z0, t)).z
    for k in (0, 513, 1199):
        P = model.integrated_state_matrix(loading.integrals(t[k : k + 1]))[0]
        assert np.allclose(batched[k], expm(P) @ z0, rtol=0, atol=1e-12 * np.abs(z0).max())


def test_cma_with_real_eigenvalues_matches_expm() -> None:
    """At w0 = 800 rad/s the paper's pipe diverges (a real eigenvalue pair, gamma > ~6):
    the conjugate-pair halving must still count real eigenvalues once. Against scipy's
    Pade expm at several times: 1e-10 relative to the largest value.  The divergence stop
    is moved out of the way (bound 1e300 m): the whole history is compared."""
    sim = paper_sim(
        Constant(0.0),
        spin=Constant(800.0),
        modes=4,
        t_end=0.05,
        samples=301,
        divergence_bound=1e300,
    )
    model = build_model(PAPER_PIPE, 4)
    loading = Loading(sim.flow, sim.spin)
    S = model.state_matrix(loading.coefficients(np.zeros(1)))[0]
    w = np.linalg.eigvals(S)
    assert np.any((w.imag == 0) & (w.real > 0))  # the divergence branch is present
    res = simulate(sim)
    d0, v0 = model.initial_state(sim.u0, sim.du0)
    z0 = model.to_balanced(d0, v0)
    scale = np.max(np.abs(res.tip_displacement))
    for k in (0, 77, 200, 300):
        d, _ = model.from_balanced(expm(S * res.t[k]) @ z0)
        assert abs(d @ model.tip - res.tip_displacement[k]) < 1e-10 * scale


@pytest.mark.parametrize(
    "flow", [polynomial(0, 0.4), polynomial(0, -0.4), Harmonic(2.0, 1.0, 50.0)]
)
def test_time_variant_cma_is_expm_of_P_at_paper_size(flow: Profile) -> None:
    """The paper's example (10 modes, 1 s, 2001 samples, w0 = 100 rad/s): exp(P(t)) z0 by
    the batched exponential equals scipy's Pade expm of P(t) (an independent algorithm) at
    every 50th output time to 1e-10 relative to the largest state (measured 1.7e-12 for
    v = 0.4 t, 1.6e-11 for the growing v = -0.4 t: |P(1 s)|_1 ~ 8e4 needs 17 squarings,
    each doubling the rounding), with no eigen-decomposition."""
    model = build_model(PAPER_PIPE, 10)
    loading = Loading(flow, Constant(100.0))
    d0, v0 = model.initial_state(1e-3, 0.0)
    z0 = model.to_balanced(d0, v0)
    t = np.linspace(0.0, 1.0, 2001)
    out = CMA().solve(Problem(model, loading, z0, t))
    assert out.diagnostics["eigendecompositions"] == 0
    idx = np.arange(0, t.size, 50)
    P = model.integrated_state_matrix(loading.integrals(t[idx]))
    ref = np.stack([expm(Pk) @ z0 for Pk in P])
    err = np.max(np.linalg.norm(out.z[idx] - ref, axis=1)) / np.max(np.linalg.norm(ref, axis=1))
    assert err < 1e-10


def test_constant_coefficient_cma_peak_memory_is_near_the_output() -> None:
    """200 001 samples, 10 modes: the solver's peak traced allocation (tracemalloc, which
    counts numpy buffers; deterministic, no timing) is below 1.5x its output array (was 4x:
    complex temporaries of the whole time history)."""
    model = build_model(PAPER_PIPE, 10)
    d0, v0 = model.initial_state(1e-3, 0.0)
    t = np.linspace(0.0, 1.0, 200_001)
    p = Problem(model, Loading(Constant(0.4), Constant(100.0)), model.to_balanced(d0, v0), t)
    tracemalloc.start()
    try:
        out = CMA().solve(p)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 1.5 * out.z.nbytes
