"""pipeflow.compare: one case, several methods, their cost and their distance to the best
(checked on its document, pipeflow.computations.documents.compare)."""

from __future__ import annotations

import json

import pytest

from pipeflow.compare import compare
from pipeflow.computations import documents
from pipeflow.errors import InvalidInput
from tests.pipeflow.cases import PAPER_FLOWS, paper_sim


def test_compare_time_variant_case() -> None:
    """v = 0.4 t, 3 modes, 0.1 s: the baseline is the method claiming the smallest error:
    magnus (order 6 on 3 modes, estimate ~4e-11) rather than reference (rtol 1e-12 ~ 3e-10);
    the two agree to magnus's 1e-8 target, CMA differs by its first-Magnus-term error and
    its reported estimate says so (within a factor 2)."""
    sim = paper_sim(PAPER_FLOWS["v=0.4t"], modes=3, t_end=0.1, samples=201)
    comparison = compare(sim, ["cma", "magnus", "reference"])
    out = documents.compare(comparison)
    json.dumps(out, allow_nan=False)  # JSON-ready, every number finite
    rows = {r["method"]: r for r in out["methods"]}
    assert list(rows) == ["cma", "magnus", "reference"]
    assert out["baseline"] == "magnus"
    assert rows["magnus"]["estimated_relative_error"] < 3e-10
    assert rows[out["baseline"]]["difference_from_baseline"] == 0.0
    assert rows["magnus"]["difference_from_baseline"] < 1e-8
    assert rows["reference"]["difference_from_baseline"] < 1e-8
    cma = rows["cma"]
    assert cma["difference_from_baseline"] > 1e-4
    assert cma["difference_from_baseline"] / 2 < cma["estimated_relative_error"]
    assert cma["estimated_relative_error"] < 2 * cma["difference_from_baseline"]
    for r in out["methods"]:
        assert r["solve_seconds"] > 0 and r["wall_seconds"] >= r["solve_seconds"]
        assert r["speedup_vs_slowest"] >= 1.0
        assert r["compared_samples"] == 201
    assert max(r["speedup_vs_slowest"] for r in out["methods"]) > 1.0
    # the library's result: the runs in the order asked, the baseline among them
    assert [run.result.simulation.method for run in comparison.runs] == list(rows)
    assert comparison.baseline is comparison.runs[1].result
    assert [run.compared_samples for run in comparison.runs] == [201, 201, 201]


def test_compare_defaults_exclude_reference_and_pick_magnus() -> None:
    sim = paper_sim(PAPER_FLOWS["v=0.4t^2"], modes=2, t_end=0.05, samples=51)
    out = documents.compare(compare(sim))
    names = [r["method"] for r in out["methods"]]
    assert "reference" not in names and {"cma", "magnus", "rk4"} <= set(names)
    assert out["baseline"] == "magnus"


@pytest.mark.parametrize(
    "methods, field",
    [([], "methods"), (["cma", "nope"], "methods"), (["cma", "cma"], "methods")],
)
def test_compare_rejects_bad_method_lists(methods: list[str], field: str) -> None:
    with pytest.raises(InvalidInput) as info:
        compare(paper_sim(PAPER_FLOWS["v=0.4"], modes=2), methods)
    assert info.value.parameter == field
