"""Argand and Campbell sweeps: tracking, confidence, refinement, units."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.optimize import brentq

from pipeflow.computations import documents
from pipeflow.errors import InvalidInput
from pipeflow.model import build_model
from pipeflow.paper import PAPER_PIPE
from pipeflow.spectra import track
from pipeflow.stability.core import eigenvalues, growth_rate, nondimensional_pipe, state_matrices
from pipeflow.stability.sweeps import sweep


def test_argand_matches_core_tracker_and_locates_flutter():
    """beta = 0.2: the tracked second branch of the Argand sweep crosses sigma = 0 near
    u = 5.59 (the critical velocity), and on a grid without refinement the sweep equals
    pipeflow.spectra.track on the same matrices (one tracking algorithm, not two)."""
    beta = 0.2
    pipe = nondimensional_pipe(beta)
    vmax = 8.0 / math.sqrt(beta)
    s = sweep(pipe, "velocity", (0.0, vmax), 0.0, modes=8, tracked=3, points=81, min_confidence=0)
    ref = track(state_matrices(build_model(pipe, 8), s.values, 0.0), 3)
    np.testing.assert_allclose(s.xi.real, ref.xi.real)
    np.testing.assert_allclose(s.omega, np.abs(ref.xi.imag))
    assert list(s.mode) == [1, 2, 3]
    k = np.flatnonzero(np.diff(np.sign(s.sigma[1:, 1])) > 0)[0] + 1
    u = s.values[k : k + 2] * math.sqrt(beta)
    assert u[0] <= 5.5917 <= u[1]


def test_refinement_inserts_points_where_confidence_drops():
    """beta = 0.2, 10 modes: the first mode's pair meets the real axis; with
    min_confidence = 0.95 points are inserted there, and every inserted point lies between
    two original ones; units: Hz = rad/s / 2 pi, damping ratio = -sigma/|xi|."""
    beta = 0.2
    pipe = nondimensional_pipe(beta)
    coarse = sweep(pipe, "velocity", (0, 18.0), 0.0, 10, 4, 41, min_confidence=0.95)
    assert coarse.inserted.any() and coarse.values.size > 41
    assert np.all(np.diff(coarse.values) > 0)
    assert coarse.values.size <= 4 * 41
    d = documents.sweep(coarse)
    m = d["modes"][1]
    np.testing.assert_allclose(m["frequency_hz"], np.array(m["omega"]) / (2 * math.pi))
    xi = np.array(m["sigma"]) + 1j * np.array(m["omega"])
    np.testing.assert_allclose(m["damping_ratio"], -xi.real / np.abs(xi))
    assert all(0 <= c <= 1 for c in m["confidence"])
    assert len(d["inserted"]) == len(d["parameter"]["values"])


def test_campbell_diagram_rpm_and_rotating_beam_limit():
    """Campbell sweep at v = 0 (M2 kept): frequencies follow omega_chord^2 = omega_0^2 +
    (projection of the spin terms); at w0 = 0 the first frequency is the cantilever value
    1.8751^2 sqrt(EI/(m L^4)) (Rao Table 8.1), axis also in rpm and Hz, frequency in rpm."""
    s = sweep(PAPER_PIPE, "spin", (0.0, 400.0), 0.0, 8, 3, 31)
    om1 = 1.8751040687**2 * math.sqrt(PAPER_PIPE.EI / (PAPER_PIPE.mass * PAPER_PIPE.L**4))
    assert s.omega[0, 0] == pytest.approx(om1, rel=1e-6)
    d = documents.sweep(s)
    assert d["kind"] == "campbell"
    np.testing.assert_allclose(d["parameter"]["values_rpm"], s.values * 60 / (2 * math.pi))
    np.testing.assert_allclose(d["modes"][0]["frequency_rpm"], s.omega[:, 0] * 60 / (2 * math.pi))
    assert np.all(np.abs(s.sigma) < 1e-9 * np.abs(s.xi).max())  # v = 0: conservative


def test_bad_sweep_input_names_the_field():
    """A decreasing range is refused naming the request field of that sweep kind."""
    for parameter, field in (("velocity", "velocity_range"), ("spin", "spin_range")):
        with pytest.raises(InvalidInput) as exc:
            sweep(PAPER_PIPE, parameter, (1.0, 0.0), modes=3, tracked=2, points=5)
        assert exc.value.parameter == field
    with pytest.raises(InvalidInput) as exc:
        sweep(PAPER_PIPE, "pressure", (0.0, 1.0), modes=3, tracked=2, points=5)  # type: ignore[arg-type]
    assert exc.value.parameter == "parameter"


def _sorted_frequency(model, v: float, w0: float, k: int) -> float:
    """Frequency [rad/s] of mode k of the frozen spectrum at (v, w0) by sorting (no
    tracking): the k-th lowest positive frequency, where the lowest modes that are
    overdamped (a real pair, frequency 0) still count; valid while frequencies stay apart."""
    xi = eigenvalues(model, v, w0)[0]
    real = np.abs(xi.imag) <= 1e-9 * np.max(np.abs(xi))
    idx = k - 1 - int(real.sum()) // 2
    return 0.0 if idx < 0 else float(np.sort(xi.imag[(xi.imag > 0) & ~real])[idx])


def test_campbell_excitation_crossings_match_an_independent_root_search():
    """Paper pipe, v = 10 m/s, w0 in [0, 800] rad/s: mode 1 becomes overdamped (a real pair)
    on the way, the other frequencies stay apart, so sorting identifies the modes.
    Independent computation: scan omega_k(w0) - n w0 of the sorted frozen spectrum on a grid
    of its own (1201 points), then Brent's method.  Same set of crossings (order, mode), each
    spin to 1e-9 relative: both are roots of the same smooth function located to ~1e-12; the
    margin covers eigenvalue rounding (~1e-13 of a spectral radius ~1e5 rad/s)."""
    v, orders, k_max = 10.0, (0.5, 1.0, 2.0, 3.0), 3
    s = sweep(PAPER_PIPE, "spin", (0.0, 800.0), v, modes=10, tracked=k_max, orders=orders)
    model = build_model(PAPER_PIPE, 10)
    grid = np.linspace(0.0, 800.0, 1201)
    expected = []
    for n in orders:
        for k in range(1, k_max + 1):

            def g(w, n=n, k=k):
                return _sorted_frequency(model, v, w, k) - n * w

            vals = np.array([g(w) for w in grid])
            for i in np.flatnonzero(np.sign(vals[:-1]) * np.sign(vals[1:]) < 0):
                expected.append((n, k, brentq(g, grid[i], grid[i + 1], xtol=1e-13, rtol=1e-14)))
    got = [(c.order, c.mode, c.spin) for c in s.excitation]
    assert sorted((n, k) for n, k, _ in got) == sorted((n, k) for n, k, _ in expected)
    assert len(expected) >= 4  # mode 1 meets every line, mode 2 meets 3x
    for n, k, w in expected:
        (mine,) = [c for c in s.excitation if c.order == n and c.mode == k]
        assert mine.spin == pytest.approx(w, rel=1e-9), (n, k)
        assert mine.frequency == pytest.approx(n * w, rel=1e-9)
        xi = eigenvalues(model, v, mine.spin)[0]
        j = np.argmin(np.abs(xi.imag - mine.frequency))
        assert mine.sigma == pytest.approx(xi.real[j], rel=1e-6)
    d = documents.sweep(s)["excitation"]
    assert d["orders"] == list(orders)
    first = d["crossings"][0]
    assert first["spin_rpm"] == pytest.approx(first["spin"] * 60 / (2 * math.pi))


def test_argand_critical_point_is_the_root_of_the_growth_rate():
    """Paper pipe at w0 = 100 rad/s: the first sigma = 0 loss of the tracked branches is the
    root of the largest real part of the whole frozen spectrum (brentq on growth_rate, an
    independent search) to 1e-9 relative, 27.69 m/s (README / critical_velocities)."""
    s = sweep(PAPER_PIPE, "velocity", (0.0, 60.0), 100.0, modes=10, tracked=4)
    first = next(c for c in s.zero_crossings if c.direction == "loss")
    model = build_model(PAPER_PIPE, 10)
    v_cr = brentq(lambda v: float(growth_rate(model, v, 100.0)[0]), 20.0, 35.0, xtol=1e-12)
    assert first.value == pytest.approx(v_cr, rel=1e-9)
    assert first.value == pytest.approx(27.69, abs=0.005)
    assert first.mode == 3 and first.frequency > 0


def test_bad_excitation_orders_name_the_field():
    with pytest.raises(InvalidInput) as e:
        sweep(PAPER_PIPE, "spin", (0.0, 100.0), 1.0, modes=4, tracked=2, orders=(1.0, -2.0))
    assert e.value.parameter == "orders"


def test_campbell_excitation_crossings_at_negative_spin_mirror_positive_spin():
    """The excitation lines are n |w0|: a sweep over w0 in (-200, -1) rad/s finds the
    crossings of (1, 200) at -w0 (reviewer's case, paper pipe at v = 1 m/s: mode 1 meets the
    2 |w0| line at |w0| = 138.47 rad/s, frequency 276.94 rad/s).  Before the fix the lines
    were n w0 < 0 and no crossing was found.  The two sweeps are independent computations
    (the spectrum is even in w0 here); spins agree to 1e-9 relative (both located by
    Brent to CROSSING_RTOL, margin for eigenvalue rounding), and a frozen eigenvalue at the
    crossing has |omega| = 2 |w0| to 1e-9."""
    kw = dict(fixed=1.0, modes=4, tracked=3, points=41, orders=(1.0, 2.0))
    pos = sweep(PAPER_PIPE, "spin", (1.0, 200.0), **kw).excitation  # type: ignore[arg-type]
    neg = sweep(PAPER_PIPE, "spin", (-200.0, -1.0), **kw).excitation  # type: ignore[arg-type]
    assert len(pos) == len(neg) >= 1
    assert pos[0].spin == pytest.approx(138.47, abs=0.005)
    for p, n in zip(pos, sorted(neg, key=lambda c: (c.order, -c.spin)), strict=True):
        assert (n.order, n.mode) == (p.order, p.mode)
        assert n.spin == pytest.approx(-p.spin, rel=1e-9)
        assert n.frequency == pytest.approx(p.frequency, rel=1e-9)
        assert n.frequency == pytest.approx(n.order * abs(n.spin), rel=1e-12)
        xi = eigenvalues(build_model(PAPER_PIPE, 4), 1.0, n.spin)[0]
        assert np.min(np.abs(np.abs(xi.imag) - n.frequency)) < 1e-9 * n.frequency
