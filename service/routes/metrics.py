"""GET /metrics: Prometheus text exposition (see :mod:`service.observability`)."""

from __future__ import annotations

import asyncio

from fastapi import APIRouter, Response

from service import observability
from service.deps import RunnerDep, StoreDep

router = APIRouter(tags=["health"])


@router.get(
    "/metrics",
    operation_id="getMetrics",
    summary="Prometheus metrics",
    response_class=Response,
    responses={
        200: {
            "description": "Prometheus text format 0.0.4.",
            "content": {observability.METRICS_CONTENT_TYPE: {"schema": {"type": "string"}}},
        }
    },
)
async def metrics(runner: RunnerDep, store: StoreDep) -> Response:
    """Requests by route template, method and status (count, latency histogram [s]);
    computations by kind and method_used (count, duration histogram [s]); cache hits and
    misses; job records by status; queue depth, computations in flight and workers."""
    stats = await asyncio.to_thread(observability.engine_stats, runner, store)
    body = await asyncio.to_thread(observability.exposition, stats)
    return Response(body, media_type=observability.METRICS_CONTENT_TYPE)
