"""What every page does for its reader (issue 34 item 10), in a real headless browser
(set-up and screenshots: ``tests/conftest.py``, ``tests/service/browser.py``).

Checks: a Run brings its result into view (the simulation form is taller than the window:
the result section is scrolled to the window's top and focused), on the simulation and the
stability pages; every help text of every page (each stability analysis's form too) is one
plain sentence, with no reST markup of the docstrings it comes from; the velocity fields
that the API takes as quantities get a unit select (m/s, mm/s, km/h, ft/s) and 3.6 km/h is
the result of 1 m/s (one cache key); a run that diverges after a few output samples says
so, and its "run again" button (t_end at the divergence time) gives every requested sample.
"""

from __future__ import annotations

import re
from typing import Any

import pytest

from tests.service.browser import Page, open_page, page

#: slow (CI's second step): a real chromium and a server of its own: over 10 s a file
pytestmark = pytest.mark.slow

__all__ = ["page"]

#: where the result section's top may be after a Run: at the window's top (a few pixels of
#: rounding and margin), not 1,700 px below it
TOP_PX = 40

#: reST of the docstrings the descriptions come from: roles, literals, emphasis
MARKUP = re.compile(r"``|`|:[a-z]+:|\*\*")
#: a sentence's end: a full stop (or ! ?) and any closing quotes or brackets
SENTENCE_END = re.compile(r"[.!?][\"'’)\]]*$")
#: a "name: " label opening a help text (a method's or a kind's name: "cma: ...")
LABEL = re.compile(r"^[a-z0-9_/]+: ")
#: an opening plain lowercase word (not a symbol such as p(t), c_k or omega0)
LOWER_START = re.compile(r"^[a-z]{2,}(?=[ ,;:.]|$)")


def _result_in_view(page: Page, top_px: float = TOP_PX) -> None:
    top = page.evaluate("document.getElementById('results').getBoundingClientRect().top")
    assert -2 <= top <= top_px, top
    assert page.evaluate("document.activeElement.id") == "results"
    assert page.evaluate("window.scrollY") > 0


def test_run_brings_the_result_into_view(server: str, page: Page, screenshot: Any) -> None:
    open_page(page, server + "/")
    height = page.evaluate("document.getElementById('spec-form').offsetHeight")
    window = page.evaluate("window.innerHeight")
    assert height > window  # the form alone is taller than the window
    page.click("#run")
    page.wait_for_selector("#chart-tip[data-points='2001']")
    _result_in_view(page)
    screenshot(page, "viewer-result-in-view-after-run")
    # the stability page: its result comes into view too
    open_page(page, server + "/stability")
    page.click("#run")
    page.wait_for_function("document.getElementById('results').hidden === false")
    page.wait_for_function("document.activeElement && document.activeElement.id === 'results'")
    # a short page (its figures still loading) scrolls as far as it goes: the result's top
    # in the window's upper half
    _result_in_view(page, page.evaluate("window.innerHeight") / 2)


def _help_texts(page: Page) -> list[str]:
    texts: list[str] = page.eval_on_selector_all(
        "small.help, #analysis-help", "es => es.map(e => e.textContent)"
    )
    titles: list[str] = page.eval_on_selector_all(
        "label.field[title]", "es => es.map(e => e.title).filter(t => t)"
    )
    return [t for t in texts + titles if t]


def test_help_texts_are_plain_sentences(server: str, page: Page, screenshot: Any) -> None:
    seen: dict[str, str] = {}
    for path in ("/", "/frequency-response", "/studies"):
        open_page(page, server + path)
        seen.update((t, path) for t in _help_texts(page))
    open_page(page, server + "/stability")
    analyses = page.eval_on_selector_all("#analysis option", "os => os.map(o => o.value)")
    assert len(analyses) > 3
    for name in analyses:
        page.select_option("#analysis", name)
        seen.update((t, f"/stability {name}") for t in _help_texts(page))
    assert len(seen) > 100  # every page's fields, not a few
    bad = {
        text: where
        for text, where in seen.items()
        if MARKUP.search(text)
        or not SENTENCE_END.search(text)
        or LOWER_START.match(LABEL.sub("", text))
        or "\n" in text
        or "  " in text
    }
    assert not bad, bad
    # the solver options' description came with a reST role; the sampling mode with `x`
    open_page(page, server + "/")
    page.click("details[data-group='options'] > summary")
    options = page.inner_text("[data-group='options'] > small.help")
    assert options.startswith("Solver options (pipeflow.solvers.Options, field for field")
    page.locator("fieldset[data-group='options']").scroll_into_view_if_needed()
    screenshot(page, "viewer-help-texts-plain-sentences")


