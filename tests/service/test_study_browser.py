"""The design-study page (/studies) in a real headless browser (set-up and screenshots:
``tests/conftest.py``, ``tests/service/browser.py``).

Checks: the form is the API's (its examples offered, the sampled parameters as a map editor);
a sampled study (16 Sobol' points of a lognormal pipe.E on a short simulation) runs as a job
followed to success, and shows the banner with P(unstable) and its standard error, a
histogram per numeric summary column (canvas drawn, mean and 5/50/95 % quantiles in its
legend equal to the answer's statistics), the statistics table and the first rows with
CSV/Parquet links that download; the shareable link reloads it by key; a saltelli study of
two parameters (the second added in the form's map editor) draws S1 and ST per parameter
with their confidence half-widths; a bad distribution shows the API's message next to its
field.
"""

from __future__ import annotations

import json
import re
from typing import Any
from urllib.parse import quote

import httpx
import pytest

from pipeflow.schema.simulation import PAPER_EXAMPLE
from tests.service.browser import Page, open_page, page

#: slow (CI's second step): a real chromium and a server of its own: over 10 s a file
pytestmark = pytest.mark.slow

__all__ = ["page"]

#: a short simulation (2 modes, 0.05 s): each case takes milliseconds
BASE = {
    "kind": "simulation",
    "spec": {**PAPER_EXAMPLE, "modes": 2, "time": {"t_end": 0.05, "samples": 51}},
}
SOBOL = {
    "base": BASE,
    "samples": {
        "count": 16,
        "method": "sobol",
        "seed": 3,
        "parameters": {"pipe.E": {"distribution": "lognormal", "median": 7.8e9, "sigma": 0.1}},
    },
}
NUMBER = re.compile(r"= (-?[0-9.]+(?:e-?[0-9]+)?)")


def _run(page: Page) -> dict[str, Any]:
    page.click("#run")
    page.wait_for_function(
        "window.pipeflowStudies.state.result !== null"
        " && document.getElementById('job-status').textContent.startsWith('done')",
        timeout=180_000,
    )
    result: dict[str, Any] = page.evaluate("window.pipeflowStudies.state.result")
    return result


def _legend(page: Page, chart: str) -> dict[str, str]:
    items: dict[str, str] = page.evaluate(
        """id => Object.fromEntries(
            [...document.querySelectorAll('#' + id + ' .chart-legend .item')]
                .map(i => [i.dataset.marker, i.textContent]))""",
        chart,
    )
    return items


def _value(text: str) -> float:
    match = NUMBER.search(text)
    assert match, text
    return float(match.group(1))


