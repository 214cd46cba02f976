"""The pipe from its drawing in the viewer's form (issue 34, item 7), in a real headless
browser (set-up and screenshots: ``tests/conftest.py``, ``tests/service/browser.py``).

The form, generated from the schema, offers both ways: the explicit E, I, M1, M2 and the
drawing (diameters, densities, a material and a fluid from <select>s with an empty
choice).  Cleared, I, M1 and M2 are not sent; the drawing is, and the result has the key
of the explicit request it stands for.
"""

from __future__ import annotations

from typing import Any

import pytest

from pipeflow.schema.keys import canonical_key
from pipeflow.schema.simulation import PipeSpec, SimulationSpec
from tests.service.browser import Page, open_page, page

#: slow (CI's second step): a real chromium and a server of its own
pytestmark = pytest.mark.slow

__all__ = ["page"]


#: the supports/axial-load fields of the pipe block at their defaults (issue 31)
MOUNTING_DEFAULTS = {
    "supports": {"x0": "clamped", "xL": "free"},
    "intermediate_supports": [],
    "tension": 0,
    "flow_area": 0,
    "poisson": 0.3,
    "axially_restrained": False,
}


def test_the_form_takes_the_pipe_from_its_drawing(server: str, page: Page, screenshot: Any) -> None:
    bodies: list[dict[str, Any]] = []
    page.on(
        "request",
        lambda r: (
            bodies.append(r.post_data_json)
            if r.method == "POST" and r.url.endswith("/v1/simulations")
            else None
        ),
    )
    open_page(page, server + "/")
    material = "select[name='pipe.material']"
    # "name or null": the empty choice first, selected, so nothing is sent by default
    options = page.eval_on_selector(material, "s => [...s.options].map(o => o.value)")
    assert options == ["", "steel", "stainless", "aluminium", "copper", "PVC", "HDPE"]
    assert page.input_value(material) == ""
    for name in ("E", "I", "M1", "M2"):
        page.fill(f"input[name='pipe.{name}']", "")
    page.fill("input[name='pipe.L']", "1")
    page.fill("input[name='pipe.outer_diameter']", "33.4")
    page.select_option("select[data-unit-for='pipe.outer_diameter']", "mm")
    page.fill("input[name='pipe.wall_thickness']", "3.38")
    page.select_option("select[data-unit-for='pipe.wall_thickness']", "mm")
    page.select_option(material, "steel")
    page.select_option("select[name='pipe.fluid']", "water")
    page.fill("input[name='modes']", "3")
    page.fill("input[name='time.t_end']", "0.05")
    page.fill("input[name='time.samples']", "51")
    page.evaluate("window.pipeflowViewer.state.result = null")
    page.click("#run")
    page.wait_for_function(
        "window.pipeflowViewer.state.result !== null"
        " && document.getElementById('status').textContent.startsWith('done')"
    )
    result = page.evaluate("window.pipeflowViewer.state.result")
    sent = bodies[-1]
    assert sent["pipe"] == {
        "L": 1,
        "outer_diameter": {"value": 33.4, "unit": "mm"},
        "wall_thickness": {"value": 3.38, "unit": "mm"},
        "material": "steel",
        "fluid": "water",
        **{k: v for k, v in sent["pipe"].items() if k == "damping" or k.startswith("tip_")},
        **{k: v for k, v in sent["pipe"].items() if k in MOUNTING_DEFAULTS},
    }
    # the supports form (issue 31) sends its fields at their defaults: today's cantilever
    assert {k: sent["pipe"][k] for k in MOUNTING_DEFAULTS if k in sent["pipe"]} == {
        k: v for k, v in MOUNTING_DEFAULTS.items() if k in sent["pipe"]
    }
    # the key of the explicit request the drawing stands for
    explicit = dict(sent, pipe=PipeSpec.model_validate(sent["pipe"]).model_dump())
    assert result["key"] == canonical_key(
        "simulation", SimulationSpec.model_validate(explicit).canonical()
    )
    page.locator("input[name='pipe.outer_diameter']").scroll_into_view_if_needed()
    screenshot(page, "viewer-pipe-from-drawing")


def test_the_page_shows_a_spin_meant_in_rpm(server: str, page: Page, screenshot: Any) -> None:
    """Issue 34, item 8: 3000 typed as rad/s for the paper's pipe (first bending frequency
    291 rad/s) runs, and the page lists the plausibility warning with the rpm form."""
    open_page(page, server + "/")
    page.fill("input[name='modes']", "3")
    page.fill("input[name='time.t_end']", "0.02")
    page.fill("input[name='time.samples']", "21")
    page.fill("input[name='rotation.omega0.value']", "3000")
    page.evaluate("window.pipeflowViewer.state.result = null")
    page.click("#run")
    page.wait_for_function(
        "window.pipeflowViewer.state.result !== null"
        " && document.getElementById('status').textContent.startsWith('done')"
    )
    shown = page.inner_text("#warnings")
    assert "rotation.omega0 = 3000 rad/s is 10.3x the pipe's first bending frequency" in shown
    assert '{"value": 3000, "unit": "rpm"} (314 rad/s)' in shown
    page.locator("#warnings").scroll_into_view_if_needed()
    screenshot(page, "viewer-spin-plausibility-warning")
