"""Complex mode shapes of the frozen spectrum (pipeflow.modeshapes) against analytic shapes
and the second-order eigenvalue identity."""

from __future__ import annotations

import numpy as np
import pytest

from pipeflow.basis import mode_shapes as cantilever_shapes
from pipeflow.computations import documents
from pipeflow.errors import InvalidInput
from pipeflow.io.export import to_csv
from pipeflow.io.plots import available_plots, render
from pipeflow.loading import Loading
from pipeflow.model import build_model
from pipeflow.paper import PAPER_PIPE
from pipeflow.profiles import Constant, polynomial
from pipeflow.simulation import Simulation, simulate

L = PAPER_PIPE.L


def test_without_flow_or_spin_the_shapes_are_the_cantilever_modes() -> None:
    """v = 0, w0 = 0: S(t) = S_0, whose eigenvectors are the Galerkin basis vectors, so
    branch k is the clamped-free mode phi_k of eq. (2) (Rao, Mechanical Vibrations,
    Table 8.1 roots), a real shape up to one complex factor.  Normalised to 1 + 0i at its
    largest modulus, which for a cantilever mode is the tip (|phi_k(1)| = 2 is the maximum),
    it must equal phi_k(x) / phi_k(L).  Tolerance 1e-12: the eigenvectors of the
    decoupled S_0 are exact up to the rounding of the Galerkin integrals (measured 1.6e-15)."""
    sim = Simulation(
        PAPER_PIPE,
        modes=10,
        t_end=0.1,
        samples=11,
        eigen_modes=6,
        mode_shape_times=(0.0, 0.05, 0.1),
        mode_shape_points=201,
    )
    result = simulate(sim)
    shapes = result.mode_shapes
    assert shapes is not None
    assert shapes.x[0] == 0.0 and shapes.x[-1] == L and shapes.x.size == 201
    phi = cantilever_shapes(6, shapes.x / L)
    expected = phi / phi[:, -1:]
    for i in range(3):
        np.testing.assert_allclose(shapes.shapes[i].real, expected, rtol=0, atol=1e-12)
        np.testing.assert_allclose(shapes.shapes[i].imag, 0.0, rtol=0, atol=1e-12)
    # the eigenvalues are those of the result's tracked frozen spectrum: i omega_k
    np.testing.assert_allclose(shapes.xi[0], result.frozen.xi[0], rtol=1e-14)
    omega = build_model(PAPER_PIPE, 10).natural_frequencies()[:6]
    np.testing.assert_allclose(shapes.xi[1].imag, omega, rtol=1e-9)


@pytest.mark.parametrize("flow", [Constant(20.0), polynomial(0, 40.0)])
def test_shapes_with_flow_and_spin_solve_the_second_order_eigenproblem(flow: object) -> None:
    """With flow the shapes are complex; projected back onto the basis (least squares on
    the stations: the shape lies in the span of the n modes) their amplitudes d must satisfy
    (xi^2 M + xi C + K) d = 0 with C = v C_v, K = K_0 + dv/dt K_vdot + v^2 K_v2 + w0^2 K_w2,
    the equation of motion the state matrix is built from.  Relative residual below 1e-9:
    rounding of eig() times the conditioning of the non-normal S(t) (measured 3e-12 worst)."""
    spin = Constant(100.0)
    t_shapes = (0.0, 0.3, 0.5)
    sim = Simulation(
        PAPER_PIPE,
        flow=flow,  # type: ignore[arg-type]
        spin=spin,
        modes=8,
        t_end=0.5,
        samples=11,
        eigen_modes=3,
        mode_shape_times=t_shapes,
        mode_shape_points=101,
    )
    result = simulate(sim)
    shapes = result.mode_shapes
    assert shapes is not None
    # branch j of the shapes is branch j of the result's tracked spectrum (the shape times
    # lie on the eigenvalue grid here, up to the rounding of linspace)
    for i, t in enumerate(t_shapes):
        k = int(np.argmin(np.abs(result.eigen_t - t)))
        np.testing.assert_allclose(shapes.xi[i], result.frozen.xi[k], rtol=1e-9)
    model = build_model(PAPER_PIPE, 8)
    c = Loading(flow, spin).coefficients(np.asarray(t_shapes))  # type: ignore[arg-type]
    phi = cantilever_shapes(8, shapes.x / L)
    complex_part = 0.0
    for i in range(len(t_shapes)):
        C = c.v[i] * model.C_v
        K = model.K_0 + c.vdot[i] * model.K_vdot + c.v[i] ** 2 * model.K_v2 + c.w2[i] * model.K_w2
        for j in range(3):
            xi = shapes.xi[i, j]
            d, *_ = np.linalg.lstsq(phi.T.astype(complex), shapes.shapes[i, j], rcond=None)
            terms = [xi**2 * (model.M @ d), xi * (C @ d), K @ d]
            residual = np.linalg.norm(sum(terms)) / max(np.linalg.norm(t) for t in terms)
            assert residual < 1e-9, (i, j, residual)
            assert np.max(np.abs(shapes.shapes[i, j])) == pytest.approx(1.0, abs=1e-15)
            complex_part = max(complex_part, float(np.max(np.abs(shapes.shapes[i, j].imag))))
    assert complex_part > 1e-2  # Coriolis coupling by the flow makes the shapes complex


