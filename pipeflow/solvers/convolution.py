"""The particular integral of the paper's eq. (17) for external loads at constant coefficients.

Analytic profiles (constant, polynomial, harmonic, half-sine pulse, impulse, and sums of
them over the loads) have it in closed form (:func:`exact_particular`): each profile is a
sum of pieces c (t - t_a)^k e^{s (t - t_a)} on [t_a, t_b]
(:meth:`pipeflow.profiles.Profile.terms`), and the response of a modal coordinate
a' = xi a + q(t), a(0) = 0, to one of them is, for t_a <= t <= t_b and tau = t - t_a,

    a(t) = c k! tau^{k+1} e^{s tau} phi_{k+1}((xi - s) tau),
    phi_m(z) = sum_j z^j / (j + m)!        (phi_1(z) = (e^z - 1) / z, ...),

(for k = 0 and s = i W: (e^{xi tau} - e^{i W tau}) / (xi - i W), the familiar
F e^{i W t} / (i W - xi) plus its transient); an impulse (k = -1) gives c e^{xi tau}; past
t_b the coordinate decays freely, a(t_b) e^{xi (t - t_b)}.  phi_m is evaluated by its
Taylor series where |z| < 2 and by phi_{m+1} = (phi_m - 1/m!) / z from e^z elsewhere, so
resonance (xi = s: the limit c tau^{k+1} e^{s tau} / (k + 1)) needs no special case and
there is no quadrature: exact to rounding, O(1) per sample and mode.  The quadrature
below serves tables only.

With S constant, the response to the loads f(t) = sum_k g_k p_k(t) (:mod:`pipeflow.loads`) is
the convolution of the fundamental solution with the load (physics notes, section 5)::

    z_p(t) = integral_0^t exp(S (t - tau)) f(tau) dtau,

added to the homogeneous CMA solution exp(S t) z0.  It is evaluated output interval by
output interval, z_p(t_{k+1}) = exp(S dt_k) z_p(t_k) + I_k with
I_k = integral_{t_k}^{t_{k+1}} exp(S (t_{k+1} - tau)) f(tau) dtau:

- in the eigenbasis S = Y diag(xi) Y^-1 (:func:`modal_particular`): I_k is, per mode, a
  scalar integral of e^{xi (t_{k+1} - tau)} times the profile values, and the recursion
  across intervals is a first-order linear filter per mode (exact multiplication by
  e^{xi dt_k}, no quadrature);
- where Y is ill-conditioned (:func:`dense_particular`, the ``cma`` fallback): the same with
  matrix exponentials exp(S o) of the distinct node offsets o.

Quadrature and its error.  Each output interval is cut into pieces of length h with
(|xi|_max + w_load) h <= :data:`PIECE_RADIANS` (w_load the fastest harmonic load
frequency), and at the knots of tabulated profiles, so on every piece the integrand is an
exponential times a smooth profile (polynomial, harmonic, or one cubic piece of a table);
:data:`PIECE_NODES`-point Gauss-Legendre integrates it with a remainder below ~1e-12
relative to the integral's scale (the Gauss remainder term for e^{i 20 u} on [0, 1]:
measured 1.2e-12 relative, 6e-14 of the integrand's size; 1e-15 for decaying terms).  So
the forced response is exact up to that quadrature error and rounding (amplified by the
eigenvector condition number), for every profile kind.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.linalg import blas, expm

from pipeflow._types import FloatArray
from pipeflow.errors import BudgetExceeded
from pipeflow.loads import ExternalForcing
from pipeflow.profiles import Term

#: Gauss-Legendre nodes per piece, and the largest phase (|xi| + w_load) h of a piece [rad]
PIECE_NODES = 16
PIECE_RADIANS = 20.0
#: the quadrature's relative error bound claimed in diagnostics (see the module docstring)
QUADRATURE_ERROR = 1e-12
#: at most this many quadrature nodes (each costs one exponential per mode)
MAX_CONVOLUTION_NODES = 8_000_000
#: at most this many distinct matrix exponentials in the ill-conditioned fallback
MAX_DENSE_OFFSETS = 100_000
_CHUNK_ENTRIES = 1_000_000  # node x mode entries formed at once


def quadrature_nodes(t: FloatArray, rate: float) -> float:
    """Gauss nodes the table quadrature needs on the output times ``t`` [s] for a fastest
    phase rate ``rate`` [rad/s] (before the split at knots), as a float (may be inf)."""
    with np.errstate(over="ignore", invalid="ignore"):
        return float(np.sum(np.maximum(1.0, np.ceil(rate * np.diff(t) / PIECE_RADIANS))))


def load_pieces(
    t: FloatArray, rate: float, knots: FloatArray
) -> tuple[NDArray[np.int64], FloatArray, FloatArray]:
    """Pieces of the output intervals: ``(owner, left, width)`` with ``owner`` the output
    interval of each piece, sorted; no piece longer than PIECE_RADIANS / ``rate`` [s] or
    crossing a knot [s]."""
    dt = np.diff(t)
    with np.errstate(over="ignore", invalid="ignore"):
        m = np.maximum(1.0, np.ceil(rate * dt / PIECE_RADIANS))
    total = float(np.sum(m)) * PIECE_NODES
    if not total <= MAX_CONVOLUTION_NODES:
        t_end = float(t[-1])
        fits = t_end * MAX_CONVOLUTION_NODES / total if np.isfinite(total) else 0.0
        raise BudgetExceeded(
            f"the quadrature of the tabulated loads of this run needs {total:.3g} nodes "
            f"(limit {MAX_CONVOLUTION_NODES}): use time.t_end <= {fits:.3g} s, fewer modes, "
            "an analytic profile (constant, polynomial, harmonic, half_sine: exact, no "
            "quadrature) or the 'magnus' method",
            parameter="time.t_end",
        )
    counts = m.astype(np.int64)
    owner = np.repeat(np.arange(dt.size), counts)
    first = np.concatenate([[0], np.cumsum(counts)[:-1]])
    local = np.arange(owner.size) - first[owner]
    left = t[owner] + local * (dt[owner] / counts[owner])
    if knots.size:
        left = np.union1d(left, knots)
        owner = np.clip(np.searchsorted(t, left, side="right") - 1, 0, dt.size - 1)
    right = np.append(left[1:], t[-1])
    return owner.astype(np.int64), left, np.maximum(right - left, 0.0)


def _nodes(
    t: FloatArray, rate: float, loads: ExternalForcing
) -> tuple[NDArray[np.int64], FloatArray, FloatArray]:
    """Gauss nodes of every piece: ``(owner, tau, weight)``."""
    owner, left, width = load_pieces(t, rate, loads.knots(float(t[-1])))
    x, wq = np.polynomial.legendre.leggauss(PIECE_NODES)
    tau = (left[:, None] + 0.5 * width[:, None] * (x[None, :] + 1.0)).ravel()
    weight = (0.5 * width[:, None] * wq[None, :]).ravel()
    return np.repeat(owner, PIECE_NODES), tau, weight


def _accumulate(out: NDArray[np.complex128], owner: NDArray[np.int64], rows: NDArray) -> None:
    """out[owner[i]] += rows[i], for ``owner`` sorted (one reduceat per distinct owner)."""
    starts = np.flatnonzero(np.r_[True, owner[1:] != owner[:-1]])
    out[owner[starts]] += np.add.reduceat(rows, starts, axis=0)


def modal_particular(
    t: FloatArray,
    loads: ExternalForcing,
    w: NDArray[np.complex128],
    V: NDArray[np.complex128],
) -> tuple[FloatArray, int]:
    """z_p at the output times ``t`` [s] for S = V diag(w) V^-1 (module docstring), and the
    number of quadrature nodes used.  S real: one eigenvalue of each conjugate pair is kept
    and its real part doubled (as the homogeneous CMA solution does)."""
    keep = w.imag >= 0
    weight = np.where(w.imag[keep] > 0, 2.0, 1.0)
    lam = w[keep]
    coef = np.linalg.solve(V, loads.columns.T.astype(complex))[keep]  # (modes, K)
    rate = float(np.max(np.abs(w))) + loads.rate
    owner, tau, wq = _nodes(t, rate, loads)
    inc = np.zeros((t.size - 1, lam.size), dtype=complex)
    chunk = max(256, _CHUNK_ENTRIES // max(lam.size, 1))
    dt = np.diff(t)
    per = tau.size // dt.size
    uniform = np.allclose(dt, dt[0], rtol=1e-12, atol=0.0) and per * dt.size == tau.size
    shared = uniform and np.array_equal(owner, np.repeat(np.arange(dt.size), per))
    with np.errstate(over="ignore", invalid="ignore"):
        if shared:
            # the same pieces in every interval: one kernel table for all of them
            offsets = t[1] - tau[:per]
            kern = wq[:per, None] * np.exp(np.outer(offsets, lam))  # (nodes, modes)
            rows = max(1, chunk // per)
            for k0 in range(0, dt.size, rows):
                k1 = min(k0 + rows, dt.size)
                vals = loads.values(tau[k0 * per : k1 * per]) @ coef.T
                inc[k0:k1] = np.einsum("knm,nm->km", vals.reshape(k1 - k0, per, -1), kern)
        for s0 in range(0, 0 if shared else tau.size, chunk):
            sl = slice(s0, min(s0 + chunk, tau.size))
            own = owner[sl]
            modal_load = loads.values(tau[sl]) @ coef.T  # (nodes, modes)
            kern = np.exp(np.outer(t[own + 1] - tau[sl], lam))
            _accumulate(inc, own, (wq[sl, None] * kern) * modal_load)
        # a_{k+1} = e^{xi dt_k} a_k + I_k, a_0 = 0: a first-order filter per mode
        a = np.empty_like(inc)
        if np.allclose(dt, dt[0], rtol=1e-12, atol=0.0):
            # imported here: scipy.signal (and the scipy.stats it loads) is ~45 MB in every
            # process that imports the solvers, and only forced runs on a uniform grid use it
            from scipy.signal import lfilter

            for i, r in enumerate(np.exp(lam * dt[0])):
                a[:, i] = lfilter([1.0], [1.0, -r], inc[:, i])
        else:
            E = np.exp(np.outer(dt, lam))
            acc = np.zeros(lam.size, dtype=complex)
            for k in range(dt.size):
                acc = E[k] * acc + inc[k]
                a[k] = acc
        Z = np.zeros((t.size, V.shape[0]))
        Z[1:] = ((a * weight) @ V[:, keep].T).real
    return Z, int(tau.size)


def dense_particular(
    t: FloatArray, loads: ExternalForcing, S: FloatArray
) -> tuple[FloatArray, int]:
    """z_p at the output times ``t`` [s] with matrix exponentials (ill-conditioned or
    defective S): exp(S o) G at each distinct node offset o = t_{k+1} - tau (offsets equal
    to 2^-44 of the longest interval share one), then z_p marched with exp(S dt_k).
    Returns the states and the number of matrix exponentials formed."""
    rate = float(np.abs(S).sum(axis=0).max()) + loads.rate  # 1-norm >= spectral radius
    owner, tau, wq = _nodes(t, rate, loads)
    dt = np.diff(t)
    offsets = t[owner + 1] - tau
    quantum = float(np.max(dt)) * 2.0**-44
    keys, index = np.unique(np.round(offsets / quantum), return_inverse=True)
    if keys.size > MAX_DENSE_OFFSETS:
        raise BudgetExceeded(
            f"the load convolution of this ill-conditioned run needs {keys.size} matrix "
            f"exponentials (limit {MAX_DENSE_OFFSETS}); use the 'magnus' method",
            parameter="method",
        )
    B = expm(S[None] * (keys * quantum)[:, None, None]) @ loads.columns.T  # (U, 2n, K)
    inc = np.zeros((dt.size, S.shape[0]))
    chunk = max(256, _CHUNK_ENTRIES // S.shape[0])
    for s0 in range(0, tau.size, chunk):
        sl = slice(s0, min(s0 + chunk, tau.size))
        rows = wq[sl, None] * np.einsum("nij,nj->ni", B[index[sl]], loads.values(tau[sl]))
        _accumulate(inc, owner[sl], rows)  # type: ignore[arg-type]
    lengths, which = np.unique(dt, return_inverse=True)
    E = expm(S[None] * lengths[:, None, None])
    Z = np.zeros((t.size, S.shape[0]))
    z = np.zeros(S.shape[0])
    for k in range(dt.size):
        z = E[which[k]] @ z + inc[k]
        Z[k + 1] = z
    return Z, int(keys.size + lengths.size)


#: |z| below which phi_m(z) is summed as its Taylor series (30 terms: remainder < 1e-23)
_SERIES_RADIUS = 2.0
_SERIES_TERMS = 30
_EXACT_BLOCK = 16_384  # output times per block of the closed-form particular integral


def phi(
    m: int, z: NDArray[np.complex128], ez: NDArray[np.complex128] | None = None
) -> NDArray[np.complex128]:
    """phi_m(z) = sum_{j >= 0} z^j / (j + m)! elementwise (phi_0 = e^z), m >= 0: the
    functions of exponential integrators, without cancellation near z = 0 (``ez``: e^z
    when the caller has it; it is overwritten)."""
    z = np.asarray(z, dtype=complex)
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        p = _exp(z) if ez is None else ez
        for i in range(m):  # the recurrence on the whole array, in place
            p -= 1.0 / math.factorial(i)
            p /= z
    if m == 0:
        return p
    # the recurrence loses a factor (i + 1) / |z| per step where |z| < i + 1: the series
    # below radius 1 + m (its terms then fall at least like |z|^j / j!)
    radius, terms = _SERIES_RADIUS + (m - 1), _SERIES_TERMS + 2 * m
    small = np.flatnonzero((z.real * z.real + z.imag * z.imag).ravel() < radius**2)
    if small.size:  # the few entries near 0 (early times, resonance): the series
        zs = z.ravel()[small]
        acc = np.full_like(zs, 1.0 / math.factorial(terms + m))
        for j in range(terms - 1, -1, -1):
            acc = acc * zs + 1.0 / math.factorial(j + m)
        p.ravel()[small] = acc
    return p


def _exp(z: NDArray[np.complex128]) -> NDArray[np.complex128]:
    """e^z with real parts below -700 raised to -700 (e^-700 ~ 1e-304: zero for every
    purpose here, and it keeps numpy's slow underflow path out of the strongly damped
    modes' entries)."""
    with np.errstate(over="ignore", invalid="ignore"):
        return np.asarray(np.exp(np.maximum(z.real, -700.0) + 1j * z.imag))


def term_response(
    term: Term,
    lam: NDArray[np.complex128],
    t: FloatArray,
    grid: tuple[int, float] | None = None,
) -> NDArray[np.complex128]:
    """a(t) of a' = lam a + q(t), a(0) = 0, for q the unit piece ``term`` (its ``coef``
    taken as 1), shape ``(len(t), len(lam))`` (module docstring).  ``grid`` = (k0, dt):
    the times are (k0 + k) dt, and the exponentials are formed by
    :func:`modal_exponentials`'s products of two small tables."""
    tau = np.asarray(t, dtype=float) - term.start
    width = term.end - term.start
    within = (tau >= 0.0) & (tau <= width)
    with np.errstate(over="ignore", invalid="ignore"):

        def inside(x: FloatArray, tabled: bool = False) -> NDArray[np.complex128]:
            rate = lam if term.power < 0 else lam - term.rate
            if tabled and grid is not None:
                ez = np.asarray(modal_exponentials(x, rate, start=grid[0], dt=grid[1]))
            else:
                ez = _exp(np.outer(x, rate))
            if term.power < 0:
                return ez
            k = term.power
            scale = math.factorial(k) * x ** (k + 1) * np.exp(term.rate * x)
            p = phi(k + 1, np.outer(x, rate), ez)
            p *= scale[:, None]
            return p

        if np.all(within) and term.start == 0.0:
            return inside(tau, tabled=True)
        out = np.zeros((tau.size, lam.size), dtype=complex)
        if np.any(within):
            out[within] = inside(tau[within])
        past = tau > width
        if np.any(past):
            at_end = inside(np.array([width]))
            out[past] = at_end * np.exp(np.outer(tau[past] - width, lam))
    return out


class ClosedForm:
    """The particular integral of analytic loads in the modal coordinates of
    S = V diag(w) V^-1, block of output times by block (module docstring).  S real: one
    eigenvalue of each conjugate pair is kept (``keep``) and its weight (2 for a pair, 1
    for a real one) is folded into the amplitudes, as the homogeneous CMA solution does,
    so that z_p = Re(amplitudes @ V[:, keep].T).  Pieces equal across loads are evaluated
    once, with their modal loads summed."""

    def __init__(
        self, loads: ExternalForcing, w: NDArray[np.complex128], V: NDArray[np.complex128]
    ) -> None:
        self.keep = w.imag >= 0
        weight = np.where(w.imag[self.keep] > 0, 2.0, 1.0)
        self.lam = w[self.keep]
        coef = np.linalg.solve(V, loads.columns.T.astype(complex))[self.keep]  # (modes, K)
        coef *= weight[:, None]
        grouped: dict[Term, NDArray[np.complex128]] = {}
        for k, profile in enumerate(loads.profiles):
            for term in profile.terms() or ():
                if term.coef != 0:
                    unit = Term(1.0, term.power, complex(term.rate), term.start, term.end)
                    before = grouped.get(unit, np.zeros(self.lam.size, dtype=complex))
                    grouped[unit] = np.asarray(before + term.coef * coef[:, k], dtype=complex)
        self.pieces = grouped

    def amplitudes(
        self,
        t: FloatArray,
        grid: tuple[int, float] | None = None,
        E: NDArray[np.complex128] | None = None,
        homogeneous: NDArray[np.complex128] | None = None,
    ) -> NDArray[np.complex128]:
        """The modal amplitudes (weights folded in) at the times ``t`` [s], shape
        ``(len(t), kept modes)``; ``grid`` as :func:`term_response`; ``E``: e^{lam t} at
        these times when the caller has it (the pieces c e^{s t} from t = 0, constants and
        harmonics, then reuse it: :meth:`_from_e`); ``homogeneous``: with ``E``, the
        caller's coefficients c0 of its free response E c0, added here (E is then
        multiplied once, by c0 and the pieces' weights together)."""
        from_e: list[tuple[complex, NDArray[np.complex128]]] = []
        others: list[tuple[Term, NDArray[np.complex128]]] = []
        for piece, c in self.pieces.items():
            if E is not None and piece.power == 0 and piece.start == 0 and piece.end == math.inf:
                from_e.append((piece.rate, c))
            else:
                others.append((piece, c))
        with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
            if E is not None and (from_e or homogeneous is not None):
                base = (
                    np.zeros(self.lam.size, dtype=complex) if homogeneous is None else homogeneous
                )
                a = self._from_e(from_e, t, E, base)
            else:
                a = np.zeros((t.size, self.lam.size), dtype=complex)
            for piece, c in others:
                r = term_response(piece, self.lam, t, grid)
                r *= c
                a += r
        return a

    def _from_e(
        self,
        pieces: list[tuple[complex, NDArray[np.complex128]]],
        t: FloatArray,
        E: NDArray[np.complex128],
        base: NDArray[np.complex128],
    ) -> NDArray[np.complex128]:
        """E base + sum_p c_p e^{s_p t} from t = 0 for the ``pieces`` (s_p, c_p):
        sum_p c_p (e^{lam t} - e^{s_p t}) / (lam - s_p) = E sum_p W_p - e^{t s} @ W with
        W_p = c_p / (lam - s_p), from the caller's E = e^{lam t}: one product of E with the
        summed weights and one matrix product subtracted in place (BLAS zgemm), where each
        piece cost three passes over the (times x modes) array (a harmonic is two pieces);
        where |lam - s_p| t < 2 (near resonance, early times, where the difference
        cancels) the series of phi_1 instead."""
        a = E * base
        if not pieces:
            return a
        s = np.array([rate for rate, _ in pieces], dtype=complex)
        C = np.stack([c for _, c in pieces])  # (P, modes)
        D = self.lam[None, :] - s[:, None]
        reach = np.where(D != 0, _SERIES_RADIUS / np.abs(np.where(D != 0, D, 1.0)), np.inf)
        # a (piece, mode) the series covers at every time stays out of the bulk: there
        # 1 / (lam - s) is large (at resonance infinite), and adding then removing it would
        # leave its rounding in the answer
        W = np.where(reach > t[-1], 0.0, C / np.where(D != 0, D, 1.0))  # (P, modes)
        a = E * (base + W.sum(axis=0))
        es = np.exp(np.outer(t, s))  # (T, P)
        # a -= es @ W in place: a.T (F-ordered) := -W.T es.T + a.T
        out = blas.zgemm(-1.0, W.T, es.T, 1.0, a.T, overwrite_c=1)
        if not np.shares_memory(out, a):
            a = np.ascontiguousarray(out.T)
        # t is increasing: the rows of (piece, column) below its reach are the first counts
        counts = np.searchsorted(t, reach.ravel(), side="left")
        if counts.any():
            pair = np.repeat(np.arange(counts.size), counts)  # (piece, column) flat
            first = np.repeat(np.cumsum(counts) - counts, counts)
            rows = np.arange(pair.size) - first
            p, cols = np.divmod(pair, D.shape[1])
            tr, ep = t[rows], es[rows, p]
            bulk = (E[rows, cols] - ep) * W[p, cols]
            series = C[p, cols] * tr * ep * phi(1, D[p, cols] * tr)
            np.add.at(a, (rows, cols), series - bulk)  # (two pieces may share an entry)
        return a


def exact_particular(
    t: FloatArray,
    loads: ExternalForcing,
    w: NDArray[np.complex128],
    V: NDArray[np.complex128],
) -> FloatArray:
    """z_p at the output times ``t`` [s] for S = V diag(w) V^-1 and loads whose profiles
    all have :meth:`~pipeflow.profiles.Profile.terms`: in closed form (:class:`ClosedForm`)."""
    form = ClosedForm(loads, w, V)
    Z = np.zeros((t.size, V.shape[0]))
    Vt = V[:, form.keep].T
    dt = uniform_step(t)
    for s0 in range(0, t.size, _EXACT_BLOCK):
        sl = slice(s0, min(s0 + _EXACT_BLOCK, t.size))
        a = form.amplitudes(t[sl], None if dt is None else (s0, dt))
        with np.errstate(over="ignore", invalid="ignore"):
            Z[sl] = (a @ Vt).real
    return Z


def uniform_step(t: FloatArray) -> float | None:
    """The step of a uniform grid t_k = k dt (t[0] = 0), or None [s]."""
    n = t.size
    if n < 3 or t[0] != 0.0:
        return None
    dt = float(t[1] - t[0])
    ok = np.allclose(t, dt * np.arange(n), rtol=0, atol=1e-14 * abs(float(t[-1])))
    return dt if ok else None


def modal_exponentials(
    t: FloatArray,
    w: NDArray[np.complex128],
    block: int = 64,
    start: int = 0,
    dt: float | None = None,
) -> Any:
    """exp(outer(t, w)): on a uniform grid t_k = (start + k) dt (``dt`` given) as products
    exp(w t_b) exp(w j dt) of two small tables (block starts t_b, offsets j dt), one complex
    multiply per entry instead of one complex exponential; otherwise exp directly."""
    n = t.size
    if dt is None or n <= 2 * block:
        return np.exp(np.outer(t, w))
    starts = np.exp(np.outer(dt * (start + np.arange(0, n, block)), w))
    offsets = np.exp(np.outer(dt * np.arange(block), w))
    return (starts[:, None, :] * offsets[None, :, :]).reshape(-1, w.size)[:n]
