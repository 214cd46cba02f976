"""The service's JSON encoder: orjson, under pipeflow's one rule for non-finite numbers.

:func:`pipeflow.io.json.json_safe` is the rule (Inf and NaN become null; numpy scalars
become Python numbers); orjson applies exactly that rule natively (it writes NaN and
+-Infinity as null, and numpy scalars and arrays with ``OPT_SERIALIZE_NUMPY``), so the
bytes of :func:`dumps` decode to ``json_safe(obj)`` without walking ``obj`` in Python
(tests/service/http/test_encoding.py checks the identity).  About 50x faster than ``json`` on
a 2001-sample result.  Imports neither numpy nor pipeflow (worker processes import it
before their BLAS threads are pinned).
"""

from __future__ import annotations

from typing import Any

import orjson

_OPTIONS = orjson.OPT_SERIALIZE_NUMPY


def _fallback(obj: Any) -> Any:
    """What orjson hands back: numpy arrays it cannot write directly (not C-contiguous,
    e.g. a transposed or strided view) become lists, other numpy values Python ones."""
    tolist = getattr(obj, "tolist", None)
    if callable(tolist):
        return tolist()
    raise TypeError(f"{type(obj).__name__} is not JSON serialisable")


def dumps(obj: Any) -> bytes:
    """Compact JSON bytes of ``obj``; non-finite floats are written as null."""
    return orjson.dumps(obj, default=_fallback, option=_OPTIONS)
