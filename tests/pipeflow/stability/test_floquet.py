"""Floquet analysis: monodromy against exp(S T) and against direct integration."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.optimize import linear_sum_assignment

from pipeflow.computations import documents
from pipeflow.errors import InvalidInput
from pipeflow.loading import Loading
from pipeflow.model import build_model
from pipeflow.profiles import Constant, Harmonic, polynomial
from pipeflow.stability.core import eigenvalues, nondimensional_pipe
from pipeflow.stability.floquet import floquet, resonance_chart

BETA = 0.2
PIPE = nondimensional_pipe(BETA)
V0 = 4.0 / math.sqrt(BETA)  # u = 4: stable, second mode lightly damped


def _omega(modes: int, j: int) -> float:
    w = eigenvalues(build_model(PIPE, modes), V0, 0.0)[0]
    return float(np.sort(w.imag[w.imag > 0])[j])


def test_zero_amplitude_gives_exp_of_eigenvalues():
    """With zero pulsation amplitude S is constant and the multipliers are exp(xi T) for
    the eigenvalues xi of S (to rounding: 1e-10 relative)."""
    om2 = _omega(4, 1)
    f = floquet(PIPE, Harmonic(V0, 0.0, 2 * om2), None, modes=4)
    xi = eigenvalues(build_model(PIPE, 4), V0, 0.0)[0]
    expected = np.exp(xi * f.period)
    cost = np.abs(f.multipliers[:, None] - expected[None, :])
    r, c = linear_sum_assignment(cost)
    np.testing.assert_allclose(f.multipliers[r], expected[c], rtol=1e-10, atol=1e-12)
    assert f.verdict == "stable"


def test_multipliers_match_direct_integration_over_many_periods():
    """Inside the principal parametric resonance of the second mode (Omega = 2 omega_2,
    amplitude 0.6 of the mean, beta = 0.2, u = 4, 3 modes) the monodromy matrix predicts
    growth; a directly integrated solution (solve_ivp DOP853, rtol 1e-11) after 12 periods
    equals Phi^12 z0 to 1e-6 relative, and its component along the dominant Floquet mode
    (left eigenvector of Phi) is multiplied by exactly lambda_max over the last period (to
    1e-6), and the norm grows by max |lambda| per period to 2 % (the subdominant multipliers
    still contribute after 12 periods)."""
    modes = 3
    om2 = _omega(modes, 1)
    flow = Harmonic(V0, 0.6 * V0, 2 * om2)
    f = floquet(PIPE, flow, None, modes=modes, tolerance=1e-10)
    assert f.verdict == "unstable" and f.max_multiplier > 1.1
    model = build_model(PIPE, modes)
    loading = Loading(flow, Constant(0.0))
    A = np.stack([model.S_0, model.S_v, model.S_vdot, model.S_v2, model.S_w2])

    def rhs(t: float, z: np.ndarray) -> np.ndarray:
        c = loading.coefficients(np.array([t]))
        w = np.array([1.0, c.v[0], c.vdot[0], c.v[0] ** 2, c.w2[0]])
        return np.tensordot(w, A, axes=1) @ z

    z0 = np.random.default_rng(1).standard_normal(model.size)
    K = 12
    sol = solve_ivp(
        rhs, (0, K * f.period), z0, method="DOP853", rtol=1e-11, atol=1e-14,
        t_eval=[(K - 6) * f.period, (K - 1) * f.period, K * f.period],
    )  # fmt: skip
    zK = sol.y[:, -1]
    pred = np.linalg.matrix_power(f.monodromy, K) @ z0
    assert np.linalg.norm(zK - pred) / np.linalg.norm(zK) < 1e-6
    lam, left = np.linalg.eig(f.monodromy.T)
    top = np.argmax(np.abs(lam))
    ratio = (left[:, top] @ zK) / (left[:, top] @ sol.y[:, 1])
    assert abs(ratio - lam[top]) < 1e-6 * abs(lam[top])
    assert abs(lam[top]) == pytest.approx(f.max_multiplier, rel=1e-12)
    growth = (np.linalg.norm(zK) / np.linalg.norm(sol.y[:, 0])) ** (1 / 6)
    assert growth == pytest.approx(f.max_multiplier, rel=2e-2)


def test_resonance_chart_principal_region_of_second_mode():
    """beta = 0.2, u = 4, 3 modes, v = V0 (1 + mu sin Omega t): the unstable region that
    reaches the lowest amplitude sits at Omega = 2 omega_2 (principal parametric resonance,
    Paidoussis & Issid, J. Sound Vib. 33, 1974); none is unstable at zero amplitude.  The
    grid is coarse (6 x 9) to stay fast; the region's tip is checked against one directly
    computed Floquet case inside it."""
    modes = 3
    om2 = _omega(modes, 1)
    ch = resonance_chart(
        PIPE, V0, (0.0, 0.8 * V0), (1.5 * om2, 2.5 * om2), modes=modes,
        amplitude_points=5, frequency_points=9,
    )  # fmt: skip
    assert not ch.unstable[0].any()
    regions = documents.resonance_regions(ch)
    main = regions[0]
    assert main["nearest_resonance"]["condition"] == "2*omega_2"
    lo, hi = main["frequency_range"]
    assert lo <= 2 * om2 <= hi
    tip = main["tip"]
    one = floquet(PIPE, Harmonic(V0, tip["amplitude"], tip["frequency"]), None, modes=modes)
    assert one.verdict == "unstable"
    i = int(np.argmin(np.abs(ch.amplitudes - tip["amplitude"])))
    j = int(np.argmin(np.abs(ch.frequencies - tip["frequency"])))
    assert ch.max_multiplier[i, j] == pytest.approx(one.max_multiplier, rel=1e-4)
    d = documents.resonance_chart(ch)
    assert d["regions"] and len(d["max_multiplier"]) == 5


def test_harmonic_spin_and_input_errors():
    """Oscillating spin alone (constant flow) is analysed with the spin's period; a
    non-periodic profile is refused naming the field."""
    f = floquet(PIPE, Constant(V0), Harmonic(1.0, 0.1, 30.0), modes=3)
    assert f.period == pytest.approx(2 * math.pi / 30.0)
    assert f.verdict == "stable"
    with pytest.raises(InvalidInput) as e:
        floquet(PIPE, polynomial(0.0, 1.0), None, modes=3)
    assert e.value.parameter == "flow"


def test_resonance_chart_cut_into_pieces_equals_the_serial_chart():
    """On a host of width 3 that finishes the pieces last-first, the chart (strided
    frequency columns) equals the serial one bit for bit (tolerance 0: each frequency's
    step doubling and propagation only depend on that frequency), and one column equals a
    chart computed for that frequency alone."""
    from pipeflow import parallel
    from tests.pipeflow.test_parallel import _Reversed

    def chart(freqs=(300.0, 1500.0), points=7):
        return resonance_chart(PIPE, V0, (0.0, 0.5 * V0), freqs, modes=2,
                               amplitude_points=4, frequency_points=points)  # fmt: skip

    serial = chart()
    with parallel.hosting(_Reversed()):
        fanned = chart()
    assert documents.resonance_chart(serial) == documents.resonance_chart(fanned)
    alone = chart((float(serial.frequencies[3]), 2000.0), 2)
    assert np.array_equal(alone.max_multiplier[:, 0], serial.max_multiplier[:, 3])
    assert alone.steps[0] == serial.steps[3]
