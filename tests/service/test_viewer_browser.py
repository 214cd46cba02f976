"""The simulation viewer in a real headless browser (Debian's chromium driven by playwright).

Checks: the form generated from /openapi.json offers every method and profile kind of the
schema with the schema's default method and the paper's example; a run completes and the
three charts show data; the share link reloads the result by its key; a bad input shows the
API's message next to the field; an unstable run (v = 40 m/s on the paper pipe at w0 = 100
rad/s) shows the banner and a symmetric-log tip axis with readable labels.  Set-up and
screenshots: ``tests/conftest.py`` and ``tests/service/browser.py``.
"""

from __future__ import annotations

from typing import Any

import httpx
import pytest

from tests.service.browser import Page, open_page, page

#: slow (CI's second step): a real chromium and a server of its own: over 10 s a file
pytestmark = pytest.mark.slow

__all__ = ["page"]


def _points(page: Page, chart: str) -> int:
    return int(page.get_attribute(f"#{chart}", "data-points") or 0)


def _schema(server: str) -> tuple[dict[str, Any], dict[str, Any]]:
    doc: dict[str, Any] = httpx.get(server + "/openapi.json", timeout=10).json()
    content = doc["paths"]["/v1/simulations"]["post"]["requestBody"]["content"]
    ref = content["application/json"]["schema"]["$ref"].split("/")[-1]
    return doc, doc["components"]["schemas"][ref]


def _ref(doc: dict[str, Any], ref: str) -> dict[str, Any]:
    schema: dict[str, Any] = doc["components"]["schemas"][ref.split("/")[-1]]
    return schema


def test_run_the_papers_example_and_share_it(server: str, page: Page, screenshot: Any) -> None:
    open_page(page, server + "/")
    assert page.input_value("input[name='pipe.E']") == "7.8e9"
    assert page.input_value("input[name='flow.velocity.coefficients']") == "0, 0.4"
    page.click("#run")
    page.wait_for_selector("#chart-tip[data-points='2001']")
    assert "done (ok" in page.inner_text("#status")
    # sigma = 0 at t = 0 (rounding: 1e-12) is not growth: no banner
    result = page.evaluate("window.pipeflowViewer.state.result")
    assert result["first_unstable_time"] is None
    assert result["diagnostics"]["max_growth_rate"] == 0
    assert page.locator("#unstable").is_hidden()
    for chart in ("chart-damping", "chart-frequency"):
        assert _points(page, chart) == 201
        assert page.locator(f"#{chart} canvas").count() == 1
    # the charts hold the result's numbers: the fundamental frequency near 284 rad/s
    omega0 = page.evaluate("window.pipeflowViewer.charts['chart-frequency'].data[1][0]")
    assert 280 < omega0 < 290

    link = page.get_attribute("#share-link", "href")
    assert link and "key=" in link
    key = page.evaluate("window.pipeflowViewer.state.key")
    page.goto("about:blank")
    open_page(page, link)
    page.wait_for_selector("#chart-tip[data-points='2001']")
    assert key[:12] in page.inner_text("#status")
    assert page.input_value("input[name='pipe.E']") == "7.8e9"
    csv_href = page.get_attribute("#csv-history", "href")
    assert csv_href is not None
    text = httpx.get(f"{server}/{csv_href}", timeout=10).text
    assert text.startswith("t [s],tip_displacement [m]")

    # a link whose spec is mangled still loads the result by its key
    page.goto("about:blank")
    open_page(page, f"{server}/?key={key}&spec=%7Bbroken")
    page.wait_for_selector("#chart-tip[data-points='2001']")
    assert page.inner_text("#status").startswith("loaded result " + key[:12])
    page.locator("#results").scroll_into_view_if_needed()
    screenshot(page, "viewer-paper-example")


