"""Request dependencies as ``Annotated`` aliases: the seam tests override."""

from __future__ import annotations

from typing import Annotated

from fastapi import Depends, Request

from service.engine import Runner
from service.http.negotiation import accepts_gzip
from service.http.responses import Hit
from service.settings import Settings
from service.store import Store


async def get_settings(request: Request) -> Settings:
    settings: Settings = request.app.state.settings
    return settings


async def get_runner(request: Request) -> Runner:
    runner: Runner = request.app.state.runner
    return runner


async def get_store(request: Request) -> Store:
    store: Store = request.app.state.store
    return store


async def get_hit(request: Request) -> Hit:
    """The hit path of this request: the app's hit cache and the client's gzip acceptance."""
    return Hit(request.app.state.hits, accepts_gzip(request.headers.get("accept-encoding")))


SettingsDep = Annotated[Settings, Depends(get_settings)]
RunnerDep = Annotated[Runner, Depends(get_runner)]
StoreDep = Annotated[Store, Depends(get_store)]
HitDep = Annotated[Hit, Depends(get_hit)]
