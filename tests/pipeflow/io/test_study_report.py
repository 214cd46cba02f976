"""The report of a design study (issue 34 item 9): the Sobol' indices with their confidence
intervals, the standard errors of the estimates, the histograms and the Sobol' figure, and
a filled "Method and diagnostics" section (the design from the study's own request, which
the result echoes, the estimators, the diagnostics).

Every number of the report is checked against the result it is written from: the Sobol'
rows print the indices and half-widths with 3 decimals (so within 5e-4 of the result's),
the standard error of a mean with 2 significant digits (so within 5 % of std / sqrt(n));
the histograms' bars count every ok case (exactly: integers).
"""

from __future__ import annotations

import math
import re
from typing import Any

import pytest

from pipeflow.computations import registry
from pipeflow.io import report
from pipeflow.io.plots import figure
from pipeflow.paper import PAPER_PIPE_JSON
from pipeflow.schema.keys import canonical_key
from pipeflow.schema.study import StudySpec

#: the paper's pipe at rest (2 modes, 3 samples): each case takes about a millisecond
AT_REST: dict[str, Any] = {
    "pipe": PAPER_PIPE_JSON,
    "flow": {"velocity": {"kind": "constant", "value": 0.0}},
    "rotation": {"omega0": {"kind": "constant", "value": 0.0}},
    "modes": 2,
    "time": {"t_end": 0.01, "samples": 3},
    "output": {"eigen_samples": 3},
}
PARAMETERS = {
    "pipe.E": {"distribution": "lognormal", "median": PAPER_PIPE_JSON["E"], "sigma": 0.2},
    "pipe.M2": {"distribution": "uniform", "low": 1.5e-5, "high": 1.8e-5},
}
N = 16


@pytest.fixture(scope="module")
def study() -> tuple[StudySpec, dict[str, Any]]:
    spec = StudySpec.model_validate(
        {
            "base": {"kind": "simulation", "spec": AT_REST},
            "samples": {"count": N, "method": "saltelli", "seed": 1, "parameters": PARAMETERS},
        }
    )
    return spec, registry.COMPUTATIONS["study"].execute(spec)


def _section(rep: report.Report, title: str) -> dict[str, str]:
    return dict(next(rows for t, rows in rep.sections if t.startswith(title)))


def _numbers(text: str) -> list[float]:
    return [float(x) for x in re.findall(r"-?\d+\.\d+(?:e-?\d+)?", text)]


def test_the_result_echoes_its_request(study: tuple[StudySpec, dict[str, Any]]) -> None:
    """The echoed request is the study again: the same key when posted."""
    spec, doc = study
    assert doc["request"] == spec.canonical()
    again = StudySpec.model_validate(doc["request"])
    assert canonical_key("study", again.canonical()) == canonical_key("study", spec.canonical())


def test_sobol_indices_with_their_intervals(study: tuple[StudySpec, dict[str, Any]]) -> None:
    _, doc = study
    rep = report.report(doc)
    rows = _section(rep, "Sensitivity: Sobol' indices")
    drawn = 0
    for name, column in doc["sensitivity"]["columns"].items():
        if not column["available"]:
            assert rows[name] == f"no indices: {column['reason']}"
            continue
        for path, ix in column["parameters"].items():
            for index in ("S1", "ST"):
                value, half, lo, hi = _numbers(
                    rows[f"{name} w.r.t. {path}: {index} ± half-width [95 % interval]"]
                )
                assert value == pytest.approx(ix[index], abs=5e-4)
                assert half == pytest.approx(ix[index + "_conf"], abs=5e-4)
                assert (lo, hi) == pytest.approx((value - half, value + half), abs=1.5e-3)
                drawn += 1
    assert drawn >= 4  # final_omega_1 (and final_sigma_1) over two parameters


def test_standard_errors_of_the_estimates(study: tuple[StudySpec, dict[str, Any]]) -> None:
    _, doc = study
    rows = _section(report.report(doc), "Key numbers")
    for name, s in doc["statistics"]["columns"].items():
        label = f"{name} [{s['unit']}]: mean ± standard error of the mean"
        text = rows[f"{label} ({s['count']} values)"]
        mean, se = (float(x) for x in text.split(" ± "))
        assert mean == pytest.approx(s["mean"], rel=1e-5)
        assert se == pytest.approx(s["std"] / math.sqrt(s["count"]), rel=0.05)
    p = doc["statistics"]["instability"]
    text = rows["probability of instability P(unstable) [-] ± standard error"]
    assert text.startswith(f"{p['probability']:.4g} ± {p['standard_error']:.2g}")


