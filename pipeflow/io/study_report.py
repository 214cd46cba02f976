"""The sections of a design study's report (:mod:`pipeflow.io.report`), from the study's
JSON form (:class:`~pipeflow.schema.results.StudyResponse`) and its request (the result's
own ``request``, or the one the service held).

- :func:`numbers`: the cases, the probability of instability with its standard error, and
  per numeric summary column its mean with the standard error of the mean, its spread and
  quantiles;
- :func:`sensitivity`: the Sobol' indices S1 and ST of a saltelli study per column and
  parameter, each with its confidence interval;
- :func:`method`: the design (mode, sampler, sample size N, seed, parameters, number of
  evaluations), the estimators, and the diagnostics (failed cases, indices outside [0, 1],
  the widest confidence interval and the sample size that would halve it, the sum of the
  first-order indices, columns without indices and why).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

from pipeflow.uq import CONF_LEVEL, RESAMPLES

Rows = list[tuple[str, str]]

#: how each sampling method draws its points
SAMPLERS = {
    "sobol": "scrambled Sobol' sequence (scipy.stats.qmc.Sobol)",
    "latin_hypercube": "Latin hypercube (scipy.stats.qmc.LatinHypercube)",
    "random": "independent uniform draws (numpy's default_rng)",
    "saltelli": "Saltelli's design for Sobol' indices (SALib.sample.sobol, second order): "
    "N (2 D + 2) points from N base points and D parameters",
}
STATISTICS = (
    "sample mean and standard deviation (divisor n - 1), empirical quantiles (linear "
    "interpolation); standard errors s / sqrt(n) of a mean and sqrt(p (1 - p) / n) of "
    "P(unstable), both for independent draws (a quasi-Monte Carlo design is usually more "
    "accurate than they say)"
)


def _g(x: Any, digits: int = 4) -> str:
    if x is None:
        return "-"
    if isinstance(x, float):
        return f"{x:.{digits}g}"
    return str(x)


def _unit(unit: str) -> str:
    return unit if unit not in ("", "-") else "-"


def numbers(r: Mapping[str, Any]) -> Rows:
    """The study's key numbers, every estimate with its standard error."""
    counts = r.get("counts") or {}
    rows: Rows = [(f"cases: {k}", _g(v)) for k, v in counts.items()]
    stats = r.get("statistics") or {}
    inst = stats.get("instability")
    if inst:
        p, se = inst.get("probability"), inst.get("standard_error")
        rows.append(
            (
                "probability of instability P(unstable) [-] ± standard error",
                f"{_g(p)} ± {_g(se, 2)} ({inst.get('unstable')} of {inst.get('decided')} "
                "decided cases unstable)"
                if p is not None
                else "no case decided",
            )
        )
        rows.append(("unstable means", str(inst.get("criterion"))))
    for name, st in (stats.get("columns") or {}).items():
        unit = _unit(st.get("unit", ""))
        n, mean, std = st.get("count") or 0, st.get("mean"), st.get("std")
        se = std / math.sqrt(n) if std is not None and n >= 2 else None
        q = st.get("quantiles") or {}
        rows.append(
            (
                f"{name} [{unit}]: mean ± standard error of the mean ({n} values)",
                f"{_g(mean, 6)} ± {_g(se, 2)}",
            )
        )
        rows.append(
            (
                f"{name} [{unit}]: std, min, 5 %, 50 %, 95 %, max",
                ", ".join(
                    _g(v) for v in (std, st.get("min"), q.get("0.05"), q.get("0.5"), q.get("0.95"))
                )
                + f", {_g(st.get('max'))}",
            )
        )
    return rows


def _interval(value: float, half: float) -> str:
    return f"{value:.3f} ± {half:.3f} [{value - half:.3f}, {value + half:.3f}]"


def sensitivity(r: Mapping[str, Any]) -> Rows | None:
    """Each column's Sobol' indices per parameter with their confidence intervals (a
    saltelli study), else None."""
    sens = r.get("sensitivity")
    if not sens:
        return None
    level = round(100 * sens["conf_level"])
    rows: Rows = []
    for name, column in sens["columns"].items():
        if not column.get("available"):
            rows.append((f"{name}", f"no indices: {column.get('reason')}"))
            continue
        for path, ix in (column.get("parameters") or {}).items():
            rows.append(
                (
                    f"{name} w.r.t. {path}: S1 ± half-width [{level} % interval]",
                    _interval(ix["S1"], ix["S1_conf"]),
                )
            )
            rows.append(
                (
                    f"{name} w.r.t. {path}: ST ± half-width [{level} % interval]",
                    _interval(ix["ST"], ix["ST_conf"]),
                )
            )
    return rows


