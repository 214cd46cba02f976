"""The one rule for numbers in every JSON document pipeflow writes: JSON has no Inf/NaN."""

from __future__ import annotations

import math
from typing import Any

_FLOAT = frozenset({float})
#: exact types a JSON-ready list may hold as they are (floats when finite)
_PLAIN = frozenset({float, int, bool, str, type(None)})


def json_safe(data: Any) -> Any:
    """JSON-ready copy: non-finite floats become null (JSON has no Inf/NaN), numpy scalars
    Python numbers, nested dicts, lists and tuples are walked.  The one rule for every result.

    A list of Python floats whose sum is finite (no Inf or NaN among them, which would make
    it Inf or NaN; a sum that overflows takes the element-wise path too) is copied as it is:
    the traces of a result are such lists, and the per-element walk cost ~4 ms on a
    2001-sample result.  So is a list of plain scalars (``int``, ``bool``, ``str``,
    ``None`` and such floats, exact types: a study's rows), whose walk cost ~100 ms of a
    10,000-case study's serial tail."""
    if isinstance(data, dict):
        return {k: json_safe(v) for k, v in data.items()}
    if isinstance(data, list | tuple):
        kinds = set(map(type, data))
        if kinds <= _FLOAT:
            if math.isfinite(sum(data)):
                return list(data)
        elif kinds <= _PLAIN and math.isfinite(sum(v for v in data if type(v) is float)):
            return list(data)
        return [json_safe(v) for v in data]
    if hasattr(data, "item") and not isinstance(data, str):
        data = data.item()
    if isinstance(data, float) and not math.isfinite(data):
        return None
    return data