def test_method_and_diagnostics_is_filled(study: tuple[StudySpec, dict[str, Any]]) -> None:
    _, doc = study
    rows = _section(report.report(doc), "Method and diagnostics")
    assert rows["base computation"] == "simulation"
    assert rows["design"].startswith("samples: Saltelli's design")
    assert rows["sample size N [-] (base points)"] == str(N)
    assert rows["seed"] == "1"
    assert rows["sampled parameters (D = 2)"].startswith("pipe.E: lognormal(median 7.8e+09")
    total = doc["counts"]["total"]
    assert total == N * (2 * 2 + 2)
    assert rows["number of evaluations (cases) [-]"].startswith(f"{total} (")
    assert "SALib.analyze.sobol" in rows["Sobol' estimators"]
    assert "100 resamples at 95 %" in rows["Sobol' estimators"]
    assert rows["failed cases"] == f"0 of {total}"
    for name, column in doc["sensitivity"]["columns"].items():
        if not column["available"]:
            assert rows[f"{name}: Sobol' indices"].startswith("none: ")
            continue
        values = [ix[k] for ix in column["parameters"].values() for k in ("S1", "ST")]
        inside = rows[f"{name}: indices within [0, 1]"]
        # the diagnostic agrees with the indices (and the result's own warning)
        assert (inside == "yes") == all(0 <= v <= 1 for v in values)
        if inside != "yes":
            assert "design is too small" in inside
            assert any(w.startswith(f"Sobol' indices of {name} outside") for w in doc["warnings"])
        widest = max(max(ix["S1_conf"], ix["ST_conf"]) for ix in column["parameters"].values())
        text = rows[f"{name}: widest 95 % half-width (convergence) [-]"]
        assert _numbers(text)[0] == pytest.approx(widest, abs=5e-4)
        assert f"N = {4 * N} would about halve them" in text


def test_a_study_without_its_request_says_so(study: tuple[StudySpec, dict[str, Any]]) -> None:
    """A study stored before results echoed their request: the design is unknown unless
    the service still held the job's request (``inputs``)."""
    spec, doc = study
    old = {k: v for k, v in doc.items() if k != "request"}
    rows = _section(report.report(old), "Method and diagnostics")
    assert rows["design"].startswith("not stored with this result")
    rows = _section(report.report(old, spec.canonical()), "Method and diagnostics")
    assert rows["sample size N [-] (base points)"] == str(N)


def test_histograms_and_sobol_figures(study: tuple[StudySpec, dict[str, Any]]) -> None:
    _, doc = study
    rep = report.report(doc)
    assert rep.figures[:2] == ["study_histograms", "sobol_indices"]
    fig = figure("study_histograms", [(None, doc)])
    stats = doc["statistics"]["columns"]
    assert len(fig.axes) == len(stats)  # one panel per numeric summary column
    for ax, (name, s) in zip(fig.axes, stats.items(), strict=True):
        assert ax.get_xlabel() == f"{name} [{s['unit']}]"
        assert sum(p.get_height() for p in ax.patches) == s["count"] == doc["counts"]["ok"]
        marks = sorted(line.get_xdata()[0] for line in ax.get_lines())
        expected = [s["mean"], *s["quantiles"].values()]
        assert marks == pytest.approx(sorted(expected), rel=1e-12)
    fig = figure("sobol_indices", [(None, doc)])
    available = [n for n, c in doc["sensitivity"]["columns"].items() if c["available"]]
    assert len(fig.axes) == len(available)
    ax = fig.axes[available.index("final_omega_1")]
    bars = [p.get_height() for p in ax.patches]
    ix = doc["sensitivity"]["columns"]["final_omega_1"]["parameters"]
    assert bars == pytest.approx([i["S1"] for i in ix.values()] + [i["ST"] for i in ix.values()])
    html = report.to_html(doc)
    assert 'id="figure-study_histograms"' in html and 'id="figure-sobol_indices"' in html
