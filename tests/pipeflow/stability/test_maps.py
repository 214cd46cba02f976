"""Stability maps: critical velocity against spin, and u_cr(beta)."""

from __future__ import annotations

import dataclasses
import math
import traceback

import pytest

from pipeflow.computations import documents
from pipeflow.paper import PAPER_PIPE
from pipeflow.stability import critical_velocities
from pipeflow.stability.core import nondimensional_pipe
from pipeflow.stability.maps import beta_map, spin_map


def test_spin_map_agrees_with_single_line_analysis():
    """Each line of the (w0, v) map gives the same first loss as critical_velocities (both
    to 1e-10 relative by root-finding; compared at 1e-8)."""
    m = spin_map(PAPER_PIPE, (0.0, 50.0), (0.0, 400.0), modes=8, velocity_points=40, spin_points=3)
    for w0, v in zip(m.spins, m.critical_velocity, strict=True):
        one = critical_velocities(PAPER_PIPE, float(w0), (0.0, 50.0), 8, points=41)
        assert v == pytest.approx(one.critical_velocity, rel=1e-8)
    d = documents.spin_map(m)
    assert len(d["growth_rate"]) == 3 and len(d["growth_rate"][0]) == 40
    assert d["stable_intervals"][0][0] == [0.0, pytest.approx(m.critical_velocity[0])]


def test_beta_map_s_shape_and_literature_points():
    """u_cr(beta), gamma = 0, 10 modes: beta = 0.2 -> 5.59 (Gregory & Paidoussis 1966,
    ~5.6); beta = 0.295 has three crossings (loss, gain, loss: the S-shaped segment near
    beta ~ 0.3 of Paidoussis 1998 sec. 3.5), beta = 0.3 one crossing after the jump (8.27)."""
    b = beta_map((0.2, 0.3), (0.0, 12.0), modes=10, beta_points=5, u_points=61)
    # betas 0.2, 0.225, 0.25, 0.275, 0.3
    assert b.u_cr[0] == pytest.approx(5.5917, abs=1e-3)
    assert b.u_cr[-1] == pytest.approx(8.2714, abs=1e-3)
    single = beta_map((0.2949, 0.2951), (0.0, 12.0), beta_points=3, u_points=61)
    mid = single.crossings[1]
    assert [c.direction for c in mid] == ["loss", "gain", "loss"]
    assert [round(c.velocity, 3) for c in mid] == [7.262, 7.852, 8.191]
    d = documents.beta_map(single)
    assert d["multiple_crossings"] and all(len(c) == 2 for c in d["curve"])


def test_beta_map_matches_dimensional_analysis():
    """The non-dimensional map equals the dimensional analysis of a pipe with that beta:
    u = v L sqrt(M2/EI) (physics notes sec. 1)."""
    b = beta_map((0.5, 0.5 + 1e-9), (0.0, 12.0), modes=8, beta_points=1, u_points=61)
    pipe = nondimensional_pipe(0.5)
    one = critical_velocities(pipe, 0.0, (0.0, 12.0 / math.sqrt(0.5)), 8, points=61)
    assert b.u_cr[0] == pytest.approx(one.u_cr, rel=1e-6)


def test_maps_cut_into_pieces_finished_in_reverse_order_equal_the_serial_maps():
    """The fan-out (pipeflow.parallel) does not change a map: on a host of width 3 that
    finishes the pieces last-first, the spin map (reverse-flow range, so v = 0 is
    inserted) and the beta map equal the serial ones bit for bit (tolerance 0: every line
    is computed on its own from the same inputs, only the cut and the order differ), and
    the spin map's points equal single-point eigenvalue calls (to 1e-12 relative: a batch
    of one is assembled along another BLAS path, seen differing by 3e-14)."""
    from pipeflow import parallel
    from pipeflow.model import build_model
    from pipeflow.stability.core import eigenvalues
    from tests.pipeflow.test_parallel import _Reversed

    def maps(progress=None):
        return (
            spin_map(PAPER_PIPE, (-5.0, 50.0), (0.0, 1500.0), modes=6, velocity_points=30,
                     spin_points=11, progress=progress),
            beta_map((0.1, 0.9), modes=5, beta_points=13, u_points=61, progress=progress),
        )  # fmt: skip

    serial = maps()
    seen: list[float] = []
    with parallel.hosting(_Reversed()):
        assert len(parallel.split(11)) > 1
        fanned = maps(seen.append)
    assert documents.spin_map(serial[0]) == documents.spin_map(fanned[0])
    assert documents.beta_map(serial[1]) == documents.beta_map(fanned[1])
    assert seen[-1] == 1.0 and len(seen) > 2
    m = fanned[0]
    model = build_model(PAPER_PIPE, 6)
    for i, k in ((0, 0), (5, 7), (10, 29)):
        one = eigenvalues(model, m.velocities[k], m.spins[i])[0].real.max()
        assert m.growth[i, k] == pytest.approx(one, rel=1e-12)


def test_conservative_divergence_located_on_lambda_squared(monkeypatch: pytest.MonkeyPatch):
    """A supported pipe without damping diverges where a pair +-i omega meets at 0 (sigma
    grows like the square root past the point, flat before it): the map locates it on
    lambda^2, which crosses zero linearly.  Pinned-pinned, u_cd = pi (Paidoussis 1998,
    Vol. 1, sec. 3.3; the Galerkin sine basis has it exactly, any number of modes): measured
    3.5e-15 relative against 8e-12 by the search on sigma (tolerance 1e-13), with 7-12
    spectra per crossing against ~48 (bound 16).  Clamped-pinned: tan(u) = u, u = 4.4934095
    (sec. 3.3), Galerkin truncation 2e-6 at 10 modes (tolerance 1e-5)."""
    from pipeflow.stability import maps
    from pipeflow.supports import Support, Supports

    beta = 0.2
    counted = {"points": 0}
    eigenvalues = maps.eigenvalues

    def counting(model, v, w0):  # type: ignore[no-untyped-def]
        # the spectra of the crossing's search (sign_changes' root: on sigma or lambda^2)
        names = {frame.name for frame in traceback.extract_stack()}
        counted["points"] += bool(names & {"root", "collision_root"})
        return eigenvalues(model, v, w0)

    monkeypatch.setattr(maps, "eigenvalues", counting)
    for ends, exact, tol in (
        (("pinned", "pinned"), math.pi, 1e-13),
        (("clamped", "pinned"), 4.493409457909064, 1e-5),
    ):
        pipe = dataclasses.replace(
            nondimensional_pipe(beta), supports=Supports(Support(ends[0]), Support(ends[1]))
        )
        counted["points"] = 0
        m = spin_map(pipe, (0.0, 20.0), (0.0, 1e-3), modes=10, velocity_points=30, spin_points=2)
        assert [c.kind for c in m.crossings[0]] == ["divergence"]
        v = m.critical_velocity[0]
        assert v is not None and abs(v * math.sqrt(beta) / exact - 1) < tol, (ends, v)
        assert counted["points"] <= 2 * 16, counted  # two lines, one crossing each
