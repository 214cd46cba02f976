"""Every solver on supported pipes (issue 31): the solvers take the supports through
PipeModel, so each must agree with the reference integrator on a supported, tensioned,
hanging, spinning pipe with time-varying flow, and CMA must be exact for constant flow."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from pipeflow import profiles
from pipeflow.model import Pipe
from pipeflow.simulation import Simulation, simulate
from pipeflow.supports import PointSupport, Support, Supports

PIPE = Pipe(
    E=1.0, I=1.0, L=1.0, M1=0.6, M2=0.4, supports=Supports(Support("clamped"), Support("pinned")),
    intermediate_supports=(PointSupport(0.3, translational=50.0),), tension=2.0, gravity=3.0,
    hub_radius=0.2,
)  # fmt: skip


def _run(method: str, flow: profiles.Profile) -> np.ndarray:
    sim = Simulation(
        pipe=PIPE, flow=flow, spin=profiles.Constant(1.5), u0=1e-3, du0=0.0, modes=6,
        t_end=2.0, samples=41, method=method, positions=(0.5,),
    )  # fmt: skip
    return np.asarray(simulate(sim).displacements[0])


@pytest.mark.parametrize(
    ("method", "tol"), [("magnus", 1e-8), ("auto", 1e-8), ("rk4", 3e-3), ("cma", 5e-2)]
)
def test_solvers_agree_with_reference_on_a_supported_pipe(method: str, tol: float) -> None:
    """v(t) = 1 + 0.5 t (below divergence throughout), w0 = 1.5 rad/s: each method's midspan
    history against the adaptive reference integrator, relative to the amplitude.  Measured:
    magnus (and auto, which picks it) 1.3e-10; rk4 at its default step 5.7e-4 (6.8e-4 on the
    cantilever); cma with time-varying flow keeps only the first Magnus term, 1.3e-2 here
    (1.8e-3 on the cantilever: the supported pipe's flow terms commute less), which its
    error estimate reports.  Tolerances: about 4x the measured."""
    flow = profiles.polynomial(1.0, 0.5)
    ref = _run("reference", flow)
    got = _run(method, flow)
    assert np.max(np.abs(got - ref)) < tol * np.max(np.abs(ref))


def test_cma_is_exact_for_constant_flow_on_a_supported_pipe() -> None:
    """Constant flow and spin: CMA's exponential is exact; against the reference 1e-7."""
    ref = _run("reference", profiles.Constant(1.5))
    got = _run("cma", profiles.Constant(1.5))
    assert np.max(np.abs(got - ref)) < 1e-7 * np.max(np.abs(ref))


def test_frequency_response_of_a_pinned_pinned_pipe() -> None:
    """No flow, no spin: the receptance of a pinned-pinned beam between x = 0.3 and 0.5 is
    sum_j 2 sin(j pi a) sin(j pi x) / (m L (omega_j^2 - W^2)), omega_j = (j pi)^2 (unit pipe;
    Blevins' modes).  The model's 40 modes alone (residual=False) equal the series' first 40
    terms to 1e-10 relative (measured 1e-13); the omitted j > 40 terms are 8.9e-10 m/N.
    With the residual flexibility (the default now that the statics take any end supports)
    the answer is the whole series to 1e-12 m/N (the series' own tail past 4000 terms is
    5e-14; the static correction leaves W^2 sum_(j>40) 1/(j pi)^8, below 1e-16), where the
    modes alone miss it by 8.9e-10."""
    from pipeflow.frequency import PointForce, frequency_response

    pp = Supports(Support("pinned"), Support("pinned"))
    pipe = Pipe(E=1.0, I=1.0, L=1.0, M1=0.7, M2=0.3, supports=pp)
    W = np.array([3.0, 30.0, 100.0])
    kw: dict[str, Any] = dict(load=PointForce(0.3), positions=[0.5], frequencies=W, modes=40)
    j = np.arange(1, 4001)[:, None]
    terms = 2 * np.sin(j * np.pi * 0.3) * np.sin(j * np.pi * 0.5) / ((j * np.pi) ** 4 - W**2)
    plain = np.asarray(frequency_response(pipe, 0.0, 0.0, residual=False, **kw).H).reshape(-1)
    first = terms[:40].sum(axis=0)
    assert np.max(np.abs(plain.real - first) / np.abs(first)) < 1e-10
    assert np.max(np.abs(plain.real - terms.sum(axis=0))) > 5e-10
    full = frequency_response(pipe, 0.0, 0.0, **kw)
    assert full.residual
    whole = terms.sum(axis=0)
    got = np.asarray(full.H).reshape(-1).real
    assert np.max(np.abs(got - whole)) < 1e-12


def test_a_diverging_supported_pipe_is_stopped_without_stations() -> None:
    """Pinned-pinned past divergence (u = 4 > pi): the tip is held (w(L) = 0), yet the run
    stops with status 'diverged' at an interior station past 0.1 L, without any positions."""
    pp = Supports(Support("pinned"), Support("pinned"))
    pipe = Pipe(E=1.0, I=1.0, L=1.0, M1=0.5, M2=0.5, supports=pp)
    v = float(pipe.velocity_from_flow_number(4.0))
    r = simulate(
        Simulation(pipe=pipe, flow=profiles.Constant(v), spin=profiles.Constant(0.0), u0=1e-3,
                   du0=0.0, modes=8, t_end=10.0, samples=201)
    )  # fmt: skip
    assert r.status == "diverged"
    assert "x = " in " ".join(r.warnings)


@pytest.mark.parametrize(("freq", "unstable"), [(14.0, False), (18.0, True), (22.0, False)])
def test_floquet_parametric_resonance_of_a_pinned_pipe(freq: float, unstable: bool) -> None:
    """Pulsating flow u(t) = 1 + sin(Omega t) on a pinned-pinned pipe (beta = 0.5, 4 modes):
    the principal parametric resonance lies near Omega = 2 omega_1 of the mean flow,
    omega_1^2 = pi^4 - <u^2> pi^2 = pi^4 - 1.5 pi^2 (2 omega_1 = 18.2; Paidoussis & Issid 1974,
    Paidoussis vol. 1 ch. 3.6).  Inside it a multiplier leaves the unit circle (measured
    1.20 at Omega = 18); outside, the conservative gyroscopic pipe keeps every |mu| = 1
    (to 1e-9: Hamiltonian, no dissipation through a free end)."""
    from pipeflow.computations.registry import SWEEP_KINDS, computation_for, parse

    pipe = {"E": 1.0, "I": 1.0, "L": 1.0, "M1": 0.5, "M2": 0.5,
            "supports": {"x0": "pinned", "xL": "pinned"}}  # fmt: skip
    s = 1.0 / np.sqrt(0.5)
    velocity = {"kind": "harmonic", "mean": s, "amplitude": s, "frequency": freq}
    body = {"kind": "floquet", "pipe": pipe, "modes": 4, "flow": {"velocity": velocity}}
    request = parse(SWEEP_KINDS, body)
    doc = computation_for(request).execute(request)
    if unstable:
        assert doc["max_multiplier"] > 1.1 and doc["verdict"].startswith("unstable")
    else:
        assert abs(doc["max_multiplier"] - 1.0) < 1e-9
