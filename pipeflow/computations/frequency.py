"""How a frequency response and a state-space realisation run: a validated request model
(:mod:`pipeflow.schema.frequency`, :mod:`pipeflow.schema.state_space`) in, the plain
library call, its document (:mod:`pipeflow.computations.documents`) out.  ``progress`` is a
callback (fraction in [0, 1]) that may raise :class:`pipeflow.errors.Cancelled`."""

from __future__ import annotations

from typing import Any

from pipeflow._types import Progress
from pipeflow.computations import documents
from pipeflow.frequency import FrequencyResponse, frequency_grid, frequency_response, resonances
from pipeflow.schema.frequency import FrequencyResponseSpec
from pipeflow.schema.state_space import StateSpaceSpec
from pipeflow.state_space import state_space


def frequency_grid_of(spec: FrequencyResponseSpec) -> list[float] | Any:
    """The frequencies [rad/s]: the request's explicit list, or its range with every
    operating point's resonances in it (:func:`~pipeflow.frequency.frequency_grid`)."""
    f = spec.frequencies
    if f.values is not None:
        return list(f.values)
    pipe = spec.mounted_pipe()
    found = [r for v, w in spec.points() for r in resonances(pipe, v, w, modes=spec.modes)]
    assert f.min is not None and f.max is not None  # the validator's range form
    return frequency_grid(f.min, f.max, f.count, f.spacing, resonances=found)


def frequency_responses(
    spec: FrequencyResponseSpec, progress: Progress | None = None
) -> list[FrequencyResponse]:
    """:func:`~pipeflow.frequency.frequency_response` at each operating point."""
    pipe = spec.mounted_pipe()
    W = frequency_grid_of(spec)
    points = spec.points()
    out = []
    for i, (v, w) in enumerate(points):
        out.append(
            frequency_response(
                pipe,
                v,
                w,
                load=spec.load.to_load(),
                positions=spec.response.positions,
                frequencies=W,
                quantity=spec.response.quantity,
                modes=spec.modes,
                residual=spec.residual_flexibility,
                load_vectors=spec.load_vectors,
            )
        )
        if progress is not None:
            progress((i + 1) / len(points))
    return out


def run_frequency_response(
    spec: FrequencyResponseSpec, progress: Progress | None = None
) -> dict[str, Any]:
    """A frequency response: the responses at every operating point, their document."""
    return documents.frequency_response(frequency_responses(spec, progress))


def run_state_space(spec: StateSpaceSpec, progress: Progress | None = None) -> dict[str, Any]:
    """A state-space realisation (:func:`~pipeflow.state_space.state_space`): its document."""
    ss = state_space(
        spec.mounted_pipe(),
        spec.flow.velocity.value,
        spec.rotation.omega0.value,
        load=spec.load.to_load(),
        positions=spec.response.positions,
        quantity=spec.response.quantity,
        modes=spec.modes,
        residual=spec.residual_flexibility,
    )
    if progress is not None:
        progress(1.0)
    return documents.state_space(ss)