def test_velocity_fields_have_unit_selects(server: str, page: Page, screenshot: Any) -> None:
    open_page(page, server + "/")
    page.select_option("select[name='flow.velocity.kind']", "constant")
    select = "select[data-unit-for='flow.velocity.value']"
    units = page.eval_on_selector_all(f"{select} option", "os => os.map(o => o.value)")
    assert units == ["m/s", "mm/s", "km/h", "ft/s"]
    for kind, field in (("harmonic", "mean"), ("polynomial", "coefficients")):
        page.select_option("select[name='flow.velocity.kind']", kind)
        assert page.locator(f"select[data-unit-for='flow.velocity.{field}']").count() == 1
    assert page.locator("select[data-unit-for='initial.du0']").count() == 1
    page.select_option("select[name='flow.velocity.kind']", "constant")
    page.fill("input[name='time.t_end']", "0.05")
    page.fill("input[name='time.samples']", "51")
    page.fill("input[name='flow.velocity.value']", "1")
    page.click("#run")
    page.wait_for_selector("#chart-tip[data-points='51']")
    first = page.evaluate("window.pipeflowViewer.state.result")
    # 3.6 km/h is 1 m/s: sent as a quantity, the same cache key, answered from the cache
    page.select_option(select, "km/h")
    page.fill("input[name='flow.velocity.value']", "3.6")
    page.evaluate("window.pipeflowViewer.state.result = null")
    page.click("#run")
    page.wait_for_function("window.pipeflowViewer.state.result !== null")
    second = page.evaluate("window.pipeflowViewer.state.result")
    sent = page.evaluate("JSON.parse(new URL(location.href).searchParams.get('spec'))")
    assert sent["flow"]["velocity"]["value"] == {"value": 3.6, "unit": "km/h"}
    assert second["key"] == first["key"] and second["cached"]
    page.locator("[data-union='flow.velocity']").scroll_into_view_if_needed()
    screenshot(page, "viewer-velocity-unit-select")


def test_diverged_short_run_says_so_and_how_to_get_more(
    server: str, page: Page, screenshot: Any
) -> None:
    """v = 40 m/s on the paper pipe (past v_cr = 27.69 m/s): the run stops where the
    deflection leaves the linear range, a few samples in.  The page says how many of the
    requested samples it got and offers t_end at the divergence time; that run has them
    all (every output time before the divergence)."""
    open_page(page, server + "/")
    page.select_option("select[name='flow.velocity.kind']", "constant")
    page.fill("input[name='flow.velocity.value']", "40")
    page.click("#run")
    note = page.locator("#short-run")
    note.wait_for(state="visible")
    result = page.evaluate("window.pipeflowViewer.state.result")
    shown = len(result["t"])
    assert result["status"] == "diverged" and shown < 2001 / 4
    text = note.inner_text()
    assert f"The run diverged after {shown} output samples of the 2001 requested" in text
    assert "set time.t_end to about" in text and "output.divergence_bound" in text
    suggested = float(note.get_attribute("data-suggested-t-end") or "nan")
    # two significant digits, at or just past the divergence time (rounded up)
    assert result["divergence_time"] <= suggested <= 1.1 * result["divergence_time"]
    _result_in_view(page)
    screenshot(page, "viewer-diverged-short-run-note")
    page.evaluate("window.pipeflowViewer.state.result = null")
    page.click("#short-run button")
    page.wait_for_function("window.pipeflowViewer.state.result !== null")
    again = page.evaluate("window.pipeflowViewer.state.result")
    assert page.input_value("input[name='time.t_end']") == f"{suggested:g}"
    # the whole window before the divergence: (nearly) every requested sample
    assert len(again["t"]) > 2001 / 2
    assert note.is_hidden()
