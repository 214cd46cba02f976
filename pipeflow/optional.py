"""Optional dependencies (the ``notebook`` and ``parquet`` extras), imported when first used.

The library's core needs only numpy, scipy and matplotlib; xarray, pandas and pyarrow are
imported by the functions that use them, so ``import pipeflow`` never pays for them and a
missing one fails with the command that installs it, not a bare ``ModuleNotFoundError``.
"""

from __future__ import annotations

import importlib
from types import ModuleType


def require(module: str, extra: str, purpose: str) -> ModuleType:
    """Import ``module`` or raise :class:`ImportError` naming the extra that provides it."""
    try:
        return importlib.import_module(module)
    except ImportError as exc:
        top = module.partition(".")[0]
        raise ImportError(
            f"{purpose} needs {top}: pip install 'pipeflow[{extra}]'", name=top
        ) from exc
