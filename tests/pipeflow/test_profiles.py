"""Time profiles: closed-form derivatives and integrals against numerical quadrature."""

import numpy as np
import pytest
from scipy.integrate import quad

from pipeflow.profiles import Constant, Harmonic, Profile, polynomial, table

PROFILES: list[Profile] = [
    Constant(0.3),
    polynomial(0.1, -0.4, 0.25, 0.05),
    Harmonic(0.2, 0.1, 7.0, 0.3),
    Harmonic(-0.1, 0.3, 0.0, 1.0),
    table([0.0, 0.3, 0.7, 1.2], [0.0, 0.5, 0.1, 0.2], "linear"),
    table([-0.1, 0.3, 0.7, 1.2], [0.0, 0.5, 0.1, 0.2], "cubic"),
    table([0.0, 0.3, 0.7, 1.2], [0.0, 0.5, 0.1, 0.2], "pchip"),
]


@pytest.mark.parametrize("p", PROFILES, ids=lambda p: type(p).__name__)
def test_integrals_match_quadrature(p: Profile) -> None:
    """int_0^t p and int_0^t p^2 agree with adaptive quadrature to 1e-12 (quad's own
    accuracy on these smooth pieces), and the derivative with central differences."""
    for t in (0.0, 0.25, 0.5, 1.1):
        pts = [b for b in (0.3, 0.7) if b < t] or None
        i1 = quad(lambda s: float(p.value(s)), 0, t, points=pts, epsabs=1e-14)[0]
        i2 = quad(lambda s: float(p.value(s)) ** 2, 0, t, points=pts, epsabs=1e-14)[0]
        assert abs(float(p.integral(t)) - i1) < 1e-12
        assert abs(float(p.integral_square(t)) - i2) < 1e-12
    tt = np.array([0.11, 0.52, 0.93])
    h = 1e-6
    fd = (p.value(tt + h) - p.value(tt - h)) / (2 * h)
    assert np.allclose(p.derivative(tt), fd, atol=1e-6)


def test_constant_flags() -> None:
    assert Constant(1.0).is_constant
    assert polynomial(2.0).is_constant
    assert not polynomial(0, 1).is_constant
    assert Harmonic(1.0, 0.0, 3.0).is_constant
    assert not Harmonic(1.0, 0.5, 3.0).is_constant


def test_table_rejects_out_of_range() -> None:
    p = table([0.0, 1.0], [0.0, 1.0])
    with pytest.raises(ValueError, match="defined on"):
        p.value(2.0)
    with pytest.raises(ValueError, match="increasing"):
        table([0.0, 0.0], [1.0, 1.0])
    with pytest.raises(ValueError, match="start"):
        table([0.5, 1.0], [1.0, 1.0])
