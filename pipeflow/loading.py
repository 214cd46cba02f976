"""The time dependence of a run (:class:`Loading`): the flow velocity v(t), the spin w0(t)
and a time-varying internal pressure p(t), the values of their coefficient functions at
given times (:class:`Coefficients`, the weights of the state matrix's pieces) and their
integrals (:class:`Integrals`, for the CMA's P(t), eq. 18)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from pipeflow._types import FloatArray
from pipeflow.profiles import Profile, Shifted


@dataclass(frozen=True)
class Coefficients:
    """Values of the time-dependent coefficient functions at a set of times.

    ``v`` [m/s], ``vdot`` [m/s^2], ``w2`` = w0^2 [rad^2/s^2], ``wdot`` = dw0/dt [rad/s^2].
    """

    v: FloatArray
    vdot: FloatArray
    w2: FloatArray
    wdot: FloatArray
    #: p(t) [Pa] of a time-varying internal pressure (None: a constant one, in K_0)
    p: FloatArray | None = None

    def weights(self) -> FloatArray:
        """Rows (1, v, vdot, v^2, w0^2), shape ``(len(t), 5)``, and p when the pressure
        varies (``(len(t), 6)``): the weights of :attr:`PipeModel.state_pieces` in S(t)
        (mixed units, see the fields)."""
        rows = [np.ones_like(self.v), self.v, self.vdot, self.v * self.v, self.w2]
        if self.p is not None:
            rows.append(self.p)
        return np.stack(rows, axis=1)


@dataclass(frozen=True)
class Integrals:
    """Integrals from 0 to t of the coefficient functions, as needed by P(t) (eq. 18).

    ``t`` [s], ``v`` = int v [m], ``dv`` = v(t) - v(0) [m/s], ``v2`` = int v^2 [m^2/s],
    ``w2`` = int w0^2 [rad^2/s], ``dw`` = w0(t) - w0(0) [rad/s].
    """

    t: FloatArray
    v: FloatArray
    dv: FloatArray
    v2: FloatArray
    w2: FloatArray
    dw: FloatArray
    #: int p [Pa s] of a time-varying pressure (None: constant, in K_0)
    p: FloatArray | None = None


@dataclass(frozen=True)
class Loading:
    """The time dependence of a run: flow velocity v(t) [m/s], spin w0(t) [rad/s] and,
    when it varies, the internal pressure p(t) [Pa] (None: the pipe's constant
    ``pressure``, in K_0; the model then needs :meth:`PipeModel.with_pressure_piece`)."""

    flow: Profile
    spin: Profile
    pressure: Profile | None = None

    @property
    def is_time_invariant(self) -> bool:
        steady = self.pressure is None or self.pressure.is_constant
        return self.flow.is_constant and self.spin.is_constant and steady

    def shifted(self, when: float) -> Loading:
        """The loading seen from ``when`` [s] on (t' = t - when)."""
        pressure = None if self.pressure is None else Shifted(self.pressure, when)
        return Loading(Shifted(self.flow, when), Shifted(self.spin, when), pressure)

    def coefficients(self, t: ArrayLike) -> Coefficients:
        t = np.asarray(t, dtype=float)
        w0 = self.spin.value(t)
        return Coefficients(
            v=self.flow.value(t),
            vdot=self.flow.derivative(t),
            w2=w0 * w0,
            wdot=self.spin.derivative(t),
            p=None if self.pressure is None else self.pressure.value(t),
        )

    def integrals(self, t: ArrayLike) -> Integrals:
        t = np.asarray(t, dtype=float)
        zero = np.zeros(1)
        return Integrals(
            t=t,
            v=self.flow.integral(t),
            dv=self.flow.value(t) - self.flow.value(zero)[0],
            v2=self.flow.integral_square(t),
            w2=self.spin.integral_square(t),
            dw=self.spin.value(t) - self.spin.value(zero)[0],
            p=None if self.pressure is None else self.pressure.integral(t),
        )
