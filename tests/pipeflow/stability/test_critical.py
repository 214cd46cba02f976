"""Critical flow velocities against the literature, and the v = 0 / v < 0 conventions.

Non-dimensional pipe throughout (E = I = L = 1, M1 + M2 = 1, M2 = beta), so that the flow
number is u = v sqrt(beta) and the spin number gamma = w0 (physics notes section 1).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from pipeflow.computations import documents
from pipeflow.errors import InvalidInput
from pipeflow.model import Pipe, build_model
from pipeflow.paper import PAPER_PIPE
from pipeflow.stability import critical_velocities, eigenvalues
from pipeflow.stability.core import nondimensional_pipe


def u_crossings(beta: float, modes: int = 10, u_max: float = 12.0, points: int = 121):
    pipe = nondimensional_pipe(beta)
    res = critical_velocities(pipe, 0.0, (0.0, u_max / math.sqrt(beta)), modes, points=points)
    return res, [c for c in res.crossings if c.boundary]


def test_beta_02_flutters_in_second_mode_near_5_6():
    """Gregory & Paidoussis (1966); Paidoussis, Fluid-Structure Interactions vol. 1 (1998)
    sec. 3.5: beta = 0.2, undamped, no gravity: flutter at u_cr ~ 5.6 in the second mode.
    The source gives the value graphically (two digits), so the tolerance is 0.1; our
    10-mode value is 5.5917 (the lead's check: max sigma crosses 0 between 5.5 and 5.6).
    """
    res, boundary = u_crossings(0.2)
    assert res.stable_at_start
    first = boundary[0]
    assert first.direction == "loss" and first.kind == "flutter"
    assert first.mode == 2
    assert first.flow_number == pytest.approx(5.6, abs=0.1)
    assert 5.5 < first.flow_number < 5.6
    assert res.u_cr == pytest.approx(first.flow_number, rel=1e-12)


def test_beta_05_flutters_in_third_mode():
    """Paidoussis (1998) sec. 3.5: for beta = 0.5 the mode that flutters is the third.
    Modes are counted as the branches leaving the cantilever frequencies at u = 0, in order,
    followed by eigenvector assignment.  Our u_cr = 9.3226 (the book's Fig. 3.13 curve
    reads about 9.3; tolerance 0.2 for a graphical value)."""
    _, boundary = u_crossings(0.5)
    first = boundary[0]
    assert first.mode == 3 and first.kind == "flutter" and first.direction == "loss"
    assert first.flow_number == pytest.approx(9.3, abs=0.2)


def test_s_shaped_segment_loses_regains_loses():
    """Physics notes sec. 4 / Paidoussis (1998) sec. 3.5: near beta ~ 0.3 the u_cr(beta)
    curve is S-shaped: with increasing u the pipe loses, regains and loses stability.  In our
    10-mode model the three-crossing window is beta in about [0.2931, 0.2972]; at
    beta = 0.295 the crossings are u = 7.2619, 7.8518, 8.1911, all in the second mode.
    A coarse grid (41 points over u in [0, 12]) must still resolve them."""
    _, boundary = u_crossings(0.295, points=41)
    assert [c.direction for c in boundary] == ["loss", "gain", "loss"]
    assert [round(c.flow_number, 3) for c in boundary] == [7.262, 7.852, 8.191]
    assert {c.mode for c in boundary} == {2}
    # just outside the window: a single crossing on either side
    for beta in (0.29, 0.30):
        _, b = u_crossings(beta, points=41)
        assert len(b) == 1


def test_crossing_is_a_root_to_1e_6():
    """Each crossing is located by root-finding to (much better than) 1e-6 relative: the
    largest real part changes sign within +-1e-6 relative of the reported velocity."""
    pipe = nondimensional_pipe(0.2)
    res = critical_velocities(pipe, 0.0, (0.0, 14.0), 10, points=51)
    v = res.critical_velocity
    assert v is not None
    model = build_model(pipe, 10)
    below, above = eigenvalues(model, [v * (1 - 1e-6), v * (1 + 1e-6)], 0.0).real.max(axis=1)
    assert below < 0 < above


def test_convergence_in_modes():
    """u_cr for beta = 0.2 and 0.5 with 8, 10 and 12 modes agrees to 1e-3 relative
    (measured: 5.5917 / 9.3226 to five digits), so 10 modes are converged for these."""
    for beta in (0.2, 0.5):
        u = [u_crossings(beta, n)[1][0].flow_number for n in (8, 10, 12)]
        assert max(u) - min(u) < 1e-3 * u[1]


def test_v0_marginal_point_is_not_a_crossing():
    """At v = 0 every eigenvalue of the undamped model is on the imaginary axis (sigma = 0
    to rounding); sweeping from 0 must not report a spurious crossing there, and just above
    0 every mode is damped (Coriolis damping through the free end)."""
    pipe = nondimensional_pipe(0.2)
    res = critical_velocities(pipe, 0.0, (0.0, 1.0), 6, points=11)
    assert res.crossings == [] and res.stable_at_start and res.critical_velocity is None
    assert res.stable_throughout
    model = build_model(pipe, 6)
    assert np.all(eigenvalues(model, 1e-3, 0.0).real < 0)


def test_reverse_flow_gets_the_caveat_not_a_threshold():
    """Physics notes sec. 4 (Paidoussis & Luu 1985): the spectrum at -v is that at +v
    reflected through the imaginary axis, so every v < 0 is predicted unstable; the answer
    is the caveat, no critical velocity."""
    model = build_model(PAPER_PIPE, 6)
    a = np.sort_complex(eigenvalues(model, 5.0, 100.0)[0])
    b = np.sort_complex(-np.conj(eigenvalues(model, -5.0, 100.0)[0]))
    np.testing.assert_allclose(a, b, rtol=1e-9, atol=1e-9 * np.max(np.abs(a)))
    res = critical_velocities(PAPER_PIPE, 100.0, (-10.0, -1.0), 6)
    assert res.critical_velocity is None and res.crossings == []
    assert res.reverse_flow is not None and res.reverse_flow["predicted_unstable"]
    assert "Paidoussis & Luu" in res.reverse_flow["caveat"]
    d = documents.critical_velocities(res)
    assert d["critical_velocity"] is None and d["reverse_flow"]["caveat"]


def test_paper_pipe_dimensional_and_dimensionless_agree():
    """The paper's pipe (beta = 0.4667) at w0 = 100 rad/s: the dimensional critical velocity
    maps to u_cr through u = v L sqrt(M2/EI), and the mixed range reports both parts."""
    res = critical_velocities(PAPER_PIPE, 100.0, (-1.0, 60.0), 10, points=121)
    d = documents.critical_velocities(res)
    v = d["critical_velocity"]
    assert v == pytest.approx(27.692, rel=1e-3)
    assert d["dimensionless"]["u_cr"] == pytest.approx(
        v * PAPER_PIPE.L * math.sqrt(PAPER_PIPE.M2 / PAPER_PIPE.EI), rel=1e-12
    )
    assert d["dimensionless"]["beta"] == pytest.approx(PAPER_PIPE.beta)
    assert d["reverse_flow"] is not None
    c = d["crossings"][0]
    assert c["frequency_hz"] == pytest.approx(c["frequency"] / (2 * math.pi))


def test_divergence_under_fast_spin_and_restabilisation():
    """With M1-only centrifugal tension (physics notes sec. 1) the in-plane rotating pipe
    diverges at v = 0 for fast spin (omega_chordwise^2 = omega_flap^2 - gamma^2 < 0 for the
    first mode); flow restabilises it: the crossing is a real eigenvalue ('divergence',
    frequency 0) regaining stability."""
    res = critical_velocities(PAPER_PIPE, 1500.0, (0.0, 60.0), 8, points=81)
    assert res.stable_at_start is False
    first = res.crossings[0]
    assert first.kind == "divergence" and first.direction == "gain" and first.frequency == 0
    assert res.critical_velocity is not None and res.critical_velocity > first.velocity
    assert res.stable_intervals[0][0] == pytest.approx(first.velocity)


def test_rotating_beam_at_v0():
    """Wright, Smith, Thompson & Worley (J. Appl. Mech. 49, 1982); physics notes sec. 4:
    flapwise omega_1 L^2 sqrt(m/EI) = 4.1373 (gamma 2) ... 11.2023 (gamma 10), and for this
    in-plane model omega_chordwise^2 = omega_flap^2 - gamma^2 (M2 = 0).  The table has five
    significant figures, so the tolerance is 2e-4 relative (10 modes reach 7e-5)."""
    pipe = Pipe(E=1.0, I=1.0, L=1.0, M1=1.0, M2=0.0)
    model = build_model(pipe, 10)
    table = {2: 4.1373, 4: 5.5850, 6: 7.3603, 8: 9.2568, 10: 11.2023}
    for gamma, flap in table.items():
        w = eigenvalues(model, 0.0, float(gamma))[0]
        om = np.min(w.imag[w.imag > 0])
        assert om == pytest.approx(math.sqrt(flap**2 - gamma**2), rel=2e-4)
        assert np.max(np.abs(w.real)) < 1e-9 * np.max(np.abs(w))


def test_bad_input_names_the_field():
    with pytest.raises(InvalidInput) as e:
        critical_velocities(PAPER_PIPE, 0.0, (5.0, 1.0), 6)
    assert e.value.parameter == "velocity_range"
    with pytest.raises(InvalidInput) as e:
        critical_velocities(PAPER_PIPE, 0.0, (0.0, 1.0), 0)
    assert e.value.parameter == "modes"
