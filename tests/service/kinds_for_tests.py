"""Computations used only by the tests: cheap, controllable stand-ins for long simulations.

Registered in :data:`pipeflow.computations.registry.COMPUTATIONS` on import, without an endpoint
(no route); the worker processes import this module by reference when they unpickle the
functions.
"""

from __future__ import annotations

import time
from typing import Any

from pydantic import BaseModel, ConfigDict, Field

from pipeflow._types import Progress
from pipeflow.computations.registry import Computation, register


class SleepResult(BaseModel):
    slept: float = Field(description="Seconds slept [s].")
    tag: str
    plots: list[str]


class SleepSpec(BaseModel):
    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)

    seconds: float = Field(ge=0, le=120, description="How long to run [s].")
    report: bool = Field(True, description="Call the progress callback while sleeping.")
    tag: str = Field("", description="Makes otherwise equal specs distinct.")
    estimate_s: float | None = Field(
        None, ge=0, description="What the kind's estimate says of the run time [s] (may lie)."
    )


def sleep(spec: SleepSpec, progress: Progress | None) -> dict[str, Any]:
    """Sleep ``spec.seconds``, reporting progress unless told not to."""
    start = time.monotonic()
    while (elapsed := time.monotonic() - start) < spec.seconds:
        time.sleep(0.01)
        if spec.report and progress is not None:
            progress(elapsed / spec.seconds)
    return {"slept": spec.seconds, "tag": spec.tag}


def sleep_estimate(spec: SleepSpec) -> float | None:
    """The estimate the request states (None: none; the fast lane never takes it)."""
    return spec.estimate_s


SLEEP = register(
    Computation(
        "test-sleep",
        SleepSpec,
        SleepResult,
        sleep,
        budget="seconds <= 120",
        run_time=sleep_estimate,
    )
)
