"""The stability page (/stability) in a real headless browser (set-up and screenshots:
``tests/conftest.py``, ``tests/service/browser.py``).

Checks: the analysis list is the API's (``/v1/stability`` plus every ``/v1/sweeps`` kind of
the schema); critical velocities show every crossing (the paper pipe at 100 rad/s loses
stability at 27.69 m/s, README / ``critical_velocities``); a Campbell sweep runs as a job
with progress polled from ``/v1/jobs/{key}``, its excitation crossings tabled as the API
returned them and its figures loaded; Argand, spin and beta maps render; a shareable link
reloads the result; a bad range shows the API's message next to the field.
"""

from __future__ import annotations

from typing import Any

import httpx
import pytest

from tests.service.browser import Page, open_page, page

#: slow (CI's second step): a real chromium and a server of its own: over 10 s a file
pytestmark = pytest.mark.slow

__all__ = ["page"]


def _run(page: Page) -> dict[str, Any]:
    page.click("#run")
    page.wait_for_function(
        "window.pipeflowStability.state.result !== null"
        " && document.getElementById('job-status').textContent.startsWith('done')"
    )
    result: dict[str, Any] = page.evaluate("window.pipeflowStability.state.result")
    return result


def _table(page: Page, index: int = 0) -> list[list[str]]:
    rows: list[list[str]] = page.evaluate(
        """i => [...document.querySelectorAll('#tables table')[i].tBodies[0].rows]
            .map(r => [...r.cells].map(c => c.textContent))""",
        index,
    )
    return rows


def _figures_loaded(page: Page, names: list[str]) -> None:
    for name in names:
        page.wait_for_function(
            f"(() => {{ const i = document.querySelector(\"img[data-plot='{name}']\");"
            " return i && i.complete && i.naturalWidth > 0; })()",
            timeout=120_000,
        )


def test_critical_velocities_every_crossing_and_share(
    server: str, page: Page, screenshot: Any
) -> None:
    doc = httpx.get(server + "/openapi.json", timeout=10).json()
    content = doc["paths"]["/v1/sweeps"]["post"]["requestBody"]["content"]["application/json"]
    kinds = list(content["schema"]["discriminator"]["mapping"])
    open_page(page, server + "/stability")
    options = page.eval_on_selector_all("#analysis option", "os => os.map(o => o.value)")
    assert options == ["stability", *kinds]
    result = _run(page)
    assert result["kind"] == "stability"
    assert result["critical_velocity"] == pytest.approx(27.69, abs=0.005)
    assert "Critical velocity v_cr = 27.69" in page.inner_text("#summary")
    rows = _table(page)
    assert len(rows) == len(result["crossings"]) >= 1
    for row, crossing in zip(rows, result["crossings"], strict=True):
        assert float(row[0]) == pytest.approx(crossing["velocity"], rel=1e-5)
        assert row[3] == str(crossing["mode"]) and row[5] == crossing["direction"]
    page.locator("#summary").scroll_into_view_if_needed()
    screenshot(page, "stability-critical-velocities")
    link = page.get_attribute("#share-link", "href")
    assert link and "key=" in link and "analysis=stability" in link
    page.goto("about:blank")
    open_page(page, link)
    page.wait_for_selector("#summary:has-text('27.69')")
    assert page.inner_text("#job-status").startswith("loaded result " + result["key"][:12])


def test_campbell_sweep_job_shows_progress_and_crossings(
    server: str, page: Page, screenshot: Any
) -> None:
    open_page(page, server + "/stability?analysis=campbell")
    assert page.input_value("input[name='orders']") == "1, 2"  # the schema's default
    page.fill("input[name='spin_range']", "0, 1500")
    page.fill("input[name='orders']", "0.5, 1, 2")
    page.fill("input[name='points']", "301")
    result = _run(page)
    history = page.evaluate("window.pipeflowStability.state.history")
    # the job was followed from the 202 answer (queued or running) to success
    assert history[0]["status"] in ("queued", "running"), history
    assert history[-1] == {"status": "succeeded", "progress": 1}
    assert all(0 <= h["progress"] <= 1 for h in history)
    assert page.eval_on_selector("#progress", "p => p.value") == 1
    assert result["kind"] == "campbell"
    crossings = result["excitation"]["crossings"]
    assert result["excitation"]["orders"] == [0.5, 1, 2]
    rows = _table(page)
    assert len(rows) == len(crossings) >= 3
    for row, c in zip(rows, crossings, strict=True):
        assert float(row[0]) == c["order"] and row[1] == str(c["mode"])
        assert float(row[2]) == pytest.approx(c["spin"], rel=1e-5)
    _figures_loaded(page, ["campbell", "argand"])
    page.locator("#plots").scroll_into_view_if_needed()
    screenshot(page, "stability-campbell-job")
    # the shareable link brings back the analysis, its form values and the result
    link = page.get_attribute("#share-link", "href")
    assert link and "analysis=campbell" in link
    page.goto("about:blank")
    open_page(page, link)
    page.wait_for_selector("#tables table")
    assert page.input_value("input[name='orders']") == "0.5, 1, 2"
    assert page.input_value("#analysis") == "campbell"
    assert _table(page) == rows


@pytest.mark.parametrize(
    ("kind", "fields", "plot", "summary"),
    [
        (
            "argand",
            {"velocity_range": "0, 40", "points": "121"},
            "argand",
            "Critical point: mode 3",
        ),
        (
            "spin_map",
            {
                "velocity_range": "0, 60",
                "spin_range": "0, 600",
                "velocity_points": "31",
                "spin_points": "4",
                "modes": "6",
            },
            "spin_map",
            "Critical velocity at",
        ),
        (
            "beta_map",
            {"beta_range": "0.1, 0.9", "beta_points": "5", "u_points": "61", "modes": "6"},
            "beta_map",
            "u_cr(β)",
        ),
        ("floquet", {"modes": "2"}, "floquet_multipliers", "Verdict: "),
    ],
)
def test_argand_and_maps(
    server: str,
    page: Page,
    screenshot: Any,
    kind: str,
    fields: dict[str, str],
    plot: str,
    summary: str,
) -> None:
    open_page(page, f"{server}/stability?analysis={kind}")
    for name, value in fields.items():
        page.fill(f"input[name='{name}']", value)
    result = _run(page)
    assert result["kind"] == kind
    assert summary in page.inner_text("#summary")
    rows = _table(page)
    if kind == "argand":
        first = next(c for c in result["zero_crossings"] if c["direction"] == "loss")
        assert float(rows[0][0]) == pytest.approx(first["value"], rel=1e-5)
        assert first["value"] == pytest.approx(27.69, abs=0.005)
    elif kind == "spin_map":
        assert len(rows) == len(result["spins"]) == 4
    elif kind == "beta_map":
        assert len(rows) == len(result["betas"]) == 5
    else:  # the result's scalars, the verdict among them
        assert ["verdict", result["verdict"]] in rows
    _figures_loaded(page, [plot])
    page.locator("#plots").scroll_into_view_if_needed()
    screenshot(page, f"stability-{kind}")


def test_bad_range_shows_the_api_message_next_to_the_field(server: str, page: Page) -> None:
    open_page(page, server + "/stability?analysis=argand")
    page.fill("input[name='velocity_range']", "40, 0")
    page.click("#run")
    slot = page.locator("[data-error-for='velocity_range']")
    slot.wait_for(state="visible")
    assert "increasing" in slot.inner_text()
    assert "invalid" in (page.get_attribute("input[name='velocity_range']", "class") or "")
