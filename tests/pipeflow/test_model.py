"""Galerkin model of eq. (1): structure, natural frequencies and symmetries."""

import math

import numpy as np
import pytest

from pipeflow.basis import cantilever_roots
from pipeflow.loading import Integrals
from pipeflow.model import Pipe, build_model
from pipeflow.paper import PAPER_PIPE


def frozen_spectrum(pipe: Pipe, n: int, v: float, w0: float) -> np.ndarray:
    model = build_model(pipe, n)
    return np.linalg.eigvals(model.frozen_state_matrix(v, 0.0, w0 * w0))


def test_natural_frequencies_without_flow_or_spin() -> None:
    """omega_j = (theta_j L)^2 sqrt(EI / (m L^4)) (Rao, Mechanical Vibrations, sec. 8.5).

    Without flow and spin the Galerkin model on exact cantilever modes is diagonal, so the
    eigenvalues must equal the analytic frequencies to rounding (1e-10 relative).
    """
    n = 8
    xi = frozen_spectrum(PAPER_PIPE, n, 0.0, 0.0)
    omega = np.sort(xi.imag[xi.imag > 0])
    p = PAPER_PIPE
    exact = np.asarray(cantilever_roots(n)) ** 2 * math.sqrt(p.EI / (p.mass * p.L**4))
    assert np.allclose(omega, exact, rtol=1e-10)
    assert np.max(np.abs(xi.real)) < 1e-9 * np.max(np.abs(xi))
    assert abs(exact[0] - 290.7834) < 1e-3  # the paper's pipe: 46.3 Hz


def test_mass_matrix_is_diagonal() -> None:
    model = build_model(PAPER_PIPE, 12)
    expected = PAPER_PIPE.mass * PAPER_PIPE.L
    assert np.allclose(model.M, expected * np.eye(12), rtol=0, atol=1e-12 * expected)


def test_eq1_centrifugal_projection_is_not_eq7() -> None:
    """The w0^2 stiffness is the projection of eq. (1): -m G + M1 int x phi phi' - M1/2 int
    (L^2 - x^2) phi phi'' (physics notes sec. 1), not eq. (7)'s 1/2 and 1/4 factors."""
    p = Pipe(E=1.0, I=1.0, L=1.0, M1=1.0, M2=0.0)
    model = build_model(p, 6)
    # the centrifugal stiffness stiffens the flapwise part: K_w2 + m G is positive definite
    flap = model.K_w2 + p.mass * np.eye(6)
    assert np.all(np.linalg.eigvalsh(0.5 * (flap + flap.T)) > 0)
    # and is symmetric (it comes from a potential: tension T(x) = M1 w0^2 (L^2 - x^2)/2)
    assert np.allclose(model.K_w2, model.K_w2.T, atol=1e-10)


@pytest.mark.parametrize("v", [0.1, 0.4, 2.0])
def test_reverse_flow_spectrum_is_conjugate(v: float) -> None:
    """Physics notes sec. 4 (Paidoussis & Luu 1985): for this undamped model the spectrum at
    -v is the complex conjugate of the spectrum at +v -> sigma flips sign, omega is kept.
    Tolerance 1e-9 relative to the spectral radius: rounding of a 20x20 eigenproblem."""
    for w0 in (0.0, 100.0):
        plus = frozen_spectrum(PAPER_PIPE, 10, v, w0)
        minus = frozen_spectrum(PAPER_PIPE, 10, -v, w0)
        # the set {xi(-v)} equals the set {-conj(xi(+v))}: match every point to its nearest
        mirrored = -np.conj(plus)
        dist = np.abs(minus[:, None] - mirrored[None, :])
        scale = np.max(np.abs(plus))
        assert np.max(dist.min(axis=1)) < 1e-9 * scale
        assert np.max(dist.min(axis=0)) < 1e-9 * scale
        assert np.max(plus.real) <= 1e-9 * scale < np.max(minus.real)


def test_balanced_coordinates_round_trip() -> None:
    model = build_model(PAPER_PIPE, 5)
    rng = np.random.default_rng(1)
    d, ddot = rng.normal(size=5), rng.normal(size=5)
    back_d, back_ddot = model.from_balanced(model.to_balanced(d, ddot))
    assert np.allclose(back_d, d) and np.allclose(back_ddot, ddot)


def test_initial_state_conventions() -> None:
    model = build_model(PAPER_PIPE, 4)
    d0, v0 = model.initial_state(0.001, 0.0, "paper")
    assert abs(d0 @ model.tip - 2.72444e-3) < 1e-8 and not v0.any()
    d0, _ = model.initial_state(0.001, 0.0, "tip")
    assert abs(d0 @ model.tip - 1e-3) < 1e-15
    with pytest.raises(ValueError, match="initial shape"):
        model.initial_state(0.001, 0.0, "bogus")


def test_pipe_validation() -> None:
    with pytest.raises(ValueError, match=r"pipe\.E"):
        Pipe(E=-1.0, I=1.0, L=1.0, M1=1.0, M2=1.0)
    with pytest.raises(ValueError, match=r"M1 \+"):
        Pipe(E=1.0, I=1.0, L=1.0, M1=0.0, M2=0.0)


def test_state_matrix_and_its_integral_from_the_pieces() -> None:
    """S(t) = S_0 + v S_v + vdot S_vdot + v^2 S_v2 + w0^2 S_w2 (eq. 13-14, balanced) and
    P(t) from the same pieces with the integrals (eq. 18), written out term by term: equal
    to rounding (1e-12 relative); the stacked pieces are read-only."""
    model = build_model(PAPER_PIPE, 3)
    v, vd, w2 = np.array([0.0, 1.5, -2.0]), np.array([0.3, 0.0, -1.0]), np.array([0.0, 4.0, 9.0])
    S = model.frozen_state_matrix(v, vd, w2)
    for k in range(3):
        expected = (
            model.S_0 + v[k] * model.S_v + vd[k] * model.S_vdot + v[k] ** 2 * model.S_v2
        ) + w2[k] * model.S_w2
        assert np.allclose(S[k], expected, rtol=1e-12, atol=1e-12 * np.abs(expected).max())
    t = np.array([0.5, 1.0, 2.0])
    P = model.integrated_state_matrix(Integrals(t, vd, v, w2, v, np.zeros(3)))
    for k in range(3):
        expected = (
            t[k] * model.S_0 + vd[k] * model.S_v + v[k] * model.S_vdot + w2[k] * model.S_v2
        ) + v[k] * model.S_w2
        assert np.allclose(P[k], expected, rtol=1e-12, atol=1e-12 * np.abs(expected).max())
    with pytest.raises(ValueError):
        model.state_pieces[0, 0, 0] = 1.0
