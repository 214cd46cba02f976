"""A pipe already unstable at rest (issue 34, safety item 1): the paper's pipe spinning at
1000 rad/s diverges at v = 0, regains stability at v = 17.51 m/s (the divergence ends) and
loses it again by flutter at 34.31 m/s.  Every analysis reports that picture (stable at the
start or not, how it is unstable there, every change of stability and its mechanism, the
stable intervals), checked here against the frozen spectrum itself at chosen velocities
and spins, and against each other."""

from __future__ import annotations

import numpy as np
import pytest

from pipeflow.computations import documents
from pipeflow.computations.registry import summarize_stability
from pipeflow.model import build_model
from pipeflow.paper import PAPER_PIPE
from pipeflow.stability import beta_map, critical_velocities, spin_map, sweep
from pipeflow.stability.core import eigenvalues
from pipeflow.stability.critical import CriticalVelocity

W0 = 1000.0  # [rad/s]
MODEL = build_model(PAPER_PIPE, 10)


def _top(v: float, w0: float = W0) -> complex:
    """The fastest-growing eigenvalue of the frozen spectrum at (v, w0) [1/s]."""
    xi = eigenvalues(MODEL, v, w0)[0]
    return complex(xi[np.argmax(xi.real)])


def _radius(v: float, w0: float = W0) -> float:
    return float(np.max(np.abs(eigenvalues(MODEL, v, w0)[0])))


def test_the_spectrum_itself_unstable_at_rest_stable_between_17_51_and_34_31() -> None:
    """The independent check: eigenvalues at chosen velocities, no crossing search."""
    rest = _top(0.0)
    assert rest.real > 1.0 and abs(rest.imag) < 1e-9 * _radius(0.0)  # a real root: divergence
    for v in (5.0, 17.4):
        assert _top(v).real > 1e-6 * _radius(v), v  # still diverging
    for v in (17.7, 25.0, 34.2):
        assert _top(v).real <= 1e-9 * _radius(v), v  # stable
    above = _top(34.5)
    assert above.real > 1e-6 * _radius(34.5) and above.imag > 1000.0  # flutter


@pytest.fixture(scope="module")
def critical() -> CriticalVelocity:
    return critical_velocities(PAPER_PIPE, W0, (0.0, 60.0), modes=10)


def test_critical_velocities_report_the_instability_at_rest(critical: CriticalVelocity) -> None:
    res = critical
    assert res.stable_at_start is False
    assert res.instability_at_start == ["divergence"]
    [(a, b)] = res.stable_intervals
    assert a == pytest.approx(17.5117, abs=1e-4) and b == pytest.approx(34.3140, abs=1e-4)
    changes = [c for c in res.crossings if c.boundary]
    assert [(c.direction, c.kind) for c in changes] == [
        ("gain", "divergence"),
        ("loss", "flutter"),
    ]
    assert [c.velocity for c in changes] == [a, b]
    # the API's critical_velocity stays the first loss after the regain (documented)
    doc = documents.critical_velocities(res)
    assert doc["instability_at_start"] == ["divergence"] and doc["critical_velocity"] == b
    stable = critical_velocities(PAPER_PIPE, 100.0, (0.0, 60.0), modes=10)
    assert stable.stable_at_start and stable.instability_at_start == []


def test_the_spin_map_line_at_1000_rad_s_agrees(critical: CriticalVelocity) -> None:
    m = spin_map(PAPER_PIPE, (0.0, 60.0), (0.0, 1000.0), modes=10, velocity_points=121,
                 spin_points=5)  # fmt: skip
    doc = documents.spin_map(m)
    assert doc["spins"][-1] == W0 and doc["spins"][0] == 0.0
    assert doc["stable_at_start"][0] and doc["instability_at_start"][0] == []
    assert not doc["stable_at_start"][-1] and doc["instability_at_start"][-1] == ["divergence"]
    [(a, b)] = doc["stable_intervals"][-1]
    [(ca, cb)] = critical.stable_intervals
    assert a == pytest.approx(ca, rel=1e-8) and b == pytest.approx(cb, rel=1e-8)
    kinds = [(c["direction"], c["kind"]) for c in doc["crossings"][-1]]
    assert kinds == [("gain", "divergence"), ("loss", "flutter")]