def test_bad_input_shows_the_api_message_next_to_the_field(server: str, page: Page) -> None:
    open_page(page, server + "/")
    page.fill("input[name='pipe.L']", "-0.025")
    page.fill("input[name='flow.velocity.coefficients']", "0, fast")
    page.click("#run")
    slot = page.locator("[data-error-for='pipe.L']")
    slot.wait_for(state="visible")
    # the message is the API's own (pydantic's bound check, passed through problem+json)
    assert "greater than 0" in slot.inner_text()
    assert "invalid" in (page.get_attribute("input[name='pipe.L']", "class") or "")
    coeff = page.locator("[data-error-for='flow.velocity.coefficients']")
    assert "valid number" in coeff.inner_text()
    assert page.inner_text("#status") == "Invalid input"
    assert _points(page, "chart-tip") == 0
    # fixing the fields clears the messages on the next run
    page.fill("input[name='pipe.L']", "0.025")
    page.fill("input[name='flow.velocity.coefficients']", "0, 0.4")
    page.fill("input[name='modes']", "4")
    page.click("#run")
    page.wait_for_selector("#chart-tip[data-points='2001']")
    assert page.locator("[data-error-for='pipe.L']").inner_text() == ""


def test_form_offers_every_method_and_profile_kind_of_the_schema(
    server: str, page: Page, screenshot: Any
) -> None:
    """The method list, its default and every profile kind (with each kind's fields and
    their descriptions) are the schema's; a table profile and the magnus method run."""
    doc, spec = _schema(server)
    open_page(page, server + "/")
    method = spec["properties"]["method"]
    options = page.eval_on_selector_all(
        "select[name='method'] option", "os => os.map(o => o.value)"
    )
    assert options == method["enum"]
    assert page.input_value("select[name='method']") == method["default"]
    for group, field in (("rotation", "omega0"), ("flow", "velocity")):
        prop = _ref(doc, spec["properties"][group]["$ref"])["properties"][field]
        mapping = prop["discriminator"]["mapping"]
        sel = f"select[name='{group}.{field}.kind']"
        assert page.eval_on_selector_all(f"{sel} option", "os => os.map(o => o.value)") == list(
            mapping
        )
        for kind, ref in mapping.items():
            page.select_option(sel, kind)
            for name, sub in _ref(doc, ref)["properties"].items():
                if "const" in sub:
                    continue
                field_el = page.locator(f"[name='{group}.{field}.{name}']:visible")
                assert field_el.count() == 1, (kind, name)
                help_text = field_el.locator("xpath=..").locator("small.help").inner_text()
                # the description as a plain sentence (the page's helpText: reST unmarked)
                expected = page.evaluate("d => SchemaForm.helpText(d)", sub.get("description"))
                assert help_text == (expected or help_text), (kind, name)
    # every top-level field of the schema has an input or a group in the form
    for name in spec["properties"]:
        assert page.locator(f"[name='{name}'], [data-group='{name}']").count() >= 1, name
    page.locator("[data-union='flow.velocity']").scroll_into_view_if_needed()
    screenshot(page, "viewer-form-table-profile")
    page.select_option("select[name='rotation.omega0.kind']", "constant")
    page.select_option("select[name='flow.velocity.kind']", "table")
    page.fill("input[name='flow.velocity.t']", "0, 1")
    page.fill("input[name='flow.velocity.values']", "0, 0.4")
    page.select_option("select[name='method']", "magnus")
    page.fill("input[name='time.samples']", "201")
    # an optional block (object or null) is sent only when switched on: mode shapes
    page.click("details[data-group='output'] > summary")
    page.click("details[data-group='output.mode_shapes'] > summary")
    page.check("input[name='output.mode_shapes.enabled']")
    page.fill("input[name='output.mode_shapes.times']", "0, 0.5")
    page.click("#run")
    page.wait_for_selector("#chart-tip[data-points='201']")
    assert "magnus" in page.inner_text("#method-used")
    sent = page.evaluate("JSON.parse(new URL(location.href).searchParams.get('spec'))")
    assert sent["flow"]["velocity"] == {
        "kind": "table", "t": [0, 1], "values": [0, 0.4], "interpolation": "linear"
    }  # fmt: skip
    assert sent["method"] == "magnus"
    assert sent["output"]["mode_shapes"] == {"times": [0, 0.5], "points": 101}
    assert page.evaluate("window.pipeflowViewer.state.result.mode_shapes.t") == [0, 0.5]


