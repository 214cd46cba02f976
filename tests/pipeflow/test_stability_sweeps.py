"""Argand and Campbell sweeps: tracking, confidence, refinement, units."""

from __future__ import annotations

import math

import numpy as np
import pytest

from pipeflow.errors import InvalidInput
from pipeflow.model import PAPER_PIPE, build_model
from pipeflow.spectra import track
from pipeflow.stability.core import nondimensional_pipe, state_matrices
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
    d = coarse.to_dict()
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
    d = s.to_dict()
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