def test_sampled_study_histograms_banner_table_and_share(
    server: str, page: Page, screenshot: Any
) -> None:
    doc = httpx.get(server + "/openapi.json", timeout=10).json()
    content = doc["paths"]["/v1/studies"]["post"]["requestBody"]["content"]["application/json"]
    open_page(page, server + "/studies")
    options = page.eval_on_selector_all("#example option", "os => os.map(o => o.value)")
    assert set(content["examples"]) <= set(options)
    # the API's first example (a grid) fills the form: its grid as a map editor
    assert page.input_value("#example") == next(iter(content["examples"]))
    assert page.get_attribute("[data-map='grid']", "data-count") == "2"
    open_page(page, server + "/studies?spec=" + quote(json.dumps(SOBOL)))
    assert page.input_value("[data-map-key='samples.parameters']") == "pipe.E"
    assert page.input_value("select[name='samples.parameters.pipe.E.distribution']") == "lognormal"
    assert page.input_value("input[name='samples.parameters.pipe.E.sigma']") == "0.1"
    result = _run(page)
    history = page.evaluate("window.pipeflowStudies.state.history")
    assert history[-1] == {"status": "succeeded", "progress": 1}
    assert result["kind"] == "study" and result["counts"]["total"] == 16
    assert result["overrides"] == ["pipe.E"] and result["sensitivity"] is None
    # the banner: counts and the probability of instability with its standard error
    p = result["statistics"]["instability"]
    banner = page.inner_text("#summary")
    assert banner.startswith("16 cases of simulation: 16 ok, 0 failed")
    assert f"P(unstable) = {p['probability']:.3g}" in banner
    assert f"{p['unstable']} of {p['decided']} decided cases unstable" in banner
    # a histogram per numeric summary column, its markers the answer's statistics
    stats = result["statistics"]["columns"]
    charts = page.eval_on_selector_all(".histogram", "cs => cs.map(c => c.dataset.column)")
    assert charts == list(stats)
    units = {c["name"]: c["unit"] for c in result["columns"]}
    for name, s in stats.items():
        chart = "hist-" + name
        assert page.locator(f"#{chart} canvas").count() == 1
        assert page.get_attribute(f"#{chart}", "data-count") == str(s["count"])
        assert f"[{units[name]}]" in page.inner_text(f"#{chart} h2")
        legend = _legend(page, chart)
        assert _value(legend["mean"]) == pytest.approx(s["mean"], rel=1e-3)
        for q in ("0.05", "0.5", "0.95"):
            assert _value(legend[q]) == pytest.approx(s["quantiles"][q], rel=1e-3)
        counts = page.evaluate(f"window.pipeflowStudies.state.charts['{chart}'].data[1]")
        assert sum(counts) == s["count"]
    # something is drawn on the bars' canvas (not only the axes' background)
    bluish: int = page.evaluate(
        """() => { const c = document.querySelector('#hist-peak_tip_displacement canvas');
            const d = c.getContext('2d').getImageData(0, 0, c.width, c.height).data;
            let n = 0; for (let i = 0; i < d.length; i += 4)
              if (d[i + 3] > 0 && d[i + 2] > d[i] + 40) n++;
            return n; }"""
    )
    assert bluish > 500
    # the statistics table and the first rows, with the whole table as CSV and Parquet
    assert page.get_attribute("#cases", "data-rows") == "16"
    assert page.get_attribute("#statistics", "data-rows") == str(len(stats))
    csv = httpx.get(server + "/" + str(page.get_attribute("#csv-link", "href")), timeout=30)
    assert csv.status_code == 200 and csv.text.splitlines()[0].startswith("index [-],key,status")
    assert len(csv.text.splitlines()) == 17
    parquet = httpx.get(server + "/" + str(page.get_attribute("#parquet-link", "href")), timeout=30)
    assert parquet.status_code == 200 and parquet.content[:4] == b"PAR1"
    page.locator("#results").scroll_into_view_if_needed()
    screenshot(page, "studies-sobol-histograms")
    # the shareable link opens the study by key
    link = page.get_attribute("#share-link", "href")
    assert link and "key=" + result["key"] in link
    page.goto("about:blank")
    open_page(page, link)
    page.wait_for_selector("#hist-peak_tip_displacement canvas")
    assert page.inner_text("#job-status").startswith("loaded result " + result["key"][:12])
    assert page.inner_text("#summary") == banner
    assert page.locator("#cases tbody tr").count() == 16


def test_saltelli_study_sensitivity_bars(server: str, page: Page, screenshot: Any) -> None:
    spec = {**SOBOL, "samples": {**SOBOL["samples"], "method": "saltelli", "count": 8}}
    open_page(page, server + "/studies?spec=" + quote(json.dumps(spec)))
    # a second parameter added in the map editor: a copy of the first, renamed
    page.click("[data-add='samples.parameters']")
    keys = page.locator("[data-map-key='samples.parameters']")
    keys.nth(1).fill("pipe.M2")
    keys.nth(1).dispatch_event("change")
    page.select_option("select[name='samples.parameters.pipe.M2.distribution']", "uniform")
    page.fill("input[name='samples.parameters.pipe.M2.low']:visible", "1.5e-5")
    page.fill("input[name='samples.parameters.pipe.M2.high']:visible", "1.8e-5")
    assert page.get_attribute("[data-map='samples.parameters']", "data-count") == "2"
    page.locator("[data-map='samples.parameters']").scroll_into_view_if_needed()
    screenshot(page, "studies-form-sampled-parameters")
    result = _run(page)
    assert result["counts"]["total"] == 8 * (2 * 2 + 2)
    assert result["overrides"] == ["pipe.E", "pipe.M2"]
    sens = result["sensitivity"]
    assert sens["method"] == "saltelli" and sens["base_points"] == 8
    drawn = [n for n, c in sens["columns"].items() if c["available"]]
    assert "final_omega_1" in drawn
    for name, column in sens["columns"].items():
        if not column["available"]:  # e.g. a column constant over the design
            note = page.inner_text(f"#sensitivity p.note[data-column='{name}']")
            assert note == f"{name}: no indices ({column['reason']})"
    for name in drawn:
        chart = "sobol-" + name
        assert page.locator(f"#{chart} canvas").count() == 1
        assert page.get_attribute(f"#{chart}", "data-parameters") == "2"
        legend = _legend(page, chart)
        for path, ix in sens["columns"][name]["parameters"].items():
            s1 = legend["S1:" + path]
            assert s1.startswith(path + ": S1 = ")
            assert _value(s1) == pytest.approx(ix["S1"], abs=1e-3)
            half = float(s1.split("± ")[1])
            assert half == pytest.approx(ix["S1_conf"], rel=0.05, abs=1e-3)
            assert _value(legend["ST:" + path]) == pytest.approx(ix["ST"], abs=1e-3)
        data = page.evaluate(f"window.pipeflowStudies.state.charts['{chart}'].data")
        assert data[1] == [i["S1"] for i in sens["columns"][name]["parameters"].values()]
        assert data[2] == [i["ST"] for i in sens["columns"][name]["parameters"].values()]
    page.locator("#sensitivity").scroll_into_view_if_needed()
    screenshot(page, "studies-saltelli-sensitivity")


