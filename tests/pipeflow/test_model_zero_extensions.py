"""The extended model's new fields left out or given as zero build the same arrays, bit for
bit: two computations in this process, no file (the golden-file comparison, with its
tolerance, is in test_extended_model.py)."""

from __future__ import annotations

import numpy as np
import pytest

from pipeflow.model import build_model
from tests.pipeflow.test_extended_model import ARRAYS, _paper_and_explicit


@pytest.mark.parametrize("name", ["paper", "unit"])
@pytest.mark.parametrize("n", [3, 10, 17])
def test_explicit_zero_extensions_build_the_same_model(name: str, n: int) -> None:
    """Bit for bit, both computed in this process (no file): the new fields left out or given
    explicitly as zero build identical arrays (same bits, same signs of zero: adding a zero
    term can turn -0.0 into 0.0), because ``build_model`` adds an extension's term only when
    its field is non-zero.  Built past ``build_model``'s cache (the two pipes compare equal,
    so the cache would hand back one object)."""
    pipe, explicit = _paper_and_explicit(name)
    build = build_model.__wrapped__  # uncached: two separate computations
    plain, zeros = build(pipe, n), build(explicit, n)
    for a in ARRAYS:
        new, same = getattr(plain, a), getattr(zeros, a)
        assert np.array_equal(new, same) and np.array_equal(np.signbit(new), np.signbit(same)), a
    assert not plain.C_0.any() and not zeros.C_0.any()
