"""Static deflection of the continuous pipe (pipeflow.statics) against independent results.

- Roark's *Formulas for Stress and Strain* (cantilever with an end or intermediate load,
  uniform load): the bare pipe's deflection is a cubic / quartic, which the collocation
  must reproduce to rounding;
- the strong-form BVP of tests/pipeflow/collocation.py (differentiation matrices, another
  discretisation) at W = 0 with flow, spin, hub and tip mass.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from pipeflow.paper import PAPER_PIPE as P
from pipeflow.statics import static_deflection
from tests.pipeflow.collocation import harmonic_response

L, EI = P.L, P.EI
X = np.linspace(0.0, L, 11)


@pytest.mark.parametrize("a", [1.0, 0.4, 0.05])
def test_point_force_matches_roark(a: float) -> None:
    """u = x^2 (3a - x) / 6EI for x <= a, a^2 (3x - a) / 6EI beyond (Roark table 8.1 case
    1a); measured ~3e-16 relative, tolerance 1e-12 (rounding of a 50-unknown solve)."""
    a *= L
    u = static_deflection(P, 0.0, 0.0, X, force_at=a)
    ex = np.where(X <= a, X**2 * (3 * a - X), a**2 * (3 * X - a)) / (6 * EI)
    assert np.max(np.abs(u - ex)) < 1e-12 * ex.max()


def test_clamp_acceleration_matches_roark() -> None:
    """Uniform load q = -m per unit clamp acceleration: u = q x^2 (6L^2 - 4Lx + x^2) / 24EI
    (Roark case 2a); tolerance 1e-12 as above."""
    u = static_deflection(P, 0.0, 0.0, X, force_at=None)
    ex = -P.mass * X**2 * (6 * L**2 - 4 * L * X + X**2) / (24 * EI)
    assert np.max(np.abs(u - ex)) < 1e-12 * np.abs(ex).max()


@pytest.mark.parametrize(
    ("pipe", "v", "w0"),
    [
        (P, 10.0, 100.0),
        (replace(P, hub_radius=L, tip_mass=2e-7), 5.0, 300.0),
        (replace(P, hub_radius=2 * L, plane="out-of-plane"), 5.0, 500.0),
    ],
)
def test_flow_spin_hub_tip_mass_match_the_bvp(pipe, v: float, w0: float) -> None:
    """Against the collocated BVP at W = 0 (N = 24 points per subdomain, whose powers of
    the differentiation matrix lose ~1e-8: measured agreement 2e-8 .. 1e-7); tolerance 5e-7."""
    for a in (L, 0.4 * L, None):
        u = static_deflection(pipe, v, w0, X[1:], force_at=a)
        ref = harmonic_response(pipe, v, w0, 0.0, X[1:], a).real
        assert np.max(np.abs(u - ref)) < 5e-7 * np.abs(ref).max(), a
