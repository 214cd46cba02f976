"""The stability page (/stability) in a real headless browser (set-up and screenshots:
``tests/conftest.py``, ``tests/service/browser.py``).

Checks: the analysis list is the API's (``/v1/stability`` plus every ``/v1/sweeps`` kind of
the schema); critical velocities show every crossing (the paper pipe at 100 rad/s loses
stability at 27.69 m/s, README / ``critical_velocities``); a Campbell sweep runs as a job
with progress polled from ``/v1/jobs/{key}``, its excitation crossings tabled as the API
returned them and its figures loaded; Argand, spin and beta maps render; a shareable link
reloads the result; a bad range shows the API's message next to the field.  A pipe unstable
at rest (1000 rad/s) shows no critical velocity but its stable intervals, on the page, in
its spin map's table and in its report (issue 34).
"""

from __future__ import annotations

from typing import Any

import httpx
import pytest

from pipeflow.schema.stability import PAPER_PIPE_JSON
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
    # the range cut where the pipe changes stability: stable from rest, flutter from v_cr
    assert _table(page, 0) == [
        ["0", f"{result['critical_velocity']:.6g}", "stable", "start of the range"],
        [f"{result['critical_velocity']:.6g}", "60", "unstable", "loss by flutter, mode 3"],
    ]
    rows = _table(page, 1)
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
            "Critical velocity v_cr = 27.69",
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
            "spins the pipe is stable at v = 0 m/s",
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
        assert float(rows[0][1]) == pytest.approx(first["value"], rel=1e-5)  # stable until
        assert float(_table(page, 1)[0][0]) == pytest.approx(first["value"], rel=1e-5)
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


# -- a pipe unstable at rest (issue 34, safety item 1) ----------------------------------------
# The paper's pipe at 1000 rad/s diverges at v = 0, is stable from 17.51 to 34.31 m/s and
# flutters above (tests/pipeflow/stability/test_unstable_at_rest.py checks the numbers on
# the spectrum).  The API's critical_velocity there is 34.31 m/s, the first loss after the
# regain: no page may show it as a critical velocity.


def _g(x: float, digits: int = 6) -> str:
    """A number as the pages' fmt writes it (``digits`` significant)."""
    return f"{x:.{digits}g}"


def test_a_pipe_unstable_at_rest_has_no_critical_velocity(
    server: str, page: Page, screenshot: Any
) -> None:
    open_page(page, server + "/stability")
    page.fill("input[name='rotation.omega0.value']", "1000")
    result = _run(page)
    assert result["stable_at_start"] is False and result["instability_at_start"] == ["divergence"]
    assert result["critical_velocity"] == pytest.approx(34.314, abs=1e-3)  # the API's field
    [(a, b)] = result["stable_intervals"]
    summary = page.inner_text("#summary")
    assert summary.startswith(
        "No critical velocity: at ω0 = 1000 rad/s the pipe is already unstable at v = 0 m/s."
    )
    assert (
        f"Unstable at v = 0 m/s (divergence); regains stability at {_g(a, 5)} m/s (divergence, "
        f"mode 1), then loses stability at {_g(b, 5)} m/s (flutter, mode 3). Stable on "
        f"[{_g(a, 5)}, {_g(b, 5)}] m/s."
    ) in summary
    assert "v_cr" not in summary and "Critical velocity" not in summary
    assert "ok" not in (page.get_attribute("#summary", "class") or "")  # the red banner
    assert _table(page, 0) == [
        ["0", _g(a), "unstable", "start of the range (divergence)"],
        [_g(a), _g(b), "stable", "regained: divergence, mode 1"],
        [_g(b), "60", "unstable", "loss by flutter, mode 3"],
    ]
    page.locator("#summary").scroll_into_view_if_needed()
    screenshot(page, "stability-unstable-at-rest")

    # its report: no critical velocity either, the same picture
    page.goto(f"{server}/v1/results/{result['key']}/report.html")
    text = page.inner_text("body")
    label = "critical velocity v_cr [m/s]: the first loss of stability from v = 0 m/s"
    assert f"{label}\tnone: already unstable at v = 0 m/s" in text
    assert "stable at the start of the range, v = 0 m/s\tno: divergence" in text
    assert f"stable intervals [m/s]\t[{_g(a, 5)}, {_g(b, 5)}] m/s" in text
    screenshot(page, "report-unstable-at-rest")


def test_the_spin_map_table_gives_each_spins_stable_intervals(
    server: str, page: Page, screenshot: Any
) -> None:
    fields = {
        "velocity_range": "0, 60",
        "spin_range": "0, 1000",
        "velocity_points": "61",
        "spin_points": "5",
        "modes": "10",
    }
    open_page(page, server + "/stability?analysis=spin_map")
    for name, value in fields.items():
        page.fill(f"input[name='{name}']", value)
    result = _run(page)
    assert result["spins"] == [0, 250, 500, 750, 1000]
    assert result["stable_at_start"] == [True, True, False, False, False]
    rows = _table(page, 0)
    assert len(rows) == 5
    for row, ok, v_cr, stable in zip(
        rows,
        result["stable_at_start"],
        result["critical_velocity"],
        result["stable_intervals"],
        strict=True,
    ):
        assert row[2] == ("stable" if ok else "unstable (divergence)")
        # v_cr only from a stable start: never the loss after the regain
        assert row[3] == (_g(v_cr) if ok else "none: unstable at v = 0 m/s")
        assert row[4] == ", ".join(f"[{_g(x, 5)}, {_g(y, 5)}]" for x, y in stable)
    assert rows[-1][5] == (
        f"gain {_g(result['stable_intervals'][-1][0][0], 5)} (divergence); "
        f"loss {_g(result['stable_intervals'][-1][0][1], 5)} (flutter)"
    )
    # the same line by the independent analysis (branch following, not the map's max sigma)
    spec = {
        "pipe": PAPER_PIPE_JSON,
        "rotation": {"omega0": {"kind": "constant", "value": 1000.0}},
        "modes": 10,
        "velocity_range": [0.0, 60.0],
    }
    line = httpx.post(server + "/v1/stability", json=spec, timeout=120).json()
    [(a, b)] = line["stable_intervals"]
    assert rows[-1][4] == f"[{_g(a, 5)}, {_g(b, 5)}]"
    summary = page.inner_text("#summary")
    assert "At 2 of 5 spins the pipe is stable at v = 0 m/s and loses stability at v_cr" in summary
    assert (
        "At 3 spins (the lowest ω0 = 500 rad/s) it is already unstable at v = 0 m/s (divergence): "
        "no critical velocity there"
    ) in summary
    _figures_loaded(page, ["spin_map"])
    page.locator("#summary").scroll_into_view_if_needed()
    screenshot(page, "stability-spin-map-unstable-at-rest")