def _distribution(d: Mapping[str, Any]) -> str:
    args = ", ".join(f"{k} {_g(v)}" for k, v in d.items() if k != "distribution")
    return f"{d.get('distribution')}({args})"


def _design(r: Mapping[str, Any], request: Mapping[str, Any] | None) -> Rows:
    counts = r.get("counts") or {}
    total = counts.get("total")
    rows: Rows = [("base computation", str(r.get("base_kind")))]
    if not request:
        rows.append(("design", "not stored with this result (its request is unknown)"))
        rows.append(("number of evaluations (cases) [-]", _g(total)))
        return rows
    samples = request.get("samples")
    if samples:
        method = samples.get("method")
        params = samples.get("parameters") or {}
        rows += [
            ("design", f"samples: {SAMPLERS.get(method, method)}"),
            (
                "sample size N [-]" + (" (base points)" if method == "saltelli" else ""),
                _g(samples.get("count")),
            ),
            ("seed", _g(samples.get("seed"))),
            (
                f"sampled parameters (D = {len(params)})",
                "; ".join(f"{p}: {_distribution(d)}" for p, d in params.items()),
            ),
        ]
    elif request.get("grid"):
        grid = request["grid"]
        rows.append(
            (
                "design",
                "grid: every combination of "
                + "; ".join(f"{p} ({len(v)} values)" for p, v in grid.items()),
            )
        )
    else:
        rows.append(("design", f"cases: a list of {len(request.get('cases') or [])}"))
    rows.append(
        (
            "number of evaluations (cases) [-]",
            f"{_g(total)} ({counts.get('computed')} computed, {counts.get('cached')} from "
            "the cache)",
        )
    )
    if request.get("operating_velocity") is not None:
        rows.append(("operating velocity [m/s]", _g(request["operating_velocity"])))
    return rows


def _diagnostics(r: Mapping[str, Any]) -> Rows:
    counts = r.get("counts") or {}
    rows: Rows = [("failed cases", f"{counts.get('failed', 0)} of {counts.get('total')}")]
    sens = r.get("sensitivity")
    if not sens:
        return rows
    n = sens["base_points"]
    level = round(100 * sens["conf_level"])
    for name, column in sens["columns"].items():
        params = column.get("parameters") or {}
        if not column.get("available"):
            rows.append((f"{name}: Sobol' indices", f"none: {column.get('reason')}"))
            continue
        outside = [
            f"{p} {k} = {ix[k]:.3g}" for p, ix in params.items() for k in ("S1", "ST")
            if not 0.0 <= ix[k] <= 1.0
        ]  # fmt: skip
        rows.append(
            (
                f"{name}: indices within [0, 1]",
                "yes"
                if not outside
                else f"no ({', '.join(outside)}): the design is too small for them (N = {n}); "
                "raise samples.count",
            )
        )
        widest = max(max(ix["S1_conf"], ix["ST_conf"]) for ix in params.values())
        rows.append(
            (
                f"{name}: widest {level} % half-width (convergence) [-]",
                f"{widest:.3f} at N = {n}; the half-widths shrink as 1 / sqrt(N): N = {4 * n} "
                "would about halve them",
            )
        )
        total = sum(ix["S1"] for ix in params.values())
        rows.append(
            (
                f"{name}: sum of S1 [-]",
                f"{total:.3f} (at most 1 up to sampling error; 1 - sum is the share of the "
                "interactions)",
            )
        )
    return rows


def method(r: Mapping[str, Any], inputs: Mapping[str, Any] | None) -> Rows:
    """The "Method and diagnostics" rows of a study: its design (from its request: the
    result's own, else ``inputs``), the estimators and the diagnostics."""
    request = r.get("request") or inputs
    rows = _design(r, request)
    rows.append(("statistics", STATISTICS))
    if r.get("sensitivity"):
        rows.append(
            (
                "Sobol' estimators",
                "first-order S1 (Saltelli et al. 2010) and total ST (Jansen 1999) by "
                f"SALib.analyze.sobol; confidence intervals by bootstrap, {RESAMPLES} "
                f"resamples at {round(100 * CONF_LEVEL)} %",
            )
        )
    return rows + _diagnostics(r)
