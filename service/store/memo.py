"""The service's :class:`pipeflow.parallel.Memo`: results of pieces in the result store.

A study keeps one summary per case (:mod:`pipeflow.computations.study_runner`) under a memo key
``<kind>:<key>`` (``study_case:<the case's own key>``); here each is a row of the results
table of that kind, JSON compressed like every result, read and written in batches (one
query per look-up, one transaction per write).  The memo keys never match a result's key
(a bare SHA-256 hex), so ``GET /v1/results/{key}`` never serves a summary in place of the
full result of the standalone request.

A failing store does not fail the computation using the memo: a failed look-up is a miss,
a failed write is logged (the store is marked unhealthy and the computation's own result
write reports it).

A memo travels with the pieces of a study to the workers that run them (each piece looks
up and writes its own cases, :mod:`pipeflow.computations.study_runner`): it pickles as its
store's URL and reopens as the worker process's own store of that database
(:func:`service.store.worker_store`), never as a copy of a connection.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping, Sequence
from typing import Any

import orjson

from service import encoding
from service.store import StorageError, Store, worker_store

log = logging.getLogger("service.store")


class StoreMemo:
    """Piece results by memo key, in ``store`` (rows of kind ``<kind>`` of the key)."""

    def __init__(self, store: Store) -> None:
        self.store = store

    def __reduce__(self) -> tuple[Any, tuple[str, int]]:
        return _reopen, (self.store.url, self.store.cache_max_bytes)

    def get_many(self, keys: Sequence[str]) -> dict[str, dict[str, Any]]:
        try:
            bodies = self.store.get_results(keys)
        except StorageError as exc:
            log.warning("memo look-up failed, computing instead: %s", exc)
            return {}
        return {key: orjson.loads(body) for key, body in bodies.items()}

    def put_many(self, results: Mapping[str, dict[str, Any]]) -> None:
        items = {key: (key.partition(":")[0], encoding.dumps(r)) for key, r in results.items()}
        try:
            self.store.put_results(items)
        except StorageError as exc:
            log.warning("memo write failed (%d results not kept): %s", len(items), exc)


def _reopen(url: str, cache_max_bytes: int) -> StoreMemo:
    """A pickled :class:`StoreMemo` in the process that unpickles it (a Dask worker)."""
    return StoreMemo(worker_store(url, cache_max_bytes))
