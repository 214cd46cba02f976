"""The state-space realisation (pipeflow.state_space, issue 32) against identities.

- C (i W I - A)^-1 B + D equals the modal FRF (frequency_response with residual=False) at
  every frequency: both are the same modal model, so to rounding (tolerance 1e-10 of the
  curve's largest value: the direct solve here vs the eigen-decomposition there);
- the eigenvalues of A are the frozen spectrum (the FRF's eigenvalues): 1e-9 relative;
- python-control (an independent implementation: its own frequency response and step
  simulation) reproduces the FRF and the static deflection of a unit step force.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from pipeflow.frequency import BaseAcceleration, PointForce, frequency_response
from pipeflow.paper import PAPER_PIPE as P
from pipeflow.state_space import state_space

L = P.L
W = np.geomspace(10.0, 2e4, 300)
CASES = {
    "flow+spin, tip force": (P, 5.0, 100.0, PointForce(L)),
    "damped hub, 0.4 L force": (
        replace(P, kelvin_voigt=1e-5, hub_radius=L),
        10.0,
        200.0,
        PointForce(0.4 * L),
    ),
    "tip mass, clamp acceleration": (replace(P, tip_mass=2e-7), 3.0, 0.0, BaseAcceleration()),
}


@pytest.mark.parametrize("case", list(CASES))
@pytest.mark.parametrize("quantity", ["displacement", "velocity", "acceleration"])
def test_transfer_function_is_the_frf(case: str, quantity: str) -> None:
    pipe, v, w0, load = CASES[case]
    xs = [0.3 * L, L]
    ss = state_space(pipe, v, w0, load=load, positions=xs, quantity=quantity, modes=8)
    frf = frequency_response(
        pipe,
        v,
        w0,
        load=load,
        positions=xs,
        frequencies=W,
        quantity=quantity,
        modes=8,
        residual=False,
    )
    n2 = ss.A.shape[0]
    G = np.stack(
        [(ss.C @ np.linalg.solve(1j * w * np.eye(n2) - ss.A, ss.B) + ss.D)[:, 0] for w in W],
        axis=1,
    )
    assert np.max(np.abs(G - frf.H)) <= 1e-10 * np.max(np.abs(frf.H))
    lam = np.sort_complex(np.linalg.eigvals(ss.A))
    ref = np.sort_complex(frf.eigenvalues)
    assert np.max(np.abs(lam - ref)) <= 1e-9 * np.max(np.abs(ref))
    assert len(ss.states) == n2 and len(ss.outputs) == 2 and ss.B.shape == (n2, 1)
    assert (
        ss.output_unit
        == {"displacement": "m", "velocity": "m/s", "acceleration": "m/s^2"}[quantity]
    )


def test_python_control_frequency_response_and_step() -> None:
    """python-control's frequency response of ss(A, B, C, D) equals the FRF (1e-10), and its
    step response of a damped pipe (Kelvin-Voigt, no flow) settles on the static deflection
    of the Galerkin model K^-1 f, which is F a^2 (3L - a) / 6EI (Roark) to the 8-mode n^-3
    truncation (measured 8e-5 for the tip; tolerance 5e-4) and the FRF at W = 0 to 1e-6
    (at t = 2 s the slowest transient, zeta_1 w_1 = 8.4 1/s, has decayed to ~1e-7; the
    last 0.2 s vary by 2.5e-7 of the static value)."""
    control = pytest.importorskip("control")
    pipe = replace(P, kelvin_voigt=2e-4)
    ss = state_space(pipe, 0.0, 0.0, load=PointForce(L), positions=[L], modes=8, residual=False)
    sys = control.ss(ss.A, ss.B, ss.C, ss.D)
    resp = control.frequency_response(sys, W)
    H = np.asarray(resp.complex).reshape(-1)
    frf = frequency_response(
        pipe, 0.0, 0.0, load=PointForce(L), positions=[L], frequencies=W, modes=8, residual=False
    )
    assert np.max(np.abs(H - frf.H[0])) <= 1e-10 * np.max(np.abs(frf.H[0]))
    t = np.linspace(0.0, 2.0, 20001)
    step = control.step_response(sys, T=t)
    y_end = float(np.asarray(step.outputs).reshape(-1)[-1])
    static = L**3 / (3 * pipe.EI)
    assert abs(y_end - static) <= 5e-4 * static
    h0 = frequency_response(
        pipe,
        0.0,
        0.0,
        load=PointForce(L),
        positions=[L],
        frequencies=[0.0],
        modes=8,
        residual=False,
    ).H[0, 0]
    assert abs(y_end - h0.real) <= 1e-6 * static
    # with the residual flexibility (the default here, on a lag state: Kelvin-Voigt) the
    # step settles on the beam's own static deflection, not the truncated one (1e-6: the
    # transients' 1e-7 and the residual's exactness at W = 0)
    full = state_space(pipe, 0.0, 0.0, load=PointForce(L), positions=[L], modes=8)
    step = control.step_response(control.ss(full.A, full.B, full.C, full.D), T=t)
    assert float(np.asarray(step.outputs).reshape(-1)[-1]) == pytest.approx(static, rel=1e-6)


def test_unstable_and_reverse_flow_points_say_so() -> None:
    """Past the critical velocity (27.69 m/s at w0 = 100 rad/s) A has Re xi > 0: the answer
    says so; reverse flow carries its caveat (physics notes sec. 4)."""
    ss = state_space(P, 40.0, 100.0, load=PointForce(L), positions=[L], modes=6)
    assert np.max(np.linalg.eigvals(ss.A).real) > 0
    assert any("unstable operating point" in w for w in ss.warnings)
    back = state_space(P, -1.0, 0.0, load=PointForce(L), positions=[L], modes=6)
    assert any("reverse" in w.lower() for w in back.warnings)
    assert not state_space(P, 5.0, 100.0, load=PointForce(L), positions=[L]).warnings


def _tf(ss: object, w: np.ndarray) -> np.ndarray:
    A, B, C, D = (getattr(ss, k) for k in "ABCD")
    n2 = A.shape[0]
    return np.stack(
        [(C @ np.linalg.solve(1j * x * np.eye(n2) - A, B) + D)[:, 0] for x in w], axis=1
    )


@pytest.mark.parametrize("alpha", [0.0, 1e-5])
def test_residual_flexibility_in_the_state_space(alpha: float) -> None:
    """Issue 32: the residual flexibility of the modes left out is carried by the
    displacement output (D = R; with Kelvin-Voigt damping alpha the FRF's R / (1 + i W alpha)
    by one lag state, eigenvalue -1/alpha), so the transfer function equals the frequency
    response with residual flexibility (its default here: no flow) to 1e-10 of its largest
    value, and at W = 0 the tip's static flexibility under a tip force is the beam's
    L^3 / (3 EI) (Euler-Bernoulli; residual flexibility exact at W = 0: 1e-9) where the
    modal part alone misses it by ~1e-5 at 8 modes."""
    pipe = replace(P, kelvin_voigt=alpha)
    xs = [0.5 * L, L]
    ss = state_space(pipe, 0.0, 0.0, load=PointForce(L), positions=xs, modes=8)
    frf = frequency_response(
        pipe, 0.0, 0.0, load=PointForce(L), positions=xs, frequencies=W, modes=8
    )
    assert frf.residual
    assert np.max(np.abs(_tf(ss, W) - frf.H)) <= 1e-10 * np.max(np.abs(frf.H))
    lag = ("residual_lag",) if alpha else ()
    assert ss.states[2 * 8 :] == lag and ss.A.shape == (16 + len(lag),) * 2
    lam = np.sort_complex(np.linalg.eigvals(ss.A))
    ref = np.sort_complex(np.concatenate([frf.eigenvalues, [-1.0 / alpha] if alpha else []]))
    assert np.max(np.abs(lam - ref)) <= 1e-9 * np.max(np.abs(ref))
    static = _tf(ss, np.array([0.0]))[1, 0].real
    beam = L**3 / (3 * P.E * P.I)
    assert static == pytest.approx(beam, rel=1e-9)
    bare = state_space(pipe, 0.0, 0.0, load=PointForce(L), positions=xs, modes=8, residual=False)
    assert not np.any(bare.D) and bare.A.shape == (16, 16)
    assert abs(_tf(bare, np.array([0.0]))[1, 0].real / beam - 1.0) > 1e-6


def test_residual_flexibility_stays_out_of_velocity_outputs() -> None:
    """R (i W) has no proper realisation: asked for on a velocity output, it is left out
    with a warning, and the realisation is the FRF without it."""
    ss = state_space(
        P, 0.0, 0.0, load=PointForce(L), positions=[L], quantity="velocity", modes=6,
        residual=True,
    )  # fmt: skip
    assert any("left out of a velocity output" in w for w in ss.warnings)
    frf = frequency_response(
        P, 0.0, 0.0, load=PointForce(L), positions=[L], frequencies=W, quantity="velocity",
        modes=6, residual=False,
    )  # fmt: skip
    assert np.max(np.abs(_tf(ss, W) - frf.H)) <= 1e-10 * np.max(np.abs(frf.H))
