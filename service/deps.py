"""Request dependencies as ``Annotated`` aliases: the seam tests override."""

from __future__ import annotations

from typing import Annotated

from fastapi import Depends, Request

from service.engine import Runner
from service.settings import Settings
from service.store import Store


def get_settings(request: Request) -> Settings:
    settings: Settings = request.app.state.settings
    return settings


def get_runner(request: Request) -> Runner:
    runner: Runner = request.app.state.runner
    return runner


def get_store(request: Request) -> Store:
    store: Store = request.app.state.store
    return store


SettingsDep = Annotated[Settings, Depends(get_settings)]
RunnerDep = Annotated[Runner, Depends(get_runner)]
StoreDep = Annotated[Store, Depends(get_store)]
