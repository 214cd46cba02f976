"""Published results the model must reproduce (physics notes, section 4)."""

import math

import numpy as np
import pytest

from pipeflow.model import Pipe, build_model


def spectrum(pipe: Pipe, n: int, v: float, w0: float) -> np.ndarray:
    model = build_model(pipe, n)
    return np.linalg.eigvals(model.frozen_state_matrix(v, 0.0, w0 * w0))


@pytest.mark.parametrize(
    ("gamma", "flapwise"),
    [(2.0, 4.1373), (4.0, 5.5850), (6.0, 7.3603), (8.0, 9.2568), (10.0, 11.2023)],
)
def test_rotating_beam_wright_1982(gamma: float, flapwise: float) -> None:
    """Wright, Smith, Thompson & Worley, J. Appl. Mech. 49 (1982), hub radius 0, as tabulated
    by Hamza-Cherif & Houmat (ICAS 2004): flapwise omega_1 L^2 sqrt(m/EI).

    Our model is the in-plane (chordwise) rotating beam, for which exactly
    omega_chord^2 = omega_flap^2 - gamma^2 (physics notes sec. 4). With no fluid (M2 = 0,
    so u = 0 and beta = 0) and E = I = L = M1 = 1, gamma = w0. The tables give 5
    significant digits; 12 modes converge the fundamental to better than that, so the
    tolerance is 3e-4 absolute (half a unit in the last published digit plus margin).
    """
    pipe = Pipe(E=1.0, I=1.0, L=1.0, M1=1.0, M2=0.0)
    xi = spectrum(pipe, 12, 0.0, gamma)
    chord = np.min(np.abs(xi.imag))
    assert abs(math.sqrt(chord**2 + gamma**2) - flapwise) < 3e-4


def critical_flow_number(beta: float, n: int) -> float:
    """Smallest u where the largest sigma turns positive (bisection on a fine scan)."""
    pipe = Pipe(E=1.0, I=1.0, L=1.0, M1=1.0 - beta, M2=beta)

    def growth(u: float) -> float:
        return float(np.max(spectrum(pipe, n, float(pipe.velocity_from_flow_number(u)), 0.0).real))

    grid = np.arange(0.5, 12.0, 0.25)
    vals = [growth(u) for u in grid]
    k = next(i for i, g in enumerate(vals) if g > 1e-8)
    lo, hi = grid[k - 1], grid[k]
    for _ in range(40):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if growth(mid) <= 1e-8 else (lo, mid)
    return 0.5 * (lo + hi)


@pytest.mark.parametrize("n", [10, 12])
def test_gregory_paidoussis_flutter_beta_02(n: int) -> None:
    """Gregory & Paidoussis (1966); Paidoussis, Fluid-Structure Interactions vol. 1 (1998),
    sec. 3.5: the non-rotating cantilevered pipe (no gravity, no damping) with beta = 0.2
    loses stability by flutter at u_cr ~ 5.6 (read off the published stability curve, about
    +-0.1), in its second mode; 10 or more modes are needed for convergence."""
    u_cr = critical_flow_number(0.2, n)
    assert 5.5 < u_cr < 5.7
    # the branch that goes unstable is the second mode: its frequency sits between the
    # first and third no-flow frequencies
    pipe = Pipe(E=1.0, I=1.0, L=1.0, M1=0.8, M2=0.2)
    xi = spectrum(pipe, n, float(pipe.velocity_from_flow_number(u_cr + 0.05)), 0.0)
    unstable = xi[(xi.real > 0) & (xi.imag > 0)]
    assert unstable.size == 1
    assert 3.516 < unstable[0].imag < 61.70  # between omega_1 and omega_3 of the bare beam


def test_mode_convergence_of_critical_velocity() -> None:
    """Convergence in modes: u_cr(beta=0.2) changes by < 1e-3 from 10 to 14 modes."""
    assert abs(critical_flow_number(0.2, 10) - critical_flow_number(0.2, 14)) < 1e-3
