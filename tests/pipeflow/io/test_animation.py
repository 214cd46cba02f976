"""A complex mode shape in motion (pipeflow.io.animation, issue 24).

The curves are Re(Phi(x) e^(i theta)): at theta = 0 the real part of the shape, at
theta = pi/2 minus its imaginary part (identities of the complex exponential, to 1e-15 of
max |Phi| = 1).  The GIF is read back by Pillow: one frame per phase, looping.
"""

from __future__ import annotations

import io
from typing import Any

import numpy as np
import pytest

from pipeflow.computations import documents
from pipeflow.io.animation import mode_shape_gif, phases
from pipeflow.io.plots import PlotError
from pipeflow.paper import PAPER_PIPE
from pipeflow.profiles import Constant
from pipeflow.simulation import Simulation, simulate

pytest.importorskip("matplotlib")


@pytest.fixture(scope="module")
def doc() -> dict[str, Any]:
    sim = Simulation(
        PAPER_PIPE,
        Constant(10.0),
        Constant(100.0),
        modes=6,
        t_end=0.01,
        samples=11,
        mode_shape_times=(0.0, 0.01),
        mode_shape_points=21,
    )
    return documents.simulation(simulate(sim))


def test_phases_are_the_complex_shape_in_motion(doc: dict[str, Any]) -> None:
    branch = doc["mode_shapes"]["modes"][1]
    x, u = phases(doc, mode=branch["mode"], time_index=1, frames=8)
    assert u.shape == (8, 21) and x[-1] == pytest.approx(PAPER_PIPE.L)
    np.testing.assert_allclose(u[0], branch["real"][1], rtol=0, atol=1e-15)
    np.testing.assert_allclose(u[2], -np.asarray(branch["imag"][1]), rtol=0, atol=1e-15)
    np.testing.assert_allclose(u[4], -np.asarray(branch["real"][1]), rtol=0, atol=1e-15)
    # with flow the shape is complex: it travels, it does not only scale
    assert np.max(np.abs(branch["imag"][1])) > 1e-3


def test_gif_has_one_frame_per_phase(doc: dict[str, Any]) -> None:
    from PIL import Image

    data = mode_shape_gif(doc, mode=doc["mode_shapes"]["modes"][0]["mode"], frames=6)
    image = Image.open(io.BytesIO(data))
    assert image.format == "GIF" and image.n_frames == 6 and image.info.get("loop") == 0
    first = np.asarray(image.convert("RGB"))
    image.seek(3)
    assert np.any(first != np.asarray(image.convert("RGB")))  # the line moved


def test_bad_requests_name_the_parameter(doc: dict[str, Any]) -> None:
    with pytest.raises(PlotError) as err:
        phases(doc, mode=99)
    assert err.value.field == "mode"
    with pytest.raises(PlotError) as err:
        phases(doc, time_index=5)
    assert err.value.field == "time_index"
    with pytest.raises(PlotError):
        phases({k: v for k, v in doc.items() if k != "mode_shapes"})
