"""A fixed allow-list of files served from one package directory (the viewer's and the
documentation's static assets): no path from the request reaches the file system."""

from __future__ import annotations

from functools import lru_cache
from pathlib import Path

from fastapi import Response

from service.http.problems import ProblemError


class AllowList:
    """Files of ``directory`` by name: ``assets`` maps each servable name to its media type;
    ``what`` names them in the 404 problem ("static file", "documentation file")."""

    def __init__(self, directory: Path, assets: dict[str, str], what: str) -> None:
        self.directory = directory
        self.assets = assets
        self.what = what
        self.read = lru_cache(maxsize=None)(self._read)

    def _read(self, name: str) -> bytes:
        return (self.directory / name).read_bytes()

    def response(self, name: str) -> Response:
        """The asset ``name`` (cacheable for an hour), or a 404 problem naming it."""
        if name not in self.assets:
            raise ProblemError(404, f"no {self.what} {name!r}", slug="not-found")
        return Response(
            self.read(name),
            media_type=self.assets[name],
            headers={"Cache-Control": "public, max-age=3600"},
        )
