"""How a pipe loses stability: divergence of supported pipes, restabilisation and coupled-mode
flutter at higher u (Paidoussis, *Fluid-Structure Interactions* vol. 1, 2014, sec. 3.4), flutter
of the cantilever (issue 31).

Each crossing is checked against the spectrum itself on both sides (an independent test of
the classification: real eigenvalue -> divergence, complex pair -> flutter) and the
divergence velocities against the exact values (Euler buckling loads as u^2).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from pipeflow.model import Pipe, build_model
from pipeflow.stability.critical import critical_velocities
from pipeflow.supports import Support, Supports


def _pipe(x0: str, xL: str, beta: float) -> Pipe:
    return Pipe(E=1.0, I=1.0, L=1.0, M1=1.0 - beta, M2=beta,
                supports=Supports(Support(x0), Support(xL)))  # fmt: skip


def _top(p: Pipe, u: float) -> complex:
    m = build_model(p, 12)
    xi = np.linalg.eigvals(m.frozen_state_matrix(float(p.velocity_from_flow_number(u))))
    return complex(xi[np.argmax(xi.real)])


def _check_against_spectrum(p: Pipe, r: object) -> None:
    """Inside every stable interval the spectrum is stable, just past every boundary loss it
    grows with the named mechanism (real eigenvalue, or a pair with omega > 0)."""
    for a, b in r.stable_intervals:  # type: ignore[attr-defined]
        assert _top(p, float(p.flow_number(0.5 * (a + b)))).real < 1e-8
    for c in r.crossings:  # type: ignore[attr-defined]
        if c.boundary and c.direction == "loss":
            top = _top(p, c.flow_number * (1 + 1e-4))
            assert top.real > 0
            assert (abs(top.imag) < 1e-6) == (c.kind == "divergence")


def test_pinned_pinned_divergence_restabilisation_coupled_mode_flutter() -> None:
    """beta = 0.5, u up to 10 (12 modes): divergence at u = pi (exact: the basis holds the
    buckling mode; 1e-12), stability regained at 2 pi, coupled-mode flutter of modes 1-2 at
    u = 6.3039 (Paidoussis sec. 3.4: PP pipes regain stability after divergence and then
    flutter by coupled modes near u ~ 2 pi; measured 6.30388 at 12 modes, 6.3039 at 16)."""
    p = _pipe("pinned", "pinned", 0.5)
    r = critical_velocities(p, 0.0, (0.0, float(p.velocity_from_flow_number(10.0))), modes=12)
    assert r.mechanism == "divergence"
    assert r.u_cr == pytest.approx(math.pi, rel=1e-12)
    bounds = [(c.flow_number, c.kind, c.direction) for c in r.crossings if c.boundary]
    assert [b[1:] for b in bounds] == [
        ("divergence", "loss"),
        ("divergence", "gain"),
        ("flutter", "loss"),
    ]
    assert bounds[1][0] == pytest.approx(2 * math.pi, rel=1e-10)
    assert bounds[2][0] == pytest.approx(6.3039, abs=2e-4)
    _check_against_spectrum(p, r)


def test_clamped_clamped_divergence_then_coupled_mode_flutter() -> None:
    """beta = 0.5 (12 modes): divergence at u = 2 pi (6.283236 at 12 modes: the basis error
    of docs/model.md 9, 8e-6), regained at u = 8.987, coupled-mode flutter at u = 9.295 with
    omega ~ 17 (Paidoussis sec. 3.4, the clamped-clamped pipe's sequence)."""
    p = _pipe("clamped", "clamped", 0.5)
    r = critical_velocities(p, 0.0, (0.0, float(p.velocity_from_flow_number(10.0))), modes=12)
    assert r.mechanism == "divergence"
    assert r.u_cr == pytest.approx(2 * math.pi, rel=2e-5)
    bounds = [c for c in r.crossings if c.boundary]
    assert [(c.kind, c.direction) for c in bounds] == [
        ("divergence", "loss"),
        ("divergence", "gain"),
        ("flutter", "loss"),
    ]
    assert bounds[1].flow_number == pytest.approx(8.987, abs=2e-3)
    assert bounds[2].flow_number == pytest.approx(9.295, abs=2e-3)
    assert bounds[2].dimensionless_frequency > 10
    _check_against_spectrum(p, r)


def test_cantilever_flutters() -> None:
    """The cantilever keeps its flutter (beta = 0.2: u_cr ~ 5.6, Gregory & Paidoussis 1966;
    5.59157 at 12 modes, the value before this change) and names it."""
    p = _pipe("clamped", "free", 0.2)
    r = critical_velocities(p, 0.0, (0.0, float(p.velocity_from_flow_number(8.0))), modes=12)
    assert r.mechanism == "flutter"
    assert r.u_cr == pytest.approx(5.59157, abs=1e-4)
    _check_against_spectrum(p, r)


def test_no_critical_velocity_no_mechanism() -> None:
    p = _pipe("clamped", "free", 0.2)
    r = critical_velocities(p, 0.0, (0.0, float(p.velocity_from_flow_number(3.0))), modes=8)
    assert r.critical_velocity is None and r.mechanism is None


def test_maps_and_argand_name_divergence_restabilisation_and_flutter() -> None:
    """The spin map (its w0 = 0 line) and the Argand sweep classify each change of stability
    of the clamped-clamped pipe (beta = 0.5, 12 modes) as the critical velocity does:
    divergence loss at 2 pi, divergence gain at 8.987, flutter loss at 9.295.  Before, both
    read the eigenvalue at the crossing itself, where a divergence's pair meeting at 0 keeps
    a rounding omega, and called all three flutter."""
    from pipeflow.stability.maps import spin_map
    from pipeflow.stability.sweeps import sweep

    p = _pipe("clamped", "clamped", 0.5)
    vmax = float(p.velocity_from_flow_number(10.0))
    expected = [("divergence", "loss"), ("divergence", "gain"), ("flutter", "loss")]
    m = spin_map(p, (0.0, vmax), (0.0, 1.0), modes=12, velocity_points=200, spin_points=2)
    assert [(c.kind, c.direction) for c in m.crossings[0]] == expected
    s = sweep(p, "velocity", (0.0, vmax), modes=12, tracked=3, points=201)
    assert [(c.kind, c.direction) for c in s.boundary] == expected
    u = [float(p.flow_number(c.value)) for c in s.boundary]
    assert u == pytest.approx([6.2832, 8.987, 9.2948], abs=2e-3)
