"""Time profiles for the flow velocity v(t) [m/s] and the spin w0(t) [rad/s].

Every profile gives, for an array of times ``t`` [s]:

- ``value(t)``: p(t)
- ``derivative(t)``: dp/dt (per second)
- ``integral(t)``: integral of p from 0 to t (unit of p times s)
- ``integral_square(t)``: integral of p^2 from 0 to t (unit of p squared times s)

in closed form where the profile allows (all kinds here do), which is what makes the
complex modal analysis "semi-analytical": the integrated state matrix P(t) of eq. (18)
needs no time stepping.

``terms()`` writes an analytic profile as a finite sum of exponential-polynomial pieces
(:class:`Term`), c (t - t_a)^k e^{s (t - t_a)} on [t_a, t_b]: the form whose convolution
with the modal exponentials has a closed form (:mod:`pipeflow.solvers.convolution`).
Tables return None (they are convolved by quadrature).
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np
from numpy.polynomial import Polynomial as _Poly
from numpy.typing import ArrayLike, NDArray
from scipy.interpolate import CubicSpline, PchipInterpolator, PPoly

from pipeflow._types import FloatArray

Interpolation = Literal["linear", "cubic", "pchip"]


def _arr(t: ArrayLike) -> FloatArray:
    return np.asarray(t, dtype=float)


@dataclass(frozen=True)
class Term:
    """One exponential-polynomial piece of a profile: ``coef`` (t - start)^power
    e^{rate (t - start)} for start <= t <= end [s], zero elsewhere; ``rate`` [1/s] complex.
    ``power`` -1 is the impulse ``coef`` delta(t - start) (``coef`` in the profile's unit
    times s)."""

    coef: complex
    power: int = 0
    rate: complex = 0.0
    start: float = 0.0
    end: float = math.inf


def _sine_terms(
    amplitude: float, frequency: float, phase: float, start: float, end: float
) -> tuple[Term, Term]:
    """amplitude sin(frequency (t - start) + phase) on [start, end] as two exponentials."""
    a = amplitude * complex(math.cos(phase), math.sin(phase)) / 2j
    return (
        Term(a, 0, 1j * frequency, start, end),
        Term(a.conjugate(), 0, -1j * frequency, start, end),
    )


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

    @property
    def onset(self) -> float:
        """The profile is zero before this time [s] (0: it may act from the start; a pulse's
        start, an impulse's time)."""
        return 0.0

    def terms(self) -> tuple[Term, ...] | None:
        """The profile as a sum of :class:`Term` pieces, or None (no closed form: tables)."""
        return None

    def breaks(self) -> tuple[float, ...]:
        """Times [s] where the profile or a derivative jumps (quadrature splits there)."""
        return ()

    @property
    def rate(self) -> float:
        """A rate [rad/s] at which the profile oscillates (the quadrature of a table load
        resolves it): a harmonic's frequency, 0 for the others."""
        return 0.0

    def to_dict(self) -> dict[str, Any]:
        """The request JSON of the profile (the schema's ``kind`` forms)."""
        raise TypeError(f"no JSON form for {self!r}")

    @property
    def impulsive(self) -> bool:
        """True when the profile holds a Dirac impulse (it cannot be sampled)."""
        return any(term.power < 0 for term in self.terms() or ())


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

    def terms(self) -> tuple[Term, ...]:
        return (Term(self.val),)

    def to_dict(self) -> dict[str, Any]:
        return {"kind": "constant", "value": self.val}


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

    def terms(self) -> tuple[Term, ...]:
        return tuple(Term(c, k) for k, c in enumerate(self.coefficients) if c != 0.0)

    def to_dict(self) -> dict[str, Any]:
        return {"kind": "polynomial", "coefficients": list(self.coefficients)}


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

    def terms(self) -> tuple[Term, ...]:
        if self.is_constant:
            return (Term(float(self.value(np.zeros(1))[0])),)
        mean = (Term(self.mean),) if self.mean else ()
        return mean + _sine_terms(self.amplitude, self.frequency, self.phase, 0.0, math.inf)

    @property
    def rate(self) -> float:
        return 0.0 if self.is_constant else abs(float(self.frequency))

    def to_dict(self) -> dict[str, Any]:
        return {
            "kind": "harmonic",
            "mean": self.mean,
            "amplitude": self.amplitude,
            "frequency": self.frequency,
            "phase": self.phase,
        }


@dataclass(frozen=True)
class HalfSine(Profile):
    """A half-sine pulse: p(t) = peak sin(pi (t - start) / duration) for
    start <= t <= start + duration [s], zero elsewhere (a hammer blow of finite duration;
    its time integral is 2 peak duration / pi)."""

    peak: float
    start: float
    duration: float

    def __post_init__(self) -> None:
        if not (math.isfinite(self.duration) and self.duration > 0):
            raise ValueError("a half-sine pulse needs a duration > 0 s")
        if not (math.isfinite(self.start) and self.start >= 0):
            raise ValueError("a half-sine pulse starts at t >= 0 s")

    @property
    def onset(self) -> float:
        return self.start

    @property
    def _w(self) -> float:
        return math.pi / self.duration

    def _tau(self, t: ArrayLike) -> FloatArray:
        return np.clip(_arr(t) - self.start, 0.0, self.duration)

    def _inside(self, t: ArrayLike) -> NDArray[np.bool_]:
        t = _arr(t)
        return (t >= self.start) & (t <= self.start + self.duration)

    def value(self, t: ArrayLike) -> FloatArray:
        return np.where(self._inside(t), self.peak * np.sin(self._w * self._tau(t)), 0.0)

    def derivative(self, t: ArrayLike) -> FloatArray:
        d = self.peak * self._w * np.cos(self._w * self._tau(t))
        return np.where(self._inside(t), d, 0.0)

    def integral(self, t: ArrayLike) -> FloatArray:
        return np.asarray(self.peak / self._w * (1.0 - np.cos(self._w * self._tau(t))))

    def integral_square(self, t: ArrayLike) -> FloatArray:
        tau = self._tau(t)
        return np.asarray(
            self.peak**2 * (0.5 * tau - np.sin(2.0 * self._w * tau) / (4.0 * self._w))
        )

    def terms(self) -> tuple[Term, ...]:
        end = self.start + self.duration
        return _sine_terms(self.peak, self._w, 0.0, self.start, end)

    @property
    def rate(self) -> float:
        return self._w

    def to_dict(self) -> dict[str, Any]:
        return {
            "kind": "half_sine",
            "peak": self.peak,
            "start": self.start,
            "duration": self.duration,
        }

    def breaks(self) -> tuple[float, ...]:
        return (self.start, self.start + self.duration)


@dataclass(frozen=True)
class Impulse(Profile):
    """A Dirac impulse: p(t) = impulse delta(t - time); ``impulse`` in the unit of the
    profile times s (N s for a force), ``time`` [s] >= 0.  It cannot be sampled: ``value``
    is 0 and ``integral`` the step impulse H(t - time); solvers apply it as a jump of the
    state at ``time`` (right-continuous: the sample at ``time`` is after the jump)."""

    impulse: float
    time: float

    def value(self, t: ArrayLike) -> FloatArray:
        return np.zeros_like(_arr(t))

    def derivative(self, t: ArrayLike) -> FloatArray:
        return np.zeros_like(_arr(t))

    @property
    def onset(self) -> float:
        return self.time

    def integral(self, t: ArrayLike) -> FloatArray:
        return np.where(_arr(t) >= self.time, self.impulse, 0.0)

    def integral_square(self, t: ArrayLike) -> FloatArray:
        raise ValueError("the square of an impulse has no integral")

    def terms(self) -> tuple[Term, ...]:
        return (Term(self.impulse, -1, 0.0, self.time),)

    def breaks(self) -> tuple[float, ...]:
        return (self.time,)


def _square_ppoly(p: PPoly) -> PPoly:
    """Exact piecewise-polynomial square of ``p`` (local power basis convolution)."""
    c = p.c  # (k+1, m), highest power first
    k1, m = c.shape
    c2 = np.zeros((2 * k1 - 1, m))
    for i in range(k1):
        for j in range(k1):
            c2[i + j] += c[i] * c[j]
    return PPoly(c2, p.x, extrapolate=False)


After = Literal["hold", "zero"]


@dataclass(frozen=True, eq=False)
class Table(Profile):
    """Tabulated (t [s], value) pairs with linear, cubic-spline or PCHIP interpolation.

    The table must start at or before t = 0.  Past its last time it holds the last value
    (``after="hold"``), is zero (``after="zero"``), or is undefined (``after=None``, the
    default: evaluation raises ``ValueError``, and a run must not outlast the table).
    """

    times: tuple[float, ...]
    values: tuple[float, ...]
    interpolation: Interpolation = "linear"
    after: After | None = None
    _pp: PPoly = field(init=False, repr=False)
    _dpp: PPoly = field(init=False, repr=False)
    _ipp: PPoly = field(init=False, repr=False)
    _i2pp: PPoly = field(init=False, repr=False)
    _offset: tuple[float, float] = field(init=False, repr=False)
    _tail: tuple[float] = field(init=False, repr=False)

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
        if self.after not in (None, "hold", "zero"):
            raise ValueError(f"unknown 'after' {self.after!r}: 'hold' or 'zero'")
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
        last = float(y[-1]) if self.after == "hold" else 0.0
        object.__setattr__(self, "_tail", (last,))

    def _check(self, t: FloatArray) -> FloatArray:
        end = self.times[-1] * (1 + 1e-12) if self.after is None else math.inf
        if t.size and (np.min(t) < self.times[0] or np.max(t) > end):
            raise ValueError(
                f"table profile is defined on [{self.times[0]}, {self.times[-1]}] s; "
                f"asked for t in [{np.min(t)}, {np.max(t)}] s (past the last time, say "
                "what it does with after = 'hold' or 'zero')"
            )
        return np.clip(t, self.times[0], self.times[-1])

    def _past(self, t: ArrayLike) -> FloatArray:
        """How far past the last time [s] (0 inside the table)."""
        return np.maximum(_arr(t) - self.times[-1], 0.0)

    def value(self, t: ArrayLike) -> FloatArray:
        v = np.asarray(self._pp(self._check(_arr(t))), dtype=float)
        return v if self.after is None else np.where(self._past(t) > 0, self._tail[0], v)

    def derivative(self, t: ArrayLike) -> FloatArray:
        d = np.asarray(self._dpp(self._check(_arr(t))), dtype=float)
        return d if self.after is None else np.where(self._past(t) > 0, 0.0, d)

    def integral(self, t: ArrayLike) -> FloatArray:
        i = np.asarray(self._ipp(self._check(_arr(t))) - self._offset[0], dtype=float)
        return i if self.after is None else i + self._tail[0] * self._past(t)

    def integral_square(self, t: ArrayLike) -> FloatArray:
        i = np.asarray(self._i2pp(self._check(_arr(t))) - self._offset[1], dtype=float)
        return i if self.after is None else i + self._tail[0] ** 2 * self._past(t)

    @property
    def is_constant(self) -> bool:
        same = bool(np.all(np.asarray(self.values) == self.values[0]))
        return same and (self.after != "zero" or self.values[0] == 0.0)

    def domain_end(self) -> float:
        return float(self.times[-1]) if self.after is None else math.inf

    def breaks(self) -> tuple[float, ...]:
        return tuple(self.times)

    def to_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {
            "kind": "table",
            "t": list(self.times),
            "values": list(self.values),
            "interpolation": self.interpolation,
        }
        if self.after is not None:
            out["after"] = self.after
        return out


@dataclass(frozen=True)
class Shifted(Profile):
    """``base`` seen from ``by`` [s] on: p(t) = base(t + by), integrals from t = 0 (the
    time-variant coefficients of a run restarted at ``by``, e.g. after an impulse)."""

    base: Profile
    by: float

    def value(self, t: ArrayLike) -> FloatArray:
        return self.base.value(_arr(t) + self.by)

    def derivative(self, t: ArrayLike) -> FloatArray:
        return self.base.derivative(_arr(t) + self.by)

    def integral(self, t: ArrayLike) -> FloatArray:
        at = self.base.integral(np.array([self.by]))[0]
        return self.base.integral(_arr(t) + self.by) - at

    def integral_square(self, t: ArrayLike) -> FloatArray:
        at = self.base.integral_square(np.array([self.by]))[0]
        return self.base.integral_square(_arr(t) + self.by) - at

    @property
    def is_constant(self) -> bool:
        return self.base.is_constant

    def domain_end(self) -> float:
        return self.base.domain_end() - self.by

    def breaks(self) -> tuple[float, ...]:
        return tuple(b - self.by for b in self.base.breaks() if b > self.by)


def polynomial(*coefficients: float) -> Polynomial:
    """Shorthand: ``polynomial(0, 0.4)`` is v = 0.4 t."""
    return Polynomial(tuple(float(c) for c in coefficients))


def table(
    times: Sequence[float],
    values: Sequence[float],
    interpolation: Interpolation = "linear",
    after: After | None = None,
) -> Table:
    return Table(tuple(map(float, times)), tuple(map(float, values)), interpolation, after)
