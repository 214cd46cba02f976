"""A state-space realisation of the pipe at a frozen operating point (issue 32), for
control design (python-control, MATLAB)::

    z' = A z + B w,    y = C z + D w

with the model's balanced state z = (q'_1 / w_1, ..., q'_n / w_n, q_1, ..., q_n) [m]
(:meth:`pipeflow.model.PipeModel.state_matrix`: q the Galerkin coordinates, whose shapes
phi_j are dimensionless, so every state is a displacement in metres; w_j the natural
frequencies without flow or spin [rad/s]), A = S(v, w0) [1/s], one input w (a point force
[N], or the clamp's acceleration [m/s^2]) and one output per position: the displacement
u(x) [m] (relative to the clamp), its velocity [m/s] or acceleration [m/s^2].

    B = (M^-1 f / w, 0)                 [m/(N s) per state, or s]
    displacement:  C = (0, Phi),                    D = 0   (+ the residual, below)
    velocity:      C = (Phi diag(w), 0),            D = 0
    acceleration:  C = Phi diag(w) (A_upper),       D = Phi diag(w) B_upper

(Phi_ij = phi_j(x_i / L)).  C (i W I - A)^-1 B + D is then exactly the modal frequency
response of :func:`pipeflow.frequency.frequency_response` with the same ``residual``
choice, and the eigenvalues of A are the frozen spectrum (and -1/alpha, below).

Residual flexibility (the static response R of the modes left out, [m per input unit],
:func:`pipeflow.frequency.residual_part`: the same rule and default as the frequency
response's) is carried by the displacement output: D = R; with Kelvin-Voigt damping
alpha [s] the frequency response scales it by 1 / (1 + i W alpha), realised exactly by one
more state r, r' = (w - r) / alpha (the input lagged by alpha, in the input's unit), with
C_r = R and D = 0.  A velocity or acceleration output would need R (i W)^k, which no proper
realisation has: there the residual is left out (a warning when it was asked for).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from pipeflow.frequency import (
    Load,
    _check_load,
    _check_modes,
    _check_operating_point,
    _check_positions,
    _check_quantity,
    _generalised_force,
    residual_part,
)
from pipeflow.frequency_operator import operator_at
from pipeflow.loading import Coefficients
from pipeflow.model import REVERSE_FLOW_CAVEAT, Pipe, basis_caveats
from pipeflow.spectra import max_growth_rates

FloatArray = NDArray[np.float64]

#: the output's unit by quantity
OUTPUT_UNITS = {"displacement": "m", "velocity": "m/s", "acceleration": "m/s^2"}


@dataclass(frozen=True, eq=False)
class StateSpace:
    """A, B, C, D (real) and the names and units of the states, input and outputs.

    ``A`` (2n, 2n) [1/s]; ``B`` (2n, 1) [state unit per input unit per s]; ``C`` (p, 2n)
    [output unit per m]; ``D`` (p, 1) [output unit per input unit]; ``states`` the 2n
    names (``qdot_j/w_j``, ``q_j``, all [m]; with residual flexibility and Kelvin-Voigt
    damping one more, ``residual_lag``, in the input's unit: every matrix one larger);
    ``inputs`` one name with ``input_unit`` (N or m/s^2); ``outputs`` one name per
    position with ``output_unit``; ``velocity`` [m/s], ``omega0`` [rad/s] the operating
    point; ``natural_frequencies`` w_j [rad/s]
    (the balancing scales).
    """

    A: FloatArray
    B: FloatArray
    C: FloatArray
    D: FloatArray
    states: tuple[str, ...]
    inputs: tuple[str, ...]
    outputs: tuple[str, ...]
    input_unit: str
    output_unit: str
    velocity: float
    omega0: float
    positions: FloatArray
    natural_frequencies: FloatArray
    quantity: str
    load: Load
    warnings: tuple[str, ...] = ()


def state_space(
    pipe: Pipe,
    velocity: float,
    omega0: float,
    *,
    load: Load,
    positions: ArrayLike,
    quantity: str = "displacement",
    modes: int = 10,
    residual: bool | None = None,
) -> StateSpace:
    """The realisation (module docstring) of ``pipe`` at v = ``velocity`` [m/s], w0 =
    ``omega0`` [rad/s] with ``modes`` Galerkin modes (1 .. 40), input ``load`` (a
    :class:`~pipeflow.frequency.PointForce` [N] or
    :class:`~pipeflow.frequency.BaseAcceleration` [m/s^2]) and the ``quantity``
    ("displacement", "velocity", "acceleration") at ``positions`` x [m] in (0, L];
    ``residual``: the residual flexibility (module docstring; None: the frequency
    response's default)."""
    v, w0 = _check_operating_point(velocity, omega0)
    n = _check_modes(modes)
    load = _check_load(pipe, load)
    x = _check_positions(pipe, positions)
    quantity = _check_quantity(quantity)
    op = operator_at(pipe, v, w0, n)
    model = op.model
    c = Coefficients(np.array([v]), np.zeros(1), np.array([w0 * w0]), np.zeros(1))
    A = np.asarray(model.state_matrix(c)[0], dtype=float)
    f = _generalised_force(model, load)
    w = np.asarray(model.omega_ref, dtype=float)
    B = np.concatenate([np.linalg.solve(model.M, f) / w, np.zeros(n)])[:, None]
    Phi = model.shapes(x / pipe.L).T  # (p, n)
    p = x.size
    if quantity == "displacement":
        C = np.hstack([np.zeros((p, n)), Phi])
        D = np.zeros((p, 1))
    elif quantity == "velocity":
        C = np.hstack([Phi * w[None, :], np.zeros((p, n))])
        D = np.zeros((p, 1))
    else:
        C = (Phi * w[None, :]) @ A[:n]
        D = (Phi * w[None, :]) @ B[:n]
    states = tuple(f"qdot_{j}/w_{j}" for j in range(1, n + 1))
    states += tuple(f"q_{j}" for j in range(1, n + 1))
    name = load.input_name
    symbol = {"displacement": "u", "velocity": "du/dt", "acceleration": "d2u/dt2"}[quantity]
    warnings: list[str] = []
    growth = float(max_growth_rates(op.xi[None])[0])
    if quantity != "displacement":
        if residual:
            warnings.append(
                f"the residual flexibility is left out of a {quantity} output: R (i W)^k has "
                "no proper state-space realisation (ask displacement outputs for it)"
            )
        residual = False
    R = residual_part(op, load, x, Phi, f, v, w0, growth <= 0.0, residual, warnings)
    if R is not None and pipe.kelvin_voigt:
        alpha = pipe.kelvin_voigt
        A = np.block([[A, np.zeros((2 * n, 1))], [np.zeros((1, 2 * n)), -np.ones((1, 1)) / alpha]])
        B = np.vstack([B, np.full((1, 1), 1.0 / alpha)])
        C = np.hstack([C, R[:, None]])
        states += ("residual_lag",)
    elif R is not None:
        D = D + R[:, None]
    if growth > 0:
        warnings.append(
            f"unstable operating point: A has an eigenvalue with Re = {growth:.4g} 1/s > 0 "
            f"(v = {v} m/s, w0 = {w0} rad/s); the model grows without bound"
        )
    if v < 0:
        warnings.append(REVERSE_FLOW_CAVEAT)
    warnings += basis_caveats(pipe)
    for arr in (A, B, C, D, x, w):
        arr.setflags(write=False)
    return StateSpace(
        A=A,
        B=B,
        C=C,
        D=D,
        states=states,
        inputs=(name,),
        outputs=tuple(f"{symbol}(x={float(xi)!r})" for xi in x),
        input_unit=load.input_unit,
        output_unit=OUTPUT_UNITS[quantity],
        velocity=v,
        omega0=w0,
        positions=x,
        natural_frequencies=w,
        quantity=quantity,
        load=load,
        warnings=tuple(warnings),
    )


__all__ = ["OUTPUT_UNITS", "StateSpace", "state_space"]
