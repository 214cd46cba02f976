"""The external loads as the output of a small autonomous linear system, for the Magnus
exponential-integrator step (:func:`pipeflow.solvers.magnus.generator.forced_omega`).

A load profile that is a sum of exponential-polynomial terms c t^p e^{r t} on the whole run
(constants, polynomials, harmonics, exponentials: :meth:`pipeflow.profiles.Profile.terms`)
is exactly f(t) = G w(t) with w' = Lambda w: one Jordan chain u_j = t^j / j! e^{r t}
(u_j' = r u_j + u_{j-1}) per rate r, real for a real rate and as (Re, Im) pairs for a
complex one (a conjugate pair of terms shares one chain: the real part of each term sums to
the real profile).  On a step from t_n, w(t_n + s) = exp(s Lambda) w(t_n) =
T(w(t_n)) exp(s Lambda) w(0), with T(w) the block lower-triangular Toeplitz matrix of w
(a polynomial in Lambda's shift, so it commutes with exp(s Lambda)); and w(0) = T0 e_0 with
T0 the identity whose first column is w(0).  So each step's bordered generator carries the
constant block h T0^-1 Lambda T0 and the border C_n = G T(w(t_n)) T0, and starts from e_0,
as the interpolating polynomial's Jordan block does: the forcing is then exact (no
interpolation error, whatever the step) and the exponential no larger than the
polynomial's when the chains are short (:data:`MAX_STATES`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from pipeflow._types import FloatArray
from pipeflow.loads import ExternalForcing

#: at most as many states as order 4's interpolating polynomial has (4 nodes): the exact
#: form is then never the dearer one (a constant: 1 state, a harmonic 2, with a mean 3)
MAX_STATES = 4


@dataclass(frozen=True)
class _Chain:
    """One Jordan chain: ``rate`` [1/s] (complex: a (Re, Im) pair per link), ``length``
    links, its first state at ``first``."""

    rate: complex
    length: int
    first: int

    @property
    def complex(self) -> bool:
        return self.rate.imag != 0.0

    @property
    def width(self) -> int:
        return self.length * (2 if self.complex else 1)


@dataclass(frozen=True, eq=False)
class ForcingStates:
    """f(t) = G w(t), w' = Lambda w (module docstring), in the coordinates where w(0) = e_0:
    ``G`` (N, r) [1/s x m per unit state], ``generator`` T0^-1 Lambda T0 (r, r) [1/s]."""

    chains: tuple[_Chain, ...]
    G: FloatArray
    generator: FloatArray
    T0: FloatArray

    @property
    def count(self) -> int:
        return int(self.G.shape[1])

    @classmethod
    def of(cls, loads: ExternalForcing, size: int) -> ForcingStates | None:
        """The loads' states, or None when a profile has no such form on the whole run (a
        table, a pulse, an impulse, a term that starts or ends inside it) or they would
        need more than :data:`MAX_STATES` states."""
        # per rate (complex rates folded onto Im > 0): the highest power, and the terms
        pieces: list[tuple[FloatArray, complex, int, complex]] = []
        for column, profile in zip(loads.columns, loads.profiles, strict=True):
            terms = profile.terms()
            if terms is None:
                return None
            for term in terms:
                if term.power < 0 or term.start != 0.0 or term.end != math.inf:
                    return None
                rate, coef = complex(term.rate), complex(term.coef)
                if rate.imag < 0.0:
                    rate, coef = rate.conjugate(), coef.conjugate()
                pieces.append((np.asarray(column, dtype=float), rate, term.power, coef))
        highest: dict[complex, int] = {}
        for _, rate, power, _ in pieces:
            highest[rate] = max(highest.get(rate, 0), power)
        chains, first = [], 0
        for rate, power in highest.items():
            chain = _Chain(rate, power + 1, first)
            chains.append(chain)
            first += chain.width
        if first > MAX_STATES or first == 0:
            return None
        by_rate = {c.rate: c for c in chains}
        G = np.zeros((size, first))
        Lam = np.zeros((first, first))
        for c in chains:
            for j in range(c.length):
                if c.complex:
                    x, y = c.first + 2 * j, c.first + 2 * j + 1
                    Lam[x, x] = Lam[y, y] = c.rate.real
                    Lam[x, y], Lam[y, x] = -c.rate.imag, c.rate.imag
                    if j:
                        Lam[x, x - 2] = Lam[y, y - 2] = 1.0
                else:
                    i = c.first + j
                    Lam[i, i] = c.rate.real
                    if j:
                        Lam[i, i - 1] = 1.0
        for column, rate, power, coef in pieces:
            c = by_rate[rate]
            scale = math.factorial(power)  # c t^p e^{rt} = c p! u_p
            if c.complex:  # the real part: Re(c u_p) = Re c x_p - Im c y_p
                x = c.first + 2 * power
                G[:, x] += scale * coef.real * column
                G[:, x + 1] -= scale * coef.imag * column
            else:
                G[:, c.first + power] += scale * coef.real * column
        w0 = np.zeros(first)
        w0[[c.first for c in chains]] = 1.0
        T0 = np.eye(first)
        T0[:, 0] = w0  # unit lower triangular: its inverse is I - (w0 - e_0) e_0^T
        T0_inv = np.eye(first)
        T0_inv[1:, 0] = -w0[1:]
        return cls(tuple(chains), G, T0_inv @ Lam @ T0, T0)

    def toeplitz(self, t: FloatArray) -> FloatArray:
        """T(w(t)) at the times ``t``, shape (k, r, r): per chain sum_j w_j(t) S^j, with
        w_j = t^j / j! e^{r t} (a complex w_j acts on (Re, Im) as [[a, -b], [b, a]])."""
        t = np.asarray(t, dtype=float)
        out = np.zeros((t.size, self.count, self.count))
        for c in self.chains:
            grow = np.exp(np.multiply.outer(t, c.rate))  # (k,)
            for j in range(c.length):
                w = grow * t**j / math.factorial(j)
                for i in range(j, c.length):  # the j-th subdiagonal of the chain
                    if c.complex:
                        r, s = c.first + 2 * i, c.first + 2 * (i - j)
                        out[:, r, s] = out[:, r + 1, s + 1] = w.real
                        out[:, r + 1, s], out[:, r, s + 1] = w.imag, -w.imag
                    else:
                        out[:, c.first + i, c.first + i - j] = w.real
        return out

    def border(self, t: FloatArray) -> FloatArray:
        """C_n = G T(w(t_n)) T0 at the step starts ``t``, shape (k, N, r) [1/s x m]."""
        return np.asarray(self.G @ (self.toeplitz(t) @ self.T0))