def test_unstable_run_shows_the_banner_and_a_readable_log_axis(
    server: str, page: Page, screenshot: Any
) -> None:
    """v = 40 m/s on the paper pipe at w0 = 100 rad/s is past the critical velocity (27.69
    m/s): the run stops where the deflection leaves the linear range.  The banner says
    unstable (with the first unstable time and growth rate when the result carries them),
    the tip axis switches to symmetric log with decade labels up to the largest value, and
    the damping chart is drawn.  Every assertion is unconditional (the result's keys are
    all present)."""
    open_page(page, server + "/")
    page.select_option("select[name='flow.velocity.kind']", "constant")
    page.fill("input[name='flow.velocity.value']", "40")
    page.click("#run")
    banner = page.locator("#unstable")
    banner.wait_for(state="visible")
    text = banner.inner_text()
    assert text.startswith("Unstable run.")
    result = page.evaluate("window.pipeflowViewer.state.result")
    # constant v past v_cr: unstable from the start; the run stops where the deflection
    # leaves the linear range (issue 24: it used to run on to 1e304 m), and the banner
    # quotes the first unstable time, the growth rate and the stop
    assert result["first_unstable_time"] == 0
    assert "First unstable at t = 0 s" in text
    assert result["diagnostics"]["max_growth_rate"] > 0
    assert "Growth rate max σ = " in text
    assert result["status"] == "diverged"
    assert result["t"][-1] == result["divergence_time"] < 0.01
    assert "Diverged: the deflection left the linear model's range" in text
    assert abs(result["tip_displacement"][-1]) > result["divergence_bound"]
    # the frequency chart adds the least stable branch (mode 5 here, not the fundamental)
    least = next(m for m in result["eigenvalues"]["modes"] if m["least_stable"])
    assert least["mode"] != 1
    series = page.evaluate(
        "window.pipeflowViewer.charts['chart-frequency'].series.map((s) => s.label)"
    )
    assert any(f"mode {least['mode']} (least stable)" in label for label in series), series
    tip = page.locator("#chart-tip")
    assert tip.get_attribute("data-scale") == "symlog"
    page.wait_for_function("window.pipeflowViewer.axisLabels('chart-tip').length > 2")
    labels = page.evaluate("window.pipeflowViewer.axisLabels('chart-tip')")
    assert "0" in labels
    assert all(len(x) <= 8 and "Infinity" not in x and "NaN" not in x for x in labels), labels
    finite = [abs(float(x)) for x in labels if x]
    peak = max(abs(v) for v in result["tip_displacement"] if v is not None)
    assert max(finite) <= peak < 10 * max(finite)  # the top label is the data's decade
    assert int(page.get_attribute("#chart-damping", "data-points") or 0) > 0
    page.locator("#results").scroll_into_view_if_needed()
    path = screenshot(page, "viewer-unstable-v40")
    assert path.stat().st_size > 10_000
    # the linear choice is still offered and redraws
    page.select_option("#tip-scale", "linear")
    assert tip.get_attribute("data-scale") == "linear"