def test_bad_distribution_shows_the_api_message_next_to_the_field(server: str, page: Page) -> None:
    open_page(page, server + "/studies?spec=" + quote(json.dumps(SOBOL)))
    page.fill("input[name='samples.parameters.pipe.E.sigma']", "-1")
    page.click("#run")
    slot = page.locator("[data-error-for='samples.parameters.pipe.E.sigma']")
    slot.wait_for(state="visible")
    assert slot.inner_text()


def test_a_study_opened_by_key_fills_the_form_and_links_its_report(
    server: str, page: Page, screenshot: Any
) -> None:
    """A saltelli study run through the API, then opened on the page by its key alone (the
    key box): the form shows the study's own request (the result echoes it), the share link
    carries it, and the page links the study's report, whose HTML shows the Sobol' indices
    with their intervals, the standard errors, the filled "Method and diagnostics" section
    and the histogram and Sobol' figures."""
    spec = {
        **SOBOL,
        "samples": {
            **SOBOL["samples"],
            "method": "saltelli",
            "count": 8,
            "parameters": {
                **SOBOL["samples"]["parameters"],
                "pipe.M2": {"distribution": "uniform", "low": 1.5e-5, "high": 1.8e-5},
            },
        },
    }
    job = httpx.post(server + "/v1/studies", json=spec, timeout=60)
    assert job.status_code in (200, 202), job.text
    key = job.json()["key"]
    httpx.get(f"{server}/v1/jobs/{key}?wait=60", timeout=90)
    open_page(page, server + "/studies")
    assert page.input_value("#example") != ""  # the API's first example fills the form
    page.fill("#open-key", key)
    page.click("#open")
    page.wait_for_function(
        "document.getElementById('job-status').textContent.startsWith('loaded result')",
        timeout=180_000,
    )
    result = page.evaluate("window.pipeflowStudies.state.result")
    assert result["request"]["samples"]["method"] == "saltelli"
    # the form is the study's own request: collected again, it is that request
    collected = page.evaluate(
        "SchemaForm.collect(document.getElementById('fields'), window.pipeflowStudies.state.doc,"
        " window.pipeflowStudies.state.schema)"
    )
    assert collected["samples"] == result["request"]["samples"]
    assert collected["base"]["spec"]["time"] == spec["base"]["spec"]["time"]
    assert page.input_value("select[name='samples.method']") == "saltelli"
    assert page.input_value("input[name='samples.count']") == "8"
    keys = page.eval_on_selector_all(
        "[data-map-key='samples.parameters']", "es => es.map(e => e.value)"
    )
    assert keys == ["pipe.E", "pipe.M2"]
    assert page.input_value("#example") == ""  # "(as in the link)", not an example
    link = page.get_attribute("#share-link", "href") or ""
    assert "key=" + key in link and "spec=" in link
    page.locator("[data-group='samples']").first.scroll_into_view_if_needed()
    screenshot(page, "studies-opened-by-key-form-filled")
    # the report: Sobol' indices with intervals, standard errors, method and diagnostics
    href = page.get_attribute("#report-html", "href")
    assert href == f"v1/results/{key}/report.html"
    html = httpx.get(f"{server}/{href}", timeout=120).text
    assert "Sensitivity: Sobol&#x27; indices and their intervals" in html
    assert "S1 ± half-width [95 % interval]" in html
    assert "mean ± standard error of the mean" in html
    for row in ("sample size N [-] (base points)", "seed", "number of evaluations (cases) [-]"):
        assert f"<td>{row}</td>" in html, row
    assert 'id="figure-study_histograms"' in html and 'id="figure-sobol_indices"' in html
    page.goto(f"{server}/{href}")
    page.locator("text=Method and diagnostics").scroll_into_view_if_needed()
    screenshot(page, "study-report-method-and-diagnostics")
    page.locator("#figure-sobol_indices").scroll_into_view_if_needed()
    screenshot(page, "study-report-sobol-figure")