def test_json_csv_and_plot_of_mode_shapes() -> None:
    sim = Simulation(
        PAPER_PIPE,
        flow=Constant(10.0),
        modes=4,
        t_end=0.1,
        samples=11,
        eigen_modes=2,
        mode_shape_times=(0.05,),
        mode_shape_points=11,
    )
    doc = documents.simulation(simulate(sim))
    block = doc["mode_shapes"]
    assert block["t"] == [0.05] and len(block["x"]) == 11
    mode = block["modes"][1]
    assert mode["mode"] == 2 and len(mode["real"]) == 1 and len(mode["real"][0]) == 11
    rows = to_csv(doc, "mode_shapes").splitlines()
    assert rows[0].split(",") == [
        "x [m]",
        "real_1(t=0.05) [-]",
        "imag_1(t=0.05) [-]",
        "real_2(t=0.05) [-]",
        "imag_2(t=0.05) [-]",
    ]
    assert [float(r.split(",")[3]) for r in rows[1:]] == mode["real"][0]
    assert "mode_shapes" in available_plots(doc)
    svg = render(doc, "mode_shapes", "svg").decode()
    assert "position along the pipe x [m]" in svg and "mode 2, t = 0.05 s (Re)" in svg
    # without the request there is no block, no table and no plot
    plain = documents.simulation(simulate(Simulation(PAPER_PIPE, modes=4, t_end=0.1, samples=11)))
    assert "mode_shapes" not in plain and "mode_shapes" not in available_plots(plain)


@pytest.mark.parametrize(
    ("kwargs", "parameter", "field"),
    [
        ({"mode_shape_times": (0.05, 0.2)}, "mode_shape_times", "output.mode_shapes.times"),
        ({"mode_shape_times": (-0.01,)}, "mode_shape_times", "output.mode_shapes.times"),
        (
            {"mode_shape_times": (0.0,), "mode_shape_points": 1},
            "mode_shape_points",
            "output.mode_shapes.points",
        ),
        ({"mode_shape_times": tuple([0.0] * 33)}, "mode_shape_times", "output.mode_shapes.times"),
    ],
)
def test_bad_mode_shape_requests_name_the_field(
    kwargs: dict[str, object], parameter: str, field: str
) -> None:
    """The library names its parameter; the schema layer's mapping gives the request field."""
    from pipeflow.schema.simulation import SIMULATION_FIELDS, request_fields

    sim = Simulation(PAPER_PIPE, modes=2, t_end=0.1, samples=11, **kwargs)  # type: ignore[arg-type]
    with pytest.raises(InvalidInput) as err, request_fields(SIMULATION_FIELDS):
        simulate(sim)
    assert err.value.parameter == parameter
    assert err.value.field == field


def test_shapes_follow_the_traced_branches_including_the_least_stable() -> None:
    """Above v_cr (v = 40 m/s, w0 = 100 rad/s, 10 modes) the flutter branch (mode 5) is
    traced besides the three lowest; the shapes are of the same four branches, in the same
    order: their eigenvalues equal the result's traced ones (same decomposition of S(0))."""
    from pipeflow.profiles import Constant

    r = simulate(
        Simulation(
            PAPER_PIPE,
            flow=Constant(40.0),
            spin=Constant(100.0),
            t_end=0.01,
            samples=11,
            mode_shape_times=(0.0, 0.01),
        )
    )
    assert r.frozen.xi.shape[1] == 4 and r.frozen.least_stable == 3
    assert r.mode_shapes is not None
    np.testing.assert_allclose(r.mode_shapes.xi[0], r.frozen.xi[0], rtol=1e-14)
    np.testing.assert_allclose(r.mode_shapes.xi[1], r.frozen.xi[-1], rtol=1e-9)
    doc = documents.simulation(r)
    modes = doc["mode_shapes"]["modes"]
    assert [m["mode"] for m in modes] == [m["mode"] for m in doc["eigenvalues"]["modes"]]
    assert modes[-1]["mode"] == 5


def test_mode_shape_output_size_is_bounded() -> None:
    """times x points x branches is capped at MAX_SHAPE_VALUES (the reviewer's 32 times x
    2001 points x 41 branches made 114 MB of JSON from a 1 KB request).  The branch count
    is eigen_modes (capped at modes) plus the least-stable branch.  Refused up front, naming
    output.mode_shapes.points; 32 x 2001 x (2 + 1) = 192096 (modes = 2) is under the cap and
    runs (2 branches here: the least-stable one is among the traced), and its JSON block
    holds that many shape values in 4.8 MB (asserted < 10 MB)."""
    import json

    from pipeflow.modeshapes import MAX_SHAPE_VALUES
    from pipeflow.schema.simulation import SIMULATION_FIELDS, request_fields

    times = tuple(np.linspace(0.0, 0.1, 32).tolist())
    big = Simulation(
        PAPER_PIPE, modes=40, eigen_modes=40, t_end=0.1, samples=11, mode_shape_times=times,
        mode_shape_points=2001,
    )  # fmt: skip
    with pytest.raises(InvalidInput, match=str(MAX_SHAPE_VALUES)) as err:
        with request_fields(SIMULATION_FIELDS):
            simulate(big)
    assert err.value.field == "output.mode_shapes.points"
    ok = simulate(
        Simulation(
            PAPER_PIPE, modes=2, t_end=0.1, samples=11, mode_shape_times=times,
            mode_shape_points=2001,
        )
    )  # fmt: skip
    assert ok.mode_shapes is not None
    block = documents.simulation(ok)["mode_shapes"]
    values = sum(len(row) for m in block["modes"] for row in m["real"])
    assert values in (32 * 2001 * 2, 32 * 2001 * 3)  # the least-stable branch may be traced
    assert values <= MAX_SHAPE_VALUES
    assert len(json.dumps(block)) < 10e6