def test_harmonic_tip_force_from_rest(server: str, page: Page, screenshot: Any) -> None:
    """Forced vibration from rest, built in the form: u0 = 0 and one load, a harmonic point
    force at the tip (the list editor generated from the schema's discriminated loads).
    The tip history starts at zero and is not zero after; the tip axis stays linear (growth
    from zero is not divergence); the result's echoed loads are listed; an out-of-range
    position is flagged while typing and a position beyond the tip by the API, next to the
    item's field."""
    _, spec = _schema(server)
    open_page(page, server + "/")
    loads = page.locator("[data-list='loads']")
    assert loads.get_attribute("data-count") == "0"
    mapping = spec["properties"]["loads"]["items"]["discriminator"]["mapping"]
    assert str(spec["properties"]["loads"]["maxItems"]) in loads.locator("legend").inner_text()
    page.select_option("select[name='flow.velocity.kind']", "constant")
    page.fill("input[name='flow.velocity.value']", "5")
    page.fill("input[name='initial.u0']", "0")
    page.fill("input[name='time.t_end']", "0.2")
    page.click("[data-add='loads']")
    assert loads.get_attribute("data-count") == "1"
    kinds = page.eval_on_selector_all(
        "select[name='loads.0.kind'] option", "os => os.map(o => o.value)"
    )
    assert kinds == list(mapping)
    # a new load is a point force at the tip (x = pipe.L as typed), its force harmonic
    assert page.input_value("select[name='loads.0.kind']") == "point_force"
    # (the point force's field: the impulse kind's hidden block has a position too)
    position = "[data-kind='point_force'] input[name='loads.0.position']"
    assert page.input_value(position) == "0.025"
    assert page.input_value("select[name='loads.0.force.kind']") == "harmonic"
    # the units are the schema's: position [m], the force's amplitude in N
    item = page.locator("[data-item='loads.0']")
    assert "position [m]" in item.inner_text()
    assert "amplitude [N]" in item.inner_text()
    # the schema's bounds, checked while typing
    page.fill(position, "-1")
    slot = page.locator("[data-kind='point_force'] [data-error-for='loads.0.position']")
    assert slot.inner_text().startswith("allowed: (0, ")
    # a position beyond the tip: the API's message next to the item's field
    page.fill(position, "0.05")
    page.fill("input[name='loads.0.force.amplitude']", "1e-5")
    page.fill("input[name='loads.0.force.frequency']", "244")
    page.click("#run")
    page.wait_for_function("document.getElementById('status').textContent === 'Invalid input'")
    assert "beyond the tip" in slot.inner_text()
    # a second load added and removed again
    page.click("[data-add='loads']")
    assert loads.get_attribute("data-count") == "2"
    page.click("[data-remove='loads.1']")
    assert loads.get_attribute("data-count") == "1"
    page.fill(position, "0.025")
    page.click("#run")
    page.wait_for_function("document.getElementById('status').textContent.startsWith('done')")
    page.wait_for_selector("#chart-tip[data-points='2001']")
    result = page.evaluate("window.pipeflowViewer.state.result")
    sent = page.evaluate("JSON.parse(new URL(location.href).searchParams.get('spec'))")
    force = {"kind": "harmonic", "mean": 0, "amplitude": 1e-5, "frequency": 244, "phase": 0}
    assert sent["loads"] == [{"kind": "point_force", "position": 0.025, "force": force}]
    assert result["loads"] == sent["loads"]
    tip = result["tip_displacement"]
    assert result["initial_tip_displacement"] == 0 and tip[0] == 0
    assert max(abs(v) for v in tip) > 1e-5  # the force's response (about 4e-4 m)
    assert result["first_unstable_time"] is None
    assert page.locator("#unstable").is_hidden()
    chart = page.locator("#chart-tip")
    assert chart.get_attribute("data-scale") == "linear"
    drawn = page.evaluate("window.pipeflowViewer.charts['chart-tip'].data[1]")
    assert max(abs(v) for v in drawn) == max(abs(v) for v in tip)
    labels = page.evaluate("window.pipeflowViewer.axisLabels('chart-tip')")
    assert len(labels) > 2 and not [x for x in labels if "NaN" in x or "Infinity" in x]
    applied = page.locator("#loads-applied")
    assert applied.is_visible() and applied.get_attribute("data-count") == "1"
    text = applied.inner_text()
    assert "point force: position 0.025 m, force 1e-5 sin(244 t) N" in text
    assert page.locator("#start-note").is_visible()
    page.locator("#results").scroll_into_view_if_needed()
    path = screenshot(page, "viewer-forced-from-rest")
    assert path.stat().st_size > 10_000
    # the symmetric-log choice on a history from zero: finite, readable labels
    page.select_option("#tip-scale", "symlog")
    assert chart.get_attribute("data-scale") == "symlog"
    labels = page.evaluate("window.pipeflowViewer.axisLabels('chart-tip')")
    assert "0" in labels
    assert all(len(x) <= 8 and "NaN" not in x and "Infinity" not in x for x in labels), labels


def test_all_zero_history(server: str, page: Page) -> None:
    """u0 = 0 without loads: the tip stays zero; the charts, the scale choice and the banner
    cope (no division by zero, no error in the page's console, checked by ``page``)."""
    open_page(page, server + "/")
    page.select_option("select[name='flow.velocity.kind']", "constant")
    page.fill("input[name='initial.u0']", "0")
    page.fill("input[name='time.t_end']", "0.1")
    page.fill("input[name='time.samples']", "101")
    page.click("#run")
    page.wait_for_selector("#chart-tip[data-points='101']")
    result = page.evaluate("window.pipeflowViewer.state.result")
    assert max(abs(v) for v in result["tip_displacement"]) == 0
    assert page.locator("#unstable").is_hidden()
    assert page.locator("#loads-applied").is_hidden()
    for scale in ("linear", "symlog", "auto"):
        page.select_option("#tip-scale", scale)
        labels = page.evaluate("window.pipeflowViewer.axisLabels('chart-tip')")
        assert labels and all("NaN" not in x and "Infinity" not in x for x in labels), labels
    assert page.get_attribute("#chart-tip", "data-scale") == "linear"
