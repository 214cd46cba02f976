"""Eigenvalue tracking through crossings (not re-sorting)."""

import numpy as np

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
