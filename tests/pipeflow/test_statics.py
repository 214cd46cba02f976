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

from pipeflow.model import Pipe
from pipeflow.paper import PAPER_PIPE as P
from pipeflow.statics import static_deflection
from pipeflow.supports import Support, Supports
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


# -- any end supports (issue 31: the residual flexibility of every pipe) ---------------------

_PIN, _CLAMP, _SLIDE = Support("pinned"), Support("clamped"), Support("sliding")
_EI, _L = 3.0, 2.0


def _pipe(x0: Support, xL: Support, **kw: object) -> Pipe:
    return Pipe(E=2.0, I=1.5, L=_L, M1=0.5, M2=0.5, supports=Supports(x0, xL), **kw)  # type: ignore[arg-type]


@pytest.mark.parametrize(
    ("x0", "xL", "at", "where", "expected"),
    [
        # Roark table 8.1: simply supported, centre load: F L^3 / 48 EI
        (_PIN, _PIN, 1.0, 1.0, _L**3 / (48 * _EI)),
        # both ends fixed, centre load: F L^3 / 192 EI
        (_CLAMP, _CLAMP, 1.0, 1.0, _L**3 / (192 * _EI)),
        # fixed-simply supported (propped cantilever), centre load, under it: 7 F L^3 / 768 EI
        (_CLAMP, _PIN, 1.0, 1.0, 7 * _L**3 / (768 * _EI)),
        # fixed-guided (slope held, free to translate), end load: F L^3 / 12 EI
        (_CLAMP, _SLIDE, _L, _L, _L**3 / (12 * _EI)),
        # a cantilever on a tip spring k = 5 N/m, tip load: F / (k + 3 EI / L^3)
        (_CLAMP, Support("elastic", translational=5.0), _L, _L, 1.0 / (5.0 + 3 * _EI / _L**3)),
        # a load on a support that holds the deflection is its reaction
        (_CLAMP, _PIN, _L, 1.0, 0.0),
    ],
)
def test_supported_beams_match_roark(
    x0: Support, xL: Support, at: float, where: float, expected: float
) -> None:
    """The collocation with any end supports reproduces the beam formulas to rounding
    (measured <= 4e-16 relative; tolerance 1e-12)."""
    u = static_deflection(_pipe(x0, xL), 0.0, 0.0, [where], force_at=at)[0]
    assert u == pytest.approx(expected, rel=1e-12, abs=1e-15)


def test_axial_loads_and_the_supports_acceleration() -> None:
    """A pinned-pinned beam under tension T with a centre load deflects
    F / (2T) (L/2 - tanh(kL/2) / k), k = sqrt(T/EI) (Timoshenko & Gere, *Theory of Elastic
    Stability*, beam-columns); the flow's M2 v^2 compresses it exactly as a tension -M2 v^2
    (the same term); an acceleration of the supports is the load -m per unit length:
    5 q L^4 / 384 EI at midspan (Roark).  Tolerance 1e-12."""
    T = 4.0
    k = float(np.sqrt(T / _EI))
    beam_column = 1.0 / (2 * T) * (_L / 2 - np.tanh(k * _L / 2) / k)
    got = static_deflection(_pipe(_PIN, _PIN, tension=T), 0.0, 0.0, [1.0], force_at=1.0)[0]
    assert got == pytest.approx(beam_column, rel=1e-12)
    flow = static_deflection(_pipe(_PIN, _PIN), 1.0, 0.0, [1.0], force_at=1.0)[0]
    compressed = static_deflection(_pipe(_PIN, _PIN, tension=-0.5), 0.0, 0.0, [1.0], force_at=1.0)
    assert flow == pytest.approx(compressed[0], rel=1e-12)
    shaken = static_deflection(_pipe(_PIN, _PIN), 0.0, 0.0, [1.0], force_at=None)[0]
    assert shaken == pytest.approx(-5 * 1.0 * _L**4 / (384 * _EI), rel=1e-12)


def test_intermediate_supports() -> None:
    """Two equal spans (a pin at midspan of a pinned-pinned beam), a load at the centre of
    one span: 23 F l^3 / 1536 EI under it, l = L/2 (AISC *Steel Construction Manual*, beam
    diagrams, case 30); a midspan spring k under a centre load: F / (k + 48 EI / L^3)
    (springs in series); a load on a pin is its reaction (0); a spring as stiff as the
    model's rigid threshold is that pin.  Tolerance 1e-12."""
    from pipeflow.supports import PointSupport

    pin = (PointSupport(1.0, pinned=True),)
    l = _L / 2
    two = static_deflection(_pipe(_PIN, _PIN, intermediate_supports=pin), 0.0, 0.0, [0.5],
                            force_at=0.5)[0]  # fmt: skip
    assert two == pytest.approx(23 * l**3 / (1536 * _EI), rel=1e-12)
    k = 7.0
    sprung = _pipe(_PIN, _PIN, intermediate_supports=(PointSupport(1.0, translational=k),))
    got = static_deflection(sprung, 0.0, 0.0, [1.0], force_at=1.0)[0]
    assert got == pytest.approx(1.0 / (k + 48 * _EI / _L**3), rel=1e-12)
    on_pin = static_deflection(_pipe(_PIN, _PIN, intermediate_supports=pin), 0.0, 0.0,
                               [1.0, 0.5], force_at=1.0)  # fmt: skip
    assert np.array_equal(on_pin, [0.0, 0.0])
    rigid = (PointSupport(1.0, translational=1e12 * _EI / _L**3),)
    same = static_deflection(_pipe(_PIN, _PIN, intermediate_supports=rigid), 0.0, 0.0, [0.5],
                             force_at=0.5)[0]  # fmt: skip
    assert same == pytest.approx(two, rel=1e-12)


def test_a_rigid_rotation_is_not_covered() -> None:
    from pipeflow.statics import statics_cover

    free = _pipe(_PIN, Support("free"))  # a rigid rotation: singular
    assert not statics_cover(free) and statics_cover(_pipe(_PIN, _PIN))
    assert np.isnan(static_deflection(free, 0.0, 0.0, [_L], force_at=_L)).all()
