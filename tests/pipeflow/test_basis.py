"""Cantilever basis: roots, boundary conditions and orthogonality."""

import numpy as np
import pytest

from pipeflow.basis import (
    cantilever_roots,
    default_quadrature_order,
    gauss_legendre_unit,
    mode_shapes,
    paper_scale,
    tip_values,
)


def test_roots_match_rao_table_8_1() -> None:
    """Rao, *Mechanical Vibrations*, Table 8.1: theta_j L for a clamped-free beam.

    The table gives 10-11 significant digits; we agree to all of them (tolerance 5e-10),
    and the roots satisfy cos z cosh z = -1 to rounding of the product.
    """
    published = [1.8751040687, 4.6940911330, 7.8547574382, 10.995540735]
    roots = cantilever_roots(4)
    assert np.allclose(roots, published, rtol=0, atol=5e-10)
    for z in cantilever_roots(40):
        # relative to the size of the terms multiplied (cosh z): rounding level
        assert abs(np.cos(z) * np.cosh(z) + 1.0) <= 1e-15 * np.cosh(z) * 8


def test_high_roots_approach_asymptote() -> None:
    roots = np.asarray(cantilever_roots(40))
    j = np.arange(1, 41)
    assert np.all(np.abs(roots[5:] - (j[5:] - 0.5) * np.pi) < 1e-5)


def test_gram_matrix_orthonormal_at_40_modes() -> None:
    """Issue 2: the Gram matrix stays orthogonal to 1e-12 with 40 modes.

    The textbook cosh/sinh form fails this past ~12 modes (physics notes, section 3).
    """
    n = 40
    x, w = gauss_legendre_unit(default_quadrature_order(n))
    phi = mode_shapes(n, x)
    gram = (phi * w) @ phi.T
    assert np.max(np.abs(gram - np.eye(n))) < 1e-12


def test_stiffness_orthogonality_and_eigen_relation() -> None:
    """phi'''' = lambda^4 phi, and int phi_i'' phi_j'' = lambda^4 delta_ij, at 40 modes."""
    n = 40
    lam = np.asarray(cantilever_roots(n))
    x, w = gauss_legendre_unit(default_quadrature_order(n))
    p2 = mode_shapes(n, x, 2)
    k = (p2 * w) @ p2.T / np.outer(lam**2, lam**2)
    assert np.max(np.abs(k - np.eye(n))) < 1e-12
    p4 = mode_shapes(n, x, 4)
    assert np.max(np.abs(p4 / lam[:, None] ** 4 - mode_shapes(n, x))) < 1e-11


@pytest.mark.parametrize("n", [1, 5, 40])
def test_boundary_conditions(n: int) -> None:
    """u = u' = 0 at the clamp, u'' = u''' = 0 at the free tip (relative to lambda^k)."""
    lam = np.asarray(cantilever_roots(n))
    at0, at1 = np.array([0.0]), np.array([1.0])
    assert np.all(np.abs(mode_shapes(n, at0, 0)) < 1e-12)
    assert np.all(np.abs(mode_shapes(n, at0, 1)[:, 0] / lam) < 1e-12)
    assert np.all(np.abs(mode_shapes(n, at1, 2)[:, 0] / lam**2) < 1e-12)
    assert np.all(np.abs(mode_shapes(n, at1, 3)[:, 0] / lam**3) < 1e-12)
    assert np.allclose(np.abs(mode_shapes(n, at1)[:, 0]), 2.0, atol=1e-12)


def test_paper_shape_scale() -> None:
    """Eq. (3) with z = lambda xi equals paper_scale * our normalised mode (tip 2.7244)."""
    lam = cantilever_roots(3)
    x = np.linspace(0, 1, 11)
    ours = mode_shapes(3, x)
    for j, z in enumerate(lam):
        r = (np.sin(z) + np.sinh(z)) / (np.cos(z) + np.cosh(z))
        zx = z * x
        eq3 = np.sin(zx) - np.sinh(zx) + r * (np.cosh(zx) - np.cos(zx))
        assert np.allclose(eq3, paper_scale(3)[j] * ours[j], atol=1e-12)
    assert abs(paper_scale(1)[0] * 2.0 - 2.7244) < 1e-4


def test_tip_values_alternate() -> None:
    """phi_j(1) = 2 (-1)^(j+1): the closed-form tip value of the unit-norm cantilever mode
    cosh - cos - s_j (sinh - sin), s_j = (cosh + cos)/(sinh + sin) at lambda_j; to 1e-12."""
    j = np.arange(1, 41)
    assert np.allclose(tip_values(40), 2.0 * (-1.0) ** (j + 1), atol=1e-12)
