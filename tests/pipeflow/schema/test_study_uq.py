"""Sampled design studies (issue 19): distributions, designs, statistics and Sobol' indices.

Each validation names its source and tolerance:

1. A lognormal Young's modulus E gives a lognormal fundamental frequency.  At v = 0 and
   w0 = 0 the pipe is an Euler-Bernoulli cantilever, omega_1 = lambda_1^2 sqrt(E I / (m
   L^4)) with lambda_1 = 1.8751040687 (cos lambda cosh lambda = -1; Blevins, *Formulas for
   natural frequency and mode shape*, table 8-1), m = M1 + M2.  So omega_1 ~ sqrt(E) and
   ln omega_1 ~ N(ln omega_med, (sigma / 2)^2): mean omega_med exp(s^2 / 2), variance
   mean^2 (exp(s^2) - 1), quantiles omega_med exp(s z_p), s = sigma / 2.  The study's
   estimates from N scrambled Sobol' points must meet these within 3 standard errors of a
   Monte Carlo estimate from N independent draws (mean: std / sqrt(N); std: std sqrt((kurt
   - 1) / (4 N)), kurt the lognormal's kurtosis; quantile p: sqrt(p (1 - p) / N) / f(q_p)).
   A randomised QMC design on this smooth, monotone integrand does far better than that
   bound (the errors are printed by ``-s``); the bound is what is asserted.
2. Sobol' indices of the Ishigami function f = sin x1 + a sin^2 x2 + b x3^4 sin x1, x_i
   uniform on [-pi, pi], a = 7, b = 0.1 (Ishigami & Homma 1990; SALib's test function
   ``SALib.test_functions.Ishigami``): analytic S1 = 0.3139, 0.4424, 0 and ST = 0.5576,
   0.4424, 0.2437, computed through the study's own path from a sample table to indices
   (:func:`pipeflow.computations.study_runner.sensitivity` over the spec's design), within the
   95 % confidence half-width the estimator reports.
3. The same seed gives the same cases and key, another seed other ones.
4. Every bad input is one error naming its field.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
import pytest
from pydantic import ValidationError
from scipy import stats

from pipeflow import uq
from pipeflow.computations import registry
from pipeflow.computations.study_runner import Column, sensitivity, statistics
from pipeflow.paper import PAPER_PIPE_JSON
from pipeflow.schema.keys import canonical_key
from pipeflow.schema.results import StudyResponse
from pipeflow.schema.study import MAX_CASES, StudySpec

#: lambda_1 of a clamped-free beam: the first root of cos x cosh x = -1
LAMBDA_1 = 1.8751040687119611

#: the paper's pipe at rest and not spinning: a cantilever beam (2 modes, 0.01 s)
AT_REST: dict[str, Any] = {
    "pipe": PAPER_PIPE_JSON,
    "flow": {"velocity": {"kind": "constant", "value": 0.0}},
    "rotation": {"omega0": {"kind": "constant", "value": 0.0}},
    "modes": 2,
    "time": {"t_end": 0.01, "samples": 3},
    "output": {"eigen_samples": 3},
}
SIM = {"kind": "simulation", "spec": AT_REST}
LOGNORMAL_E = {"distribution": "lognormal", "median": PAPER_PIPE_JSON["E"], "sigma": 0.2}


def sampled(samples: dict[str, Any], base: dict[str, Any] = SIM, **more: Any) -> StudySpec:
    return StudySpec.model_validate({"base": base, "samples": samples, **more})


def run(spec: StudySpec) -> dict[str, Any]:
    return registry.COMPUTATIONS["study"].execute(spec)


def validated(doc: dict[str, Any]) -> None:
    """``doc`` is a study response (with the fields the service adds)."""
    StudyResponse.model_validate({**doc, "key": "0" * 64, "cached": False})


def omega_1(E: float) -> float:
    p = PAPER_PIPE_JSON
    return LAMBDA_1**2 * math.sqrt(E * p["I"] / ((p["M1"] + p["M2"]) * p["L"] ** 4))


def test_the_beam_formula_is_the_model_at_rest() -> None:
    """The closed form holds for one case to rounding (the basis is the beam's own modes)."""
    doc = run(sampled({"count": 1, "method": "random", "parameters": {"pipe.E": LOGNORMAL_E}}))
    (row,) = doc["rows"]
    E, w = row[4], row[4 + 3]
    assert doc["columns"][4]["name"] == "pipe.E" and doc["columns"][7]["name"] == "final_omega_1"
    assert w == pytest.approx(omega_1(E), rel=1e-12)


def test_lognormal_E_gives_the_lognormal_fundamental_frequency() -> None:
    n, sigma = 256, LOGNORMAL_E["sigma"]
    doc = run(sampled({"count": n, "seed": 7, "parameters": {"pipe.E": LOGNORMAL_E}}))
    validated(doc)
    st = doc["statistics"]
    assert (st["ok"], st["failed"]) == (n, 0)
    got = st["columns"]["final_omega_1"]
    assert got["unit"] == "rad/s" and got["count"] == n

    s = sigma / 2
    median = omega_1(LOGNORMAL_E["median"])
    mean = median * math.exp(s**2 / 2)
    std = mean * math.sqrt(math.expm1(s**2))
    kurt = math.exp(4 * s**2) + 2 * math.exp(3 * s**2) + 3 * math.exp(2 * s**2) - 3
    bounds = {
        "mean": 3 * std / math.sqrt(n),
        "std": 3 * std * math.sqrt((kurt - 1) / (4 * n)),
    }
    errors = {"mean": abs(got["mean"] - mean), "std": abs(got["std"] - std)}
    dist = stats.lognorm(s, scale=median)
    for p in uq.QUANTILES:
        q = float(dist.ppf(p))
        errors[f"q{p:g}"] = abs(got["quantiles"][f"{p:g}"] - q)
        bounds[f"q{p:g}"] = 3 * math.sqrt(p * (1 - p) / n) / float(dist.pdf(q))
    print({k: f"{errors[k] / bounds[k]:.3g} of the bound" for k in errors})
    for k in errors:
        assert errors[k] <= bounds[k], (k, errors[k], bounds[k])
    # not growing at rest: the probability of instability is 0 over every case
    assert st["instability"]["probability"] == 0.0 and st["instability"]["decided"] == n
    assert doc["sensitivity"] is None


@dataclass(frozen=True)
class Ishigami:
    """A stand-in base computation with one summary column, for the statistics path."""

    name: str = "simulation"
    summary_columns: tuple[Column, ...] = (Column("y", "-", "Ishigami's function."),)
    summarize: Any = None


def ishigami(x: np.ndarray, a: float = 7.0, b: float = 0.1) -> np.ndarray:
    return np.sin(x[:, 0]) + a * np.sin(x[:, 1]) ** 2 + b * x[:, 2] ** 4 * np.sin(x[:, 0])


def test_sobol_indices_of_the_ishigami_function() -> None:
    a, b, pi = 7.0, 0.1, math.pi
    # analytic partial variances (Ishigami & Homma 1990)
    v1 = 0.5 * (1 + b * pi**4 / 5) ** 2
    v2 = a**2 / 8
    v13 = b**2 * pi**8 * (1 / 18 - 1 / 50)
    v = v1 + v2 + v13
    exact = {"S1": [v1 / v, v2 / v, 0.0], "ST": [(v1 + v13) / v, v2 / v, v13 / v]}
    assert np.allclose(exact["S1"], [0.3139, 0.4424, 0.0], atol=5e-5)
    assert np.allclose(exact["ST"], [0.5576, 0.4424, 0.2437], atol=5e-5)

    x = {"distribution": "uniform", "low": -pi, "high": pi}
    paths = ["pipe.E", "pipe.L", "pipe.M2"]  # any three numeric fields carry x1, x2, x3
    spec = sampled(
        {"count": 1024, "method": "saltelli", "seed": 3, "parameters": dict.fromkeys(paths, x)}
    )
    assert spec.paths() == paths and spec.count() == 1024 * 8
    y = ishigami(spec.sample_values())
    records = [{"status": "ok", "y": float(v)} for v in y]
    out = sensitivity(spec, Ishigami(), records)
    assert out is not None and out["conf_level"] == 0.95 and out["base_points"] == 1024
    found = out["columns"]["y"]
    assert found["available"] and found["reason"] is None
    for i, path in enumerate(paths):
        got = found["parameters"][path]
        for index in ("S1", "ST"):
            err, conf = abs(got[index] - exact[index][i]), got[f"{index}_conf"]
            print(f"{path} {index}: error {err:.4f}, 95% half-width {conf:.4f}")
            assert err <= conf, (path, index, got[index], exact[index][i], conf)
    # the same table, seed and names give the same indices (bootstrap drawn from the seed),
    # seed 0 (the default) included: SALib seeds only a truthy seed
    assert sensitivity(spec, Ishigami(), records) == out
    zero = [float(v) for v in y]
    assert uq.sobol_indices(paths, zero, seed=0) == uq.sobol_indices(paths, zero, seed=0)


def test_a_saltelli_study_reports_indices_per_numeric_column() -> None:
    spec = sampled(
        {
            "count": 8,
            "method": "saltelli",
            "parameters": {
                "pipe.E": LOGNORMAL_E,
                "pipe.M2": {"distribution": "uniform", "low": 1.0e-5, "high": 2.0e-5},
            },
        }
    )
    doc = run(spec)
    validated(doc)
    assert doc["counts"]["total"] == 8 * 6
    omega = doc["sensitivity"]["columns"]["final_omega_1"]
    assert omega["available"] and set(omega["parameters"]) == {"pipe.E", "pipe.M2"}
    # the peak tip displacement at rest is u0's, whatever E: no variance, no indices
    peak = doc["sensitivity"]["columns"]["peak_tip_displacement"]
    assert not peak["available"] and "does not vary" in peak["reason"]


def test_indices_outside_0_1_warn_that_the_design_is_too_small() -> None:
    """Issue 34, item 4: 8 base points estimate S1 of E at 1.57 and ST at 1.14 for the
    fundamental frequency (indices lie in [0, 1]: sampling error); the result warns, naming
    the column, the parameter and N.  64 base points estimate them inside [0, 1] (S1 of E
    0.87, of M2 0.15) and do not warn; a column that varies only by rounding has no
    indices (they would be noise)."""
    parameters = {
        "pipe.E": LOGNORMAL_E,
        "pipe.M2": {"distribution": "uniform", "low": 1.0e-5, "high": 2.0e-5},
    }
    small = run(sampled({"count": 8, "method": "saltelli", "seed": 1, "parameters": parameters}))
    validated(small)
    (warning,) = [w for w in small["warnings"] if "outside [0, 1]" in w]
    assert warning.startswith("Sobol' indices of final_omega_1 outside [0, 1] (pipe.E: S1 = 1.57")
    assert "(N = 8 base points)" in warning and "samples.count" in warning
    e = small["sensitivity"]["columns"]["final_omega_1"]["parameters"]["pipe.E"]
    assert e["S1"] > 1 and e["ST"] > 1
    large = run(sampled({"count": 64, "method": "saltelli", "seed": 0, "parameters": parameters}))
    assert not [w for w in large["warnings"] if "outside" in w], large["warnings"]
    columns = large["sensitivity"]["columns"]
    for indices in columns["final_omega_1"]["parameters"].values():
        assert 0 <= indices["S1"] <= 1 and 0 <= indices["ST"] <= 1
    # the peak deflection at rest is u0's in every case but for 1 ulp: its "indices" were
    # noise (ST of E 2.02); a spread of rounding errors is no variation
    peak = columns["peak_tip_displacement"]
    assert not peak["available"] and "beyond rounding" in peak["reason"]


def test_the_same_seed_gives_the_same_study_and_key() -> None:
    body = {
        "count": 16,
        "method": "latin_hypercube",
        "seed": 11,
        "parameters": {
            "pipe.E": LOGNORMAL_E,
            "flow.velocity.value": {"distribution": "uniform", "low": 0.0, "high": 1.0},
        },
    }
    reordered = {**body, "parameters": dict(reversed(list(body["parameters"].items())))}
    one, again, other = sampled(body), sampled(reordered), sampled({**body, "seed": 12})

    def key(s: StudySpec) -> str:
        return canonical_key("study", s.canonical())

    assert key(one) == key(again) != key(other)
    assert [c.overrides for c in one.expand()] == [c.overrides for c in again.expand()]
    assert [c.overrides for c in one.expand()] != [c.overrides for c in other.expand()]
    for method in uq.METHODS:
        a, b = (sampled({**body, "method": method, "count": 4, "seed": seed}) for seed in (1, 2))
        assert key(a) != key(b)
        assert np.array_equal(a.sample_values(), a.sample_values())
        assert not np.array_equal(a.sample_values(), b.sample_values())
    # the canonical form is a valid request again (a job is recovered from it)
    assert key(StudySpec.model_validate(one.canonical())) == key(one)


@pytest.mark.parametrize(
    ("distribution", "u", "expected"),
    [
        ({"distribution": "normal", "mean": 2.0, "std": 3.0}, 0.975, 2.0 + 3.0 * 1.959964),
        ({"distribution": "uniform", "low": 1.0, "high": 3.0}, 0.25, 1.5),
        ({"distribution": "lognormal", "median": 5.0, "sigma": 0.5}, 0.5, 5.0),
        (
            {"distribution": "truncated_normal", "mean": 0.0, "std": 1.0, "low": 0.0, "high": 9},
            0.5,
            0.6744898,  # the half-normal's median: Phi^-1(0.75)
        ),
    ],
)
def test_each_distribution_maps_probabilities_by_its_inverse_cdf(
    distribution: dict[str, Any], u: float, expected: float
) -> None:
    """Textbook values to 1e-6 (the tables' digits)."""
    assert uq.ppf(distribution, np.array([u]))[0] == pytest.approx(expected, rel=1e-6)


def test_samples_stay_inside_the_unit_cube_and_finite() -> None:
    for method in uq.METHODS:
        u = uq.unit_design(method, 8, 3, 0)
        assert u.shape == (uq.rows(method, 8, 3), 3)
        assert np.all((u > 0) & (u < 1))
    tail = uq.ppf({"distribution": "normal", "mean": 0.0, "std": 1.0}, np.array([uq.EDGE]))
    assert np.isfinite(tail).all()


def errors(body: dict[str, Any]) -> list[tuple[tuple[Any, ...], str]]:
    with pytest.raises(ValidationError) as info:
        StudySpec.model_validate(body).check()
    return [(tuple(e["loc"]), e["msg"]) for e in info.value.errors()]


def test_every_bad_input_names_its_field() -> None:
    def bad(samples: dict[str, Any], **more: Any) -> list[tuple[tuple[Any, ...], str]]:
        return errors({"base": SIM, "samples": samples, **more})

    def one(path: str, d: dict[str, Any]) -> dict[str, Any]:
        return {"count": 4, "parameters": {path: d}}

    where = ("samples", "parameters", "pipe.E")
    for d, name in [
        ({"distribution": "lognormal", "median": 7e9, "sigma": 0.0}, "sigma"),
        ({"distribution": "lognormal", "median": 7e9, "sigma": -0.1}, "sigma"),
        ({"distribution": "lognormal", "median": 0.0, "sigma": 0.1}, "median"),
        ({"distribution": "normal", "mean": 7e9, "std": 0.0}, "std"),
        ({"distribution": "uniform", "low": 8e9, "high": 7e9}, "low"),
        ({"distribution": "uniform", "low": 7e9, "high": 7e9}, "low"),
        (
            {"distribution": "truncated_normal", "mean": 7e9, "std": 1e8, "low": 8e9, "high": 7e9},
            "low",
        ),
    ]:
        ((loc, msg),) = bad(one("pipe.E", d))
        assert loc == (*where, name), (d, loc)
        assert msg.startswith(f"pipe.E: {d['distribution']} {name}")

    ((loc, msg),) = bad(one("pipe.E", {"distribution": "weibull", "scale": 1.0}))
    assert loc == where and "normal" in msg and "lognormal" in msg
    ((loc, _),) = bad(one("pipe.E", {"distribution": "lognormal", "median": 7e9}))
    assert loc == (*where, "lognormal", "sigma")  # a missing parameter, under its tag

    # not a numeric field: missing, an object, an integer (a count)
    for path, text in [
        ("pipe.X", "is not a field of the base simulation request"),
        ("pipe", "is not a numeric field (it is object"),
        ("modes", "is an integer field"),
    ]:
        ((loc, msg),) = bad(one(path, {"distribution": "uniform", "low": 1.0, "high": 2.0}))
        assert loc == ("samples", "parameters", path) and text in msg

    # samples with cases or grid
    x = {"distribution": "uniform", "low": 7e9, "high": 8e9}
    for other in ({"grid": {"pipe.E": [7e9]}}, {"cases": [{}]}):
        ((loc, msg),) = bad(one("pipe.E", x), **other)
        assert loc == () and msg.startswith("Value error, samples: give exactly one of")

    # too many cases: count itself, or a saltelli design's N (2 D + 2)
    ((loc, _),) = bad({**one("pipe.E", x), "count": MAX_CASES + 1})
    assert loc == ("samples", "count")
    three = {p: x for p in ("pipe.E", "pipe.L", "pipe.M2")}
    ((loc, msg),) = bad({"count": 1251, "method": "saltelli", "parameters": three})
    assert loc == ("samples", "count") and "count is at most 1250 for 3 parameters" in msg
    assert len(sampled({"count": 1250, "method": "saltelli", "parameters": three}).paths()) == 3

    # a draw the base model refuses names the parameter, with the case
    normal = {"distribution": "normal", "mean": 1e9, "std": 1e9}
    ((loc, msg),) = bad({"count": 64, "parameters": {"pipe.E": normal}})
    assert loc == where and msg.startswith("case ") and "pipe.E" in msg

    # operating_velocity belongs to stability bases
    ((loc, msg),) = bad(one("pipe.E", x), operating_velocity=10.0)
    assert loc == () and msg.startswith("Value error, operating_velocity: only for stability")


def test_statistics_count_instability_at_the_operating_velocity() -> None:
    """A stability base: unstable when the critical velocity is at or below
    operating_velocity (the paper's pipe at w0 = 100 rad/s: 27.71 m/s with 6 modes)."""
    base = {
        "kind": "stability",
        "spec": {
            "pipe": PAPER_PIPE_JSON,
            "rotation": {"omega0": {"kind": "constant", "value": 100.0}},
            "modes": 6,
            "points": 101,
            "velocity_range": [0.0, 40.0],
        },
    }
    spin = {"distribution": "uniform", "low": 99.0, "high": 101.0}
    spec = sampled({"count": 4, "parameters": {"rotation.omega0.value": spin}}, base)
    cases = [c.overrides for c in spec.expand()]
    stable = {"status": "ok", "critical_velocity": 30.0, "stable_at_start": True}
    records = [
        stable,
        {**stable, "critical_velocity": 20.0},
        {**stable, "critical_velocity": None, "stable_at_start": False},
        {"status": "failed"},
    ]
    comp = registry.COMPUTATIONS["stability"]
    assert statistics(spec, comp, cases, records)["instability"] is None
    spec = sampled(spec.samples.model_dump(), base, operating_velocity=25.0)  # type: ignore[union-attr]
    got = statistics(spec, comp, cases, records)
    assert (got["ok"], got["failed"]) == (3, 1)
    p = 2 / 3
    assert got["instability"] == {
        "criterion": got["instability"]["criterion"],
        "probability": p,
        "standard_error": math.sqrt(p * (1 - p) / 3),
        "unstable": 2,
        "decided": 3,
    }
    assert got["columns"]["critical_velocity"]["count"] == 2  # the null is left out
    assert got["columns"]["critical_velocity"]["mean"] == 25.0

    doc = run(spec)
    validated(doc)
    v = doc["statistics"]["columns"]["critical_velocity"]
    assert v["unit"] == "m/s" and 27.0 < v["min"] <= v["max"] < 28.5
    assert doc["statistics"]["columns"]["critical_frequency"]["unit"] == "rad/s"
    assert doc["statistics"]["instability"]["probability"] == 0.0
