"""Security headers on every answer: Content-Security-Policy, X-Content-Type-Options and
X-Frame-Options (one middleware, one table of policies).

Every response gets ``X-Content-Type-Options: nosniff`` (a browser never guesses a type
other than the declared one, e.g. runs a CSV as script), ``X-Frame-Options: DENY`` and a
``Content-Security-Policy`` with ``frame-ancestors 'none'`` (no page of the service is
framed by another site: no click-jacking), and ``Referrer-Policy: no-referrer``.  A route
sets its own policy where it serves something a browser renders: the pages
(:data:`PAGE_CSP`: scripts, styles, images and fetches from this origin only, no inline
script or style, which the viewer pages do not use), the documentation pages
(:data:`DOCS_CSP`: they configure themselves inline), SVG figures (:data:`SVG_CSP`: the
inline styles matplotlib writes, no script) and HTML reports (:data:`REPORT_CSP`).
Everything else (JSON, problem documents, tables, PNG) gets :data:`API_CSP`, which
allows nothing to load.
"""

from __future__ import annotations

from starlette.datastructures import MutableHeaders
from starlette.types import Message, Receive, Scope, Send

from service.http.middleware import HttpMiddleware

#: what every policy says besides its sources: no framing, no <base>, no plugins
_ALWAYS = {"frame-ancestors": "'none'", "base-uri": "'none'", "object-src": "'none'"}


def policy(**sources: str) -> str:
    """A Content-Security-Policy: ``default_src="'self'"`` is ``default-src 'self'``; the
    directives of :data:`_ALWAYS` are added unless given."""
    directives = {name.replace("_", "-"): value for name, value in sources.items()}
    return "; ".join(f"{k} {v}" for k, v in {**directives, **_ALWAYS, **directives}.items())


#: answers that are not pages (JSON, problems, tables, PNG): nothing may load
API_CSP = policy(default_src="'none'", form_action="'none'")
#: the viewer pages: this origin only, no inline script or style, images also as data: URLs
PAGE_CSP = policy(
    default_src="'self'",
    script_src="'self'",
    style_src="'self'",
    img_src="'self' data:",
    connect_src="'self'",
    form_action="'self'",
)
#: Swagger UI and ReDoc: inline configuration script and styles, blob: workers for ReDoc's
#: search, data: fonts and images; nothing from another origin
DOCS_CSP = policy(
    default_src="'self'",
    script_src="'self' 'unsafe-inline'",
    style_src="'self' 'unsafe-inline'",
    img_src="'self' data:",
    font_src="'self' data:",
    worker_src="'self' blob:",
    connect_src="'self'",
    form_action="'self'",
)
#: an SVG figure opened on its own: matplotlib's inline styles, nothing else
SVG_CSP = policy(default_src="'none'", style_src="'unsafe-inline'", form_action="'none'")

#: a report page (pipeflow.io.report): one self-contained document, its inline styles and
#: its figures as data: URLs, no script
REPORT_CSP = policy(
    default_src="'none'", style_src="'unsafe-inline'", img_src="data:", form_action="'none'"
)

#: the headers every answer carries (the CSP unless the route set its own)
HEADERS = {
    "X-Content-Type-Options": "nosniff",
    "X-Frame-Options": "DENY",
    "Referrer-Policy": "no-referrer",
}


class SecurityHeaders(HttpMiddleware):
    """Add :data:`HEADERS` and, unless the response has one, ``Content-Security-Policy:
    API_CSP`` to every HTTP response (outermost middleware: answers of the other
    middleware, 413s, 401s and the fast path's hits included)."""

    async def http(self, scope: Scope, receive: Receive, send: Send) -> None:
        async def secured(message: Message) -> None:
            if message["type"] == "http.response.start":
                headers = MutableHeaders(scope=message)
                for name, value in HEADERS.items():
                    headers[name] = value
                if "content-security-policy" not in headers:
                    headers["Content-Security-Policy"] = API_CSP
            await send(message)

        await self.app(scope, receive, secured)
