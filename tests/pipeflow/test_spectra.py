"""Eigenvalue tracking through crossings (not re-sorting)."""

import numpy as np
import pytest

from pipeflow.spectra import track


def oscillators(w1: np.ndarray, w2: np.ndarray, coupling: float = 0.0) -> np.ndarray:
    """Two oscillators x'' + w^2 x = 0 (optionally stiffness-coupled), state (x1', x2', x1, x2)."""
    mats = []
    for a, b in zip(w1, w2, strict=True):
        K = np.array([[a * a, coupling], [coupling, b * b]])
        mats.append(np.block([[np.zeros((2, 2)), -K], [np.eye(2), np.zeros((2, 2))]]))
    return np.array(mats)


def test_branches_follow_through_a_crossing() -> None:
    """w1 = 1 + p rises through w2 = 2 - p at p = 0.5: sorting would swap them; tracking
    by left/right eigenvector overlap keeps each branch on its own line (exact to 1e-12)."""
    p = np.linspace(0.0, 1.0, 41)
    tr = track(oscillators(1 + p, 2 - p), modes=2)
    assert np.allclose(tr.omega[:, 0], 1 + p, atol=1e-12)
    assert np.allclose(tr.omega[:, 1], 2 - p, atol=1e-12)
    assert np.all(tr.confidence > 0.99)


def test_veering_keeps_continuous_branches() -> None:
    """With coupling the crossing becomes a veering: branches exchange character but each
    stays continuous (no jumps larger than the grid step allows)."""
    p = np.linspace(0.0, 1.0, 201)
    tr = track(oscillators(1 + p, 2 - p, coupling=0.05), modes=2)
    assert np.max(np.abs(np.diff(tr.omega, axis=0))) < 0.05
    assert np.all(tr.omega[:, 0] < tr.omega[:, 1])


def test_lowest_modes_one_per_conjugate_pair() -> None:
    p = np.zeros(3)
    tr = track(oscillators(3 + p, 1 + p), modes=2)
    assert np.allclose(tr.omega[0], [1.0, 3.0])
    assert np.all(tr.sigma == 0)


def test_least_stable_branch_is_traced_even_when_it_is_no_representative() -> None:
    """A pair that meets the real axis and splits: S(p) = [[0, 2], [-k/2, 0]] has roots
    lambda^2 = -k, with k from +1 (oscillation, +-i) to -1 (divergence, +-1), 200 points.
    The representative chosen at p = 0 (the omega > 0 member) follows the decaying root
    -1 after the split here; the traced least-stable branch must be the growing one, whose
    peak sigma is the largest real part of the whole spectrum (1, to 1e-9).  (With only the
    representatives as candidates the flagged branch peaked at sigma = 0.)"""
    from pipeflow.spectra import track

    k = 1.0 - 2.0 * np.linspace(0.0, 1.0, 200)
    S = np.array([[[0.0, 2.0], [-kk / 2.0, 0.0]] for kk in k])
    tr = track(S, modes=1, least_stable=True)
    assert tr.xi[-1, 0].real < 0  # the representative went the stable way
    j = tr.least_stable
    assert j == 1  # so the other member is traced too, as an extra column
    assert abs(tr.sigma[:, j].max() - 1.0) < 1e-9
    assert abs(np.linalg.eigvals(S).real.max() - 1.0) < 1e-9


def _paper_frozen_matrices() -> np.ndarray:
    from pipeflow.loading import Loading
    from pipeflow.model import build_model
    from pipeflow.paper import PAPER_FLOW, PAPER_PIPE, PAPER_SPIN

    model = build_model(PAPER_PIPE, 10)
    times = np.linspace(0.0, 1.0, 201)
    return np.asarray(model.state_matrix(Loading(PAPER_FLOW, PAPER_SPIN).coefficients(times)))


def test_link_by_eigenvalues_equals_the_overlap_assignment(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Identity check of :func:`link` (eigenvalues, vectors only where they cannot decide)
    against :func:`assign` (eigenvector overlaps at every point): the same branches on the
    paper's frozen spectrum (201 times, 20 eigenvalues), a crossing and a veering.  On
    the paper's example no point needs eigenvectors (d1/d2 < 2e-4 there): counted by
    wrapping ``decompose``."""
    from pipeflow import spectra

    cases = {
        "paper": _paper_frozen_matrices(),
        "crossing": oscillators(1 + np.linspace(0, 1, 41), 2 - np.linspace(0, 1, 41)),
        "veering": oscillators(1 + np.linspace(0, 1, 201), 2 - np.linspace(0, 1, 201), 0.05),
    }
    original = spectra.decompose
    calls: list[int] = []

    def counting(M: np.ndarray) -> tuple[np.ndarray, ...]:
        calls.append(M.shape[0])
        return original(M)

    monkeypatch.setattr(spectra, "decompose", counting)
    decomposed: dict[str, int] = {}
    for name, S in cases.items():
        w = np.linalg.eigvals(S)
        calls.clear()
        perm, conf = spectra.link(S, w)
        decomposed[name] = sum(calls)
        we, V, W = original(S)
        ref_perm, _ = spectra.assign(we, V, W)
        xi = np.take_along_axis(w, perm, axis=1)
        ref = np.take_along_axis(we, ref_perm, axis=1)
        # the same branches: eig and eigvals agree to rounding, columns matched at point 0
        cols = spectra.match_branches(ref[0], xi[0])
        np.testing.assert_allclose(xi, ref[:, cols], rtol=0, atol=1e-9 * np.abs(ref).max())
        assert np.all((conf >= 0) & (conf <= 1))
    assert decomposed["paper"] == 0
    assert decomposed["crossing"] > 0  # every step moves 2.5% of the gap: vectors


def test_link_by_eigenvalues_never_swaps_close_branches() -> None:
    """Two branches that pass close to each other within one grid step (the nearest
    eigenvalue of the next point is not 100x nearer than the second nearest) are linked
    by eigenvectors: w1 = 1 + p and w2 = 1.06 - p on 7 points cross between two points,
    and each branch keeps its own line (sorting by eigenvalue distance alone would swap
    them at the crossing step)."""
    from pipeflow.spectra import link

    p = np.linspace(0.0, 0.06, 7)
    S = oscillators(1 + p, 1.06 - p + 0.005)
    w = np.linalg.eigvals(S)
    perm, _ = link(S, w)
    xi = np.take_along_axis(w, perm, axis=1)
    up = np.flatnonzero(xi[0].imag > 0)
    lines = sorted(up, key=lambda j: xi[0, j].imag)
    np.testing.assert_allclose(xi[:, lines[0]].imag, 1 + p, atol=1e-12)
    np.testing.assert_allclose(xi[:, lines[1]].imag, 1.065 - p, atol=1e-12)
