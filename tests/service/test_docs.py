"""/docs and /redoc reference only this server (the browser test renders them offline)."""

from __future__ import annotations

import re
from pathlib import Path

from fastapi.testclient import TestClient

from service.main import create_app
from service.routes.docs import ASSETS
from service.settings import Settings


def test_pages_and_assets_are_local(tmp_path: Path) -> None:
    tc = TestClient(create_app(Settings(data_dir=tmp_path)))  # no lifespan: no workers needed
    for page in ("/docs", "/redoc"):
        r = tc.get(page)
        assert r.status_code == 200 and r.headers["content-type"].startswith("text/html")
        assert "default-src 'self'" in r.headers["content-security-policy"]
        assert not re.search(r"https?://", r.text), page  # no CDN, no fonts from elsewhere
        for url in re.findall(r"""(?:src|href)=["']([^"']+)""", r.text):
            assert tc.get(url).status_code == 200, url
    for name, media in ASSETS.items():
        r = tc.get(f"/static/docs/{name}")
        assert r.status_code == 200 and r.headers["content-type"] == media
        assert len(r.content) > 1000
    r = tc.get("/static/docs/..%2Fcore.py")
    assert r.status_code == 404
    assert r.headers["content-type"] == "application/problem+json"
