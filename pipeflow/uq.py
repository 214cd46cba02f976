"""Uncertainty quantification of design studies: sampling designs, statistics, Sobol indices.

A sampled study (:class:`pipeflow.schema.study.Samples`) draws its cases from independent
distributions of some numeric fields of the base request.  The numerics live here, apart
from the request models, as plain functions of arrays:

- :func:`unit_design`: points of the unit hypercube [0, 1)^D by the study's method, a
  pure function of ``(method, count, dimension, seed)``: scrambled Sobol'
  (:class:`scipy.stats.qmc.Sobol`), Latin hypercube (:class:`scipy.stats.qmc.LatinHypercube`),
  independent uniform draws (:func:`numpy.random.default_rng`), or Saltelli's design for
  Sobol' indices (:func:`SALib.sample.sobol.sample`: ``count`` base points give
  ``count (2 D + 2)`` rows, in the order :func:`SALib.analyze.sobol.analyze` reads them);
- the distributions (:class:`Normal`, :class:`TruncatedNormal`, :class:`Uniform`,
  :class:`Lognormal`: the request models' ``to_distribution()``) and :func:`ppf`, each one's
  inverse CDF, mapping a column of the design to values (:mod:`scipy.stats`);
- :func:`column_statistics`: mean, sample standard deviation, extremes and quantiles;
- :func:`instability_probability`: a proportion with its binomial standard error;
- :func:`sobol_indices`: first-order and total Sobol' indices of one output column over a
  Saltelli design, with bootstrap confidence intervals (:func:`SALib.analyze.sobol.analyze`).

SALib (the ``uq`` extra, which the service installs) is imported only by the Saltelli
design and the indices; the other designs need scipy alone.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np

from pipeflow._types import FloatArray
from pipeflow.optional import require

Method = Literal["sobol", "latin_hypercube", "random", "saltelli"]
METHODS: tuple[str, ...] = ("sobol", "latin_hypercube", "random", "saltelli")
#: the quantiles every statistics block reports (JSON keys are these, as strings)
QUANTILES: tuple[float, ...] = (0.05, 0.5, 0.95)
#: confidence level of the Sobol' indices' intervals [-]
CONF_LEVEL = 0.95
#: bootstrap resamples of the Sobol' indices' intervals [-]
RESAMPLES = 100
#: design points are kept in [EDGE, 1 - EDGE] so that every ppf is finite (an unbounded
#: distribution's tail stops at ~8.2 standard deviations)
EDGE = 2.0**-53


def rows(method: str, count: int, dimension: int) -> int:
    """Cases of a design: ``count``, or ``count (2 D + 2)`` for Saltelli's [-]."""
    return count * (2 * dimension + 2) if method == "saltelli" else count


def unit_design(method: str, count: int, dimension: int, seed: int) -> FloatArray:
    """Points of [0, 1)^D by ``method`` (see the module docstring), shape
    ``(rows(method, count, D), D)``, clipped to [EDGE, 1 - EDGE]; the same arguments give
    the same points."""
    if dimension < 1 or count < 1:
        raise ValueError("a design needs at least one point and one dimension")
    from scipy.stats import qmc  # here: scipy.stats is ~40 MB in every process importing uq

    with warnings.catch_warnings():
        # a count that is not a power of 2 loses the balance of Sobol' points (documented
        # on the request's field); the warning says nothing more to a caller of the service
        warnings.filterwarnings("ignore", message=".*power of 2.*")
        warnings.filterwarnings("ignore", message=".*equal to 2\\^n.*")
        if method == "sobol":
            u = qmc.Sobol(dimension, scramble=True, seed=seed).random(count)
        elif method == "latin_hypercube":
            u = qmc.LatinHypercube(dimension, seed=seed).random(count)
        elif method == "random":
            u = np.random.default_rng(seed).random((count, dimension))
        elif method == "saltelli":
            sobol_sample = require("SALib.sample.sobol", "uq", "a saltelli study").sample
            problem = {
                "num_vars": dimension,
                "names": [f"x{i}" for i in range(dimension)],
                "bounds": [[0.0, 1.0]] * dimension,
            }
            u = sobol_sample(problem, count, calc_second_order=True, seed=seed)
        else:
            raise ValueError(f"unknown sampling method {method!r}; the methods: {METHODS}")
    return np.clip(np.asarray(u, dtype=float), EDGE, 1.0 - EDGE)


@dataclass(frozen=True)
class Normal:
    """N(mean, std^2), in the field's SI unit."""

    mean: float
    std: float

    def ppf(self, u: FloatArray) -> FloatArray:
        from scipy import stats  # here, as in unit_design

        return np.asarray(stats.norm.ppf(u, loc=self.mean, scale=self.std), dtype=float)


@dataclass(frozen=True)
class TruncatedNormal:
    """The normal N(mean, std^2) restricted to [low, high] (renormalised)."""

    mean: float
    std: float
    low: float
    high: float

    def ppf(self, u: FloatArray) -> FloatArray:
        from scipy import stats

        a = (self.low - self.mean) / self.std
        b = (self.high - self.mean) / self.std
        out = stats.truncnorm.ppf(u, a, b, loc=self.mean, scale=self.std)
        return np.asarray(np.clip(out, self.low, self.high), dtype=float)  # rounding at the ends


@dataclass(frozen=True)
class Uniform:
    """Uniform on [low, high]."""

    low: float
    high: float

    def ppf(self, u: FloatArray) -> FloatArray:
        return np.asarray(self.low + u * (self.high - self.low), dtype=float)


