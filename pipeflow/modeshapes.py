"""Complex mode shapes of the frozen spectrum: what each eigenvalue branch looks like along x.

At a time t the frozen state matrix S(t) has right eigenvectors z_j (balanced state
``[d'/omega_ref, d]``, see :class:`pipeflow.model.PipeModel`); their displacement part d_j
is a complex vector of Galerkin amplitudes, and the mode shape of branch j is

    Phi_j(x, t) = sum_k d_jk phi_k(x / L)

with phi_k the model's basis (the cantilever modes of :mod:`pipeflow.basis`, or the supports'
basis of :mod:`pipeflow.beam_modes`).  Flow makes the shapes complex
(travelling-wave content: the real and imaginary parts peak at different stations); without
flow and spin they are real multiples of the cantilever modes.

Normalisation: an eigenvector is defined up to one complex factor, so each shape is divided
by its value at the station of largest modulus: that station reads exactly 1 + 0i and
``max |Phi_j| = 1`` [-].

Branch numbering is that of ``Result.frozen`` (the ``eigenvalues`` of a result): the same
branches (the lowest modes at t = 0 and the least stable one), followed through the
eigenvalue times and the requested times by left/right eigenvector correlation
(:func:`pipeflow.spectra.assign`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from pipeflow._types import ComplexArray, FloatArray
from pipeflow.loading import Loading
from pipeflow.model import PipeModel
from pipeflow.spectra import assign, decompose, match_branches, order_lowest

#: bounds a request may ask for (the cost is one eigen-decomposition per time)
MAX_SHAPE_TIMES = 32
MAX_SHAPE_POINTS = 2001
DEFAULT_SHAPE_POINTS = 101
#: at most this many complex values times x points x branches (the traced branches plus the
#: least-stable one): under 8 MB of JSON (measured 37 bytes a value; 32 x 2001 x 41 values
#: were 114 MB from a 1 KB request)
MAX_SHAPE_VALUES = 200_000


@dataclass(frozen=True)
class ModeShapes:
    """Normalised complex mode shapes of the frozen spectrum at chosen times (SI units).

    t : times [s], shape (T,).
    x : stations along the pipe [m], shape (P,), from the clamped end 0 to the tip L.
    xi : eigenvalues sigma + i omega of the branches at those times [1/s], shape (T, B).
    shapes : Phi_j(x, t) [-], shape (T, B, P), max modulus 1 (see the module docstring).
    mode : mode number of each branch (``Traces.mode``), shape (B,); None: 1, 2, ...

    JSON form: :func:`pipeflow.computations.documents.mode_shapes`.
    """

    t: FloatArray
    x: FloatArray
    xi: ComplexArray
    shapes: ComplexArray
    mode: NDArray[np.intp] | None = None


def frozen_mode_shapes(
    model: PipeModel,
    loading: Loading,
    times: FloatArray,
    branches: int | ComplexArray,
    points: int = DEFAULT_SHAPE_POINTS,
    track_times: FloatArray | None = None,
) -> ModeShapes:
    """Mode shapes of frozen branches at ``times`` [s]: the ``branches`` lowest, or the
    branches whose eigenvalues at t = 0 are given (``Result.frozen.xi[0]``).

    ``points`` evenly spaced stations from x = 0 to x = L [m] (both included).  Branches
    are followed from t = 0 through ``track_times`` [s] (the result's eigenvalue times) and
    ``times`` together, so branch j here is branch j of the result's ``eigenvalues``.
    """
    times = np.asarray(times, dtype=float)
    grid = np.asarray(track_times if track_times is not None else [], dtype=float)
    grid = np.unique(np.concatenate([[0.0], grid, times]))
    S = model.state_matrix(loading.coefficients(grid))
    w, V, W = decompose(S)
    perm, _ = assign(w, V, W)
    if isinstance(branches, int):
        chosen = order_lowest(w[0], branches, model.pipe.damped)
    else:
        chosen = match_branches(w[0], branches)
    at = np.searchsorted(grid, times)
    cols = perm[at][:, chosen]  # (T, B): eigenvector index of branch j at each time
    xi = np.take_along_axis(w[at], cols, axis=1)
    n = model.n
    d = np.take_along_axis(V[at][:, n:, :], cols[:, None, :], axis=2)  # (T, n, B)
    x = np.linspace(0.0, model.pipe.L, points)
    phi = model.shapes(x / model.pipe.L)  # (n, P)
    shapes = np.einsum("tkb,kp->tbp", d, phi)
    peak = np.take_along_axis(shapes, np.argmax(np.abs(shapes), axis=2)[..., None], axis=2)
    return ModeShapes(t=times, x=x, xi=xi, shapes=shapes / peak)
