"""Time profiles for the flow velocity v(t) [m/s] and the spin w0(t) [rad/s].

Every profile gives, for an array of times ``t`` [s]:

- ``value(t)``: p(t)
- ``derivative(t)``: dp/dt (per second)
- ``integral(t)``: integral of p from 0 to t (unit of p times s)
- ``integral_square(t)``: integral of p^2 from 0 to t (unit of p squared times s)

in closed form where the profile allows (all four kinds here do), which is what makes the
complex modal analysis "semi-analytical": the integrated state matrix P(t) of eq. (18)
needs no time stepping.
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Literal

import numpy as np
from numpy.polynomial import Polynomial as _Poly
from numpy.typing import ArrayLike
from scipy.interpolate import CubicSpline, PchipInterpolator, PPoly

from pipeflow._types import FloatArray

Interpolation = Literal["linear", "cubic", "pchip"]


def _arr(t: ArrayLike) -> FloatArray:
    return np.asarray(t, dtype=float)


class Profile(ABC):
    """A scalar function of time with closed-form derivative and integrals."""

    @abstractmethod
    def value(self, t: ArrayLike) -> FloatArray: ...

    @abstractmethod
    def derivative(self, t: ArrayLike) -> FloatArray: ...

    @abstractmethod
    def integral(self, t: ArrayLike) -> FloatArray: ...

    @abstractmethod
    def integral_square(self, t: ArrayLike) -> FloatArray: ...

    @property
    def is_constant(self) -> bool:
        return False

    def domain_end(self) -> float:
        """Last time [s] at which the profile is defined (``inf`` for analytic ones)."""
        return math.inf


@dataclass(frozen=True)
class Constant(Profile):
    """p(t) = value."""

    val: float

    def value(self, t: ArrayLike) -> FloatArray:
        return np.full_like(_arr(t), self.val)

    def derivative(self, t: ArrayLike) -> FloatArray:
        return np.zeros_like(_arr(t))

    def integral(self, t: ArrayLike) -> FloatArray:
        return self.val * _arr(t)

    def integral_square(self, t: ArrayLike) -> FloatArray:
        return self.val**2 * _arr(t)

    @property
    def is_constant(self) -> bool:
        return True


@dataclass(frozen=True)
class Polynomial(Profile):
    """p(t) = sum_k coefficients[k] t^k (the paper's a, a t, a t^2)."""

    coefficients: tuple[float, ...]
    _c: tuple[FloatArray, ...] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        if len(self.coefficients) == 0:
            raise ValueError("a polynomial needs at least one coefficient")
        p = _Poly(np.asarray(self.coefficients, dtype=float))
        # value, derivative, integral and integral of the square, highest power first
        polys = (p, p.deriv(), p.integ(lbnd=0.0), (p * p).integ(lbnd=0.0))
        object.__setattr__(self, "_c", tuple(q.coef[::-1].copy() for q in polys))

    def value(self, t: ArrayLike) -> FloatArray:
        return np.asarray(np.polyval(self._c[0], _arr(t)), dtype=float)

    def derivative(self, t: ArrayLike) -> FloatArray:
        return np.asarray(np.polyval(self._c[1], _arr(t)), dtype=float)

    def integral(self, t: ArrayLike) -> FloatArray:
        return np.asarray(np.polyval(self._c[2], _arr(t)), dtype=float)

    def integral_square(self, t: ArrayLike) -> FloatArray:
        return np.asarray(np.polyval(self._c[3], _arr(t)), dtype=float)

    @property
    def is_constant(self) -> bool:
        return all(c == 0.0 for c in self.coefficients[1:])


@dataclass(frozen=True)
class Harmonic(Profile):
    """p(t) = mean + amplitude * sin(frequency * t + phase); frequency [rad/s], phase [rad]."""

    mean: float
    amplitude: float
    frequency: float
    phase: float = 0.0

    def _arg(self, t: FloatArray) -> FloatArray:
        return self.frequency * t + self.phase

    def value(self, t: ArrayLike) -> FloatArray:
        t = _arr(t)
        return self.mean + self.amplitude * np.sin(self._arg(t))

    def derivative(self, t: ArrayLike) -> FloatArray:
        t = _arr(t)
        return self.amplitude * self.frequency * np.cos(self._arg(t))

    def integral(self, t: ArrayLike) -> FloatArray:
        t = _arr(t)
        if self.frequency == 0.0:
            return (self.mean + self.amplitude * math.sin(self.phase)) * t
        w, ph = self.frequency, self.phase
        return self.mean * t - self.amplitude / w * (np.cos(self._arg(t)) - math.cos(ph))

    def integral_square(self, t: ArrayLike) -> FloatArray:
        t = _arr(t)
        if self.frequency == 0.0:
            return (self.mean + self.amplitude * math.sin(self.phase)) ** 2 * t
        m, a, w, ph = self.mean, self.amplitude, self.frequency, self.phase
        int_sin = -(np.cos(self._arg(t)) - math.cos(ph)) / w
        int_sin2 = 0.5 * t - (np.sin(2.0 * self._arg(t)) - math.sin(2.0 * ph)) / (4.0 * w)
        return m * m * t + 2.0 * m * a * int_sin + a * a * int_sin2

    @property
    def is_constant(self) -> bool:
        return self.amplitude == 0.0 or self.frequency == 0.0


def _square_ppoly(p: PPoly) -> PPoly:
    """Exact piecewise-polynomial square of ``p`` (local power basis convolution)."""
    c = p.c  # (k+1, m), highest power first
    k1, m = c.shape
    c2 = np.zeros((2 * k1 - 1, m))
    for i in range(k1):
        for j in range(k1):
            c2[i + j] += c[i] * c[j]
    return PPoly(c2, p.x, extrapolate=False)


@dataclass(frozen=True, eq=False)
class Table(Profile):
    """Tabulated (t [s], value) pairs with linear, cubic-spline or PCHIP interpolation.

    The table must start at or before t = 0 and cover the simulated interval; outside it
    the profile is undefined and evaluation raises ``ValueError``.
    """

    times: tuple[float, ...]
    values: tuple[float, ...]
    interpolation: Interpolation = "linear"
    _pp: PPoly = field(init=False, repr=False)
    _dpp: PPoly = field(init=False, repr=False)
    _ipp: PPoly = field(init=False, repr=False)
    _i2pp: PPoly = field(init=False, repr=False)
    _offset: tuple[float, float] = field(init=False, repr=False)

    def __post_init__(self) -> None:
        t = np.asarray(self.times, dtype=float)
        y = np.asarray(self.values, dtype=float)
        if t.ndim != 1 or t.shape != y.shape:
            raise ValueError("table times and values must be 1-D and of equal length")
        if t.size < 2:
            raise ValueError("a table needs at least two points")
        if not np.all(np.diff(t) > 0):
            raise ValueError("table times must be strictly increasing")
        if t[0] > 0.0:
            raise ValueError("table must start at or before t = 0")
        if self.interpolation == "linear":
            slope = np.diff(y) / np.diff(t)
            pp = PPoly(np.vstack([slope, y[:-1]]), t, extrapolate=False)
        elif self.interpolation == "cubic":
            if t.size < 3:
                pp = CubicSpline(t, y, bc_type="natural", extrapolate=False)
            else:
                pp = CubicSpline(t, y, bc_type="not-a-knot", extrapolate=False)
        elif self.interpolation == "pchip":
            pp = PchipInterpolator(t, y, extrapolate=False)
        else:
            raise ValueError(f"unknown interpolation {self.interpolation!r}")
        ipp = pp.antiderivative()
        i2pp = _square_ppoly(pp).antiderivative()
        object.__setattr__(self, "_pp", pp)
        object.__setattr__(self, "_dpp", pp.derivative())
        object.__setattr__(self, "_ipp", ipp)
        object.__setattr__(self, "_i2pp", i2pp)
        object.__setattr__(self, "_offset", (float(ipp(0.0)), float(i2pp(0.0))))

    def _check(self, t: FloatArray) -> FloatArray:
        if t.size and (np.min(t) < self.times[0] or np.max(t) > self.times[-1] * (1 + 1e-12)):
            raise ValueError(
                f"table profile is defined on [{self.times[0]}, {self.times[-1]}] s; "
                f"asked for t in [{np.min(t)}, {np.max(t)}] s"
            )
        return np.clip(t, self.times[0], self.times[-1])

    def value(self, t: ArrayLike) -> FloatArray:
        return np.asarray(self._pp(self._check(_arr(t))), dtype=float)

    def derivative(self, t: ArrayLike) -> FloatArray:
        return np.asarray(self._dpp(self._check(_arr(t))), dtype=float)

    def integral(self, t: ArrayLike) -> FloatArray:
        return np.asarray(self._ipp(self._check(_arr(t))) - self._offset[0], dtype=float)

    def integral_square(self, t: ArrayLike) -> FloatArray:
        return np.asarray(self._i2pp(self._check(_arr(t))) - self._offset[1], dtype=float)

    @property
    def is_constant(self) -> bool:
        return bool(np.all(np.asarray(self.values) == self.values[0]))

    def domain_end(self) -> float:
        return float(self.times[-1])


def polynomial(*coefficients: float) -> Polynomial:
    """Shorthand: ``polynomial(0, 0.4)`` is v = 0.4 t."""
    return Polynomial(tuple(float(c) for c in coefficients))


def table(
    times: Sequence[float], values: Sequence[float], interpolation: Interpolation = "linear"
) -> Table:
    return Table(tuple(map(float, times)), tuple(map(float, values)), interpolation)