@dataclass(frozen=True)
class Lognormal:
    """ln X normal with mean ln(median) and standard deviation sigma [-]."""

    median: float
    sigma: float

    def ppf(self, u: FloatArray) -> FloatArray:
        from scipy import stats

        return np.asarray(self.median * np.exp(self.sigma * stats.norm.ppf(u)), dtype=float)


Distribution = Normal | TruncatedNormal | Uniform | Lognormal
#: each distribution by its JSON name (the request's ``distribution``)
DISTRIBUTIONS: dict[str, type[Distribution]] = {
    "normal": Normal,
    "truncated_normal": TruncatedNormal,
    "uniform": Uniform,
    "lognormal": Lognormal,
}


def distribution(data: Mapping[str, Any]) -> Distribution:
    """The distribution of a JSON form (``distribution``: its name, and its parameters)."""
    kind = data["distribution"]
    if kind not in DISTRIBUTIONS:
        raise ValueError(f"unknown distribution {kind!r}")
    return DISTRIBUTIONS[kind](**{k: v for k, v in data.items() if k != "distribution"})


def ppf(distribution_: Distribution | Mapping[str, Any], u: FloatArray) -> FloatArray:
    """Values of a distribution at the probabilities ``u`` (its inverse CDF):

    - :class:`Normal`: ``mean``, ``std``;
    - :class:`TruncatedNormal`: the normal (``mean``, ``std``) restricted to [``low``,
      ``high``];
    - :class:`Uniform`: on [``low``, ``high``];
    - :class:`Lognormal`: ``ln X`` normal with mean ``ln median`` and standard deviation
      ``sigma``.

    A JSON form (a mapping) is read by :func:`distribution` first."""
    d = distribution_ if not isinstance(distribution_, Mapping) else distribution(distribution_)
    return d.ppf(u)


def column_statistics(values: Sequence[float | None]) -> dict[str, Any]:
    """Statistics of the numbers in ``values`` (``None`` skipped): ``count``, ``mean``,
    ``std`` (sample standard deviation, divisor n - 1; null below two values), ``min``,
    ``max`` and ``quantiles`` at :data:`QUANTILES` (numpy's linear interpolation between
    order statistics), keyed ``"0.05"``, ``"0.5"``, ``"0.95"``; nulls when no value."""
    x = np.asarray([v for v in values if v is not None], dtype=float)
    x = x[np.isfinite(x)]
    n = int(x.size)
    keys = [_quantile_key(q) for q in QUANTILES]
    if n == 0:
        return {
            "count": 0,
            "mean": None,
            "std": None,
            "min": None,
            "max": None,
            "quantiles": dict.fromkeys(keys),
        }
    qs = np.quantile(x, QUANTILES)
    return {
        "count": n,
        "mean": float(np.mean(x)),
        "std": float(np.std(x, ddof=1)) if n > 1 else None,
        "min": float(np.min(x)),
        "max": float(np.max(x)),
        "quantiles": {k: float(q) for k, q in zip(keys, qs, strict=True)},
    }


def _quantile_key(q: float) -> str:
    return f"{q:g}"


def instability_probability(unstable: Sequence[bool]) -> dict[str, Any]:
    """The proportion p of True in ``unstable`` and its binomial standard error
    sqrt(p (1 - p) / n) (``n`` = the decided cases; nulls when there are none)."""
    n = len(unstable)
    k = sum(1 for u in unstable if u)
    if n == 0:
        return {"probability": None, "standard_error": None, "unstable": 0, "decided": 0}
    p = k / n
    return {
        "probability": p,
        "standard_error": math.sqrt(p * (1.0 - p) / n),
        "unstable": k,
        "decided": n,
    }


def sobol_indices(
    names: Sequence[str], y: Sequence[float], *, seed: int = 0
) -> dict[str, dict[str, float]]:
    """First-order (``S1``) and total (``ST``) Sobol' indices of the output ``y`` over a
    Saltelli design of the parameters ``names`` (:func:`unit_design` with ``saltelli``:
    ``y`` in the design's row order, length ``N (2 D + 2)``), with the half-widths of their
    :data:`CONF_LEVEL` bootstrap confidence intervals (``S1_conf``, ``ST_conf``;
    :data:`RESAMPLES` resamples drawn from ``seed``): ``{name: {S1, S1_conf, ST,
    ST_conf}}``.  Raises ValueError when ``y`` is not finite or has the wrong length."""
    analyze = require("SALib.analyze.sobol", "uq", "Sobol' indices").analyze
    d = len(names)
    y_arr = np.asarray(y, dtype=float)
    if y_arr.ndim != 1 or d < 1 or y_arr.size % (2 * d + 2) != 0:
        raise ValueError(f"{y_arr.size} outputs are not a Saltelli design over {d} parameters")
    if not np.all(np.isfinite(y_arr)):
        raise ValueError("Sobol' indices need a finite output in every case")
    problem = {"num_vars": d, "names": list(names), "bounds": [[0.0, 1.0]] * d}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # 0/0 of a constant output
        res = analyze(
            problem,
            y_arr,
            calc_second_order=True,
            num_resamples=RESAMPLES,
            conf_level=CONF_LEVEL,
            # SALib seeds its bootstrap only for a truthy seed (seed=0 draws from numpy's
            # global state: the same study and key, other intervals): shift past zero
            seed=seed + 1 if seed >= 0 else seed,
        )
    return {
        name: {
            "S1": float(res["S1"][i]),
            "S1_conf": float(res["S1_conf"][i]),
            "ST": float(res["ST"][i]),
            "ST_conf": float(res["ST_conf"][i]),
        }
        for i, name in enumerate(names)
    }
