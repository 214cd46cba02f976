"""The pages' Content-Security-Policy in a real browser: each page loads and builds its
form with no violation, and the policy is enforced (an inline script injected into the
page does not run and is reported), so the other browser tests, which fail on any console
error, run under the real policy.
"""

from __future__ import annotations

from typing import Any

import pytest

#: slow: a live server (10-25 s to start here) and a browser
pytestmark = pytest.mark.slow

PAGES = ("/", "/stability", "/frequency-response", "/studies", "/docs", "/redoc")

#: records every securitypolicyviolation event of the page (added before its scripts run)
RECORD = """
window.__violations = [];
document.addEventListener("securitypolicyviolation", (e) => {
  window.__violations.push(e.violatedDirective + " " + e.blockedURI);
});
"""


@pytest.mark.parametrize("path", PAGES)
def test_page_loads_without_violations_and_the_policy_is_enforced(
    server: str, browser: Any, path: str
) -> None:
    context = browser.new_context()
    page = context.new_page()
    page.add_init_script(RECORD)
    console: list[str] = []
    page.on("console", lambda m: console.append(m.text) if m.type == "error" else None)
    try:
        response = page.goto(server + path)
        assert response is not None and response.status == 200
        assert "frame-ancestors 'none'" in response.headers["content-security-policy"]
        if path in ("/docs", "/redoc"):
            page.wait_for_selector(".swagger-ui .opblock, .redoc-wrap", timeout=60_000)
        else:
            page.wait_for_selector("#run:not([disabled])", timeout=60_000)  # form built
        violations = page.evaluate("window.__violations")
        if path in ("/docs", "/redoc"):
            # ReDoc asks for its logo at cdn.redoc.ly: refused, as the policy means to (no
            # other origin); nothing of this server's is refused
            assert all(v.split()[1].startswith("https://cdn.redoc.ly/") for v in violations)
            return  # their policy allows inline script (their configuration)
        assert violations == []
        assert not [c for c in console if "Content Security Policy" in c], console
        # an inline script (what an injected payload would be) is refused and reported
        ran = page.evaluate(
            """() => {
              const s = document.createElement("script");
              s.textContent = "window.__injected = true";
              document.head.appendChild(s);
              return window.__injected === true;
            }"""
        )
        assert ran is False
        for _ in range(100):  # the event is dispatched asynchronously
            violations = page.evaluate("window.__violations")
            if violations:
                break
            page.wait_for_timeout(50)
        assert any(v.startswith("script-src") for v in violations), violations
    finally:
        context.close()
