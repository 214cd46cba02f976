"""The cache key of a request: one parameter hash, the same wherever it is computed.

``canonical_key(name, canonical)`` is the SHA-256 of the RFC 8785 canonical JSON of
``{"pipeflow": version, "kind": name, "spec": canonical}``, where ``canonical`` is the
request's normalised form (:meth:`pipeflow.schema.simulation.StrictModel.canonical`:
defaults filled in, options the method ignores dropped).  Equivalent requests (key order,
``1`` vs ``1.0``, defaults omitted or spelled out) share a key; any change to a number
that matters, or a new pipeflow version, changes it.  The service uses it as the job id,
the cache key and the ETag; a study (:mod:`pipeflow.computations.study_runner`) keys each of its
cases with it, so a case's key is the key the case has as a standalone request.
"""

from __future__ import annotations

import hashlib
from typing import Any

import rfc8785

from pipeflow import __version__


def canonical_key(name: str, canonical: dict[str, Any]) -> str:
    """SHA-256 hex of the salted RFC 8785 form of ``canonical`` for computation ``name``."""
    payload: dict[str, Any] = {"pipeflow": __version__, "kind": name, "spec": canonical}
    return hashlib.sha256(rfc8785.dumps(payload)).hexdigest()