def test_the_argand_sweep_reports_the_pipes_stability_not_only_its_tracked_branches(
    critical: CriticalVelocity,
) -> None:
    s = sweep(PAPER_PIPE, "velocity", (0.0, 60.0), fixed=W0, modes=10, tracked=4)
    doc = documents.sweep(s)
    assert doc["stable_at_start"] is False and doc["instability_at_start"] == ["divergence"]
    assert [(c["direction"], c["kind"]) for c in doc["boundary"]] == [
        ("gain", "divergence"),
        ("loss", "flutter"),
    ]
    [(a, b)] = doc["stable_intervals"]
    [(ca, cb)] = critical.stable_intervals
    assert a == pytest.approx(ca, rel=1e-8) and b == pytest.approx(cb, rel=1e-8)


def test_the_campbell_sweep_finds_the_divergence_its_tracked_branches_miss() -> None:
    """At v = 20 m/s a spin past ~1148 rad/s diverges: the pipe's stability is read from
    its whole spectrum (the tracked branches' sigma = 0 crossings miss it)."""
    s = sweep(PAPER_PIPE, "spin", (0.0, 1500.0), fixed=20.0, modes=10, tracked=4)
    doc = documents.sweep(s)
    assert doc["stable_at_start"] is True and doc["instability_at_start"] == []
    [c] = doc["boundary"]
    assert (c["direction"], c["kind"], c["frequency"]) == ("loss", "divergence", 0.0)
    w = c["value"]
    assert 1100.0 < w < 1200.0
    assert doc["stable_intervals"] == [[0.0, w]]
    assert _top(20.0, w * (1 - 1e-6)).real <= 1e-9 * _radius(20.0, w)
    after = _top(20.0, w * (1 + 1e-3))
    assert after.real > 0 and abs(after.imag) < 1e-9 * _radius(20.0, w)


def test_the_beta_map_of_the_same_pipe_in_flow_numbers(critical: CriticalVelocity) -> None:
    p = PAPER_PIPE
    m = beta_map((p.beta, 0.6), (0.0, 15.0), gamma=float(p.spin_number(W0)), modes=10,
                 beta_points=2, u_points=151)  # fmt: skip
    doc = documents.beta_map(m)
    assert doc["stable_at_start"][0] is False
    assert doc["instability_at_start"][0] == ["divergence"]
    [(a, b)] = doc["stable_intervals"][0]
    [(ca, cb)] = critical.stable_intervals
    assert a == pytest.approx(float(p.flow_number(ca)), rel=1e-7)
    assert b == pytest.approx(float(p.flow_number(cb)), rel=1e-7)


def test_a_study_row_has_no_critical_velocity_for_a_pipe_unstable_at_rest(
    critical: CriticalVelocity,
) -> None:
    """A design study's summary row: v_cr is the first loss from the start of the range,
    so a case unstable there has none (the loss at 34.31 m/s after the regain is not a
    critical velocity to average or rank); stable_at_start says why."""
    row = summarize_stability(documents.critical_velocities(critical))
    assert row["stable_at_start"] is False and row["critical_velocity"] is None
    assert row["critical_mode"] is None and row["critical_kind"] is None
    stable = critical_velocities(PAPER_PIPE, 100.0, (0.0, 60.0), modes=10)
    row = summarize_stability(documents.critical_velocities(stable))
    assert row["critical_velocity"] == pytest.approx(27.692, abs=1e-3)
    assert (row["critical_mode"], row["critical_kind"]) == (3, "flutter")
