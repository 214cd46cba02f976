"""Load-dependent Ritz vectors in the frequency response (pipeflow.enrichment, issue 32).

References independent of the Galerkin model and of pipeflow.statics: the Chebyshev
collocation of the strong-form boundary-value problem with flow, spin and the force as a
shear jump (tests/pipeflow/collocation.py, :func:`harmonic_response`, converged to ~1e-8:
24 and 20 points agree to 1e-8), and the Galerkin model itself at 40 modes.  The vectors
are the continuous pipe's static responses (Wilson, Yuan & Dickens 1982; Dickens,
Nakagawa & Wittbrodt 1997: modal truncation augmentation).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from pipeflow.errors import InvalidInput
from pipeflow.frequency import BaseAcceleration, PointForce, frequency_response, resonances
from pipeflow.model import build_model
from pipeflow.paper import PAPER_PIPE as P
from pipeflow.supports import PointSupport, Support, Supports
from tests.pipeflow.collocation import harmonic_response

L = P.L
V, W0 = 10.0, 100.0  # the operating point of tests/pipeflow/test_frequency.py's flow cases


def _frequencies() -> list[float]:
    rs = resonances(P, V, W0, modes=40)
    mid = 0.5 * (rs[1].frequency + rs[2].frequency)
    return [0.0, 0.3 * rs[0].natural_frequency, rs[1].frequency, rs[2].frequency, mid]


@pytest.mark.parametrize(
    ("a", "tol", "plain_min"),
    [
        (L, 2e-5, 5e-3),  # measured 1.0e-5 (plain 10 modes: 7.3e-3 .. 1.2e-2)
        (0.4 * L, 4e-5, 4e-4),  # 2.4e-5 (plain 4.1e-4 .. 6.8e-4)
        (None, 3e-5, 3e-5),  # base acceleration: 1.9e-5 (plain 3.2e-5 .. 1.4e-4)
    ],
)
def test_ten_modes_and_two_load_vectors_against_collocation(
    a: float | None, tol: float, plain_min: float
) -> None:
    """v = 10 m/s, w0 = 100 rad/s, 10 modes, responses at 0.3 L, 0.7 L and L (max-norm
    relative error) at W = 0, 0.3 w1, the 2nd and 3rd resonances and between them.  With
    two load vectors the tip force meets the issue's goal (2e-5 at the default 10 modes;
    the modes alone converge like n^-2 there) and W = 0 is exact (the static response is
    in the basis: measured 1.6e-8, the collocation's own error; tolerance 1e-7)."""
    freqs = _frequencies()
    xs = np.array([0.3, 0.7, 1.0]) * L
    ref = np.array([harmonic_response(P, V, W0, w, xs, a) for w in freqs]).T
    load = BaseAcceleration() if a is None else PointForce(a)
    errors = {}
    for k in (0, 2):
        r = frequency_response(
            P, V, W0, load=load, positions=xs, frequencies=freqs, modes=10, load_vectors=k
        )
        assert r.load_vectors == k and not r.residual and r.diagnostics.method == "modal"
        errors[k] = np.max(np.abs(r.H - ref), axis=0) / np.max(np.abs(ref), axis=0)
    assert errors[2].max() < tol, errors[2]
    assert errors[2][0] < 1e-7
    assert errors[0].min() > plain_min  # what the vectors remove


def test_the_spectrum_with_load_vectors_is_the_modes() -> None:
    """The response reports the modes' eigenvalues (2n), the vectors' own left out; they are
    closer to the 40-mode spectrum than the plain 10-mode ones (the vectors carry the
    truncated modes' coupling): measured 7.3e-6, 1.3e-6, 4.7e-7 against 2.6e-4, 1.4e-5,
    1.3e-5 relative on the lowest three; asserted: the largest 3x smaller."""
    kw = dict(load=PointForce(L), positions=[L], frequencies=[10.0], modes=10)
    plain = frequency_response(P, V, W0, **kw)  # type: ignore[arg-type]
    enriched = frequency_response(P, V, W0, load_vectors=2, **kw)  # type: ignore[arg-type]
    assert enriched.eigenvalues.size == plain.eigenvalues.size == 20
    target = np.array([r.xi for r in resonances(P, V, W0, modes=40)])
    target = target[target.imag > 0]
    target = target[np.argsort(target.imag)][:3]

    def error(xi: np.ndarray) -> float:
        upper = xi[xi.imag > 0]
        low = upper[np.argsort(upper.imag)][:3]
        return float(np.max(np.abs(low - target) / np.abs(target)))

    assert error(enriched.eigenvalues) < error(plain.eigenvalues) / 3


@pytest.mark.parametrize("kv", [1e-4, 1e-3])
def test_the_vectors_own_eigenvalues_are_told_apart_from_overdamped_modes(kv: float) -> None:
    """With Kelvin-Voigt damping the largest eigenvalues are the high modes' overdamped real
    roots, not the vectors' own: the ones left out are those whose eigenvectors lie on the
    vectors' coordinates.  Each reported eigenvalue matches one of the plain 10-mode
    model's (an assignment): measured 1.2e-2 and 7.5e-3 relative at worst (the highest
    modes, which the vectors improve); tolerance 3e-2 (dropping by size missed by ~1)."""
    from scipy.optimize import linear_sum_assignment

    p = dataclasses.replace(P, kelvin_voigt=kv)
    kw = dict(load=PointForce(L), positions=[L], frequencies=[10.0], modes=10)
    plain = frequency_response(p, V, W0, **kw).eigenvalues  # type: ignore[arg-type]
    enriched = frequency_response(p, V, W0, load_vectors=2, **kw).eigenvalues  # type: ignore[arg-type]
    assert enriched.size == plain.size == 20
    cost = np.abs(plain[:, None] - enriched[None, :]) / np.abs(plain[:, None])
    rows, cols = linear_sum_assignment(cost)
    assert cost[rows, cols].max() < 3e-2


def test_a_supported_pipe_with_a_spring_converges_to_forty_modes() -> None:
    """Pinned-pinned with a midspan spring (100 N/m), Kelvin-Voigt 1e-5 s, a force at 0.3 L,
    at half the divergence velocity (u = pi / 2): 10 modes with two load vectors against
    40 modes alone (the springs' weak form and the supports' basis carry over to the
    vectors), W = 0 to above the 3rd resonance: measured 2e-5 .. 3.8e-4 (the 40 modes' own
    error is of that order) against 1.9e-4 .. 1.4e-2 for the plain 10 modes; asserted: the
    largest at least 5x smaller."""
    pipe = dataclasses.replace(
        P,
        supports=Supports(Support("pinned"), Support("pinned")),
        intermediate_supports=(PointSupport(0.5 * L, translational=100.0),),
        kelvin_voigt=1e-5,
    )
    v = 0.5 * pipe.velocity_from_flow_number(math.pi)
    rs = resonances(pipe, v, 0.0, modes=40)
    freqs = [0.0, 0.5 * rs[0].frequency, rs[0].frequency, rs[1].frequency, rs[2].frequency]
    freqs.append(0.5 * (rs[1].frequency + rs[2].frequency))
    kw = dict(load=PointForce(0.3 * L), positions=[0.3 * L, 0.7 * L], frequencies=freqs)
    ref = frequency_response(pipe, v, 0.0, modes=40, residual=False, **kw).H  # type: ignore[arg-type]
    e = {}
    for k in (0, 2):
        H = frequency_response(pipe, v, 0.0, modes=10, residual=False if k == 0 else None,
                               load_vectors=k, **kw).H  # type: ignore[arg-type]  # fmt: skip
        per_frequency = np.max(np.abs(H - ref), axis=0) / np.max(np.abs(ref), axis=0)
        e[k] = float(per_frequency.max())
    assert e[2] < e[0] / 5, e


def test_refusals_and_a_pipe_without_a_static_solution() -> None:
    """The count is bounded and excludes residual=True (both name load_vectors); a pinned-free
    pipe (a rigid rotation: no static solution) is answered by its modes, with a warning."""
    kw = dict(load=PointForce(L), positions=[L], frequencies=[10.0])
    for bad in ({"load_vectors": 4}, {"load_vectors": -1}, {"load_vectors": 1, "residual": True}):
        with pytest.raises(InvalidInput) as exc:
            frequency_response(P, V, W0, **kw, **bad)  # type: ignore[arg-type]
        assert exc.value.parameter == "load_vectors"
    free = dataclasses.replace(P, supports=Supports(Support("pinned"), Support("free")))
    r = frequency_response(free, 0.0, 0.0, load_vectors=2, **kw)
    assert r.load_vectors == 0 and any("no load vectors" in w for w in r.warnings)
    assert build_model(free, 10) is not None


@pytest.mark.parametrize(
    "case", ["flow", "flow+hub", "out-of-plane hub", "KV+flow+spin", "tip mass+hub"]
)
def test_every_collocation_case_at_ten_modes(case: str) -> None:
    """The flow, spin, hub, plane, damping and tip-mass cases of test_frequency.py's
    COLLOCATION_CASES, 10 modes: with two load vectors a tip force and the clamp's
    acceleration within 3e-5 of the collocation at W = 0, 0.3 w1, the 2nd and 3rd
    resonances and between (measured <= 1.9e-5; the modes alone 7.5e-5 .. 2.2e-1).  A force
    at 0.4 L on the pipe with a tip mass needs the third vector (the inertia of the tip
    mass in the second one's response reaches the tip mode only there): 4.9e-6 with three,
    2.1e-1 with two (the third resonance, zeta = 0.0016, is then the 10 modes' own
    frequency, 1.6 rad/s off)."""
    from tests.pipeflow.test_frequency import COLLOCATION_CASES

    pipe, v, w0, _ = COLLOCATION_CASES[case]
    rs = resonances(pipe, v, w0, modes=40)
    freqs = [0.0, 0.3 * rs[0].natural_frequency, rs[1].frequency, rs[2].frequency]
    freqs.append(0.5 * (rs[1].frequency + rs[2].frequency))
    xs = np.array([0.3, 0.7, 1.0]) * L
    loads: list[tuple[float | None, int, float]] = [(L, 2, 3e-5), (None, 2, 3e-5)]
    if case == "tip mass+hub":
        loads.append((0.4 * L, 3, 2e-5))
    for a, k, tol in loads:
        ref = np.array([harmonic_response(pipe, v, w0, w, xs, a) for w in freqs]).T
        load = BaseAcceleration() if a is None else PointForce(a)
        r = frequency_response(
            pipe, v, w0, load=load, positions=xs, frequencies=freqs, modes=10, load_vectors=k
        )
        err = np.max(np.abs(r.H - ref), axis=0) / np.max(np.abs(ref), axis=0)
        assert err.max() < tol, (case, a, k, err)
