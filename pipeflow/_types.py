"""The array type aliases of pipeflow, defined once (annotations only)."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

#: real arrays (times, states, matrices) [units of the quantity]
FloatArray = NDArray[np.float64]
#: complex arrays (eigenvalues, eigenvectors, Floquet multipliers)
ComplexArray = NDArray[np.complex128]
#: integer arrays (step counts, indices)
IntArray = NDArray[np.int64]
#: a progress callback, called with the fraction done in [0, 1]
Progress = Callable[[float], None]

__all__ = ["ComplexArray", "FloatArray", "IntArray", "Progress"]
