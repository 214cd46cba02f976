"""A test computation that fans out (the isolation tests): two pieces, one quick where its
parent runs, one slow and silent elsewhere, so the parent's process has a free thread while
the parent waits (another job starts there) and the job overruns its limit.

Registered in :data:`pipeflow.computations.registry.COMPUTATIONS` on import, without a route; the
workers import this module by reference when they unpickle the functions."""

from __future__ import annotations

import time
from typing import Any

from pydantic import BaseModel, ConfigDict, Field

from pipeflow import parallel
from pipeflow._types import Progress
from pipeflow.computations.registry import Computation, register


class FanSpec(BaseModel):
    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)

    near_s: float = Field(0.0, ge=0, le=120, description="Piece time in the parent's process [s].")
    far_s: float = Field(20.0, ge=0, le=120, description="Piece time in other processes [s].")
    pieces: int = Field(2, ge=2, le=8, description="Pieces of the fan-out.")
    tag: str = Field("", description="Makes otherwise equal specs distinct.")


class FanResult(BaseModel):
    workers: list[str] = Field(description="The worker of each piece.")
    plots: list[str]


def _here() -> str:
    try:
        from distributed import get_worker

        return str(get_worker().address)
    except (ImportError, ValueError):
        return ""


def _piece(item: tuple[str, float, float]) -> str:
    """Sleep without reporting: ``near`` [s] in the parent's process, ``far`` elsewhere."""
    parent, near, far = item
    here = _here()
    time.sleep(near if here == parent else far)
    return here


def fan(spec: FanSpec, progress: Progress | None) -> dict[str, Any]:
    item = (_here(), spec.near_s, spec.far_s)
    return {"workers": parallel.gather(_piece, [item] * spec.pieces, progress)}


FAN = register(Computation("test-fan", FanSpec, FanResult, fan, budget="pieces <= 8"))
