"""Supports, springs, intermediate supports, tension, pressure and gravity (issue 31).

Every expected number is independent of ``pipeflow.beam_modes``: Blevins' tables, the
textbook (cosh/sinh) characteristic determinant, the divergence condition of supported pipes
(Paidoussis vol. 1, sec. 3.3), Greenhill's column, Paidoussis' published hanging pipe, and
the Chebyshev collocation of ``tests/pipeflow/collocation_supports.py`` (the strong-form PDE
with its boundary conditions, no basis).  Unit pipe: E = I = L = M1 + M2 = 1, so frequencies
are lambda^2 and flow numbers are velocities times sqrt(M2) (tau = t).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest
import scipy.linalg
from scipy.optimize import brentq

from pipeflow.beam_modes import support_basis
from pipeflow.model import Pipe, build_model
from pipeflow.supports import PointSupport, Support, Supports
from tests.pipeflow import collocation_supports as cs

C, P, F, S = Support("clamped"), Support("pinned"), Support("free"), Support("sliding")


def pipe(x0: Support, xL: Support, beta: float = 0.5, **kw: object) -> Pipe:
    return Pipe(E=1.0, I=1.0, L=1.0, M1=1.0 - beta, M2=beta, supports=Supports(x0, xL), **kw)  # type: ignore[arg-type]


def spectrum(p: Pipe, n: int, u: float) -> np.ndarray:
    m = build_model(p, n)
    v = float(p.velocity_from_flow_number(u)) if u else 0.0
    return np.asarray(np.linalg.eigvals(m.frozen_state_matrix(v)))


def omega2(p: Pipe, n: int) -> np.ndarray:
    m = build_model(p, n)
    return np.asarray(scipy.linalg.eigh(m.K_0, m.M, eigvals_only=True))


def relative_errors(galerkin: np.ndarray, ref: np.ndarray) -> np.ndarray:
    """Each reference eigenvalue (|xi| > 1e-2: rigid-body zeros are compared absolutely by
    the collocation only to sqrt(eps)) against the nearest Galerkin one."""
    ref = ref[np.abs(ref) > 1e-2]
    return np.array([np.min(np.abs(galerkin - r)) / abs(r) for r in ref])


# -- natural frequencies at u = 0 ---------------------------------------------------------------
@pytest.mark.parametrize(
    ("x0", "xL", "lam1"),
    [
        (C, C, 4.730040745),  # Blevins 1979, table 8-1
        (P, P, math.pi),
        (C, P, 3.926602312),
        (C, F, 1.875104069),
        (S, P, math.pi / 2),
        (C, S, 2.365020372),
    ],
)
def test_frequencies_at_rest_blevins(x0: Support, xL: Support, lam1: float) -> None:
    """Blevins, *Formulas for Natural Frequency and Mode Shape* (1979), table 8-1 (10 digits
    from the frequency equations cos cosh = 1, tan = tanh, ...): the first elastic
    omega = lambda^2 sqrt(EI/(m L^4)).  The basis is the beams' own eigenfunctions, so any n
    gives them to rounding: 1e-10 relative at n = 1..40; the 40th is checked too."""
    for n in (1 + (x0.kind in "free sliding") + (xL.kind == "free"), 40):
        w2 = np.sort(omega2(pipe(x0, xL), n))
        elastic = w2[w2 > 1e-8]
        assert elastic[0] == pytest.approx(lam1**4, rel=1e-9)
    if (x0.kind, xL.kind) == ("pinned", "pinned"):
        assert np.sqrt(np.sqrt(elastic)) == pytest.approx(math.pi * np.arange(1, 41), rel=1e-11)


def test_general_basis_reproduces_cantilever_modes() -> None:
    """The support basis computed for clamped-free equals the cantilever modes of
    pipeflow.basis (two independent constructions): roots 1e-13, model matrices 1e-11."""
    from pipeflow.basis import cantilever_roots

    b = support_basis(40, ("clamped", 0.0, 0.0), ("free", 0.0, 0.0))
    assert np.max(np.abs(b.lam4**0.25 / np.array(cantilever_roots(40)) - 1)) < 1e-13
    # the bases with rigid-body modes (no model takes them alone: nothing holds the pipe):
    # free-free 0, 0, 4.7300, 7.8532 and sliding-sliding 0, pi, 2 pi (Blevins table 8-1)
    ff = support_basis(4, ("free", 0.0, 0.0), ("free", 0.0, 0.0)).lam4 ** 0.25
    assert ff == pytest.approx([0.0, 0.0, 4.730040745, 7.853204624], abs=1e-9)
    ss = support_basis(3, ("sliding", 0.0, 0.0), ("sliding", 0.0, 0.0)).lam4 ** 0.25
    assert ss == pytest.approx([0.0, math.pi, 2 * math.pi], abs=1e-9)
    # a spring of 1e14 at x = 0 clamps it: same spectrum with flow through another path
    stiff = Support("elastic", translational=1e14, rotational=1e14)
    xi = spectrum(pipe(stiff, F), 12, 3.0)
    ref = spectrum(pipe(C, F), 12, 3.0)
    assert np.max(relative_errors(xi, ref)) < 1e-8


def _textbook_roots(kt: float, kr: float, count: int) -> np.ndarray:
    """Roots of the characteristic determinant of the beam with springs (K_t, K_r) at x = 0
    and a pin at x = 1, written with cosh, sinh, cos, sin (fine for the low modes)."""

    def det(z: float) -> float:
        ch, sh, c, s = math.cosh(z), math.sinh(z), math.cos(z), math.sin(z)
        d0 = [1.0, 0.0, 1.0, 0.0]
        d1 = [0.0, z, 0.0, z]
        d2 = [z * z, 0.0, -z * z, 0.0]
        d3 = [0.0, z**3, 0.0, -(z**3)]
        rows = [
            [d2[i] - kr * d1[i] for i in range(4)],  # w''(0) = K_r w'(0)
            [d3[i] + kt * d0[i] for i in range(4)],  # w'''(0) = -K_t w(0)
            [ch, sh, c, s],  # w(1) = 0
            [z * z * ch, z * z * sh, -z * z * c, -z * z * s],  # w''(1) = 0
        ]
        return float(np.linalg.det(np.array(rows)))

    grid = np.linspace(0.05, 4 * count + 4, 4000)
    vals = [det(z) for z in grid]
    roots = [
        brentq(det, a, b, xtol=1e-14)
        for a, b, fa, fb in zip(grid[:-1], grid[1:], vals[:-1], vals[1:], strict=True)
        if fa * fb < 0
    ]
    return np.array(roots[:count])


@pytest.mark.parametrize(("kt", "kr"), [(10.0, 0.0), (50.0, 5.0), (0.0, 20.0), (1e3, 1e2)])
def test_springs_against_characteristic_determinant(kt: float, kr: float) -> None:
    """Elastic end (K_t = k_t L^3/EI, K_r = k_r L/EI) against the pin: the first three
    lambda against the textbook determinant, 1e-9 relative (its roots are refined to 1e-14;
    cosh z stays below 1e6 for these modes)."""
    p = pipe(Support("elastic", translational=kt, rotational=kr), P)
    lam = np.sort(omega2(p, 10))[:3] ** 0.25
    assert lam == pytest.approx(_textbook_roots(kt, kr, 3), rel=1e-9)


def test_springs_recover_the_limits() -> None:
    """Springs -> infinity give the clamped (rotational and translational) or pinned
    (translational) end, springs -> 0 the free end: lambda_1 to 1e-5 relative at
    K = 1e8 (the error is O(1/K) times lambda^3) and to the rigid-body zero at K = 1e-10."""
    hard = Support("elastic", translational=1e8, rotational=1e8)
    assert np.sort(omega2(pipe(hard, P), 10))[0] ** 0.25 == pytest.approx(3.926602312, rel=1e-5)
    pin = Support("elastic", translational=1e8)
    assert np.sort(omega2(pipe(pin, P), 10))[0] ** 0.25 == pytest.approx(math.pi, rel=1e-5)
    soft = Support("elastic", translational=1e-10)
    w2 = np.sort(omega2(pipe(soft, F), 10))
    assert w2[0] < 1e-9 and w2[1] < 1e-9
    assert w2[2] ** 0.25 == pytest.approx(4.730040745, rel=1e-9)


# -- divergence of supported pipes ------------------------------------------------------------
def _divergence_u(p: Pipe, n: int, lo: float, hi: float) -> float:
    """The flow number at which the lowest eigenvalue of K_0 + v^2 K_v2 reaches zero."""
    m = build_model(p, n)

    def low(u: float) -> float:
        v = float(p.velocity_from_flow_number(u))
        K = m.K_0 + v * v * m.K_v2
        return float(np.min(np.linalg.eigvals(np.linalg.solve(m.M, K)).real))

    return float(brentq(low, lo, hi, xtol=1e-12))


@pytest.mark.parametrize("beta", [0.1, 0.5, 0.9])
@pytest.mark.parametrize(
    ("x0", "xL", "u_cr"),
    [(P, P, math.pi), (C, C, 2 * math.pi), (C, P, 4.493409458), (S, P, math.pi / 2)],
)
def test_divergence_independent_of_beta(beta: float, x0: Support, xL: Support, u_cr: float) -> None:
    """Paidoussis vol. 1 (2014), sec. 3.3: a pipe with conservative supports diverges where
    u^2 equals the Euler buckling load, whatever beta: pinned-pinned pi, clamped-clamped 2 pi,
    clamped-pinned 4.4934 (tan z = z), sliding-pinned pi/2.  Measured relative error at
    10 / 20 / 30 / 40 modes: CC 1.9e-5 / 7.0e-7 / 9.8e-8 / 2.4e-8, CP 2.2e-6 / 8.5e-8 /
    1.2e-8 / 3.0e-9, PP and SP rounding (their basis is the buckling mode); asserted at 30
    modes: 1e-6 relative.  Just past it a real positive eigenvalue appears."""
    p = pipe(x0, xL, beta)
    u = _divergence_u(p, 30, 0.8 * u_cr, 1.2 * u_cr)
    assert u == pytest.approx(u_cr, rel=1e-6)
    xi = spectrum(p, 30, 1.01 * u_cr)
    top = xi[np.argmax(xi.real)]
    assert top.real > 1e-3 and abs(top.imag) < 1e-8


def test_divergence_shifted_by_pressure_and_tension() -> None:
    """u^2 + Pi (1 - 2 nu delta) - Gamma = pi^2 (pinned-pinned, axially restrained, nu = 0.3:
    Pi (1 - 0.6)); Pi = p A L^2/EI = 2, Gamma = T L^2/EI = 3: u_cr = sqrt(pi^2 - 0.8 + 3).
    Without axial restraint delta = 0: sqrt(pi^2 - 2 + 3)."""
    p = pipe(P, P, 0.3, tension=3.0, pressure=2.0, flow_area=1.0, axially_restrained=True)
    assert _divergence_u(p, 30, 2.0, 5.0) == pytest.approx(math.sqrt(math.pi**2 + 2.2), rel=2e-6)
    p = pipe(P, P, 0.3, tension=3.0, pressure=4.0, flow_area=0.5)
    assert _divergence_u(p, 30, 2.0, 5.0) == pytest.approx(math.sqrt(math.pi**2 + 1.0), rel=2e-6)


def test_compression_buckles_the_pipe_at_rest() -> None:
    """Gamma = -1.2 pi^2 on a pinned-pinned pipe: buckled without flow.  The spectrum has a
    real positive eigenvalue sqrt(0.2) pi^2 (omega^2 = pi^4 + Gamma pi^2 < 0; the basis is
    the buckling mode, so 1e-10) and the natural frequency reports 0, no error."""
    p = pipe(P, P, 0.2, tension=-1.2 * math.pi**2)
    xi = spectrum(p, 10, 0.0)
    assert np.max(xi.real) == pytest.approx(math.sqrt(0.2) * math.pi**2, rel=1e-10)
    assert build_model(p, 10).natural_frequencies()[0] == 0.0


def test_pressure_cancels_at_a_free_discharging_end() -> None:
    """Paidoussis vol. 1, sec. 3.2.2: for the cantilever discharging to atmosphere the
    pressurisation term and the outlet's reaction cancel, so a pressure changes nothing
    (identical matrices); on a pinned-pinned pipe the same pressure lowers the frequency."""
    a = build_model(pipe(C, F, 0.3), 8)
    b = build_model(pipe(C, F, 0.3, pressure=5e5, flow_area=1.0), 8)
    assert np.array_equal(a.K_0, b.K_0) and np.array_equal(a.S_0, b.S_0)
    lo = build_model(pipe(P, P, 0.3, pressure=2.0, flow_area=1.0), 8).natural_frequencies()[0]
    assert lo == pytest.approx(math.pi * math.sqrt(math.pi**2 - 2.0), rel=1e-10)


# -- with flow: the continuous problem by collocation -----------------------------------------
@pytest.mark.parametrize(
    ("x0", "xL", "tol"),
    [
        (C, C, 1e-7),
        (P, P, 1e-7),
        (C, P, 1e-7),
        (C, F, 1e-6),
        (P, F, 5e-5),
        (
            Support("elastic", translational=50.0, rotational=5.0),
            Support("elastic", translational=200.0),
            1e-6,
        ),
    ],
)
def test_flow_against_collocation(x0: Support, xL: Support, tol: float) -> None:
    """u = 2, beta = 0.3: the lowest three eigenvalues against the collocation (32 points;
    it moves by < 1e-8 from 28 to 36 points for these).  Measured at 40 modes: 5.3e-10 (CC),
    3.1e-9 (PP), 2.1e-9 (CP), 1.3e-8 (CF), 7.8e-8 (springs: the strong-form flow term meets
    an end that moves, slow past 20 modes; docs/model.md 9).  Tolerance: about ten times the
    measured (the collocation's own error is ~1e-9).
    Pinned-free has a neutral rigid rotation (lambda = 0 exactly, with flow too): the
    collocation's double zero root splits to +-1e-4 and moves its real eigenvalue -3.3448 by
    2.5e-5 between 24 and 32 points (Galerkin -3.344867 at 20 and 40 modes, the 24-point
    collocation -3.344867): tolerance 5e-5 there."""
    ends = [(s.kind, s.translational, s.rotational) for s in (x0, xL)]
    ref = cs.lowest(cs.eigenvalues(ends[0], ends[1], 2.0, 0.3, N=32), 3)
    assert np.max(relative_errors(spectrum(pipe(x0, xL, 0.3), 40, 2.0), ref)) < tol


@pytest.mark.parametrize(
    ("xs", "K", "tol10", "tol40"),
    [
        (0.5, math.inf, 2e-5, 6e-8),  # measured 6.1e-6, 1.7e-8
        (0.37, math.inf, 3e-5, 3e-8),  # 1.1e-5, 8.4e-9
        (0.5, 100.0, 8e-6, 2e-7),  # 2.4e-6, 5.6e-8 (the collocation's own error)
        (0.3, 1e3, 8e-6, 1e-7),  # 2.8e-6, 3.2e-8
    ],
)
def test_intermediate_supports_with_flow_against_collocation(
    xs: float, K: float, tol10: float, tol40: float
) -> None:
    """u = 2, beta = 0.3, pinned-pinned with a pin or a spring K = k L^3 / EI at xs: the
    lowest three eigenvalues against a two-subdomain Chebyshev collocation of the strong
    form (tests/pipeflow/collocation_supports.py, eigenvalues_spans: 32 points a span, its
    own error ~1e-9 with a pin, ~5e-8 with a spring: 24 against 32 points).  Measured with
    the spans' eigenfunctions at 10 / 40 modes in the comments; the Ritz basis before:
    2.1e-4 / 1.3e-5, 4.4e-4 / 2.5e-5, 2.2e-5 / 1.2e-6, 1.6e-4 / 8.9e-6.  Tolerances about
    three times the measured."""
    ref = cs.lowest(cs.eigenvalues_spans(("pinned", 0, 0), ("pinned", 0, 0), xs, K, 2.0, 0.3), 3)
    point = PointSupport(xs, pinned=True) if math.isinf(K) else PointSupport(xs, translational=K)
    for n, tol in ((10, tol10), (40, tol40)):
        galerkin = spectrum(pipe(P, P, 0.3, intermediate_supports=(point,)), n, 2.0)
        assert np.max(relative_errors(galerkin, ref)) < tol, (n, xs, K)


@pytest.mark.parametrize("gx", [10.0, -5.0])
def test_gravity_against_collocation(gx: float) -> None:
    """Hanging (g_x = +10) and standing (-5) cantilever at u = 4, beta = 0.3 against the
    collocation of the variable-coefficient equation (32 points).  Measured at 40 modes:
    3.8e-7 and 3.0e-7 (the cantilever modes meet N' at the tip only weakly; about n^-3)."""
    ref = cs.lowest(cs.eigenvalues(("clamped", 0, 0), ("free", 0, 0), 4.0, 0.3, (0.0, gx), 32), 3)
    assert np.max(relative_errors(spectrum(pipe(C, F, 0.3, gravity=gx), 40, 4.0), ref)) < 1.5e-6


def test_tension_pressure_gravity_supported_against_collocation() -> None:
    """Everything on a clamped-pinned, axially restrained pipe: T = 3, p A = 2, nu = 0.3,
    hanging gamma = 4 (restrained: N - mean N), u = 2, beta = 0.2; 40 modes, measured 5e-9."""
    p = pipe(
        C, P, 0.2, tension=3.0, pressure=2.0, flow_area=1.0, gravity=4.0, axially_restrained=True
    )
    # N(xi) = 3 - 2 (1 - 0.6) + 4 (1 - xi) - 4 / 2
    ref = cs.lowest(
        cs.eigenvalues(("clamped", 0, 0), ("pinned", 0, 0), 2.0, 0.2, (3.0 - 0.8 - 2.0, 4.0), 32), 3
    )
    assert np.max(relative_errors(spectrum(p, 40, 2.0), ref)) < 1e-7


# -- gravity: Greenhill and Paidoussis ------------------------------------------------------------
def test_greenhill_standing_column() -> None:
    """Greenhill (1881): a standing cantilever buckles under its own weight at
    gamma = (m + M) g L^3/EI = 7.8373 (7.83735 to 6 digits).  Measured: 7.837471 (6 modes),
    7.837358 (10), 7.8373478 (20), 7.83734745 (40); asserted at 20 modes to 1e-5."""

    def low(gamma: float) -> float:
        return float(np.min(omega2(pipe(C, F, 0.3, gravity=-gamma), 20)))

    assert brentq(low, 5.0, 10.0, xtol=1e-12) == pytest.approx(7.83735, abs=1e-4)


def _flutter_u(p: Pipe, n: int, lo: float, hi: float) -> float:
    def growth(u: float) -> float:
        return float(np.max(spectrum(p, n, u).real))

    while hi - lo > 1e-9:
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if growth(mid) <= 1e-9 else (lo, mid)
    return 0.5 * (lo + hi)


def test_hanging_cantilever_paidoussis() -> None:
    """Paidoussis vol. 1 (1998), sec. 3.5.3, p. 118 (Paidoussis & Issid 1974): beta = 0.65,
    hanging, gamma = 10, undamped: flutter at u_cf = 12.88 (4 digits: tolerance 0.02).
    Measured 12.8986 / 12.8826 / 12.8805 / 12.8798 at 8 / 12 / 16 / 24 modes.  Gravity
    stabilises the hanging pipe and destabilises the standing one (beta = 0.2: 5.59 without,
    5.96 hanging, 5.23 standing at gamma = 5; Gregory & Paidoussis 1966's trend)."""
    p = pipe(C, F, 0.65, gravity=10.0)
    assert abs(_flutter_u(p, 12, 10.0, 14.0) - 12.88) < 0.02
    bare = _flutter_u(pipe(C, F, 0.2), 12, 4.0, 7.0)
    assert _flutter_u(pipe(C, F, 0.2, gravity=5.0), 12, 4.0, 7.0) > bare + 0.3
    assert _flutter_u(pipe(C, F, 0.2, gravity=-5.0), 12, 4.0, 7.0) < bare - 0.3


# -- intermediate supports ---------------------------------------------------------------------
def test_midspan_pin_two_equal_spans() -> None:
    """A pin at midspan of a pinned-pinned pipe: two equal spans.  Blevins table 8-1 for the
    halves: antisymmetric mode lambda = 2 pi (pinned-pinned span L/2), symmetric
    2 x 3.9266023120 (clamped-pinned span L/2: tan x = tanh x); divergence at u = 2 pi
    (Paidoussis sec. 3.3 on the span).  The basis is the two-span beam's own eigenfunctions,
    so these are exact at any number of modes: measured <= 5e-13 at 5, 10, 20 and 40 (the
    Ritz basis before: the symmetric mode off by 1.1e-4 at 10 modes, 6.8e-6 at 40);
    tolerance 1e-11 at 5 and 10 modes."""
    p = Pipe(E=1.0, I=1.0, L=1.0, M1=0.5, M2=0.5, supports=Supports(P, P),
             intermediate_supports=(PointSupport(0.5, pinned=True),))  # fmt: skip
    for n in (5, 10):
        lam = np.sort(omega2(p, n))[:2] ** 0.25
        assert lam[0] == pytest.approx(2 * math.pi, rel=1e-11)
        assert lam[1] == pytest.approx(2 * 3.9266023120479220, rel=1e-11)
        assert _divergence_u(p, n, 5.0, 7.0) == pytest.approx(2 * math.pi, rel=1e-11)
    # every basis function vanishes at the pin
    assert np.max(np.abs(build_model(p, 40).shapes(np.array([0.5])))) < 1e-12


def test_midspan_spring_against_its_characteristic_equation() -> None:
    """A point spring K = k L^3 / EI = 100 at midspan of a pinned-pinned pipe.  Its
    symmetric modes are those of the half span pinned at 0 with w' = 0 and
    EI w''' = (k / 2) w at L/2 (the spring's force shared by the halves): with
    w = A sin(lambda x) + B sinh(lambda x), 2 lambda^3 cos(h) cosh(h) = (K / 2)
    (cos(h) sinh(h) - cosh(h) sin(h)), h = lambda / 2 (the half span's end conditions, by
    symmetry); the antisymmetric ones do not move the spring: 2 pi.  Exact at any number
    of modes: measured 2e-16 at 10 and 30 (the Ritz basis before: 9.4e-6 at 10 modes,
    1.0e-6 at 30); tolerance 1e-12."""
    K = 100.0

    def symmetric(lam: float) -> float:
        h = 0.5 * lam
        c, s, ch, sh = math.cos(h), math.sin(h), math.cosh(h), math.sinh(h)
        return 2 * lam**3 * c * ch - 0.5 * K * (c * sh - ch * s)

    exact = brentq(symmetric, 2.0, 5.0, xtol=1e-15)
    p = Pipe(E=1.0, I=1.0, L=1.0, M1=0.5, M2=0.5, supports=Supports(P, P),
             intermediate_supports=(PointSupport(0.5, translational=K),))  # fmt: skip
    for n in (10, 30):
        lam = np.sort(omega2(p, n))[:2] ** 0.25
        assert lam == pytest.approx([exact, 2 * math.pi], rel=1e-12)


def test_the_basis_of_many_unequal_spans() -> None:
    """Seven pins (one 0.01 L span among them) and a stiff spring on a clamped-free pipe,
    40 functions: orthonormal to 1e-12 and with the diagonal bending matrix (springs
    included) to 5e-10 of its largest entry, zero at every pin, w' and w'' continuous
    across every support (the third derivative jumps: the shear the support takes), and
    each lambda_j^4 at or below the value of the Ritz basis (an upper bound:
    Rayleigh-Ritz).  Also when the scan of det B(lambda) misses roots (its step made 2 on
    purpose): the finer scan finds them; where that too is made coarse, the Ritz basis is
    the answer."""
    from pipeflow import beam_modes

    pins = (0.1, 0.23, 0.4, 0.41, 0.6, 0.77, 0.9)
    points = (*((x, math.inf) for x in pins), (0.95, 1e3))
    C_, F_ = ("clamped", 0.0, 0.0), ("free", 0.0, 0.0)
    b = support_basis(40, C_, F_, points)
    assert isinstance(b, beam_modes.SpanBasis)
    xi, w = b.quadrature(200)
    p0, p2 = b.shapes(xi, 0), b.shapes(xi, 2)
    spring = b.shapes(np.array([0.95]))[:, 0]
    bending = (p2 * w) @ p2.T + 1e3 * np.outer(spring, spring)
    assert np.max(np.abs((p0 * w) @ p0.T - np.eye(40))) < 1e-12
    # diagonal to the accuracy of the computed functions' interface conditions (~1e-9
    # where B(lambda) is nearly singular, the 0.01 L span): measured 7e-11 of the largest
    assert np.max(np.abs(bending - np.diag(b.lam4))) < 5e-10 * b.lam4.max()
    assert np.max(np.abs(b.shapes(np.array(pins)))) == 0.0
    for x in (*pins, 0.95):
        for k in (1, 2):
            jump = b.shapes(np.array([x + 1e-13]), k) - b.shapes(np.array([x - 1e-13]), k)
            assert np.max(np.abs(jump)) < 1e-8 * b.lam4.max() ** (k / 4), (x, k)
    step, finer = beam_modes._SCAN_STEP, beam_modes._FINER_SCANS
    beam_modes.support_basis.cache_clear()
    try:
        beam_modes._SCAN_STEP = 2.0
        assert np.allclose(support_basis(40, C_, F_, points).lam4, b.lam4, rtol=1e-13)
        beam_modes.support_basis.cache_clear()
        beam_modes._FINER_SCANS = (2.0,)
        ritz = support_basis(40, C_, F_, points)
        assert isinstance(ritz, beam_modes.SupportBasis)
        assert np.all(b.lam4 <= ritz.lam4 * (1 + 1e-8))
    finally:
        beam_modes._SCAN_STEP, beam_modes._FINER_SCANS = step, finer
        beam_modes.support_basis.cache_clear()


@pytest.mark.parametrize("eps", [1e-3, 1e-4, 2.5e-6])
def test_a_pin_next_to_the_clamp_is_a_rotational_spring(eps: float) -> None:
    """A pin at eps L next to the clamp leaves no rigid-body mode (before, the rank of B(0)
    counted one: natural frequencies [0, 290.8, ...] for a pin at 2.5e-6 L on the paper's
    pipe).  The short clamped-pinned span is a rotational spring 4 EI / (eps L) at the
    root of a cantilever of length (1 - eps) L (statics; its inertia enters at
    (lambda eps)^4 < 1e-11): the exact basis agrees with that cantilever's exact one to
    1e-12 (measured 3e-14)."""
    C_, F_ = ("clamped", 0.0, 0.0), ("free", 0.0, 0.0)
    b = support_basis(6, C_, F_, ((eps, math.inf),))
    rest = 1.0 - eps
    # a translational spring of 1e16 is a pin to rounding
    from pipeflow.beam_modes import end_support_modes

    _, lam4 = end_support_modes(("elastic", 1e16, 4.0 * rest / eps), F_, 6)
    assert b.lam4**0.25 == pytest.approx(lam4**0.25 / rest, rel=1e-12)


def test_two_pins_close_together_leave_no_rigid_mode() -> None:
    """Pins 1e-6 L apart at midspan of a clamped-free pipe act as a clamp there: the first
    frequency tends to the cantilever of length L / 2, lambda_1 = 2 x 1.8751.  The scan of
    det B misses the near-double roots of the two nearly equal halves, so the Ritz basis
    answers: an upper bound, measured 1.2 % above; tolerance 2 %.  Free-free with one pin
    rotates about it: exactly one rigid mode, and the caveat says so."""
    from pipeflow.model import basis_caveats

    C_, F_ = ("clamped", 0.0, 0.0), ("free", 0.0, 0.0)
    lam = support_basis(6, C_, F_, ((0.5, math.inf), (0.5 + 1e-6, math.inf))).lam4 ** 0.25
    assert 2 * 1.8751040687 * (1 - 1e-9) <= lam[0] <= 2 * 1.8751040687 * 1.02
    free = support_basis(6, F_, F_, ((0.5, math.inf),)).lam4
    assert free[0] == 0.0 and np.all(free[1:] > 10.0)
    p = pipe(F, F, intermediate_supports=(PointSupport(0.5, pinned=True),))
    assert p.rotates_rigidly and any("rigid body" in w for w in basis_caveats(p))
    spring = pipe(F, F, intermediate_supports=(PointSupport(0.3, translational=5.0),))
    assert spring.rotates_rigidly and not pipe(C, F).rotates_rigidly


def test_intermediate_spring_limits() -> None:
    """A point spring at midspan: k -> 0 gives the bare pinned-pinned pipe, k large the pin
    (the symmetric mode tends to 2 x 3.9266 like 1/k)."""

    def first_two(k: float) -> np.ndarray:
        p = Pipe(E=1.0, I=1.0, L=1.0, M1=0.5, M2=0.5, supports=Supports(P, P),
                 intermediate_supports=(PointSupport(0.5, translational=k),))  # fmt: skip
        return np.sort(omega2(p, 30))[:2] ** 0.25

    assert first_two(1e-9) == pytest.approx([math.pi, 2 * math.pi], rel=1e-9)
    assert first_two(1e9)[1] == pytest.approx(2 * 3.926602312, rel=1e-4)


@pytest.mark.parametrize("k", [1e10, 1e12, 1e15, 1e18])
def test_a_rigid_intermediate_spring_is_a_pin(k: float) -> None:
    """K = k L^3 / EI >= 1e10 (pipeflow.supports.RIGID_POINT_SPRING) is the pin: before,
    the Ritz eigenproblem diag(lambda^4) + K phi phi^T lost the low eigenvalues to rounding
    (lambda_1 of this pipe off by 7e-5 at K = 1e14 and 58 % at 1e18).  Expected: the
    exact two-span values of test_midspan_pin_two_equal_spans (2 pi exact in this basis;
    2 x 3.9266 exact too, in the two-span basis), tolerance 1e-11."""
    p = Pipe(E=1.0, I=1.0, L=1.0, M1=0.5, M2=0.5, supports=Supports(P, P),
             intermediate_supports=(PointSupport(0.5, translational=k),))  # fmt: skip
    lam = np.sort(omega2(p, 40))[:2] ** 0.25
    assert lam[0] == pytest.approx(2 * math.pi, rel=1e-11)
    assert lam[1] == pytest.approx(2 * 3.9266023120479220, rel=1e-11)


def test_a_stiff_spring_below_the_rigid_threshold_approaches_the_pin() -> None:
    """Just below the threshold the spring is still a spring, already within its 1/K
    physics of the pin: measured 2.5e-8 on the symmetric mode at 30 modes (the antisymmetric
    one does not move the spring: 7e-14); tolerance 1e-7."""

    def first_two(k: float) -> np.ndarray:
        p = Pipe(E=1.0, I=1.0, L=1.0, M1=0.5, M2=0.5, supports=Supports(P, P),
                 intermediate_supports=(PointSupport(0.5, translational=k),))  # fmt: skip
        return np.sort(omega2(p, 30))[:2] ** 0.25

    below, above = first_two(0.99e10), first_two(1e10)
    assert below == pytest.approx(above, rel=1e-7)
    assert above[0] == pytest.approx(2 * math.pi, rel=1e-10)


# -- the default is today's model ----------------------------------------------------------------
def test_default_supports_leave_the_model_unchanged() -> None:
    """Explicit default supports and zero loads: the same arrays, bit for bit."""
    base = Pipe(E=7.8e9, I=1.21e-17, L=0.025, M1=1.884e-5, M2=1.6485e-5)
    same = Pipe(E=7.8e9, I=1.21e-17, L=0.025, M1=1.884e-5, M2=1.6485e-5, supports=Supports(),
                tension=0.0, pressure=0.0, gravity=0.0, poisson=0.3)  # fmt: skip
    a, b = build_model(base, 12), build_model(same, 12)
    for name in ("M", "K_0", "C_v", "K_v2", "K_w2", "S_0", "S_v", "S_v2", "S_w2", "f_wdot"):
        assert np.array_equal(getattr(a, name), getattr(b, name))


@pytest.mark.parametrize(
    ("kw", "field"),
    [
        ({"supports": Supports(C, P), "tip_mass": 1e-3}, "tip_mass"),
        ({"axially_restrained": True}, "axially_restrained"),
        ({"pressure": 1e5}, "flow_area"),
        ({"intermediate_supports": (PointSupport(2.0, pinned=True),)}, "intermediate_supports.0"),
        ({"poisson": 0.7}, "poisson"),
    ],
)
def test_refused_mountings(kw: dict[str, object], field: str) -> None:
    with pytest.raises(ValueError, match=field):
        Pipe(E=1.0, I=1.0, L=1.0, M1=0.5, M2=0.5, **kw)  # type: ignore[arg-type]


def test_a_pipe_nothing_holds_is_refused_and_a_rigid_rotation_is_flagged() -> None:
    """Free-free, sliding-free, sliding-sliding translate freely: refused (naming
    pipe.supports).  Pinned-free rotates freely: accepted, with the basis caveat."""
    from pipeflow.model import basis_caveats

    for x0, xL in ((F, F), (S, F), (S, S)):
        with pytest.raises(ValueError, match=r"pipe\.supports"):
            pipe(x0, xL)
    # springs that hold nothing (0 N/m, or below the basis' SPRING_FLOOR, 1e-12 EI / L^3)
    # leave the pipe as free to translate: refused too (before, accepted, and flagged as
    # "rotating" rigidly while it translated)
    soft = (PointSupport(0.3, 0.0), PointSupport(0.6, 1e-14))
    for x0, xL, points in ((S, F, soft[:1]), (F, F, soft), (Support("elastic", 1e-14), S, ())):
        with pytest.raises(ValueError, match=r"pipe\.supports: nothing holds"):
            pipe(x0, xL, intermediate_supports=points)
    # one real spring is enough: sliding-free on a 1 N/m spring is held (no rigid line)
    assert not pipe(S, F, intermediate_supports=(PointSupport(0.3, 1.0),)).rotates_rigidly
    assert pipe(F, F, intermediate_supports=(PointSupport(0.3, pinned=True),)).rotates_rigidly
    assert any("rigid body" in w for w in basis_caveats(pipe(P, F)))
    assert not basis_caveats(pipe(C, P))


def test_only_the_bare_cantilever_is_the_paper_model() -> None:
    assert pipe(C, F).is_paper_model
    assert not pipe(P, P).is_paper_model
    assert not pipe(C, F, tension=1.0).is_paper_model
    assert not pipe(C, F, gravity=9.81).is_paper_model
    # a pressure on the free discharging cantilever cancels: still the paper's equations
    assert pipe(C, F, pressure=1e5, flow_area=1e-3).is_paper_model


@pytest.mark.parametrize(("x0", "xL"), [(C, P), (P, P), (C, C), (S, P), (C, S)])
def test_held_ends_hold_exactly(x0: Support, xL: Support) -> None:
    """w = 0 at a clamped or pinned end and at a pin, w' = 0 at a clamped or sliding end:
    exactly, not to rounding (the basis' values there were ~1e-15, so a held tip "moved")."""
    p = Pipe(E=1.0, I=1.0, L=1.0, M1=0.5, M2=0.5, supports=Supports(x0, xL),
             intermediate_supports=(PointSupport(0.3, pinned=True),))  # fmt: skip
    m = build_model(p, 12)
    for at, spec in ((0.0, x0), (1.0, xL)):
        w, slope = m.shapes(np.array([at]))[:, 0], m.shapes(np.array([at]), 1)[:, 0]
        assert np.all(w == 0.0) == (spec.kind in ("clamped", "pinned"))
        assert np.all(slope == 0.0) == (spec.kind in ("clamped", "sliding"))
    assert np.all(m.shapes(np.array([0.3]))[:, 0] == 0.0)
    if xL.kind in ("clamped", "pinned"):
        assert np.all(m.tip == 0.0)


def test_material_damping_spares_the_springs() -> None:
    """Kelvin-Voigt damping is the wall material's (E* I w''''' in the equation,
    docs/model.md): it acts on the beam's strain energy, not on the support springs.  A pipe
    pinned at x = 0 on a soft translational spring at x = L (K_t = k L^3 / EI = 1e-2)
    swings as a nearly rigid bar: omega_1^2 = 3 K_t (a bar of unit mass, hinged, on a
    spring: k L^2 / (m L^3 / 3)) to O(K_t), its bending energy a fraction O(K_t) of the total,
    so the decay rate is O(K_t) of alpha omega_1^2 / 2 (the rate had the springs been
    damped too, as before).  Without springs the material damping is unchanged."""
    alpha, kt = 1e-3, 1e-2
    spring = Support("elastic", translational=kt)
    p = pipe(P, spring, kelvin_voigt=alpha)
    lam = spectrum(p, 12, 0.0)
    first = lam[np.argmin(np.abs(lam.imag) + 1e9 * (lam.imag <= 0))]
    assert first.imag**2 == pytest.approx(3 * kt, rel=2 * kt)
    assert -first.real < 1e-2 * alpha * first.imag**2 / 2
    # pinned-pinned: no spring, every mode decays at alpha omega^2 / 2 (modal damping)
    bare = spectrum(pipe(P, P, kelvin_voigt=alpha), 6, 0.0)
    up = bare[bare.imag > 0]
    assert -up.real == pytest.approx(alpha * np.abs(up) ** 2 / 2, rel=1e-9)


def test_the_frequency_response_of_a_pinned_free_pipe_names_its_rigid_rotation() -> None:
    """A pinned-free pipe's state matrix has a double zero eigenvalue with one eigenvector
    (the rigid rotation about the pin): the modal sum cannot represent it, every frequency
    is solved directly, and the warning says why in those words (before: "coalescing
    eigenvalues", the words for flutter onset).  The directly solved receptance is checked
    at a low frequency against the rigid bar: a tip force F on a hinged bar of mass m L
    swings it as u(L) = -F / (W^2 m L / 3) (bending negligible at W << w1)."""
    from pipeflow.frequency import PointForce, frequency_response

    p = pipe(P, F)
    assert p.rotates_rigidly and not pipe(C, F).rotates_rigidly and not pipe(P, P).rotates_rigidly
    W = np.array([0.05, 1.0, 20.0])
    r = frequency_response(
        p, 0.0, 0.0, load=PointForce(1.0), positions=(1.0,), frequencies=W, modes=8
    )
    (why,) = [w for w in r.warnings if w.startswith("the modal sum")]
    assert "rigid rotation about its support" in why and "coalescing" not in why
    H = r.H[0, 0]
    assert H.real == pytest.approx(-1.0 / (W[0] ** 2 * 1.0 / 3.0), rel=1e-4)


@pytest.mark.parametrize(
    ("x0", "xL", "plain_min", "corrected_max"),
    [(P, P, 3e-6, 3e-7), (C, C, 1e-5, 1e-6)],  # measured 7e-6 -> 6.1e-8, 2.8e-5 -> 1.8e-7
)
def test_residual_flexibility_of_supported_pipes(
    x0: Support, xL: Support, plain_min: float, corrected_max: float
) -> None:
    """The static solution now takes any end supports (pipeflow.statics), so supported
    pipes get the FRF's residual flexibility by default (no flow): at 10 modes the
    receptance between x = 0.3 and 0.7 (Kelvin-Voigt 1e-3, W up to 150 rad/s, past the
    second resonance) approaches the converged 40-mode answer ~100x closer, and at W = 0 it
    is the continuous pipe's static deflection (Roark, checked in test_statics.py) to
    rounding (1e-12)."""
    from pipeflow.frequency import PointForce, frequency_response
    from pipeflow.statics import static_deflection

    p = pipe(x0, xL, kelvin_voigt=1e-3)
    W = np.linspace(0.0, 150.0, 301)
    kw: dict[str, Any] = dict(load=PointForce(0.3), positions=[0.3, 0.7], frequencies=W)
    ref = frequency_response(p, 0.0, 0.0, modes=40, **kw).H
    plain = frequency_response(p, 0.0, 0.0, modes=10, residual=False, **kw)
    corrected = frequency_response(p, 0.0, 0.0, modes=10, **kw)
    assert corrected.residual and not plain.residual

    def err(H: np.ndarray) -> float:
        return float(np.max(np.abs(H - ref)) / np.max(np.abs(ref)))

    assert err(plain.H) > plain_min and err(corrected.H) < corrected_max
    static = static_deflection(p, 0.0, 0.0, [0.3, 0.7], force_at=0.3)
    assert np.allclose(corrected.H[:, 0].real, static, rtol=1e-12, atol=0.0)


def test_residual_flexibility_with_a_midspan_pin() -> None:
    """The statics take intermediate supports too: a pinned-pinned pipe with a midspan pin
    (two spans) gets the residual flexibility by default, exact at W = 0 (the two-span
    beam of test_statics.py, 1e-12).  Below the 10th mode, against 40 modes, the two-span
    eigenfunctions converge like the end supports' (n^-3 for a point force, 9.3e-5 at 10
    modes; the Ritz basis before: 1.4e-3) and the static correction removes most of it
    (6.2e-7, measured); asserted: at least 50x better."""
    from pipeflow.frequency import PointForce, frequency_response
    from pipeflow.statics import static_deflection

    p = pipe(P, P, kelvin_voigt=1e-3, intermediate_supports=(PointSupport(0.5, pinned=True),))
    W = np.linspace(0.0, 150.0, 301)
    kw: dict[str, Any] = dict(load=PointForce(0.3), positions=[0.3, 0.7], frequencies=W)
    ref = frequency_response(p, 0.0, 0.0, modes=40, **kw).H
    plain = frequency_response(p, 0.0, 0.0, modes=10, residual=False, **kw).H
    corrected = frequency_response(p, 0.0, 0.0, modes=10, **kw)
    assert corrected.residual

    def err(H: np.ndarray) -> float:
        return float(np.max(np.abs(H - ref)) / np.max(np.abs(ref)))

    assert err(corrected.H) < err(plain) / 50
    static = static_deflection(p, 0.0, 0.0, [0.3, 0.7], force_at=0.3)
    assert np.allclose(corrected.H[:, 0].real, static, rtol=1e-12, atol=0.0)


@pytest.mark.parametrize("at", [0.5, 1.0])
@pytest.mark.parametrize("vectors", [0, 2])
def test_a_force_on_a_held_point_is_taken_by_the_support(at: float, vectors: int) -> None:
    """A force on the midspan pin or at the pinned end does nothing: H is exactly 0 (every
    function vanishes there), the modal answer stands (before, 0 against 0 read as a relative
    difference of inf and every frequency was solved directly, blamed on 'coalescing
    eigenvalues'), and a warning says why the response is zero."""
    from pipeflow.frequency import PointForce, frequency_response

    p = pipe(P, P, intermediate_supports=(PointSupport(0.5, pinned=True),))
    r = frequency_response(p, 1.0, 0.0, load=PointForce(at), positions=[0.3],
                           frequencies=np.geomspace(1.0, 1e3, 40), modes=8,
                           load_vectors=vectors)  # fmt: skip
    assert np.all(r.H == 0.0)
    assert r.diagnostics.method == "modal" and r.diagnostics.max_relative_difference == 0.0
    assert r.warnings == (
        "load: it acts where the pipe is held (a support takes it): it moves nothing "
        "(the response is zero)",
    )


def test_simulate_names_a_load_on_a_held_point() -> None:
    """simulate() with a force on the midspan pin beside one in the span: the held one moves
    nothing (the run equals the run without it to rounding, 1e-13 of the largest
    deflection: its forcing column is zero, only the order of the sums differs) and the
    result names it by its index."""
    from pipeflow.loads import PointForce
    from pipeflow.profiles import Constant, Harmonic
    from pipeflow.simulation import Simulation, simulate

    p = pipe(P, P, intermediate_supports=(PointSupport(0.5, pinned=True),))
    span = PointForce(0.3, Constant(1.0))
    kw: dict[str, Any] = dict(pipe=p, flow=Constant(0.5), u0=0.0, t_end=0.5, samples=51)
    both = simulate(Simulation(loads=(span, PointForce(0.5, Harmonic(0.0, 1.0, 7.0))), **kw))
    alone = simulate(Simulation(loads=(span,), **kw))
    held = [w for w in both.warnings if "where the pipe is held" in w]
    assert held == [
        "loads.1: it acts where the pipe is held (a support takes it): it moves nothing"
    ]
    assert not any("where the pipe is held" in w for w in alone.warnings)
    peak = np.abs(alone.d).max()
    assert peak > 0 and np.abs(both.d - alone.d).max() <= 1e-13 * peak


@pytest.mark.parametrize(
    ("x0", "xL", "points"),
    [
        (("free", 0.0, 0.0), ("free", 0.0, 0.0), ((0.3, math.inf),)),
        (("free", 0.0, 0.0), ("free", 0.0, 0.0), ((0.62, 25.0),)),
        (("elastic", 1e-13, 0.0), ("free", 0.0, 0.0), ((0.5, 7.0),)),
        (("free", 0.0, 0.0), ("free", 0.0, 0.0), ((0.4, 1e-13), (0.8, math.inf))),
    ],
)
def test_rigid_modes_vanish_at_their_supports(
    x0: tuple[str, float, float],
    xL: tuple[str, float, float],
    points: tuple[tuple[float, float], ...],
) -> None:
    """Each rigid-body mode (lambda = 0) of an exact span basis is a line that is zero at
    every support that holds the pipe there (evaluated through the raw span functions, not
    the basis' forced zeros at held stations: a line through the wrong point passes every
    other test) and satisfies the span equations B(0) c = 0, to 1e-12; and the basis is
    orthonormal (a spring below SPRING_FLOOR, 1e-13, is no spring: before, it and the rigid
    line gave the same function twice, NaN coefficients)."""
    from pipeflow import beam_modes

    b = support_basis(6, x0, xL, points)
    assert isinstance(b, beam_modes.SpanBasis)
    x0, xL = beam_modes._clean(x0), beam_modes._clean(xL)
    xi, w = b.quadrature(100)
    p0 = b.shapes(xi, 0)
    assert np.max(np.abs((p0 * w) @ p0.T - np.eye(6))) < 1e-12
    rigid = [m for m in b.modes if m.lam == 0.0]
    assert rigid
    held = [xs for xs, k in points if k >= beam_modes.SPRING_FLOOR]
    held += [
        at
        for at, (kind, kt, _) in ((0.0, x0), (1.0, xL))
        if kind in ("pinned", "clamped") or kt > 0
    ]
    kept = tuple(p for p in points if p[1] >= beam_modes.SPRING_FLOOR)
    for m in rigid:
        assert np.max(np.abs(m.values(np.array(held), 0))) < 1e-12
        B0 = beam_modes._span_matrix(x0, xL, kept, np.zeros(1), (True,) * (len(kept) + 1))[0]
        assert np.max(np.abs(B0 @ np.ravel(m.coef))) < 1e-12
