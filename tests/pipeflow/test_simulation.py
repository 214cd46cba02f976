"""Simulation driver: validation, non-finite handling, JSON output."""

import json
import math

import numpy as np
import pytest

from pipeflow.errors import PipeflowError
from pipeflow.model import PAPER_PIPE
from pipeflow.profiles import Constant, table
from pipeflow.simulation import Simulation, simulate
from pipeflow.solvers import Options
from pipeflow.spec import SIMULATION_FIELDS, request_fields
from tests.pipeflow.cases import paper_sim


def test_overflow_is_reported_not_serialised() -> None:
    """v = -0.4 m/s grows like e^(14.9 t); over 60 s that overflows double precision. The
    result keeps the finite prefix, says 'overflow', and its JSON has no NaN/Inf."""
    r = simulate(paper_sim(Constant(-0.4), modes=3, t_end=60.0, samples=601))
    assert r.status == "overflow"
    assert r.divergence_time is not None and r.divergence_time < 1.0
    assert np.all(np.isfinite(r.tip_displacement)) and r.t.size < 601
    text = json.dumps(r.to_dict(), allow_nan=False)
    assert "NaN" not in text and "Infinity" not in text


def test_divergence_time_is_when_bound_is_passed() -> None:
    r = simulate(paper_sim(Constant(-0.4), modes=3, t_end=1.0, samples=1001, divergence_bound=0.01))
    assert r.status == "diverging"
    k = int(np.flatnonzero(np.abs(r.tip_displacement) > 0.01)[0])
    assert r.divergence_time == pytest.approx(r.t[k])
    assert np.all(np.abs(r.tip_displacement[:k]) <= 0.01)


@pytest.mark.parametrize(
    ("kw", "parameter", "field"),
    [
        ({"method": "nope"}, "method", "method"),
        ({"t_end": -1.0}, "t_end", "time.t_end"),
        ({"t_end": math.inf}, "t_end", "time.t_end"),
        ({"samples": 1}, "samples", "time.samples"),
        ({"modes": 41}, "modes", "modes"),
        ({"positions": (0.5,)}, "positions", "output.positions"),
        ({"initial_shape": "mode2"}, "initial_shape", "initial.shape"),
        ({"flow": table([0, 0.5], [0.1, 0.2])}, "flow", "flow.velocity"),
        ({"method": "rk4", "options": Options(step=1e-300)}, "step", "options.step"),
    ],
)
def test_invalid_input_names_the_parameter(
    kw: dict[str, object], parameter: str, field: str
) -> None:
    """The library names its own parameter (no JSON path); the schema layer's one mapping
    (pipeflow.spec.SIMULATION_FIELDS) turns it into the request field."""
    with pytest.raises(PipeflowError) as err:
        simulate(Simulation(PAPER_PIPE, **kw))  # type: ignore[arg-type]
    assert err.value.parameter == parameter
    assert err.value.field is None
    with pytest.raises(PipeflowError) as err, request_fields(SIMULATION_FIELDS):
        simulate(Simulation(PAPER_PIPE, **kw))  # type: ignore[arg-type]
    assert err.value.field == field


def test_table_profile_matches_polynomial() -> None:
    """A linear table of v = 0.4 t gives the same run as the polynomial (same closed forms)."""
    from pipeflow.profiles import polynomial

    a = simulate(paper_sim(polynomial(0, 0.4), modes=3, t_end=0.1, samples=101))
    b = simulate(paper_sim(table([0.0, 0.1], [0.0, 0.04]), modes=3, t_end=0.1, samples=101))
    assert np.allclose(a.tip_displacement, b.tip_displacement, rtol=0, atol=1e-14)
