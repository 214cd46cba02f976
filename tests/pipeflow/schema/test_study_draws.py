"""A sampled study's cases are drawn once (issue 33): the check before a study is accepted
(:meth:`StudySpec.check`, run by :func:`~pipeflow.computations.registry.parse`) and its run
read the same draws; each distribution is the library's typed one
(:meth:`~pipeflow.schema.distributions.NormalDistribution.to_distribution`)."""

from __future__ import annotations

import pickle
from collections import Counter
from typing import Any

import numpy as np
import pytest

from pipeflow import uq
from pipeflow.computations import registry
from pipeflow.schema.study import StudySpec
from tests.pipeflow.schema.test_study_uq import LOGNORMAL_E, SIM

BODY: dict[str, Any] = {
    "base": SIM,
    "samples": {
        "count": 4,
        "parameters": {
            "pipe.E": LOGNORMAL_E,
            "flow.velocity.value": {"distribution": "uniform", "low": 0.0, "high": 1.0},
        },
    },
}


@pytest.fixture
def draws(monkeypatch: pytest.MonkeyPatch) -> Counter[str]:
    """Calls of the sampler's two stages at their seam in :mod:`pipeflow.uq`: the design of
    the unit hypercube and the inverse CDFs."""
    calls: Counter[str] = Counter()
    design, ppf = uq.unit_design, uq.ppf

    def counted_design(*args: Any) -> Any:
        calls["unit_design"] += 1
        return design(*args)

    def counted_ppf(*args: Any) -> Any:
        calls["ppf"] += 1
        return ppf(*args)

    monkeypatch.setattr(uq, "unit_design", counted_design)
    monkeypatch.setattr(uq, "ppf", counted_ppf)
    return calls


def test_a_sampled_study_is_drawn_once_from_check_to_table(draws: Counter[str]) -> None:
    """parse (model validation and the check of every drawn value) then the run: one
    design, one inverse CDF per parameter (before: two of each, the check's and the run's)."""
    spec = registry.parse("study", BODY)
    assert draws == {"unit_design": 1, "ppf": 2}
    doc = registry.STUDY.execute(spec)
    assert draws == {"unit_design": 1, "ppf": 2}
    assert len(doc["rows"]) == 4
    # the table's values are the draws
    drawn = spec.sample_values()
    j = [c["name"] for c in doc["columns"]].index("flow.velocity.value")
    column = [row[j] for row in doc["rows"]]
    assert column == pytest.approx(drawn[:, 0].tolist(), rel=0, abs=0)


def test_the_draws_are_not_pickled_with_the_study() -> None:
    """The pieces a study ships to workers carry their own overrides: the cached draws stay
    behind, and a study read back draws the same values again."""
    spec = StudySpec.model_validate(BODY)
    drawn = spec.sample_values()
    back = pickle.loads(pickle.dumps(spec))
    assert "_drawn" in vars(spec) and "_drawn" not in vars(back)
    assert np.array_equal(back.sample_values(), drawn)  # the design is seeded: the same
    assert back == spec


@pytest.mark.parametrize(
    "data",
    [
        {"distribution": "normal", "mean": 2.0, "std": 3.0},
        {"distribution": "uniform", "low": 1.0, "high": 3.0},
        {"distribution": "lognormal", "median": 5.0, "sigma": 0.5},
        {"distribution": "truncated_normal", "mean": 0.0, "std": 1.0, "low": 0.0, "high": 9.0},
    ],
)
def test_each_request_model_gives_its_typed_distribution(data: dict[str, Any]) -> None:
    """The request model's library distribution is the one its JSON form names, and maps
    probabilities to the same values (same scipy calls: equal to rounding, 1e-15)."""
    spec = StudySpec.model_validate(
        {**BODY, "samples": {"count": 2, "parameters": {"pipe.E": data}}}
    )
    model = spec.samples.parameters["pipe.E"]  # type: ignore[union-attr]
    typed = model.to_distribution()
    assert type(typed) is uq.DISTRIBUTIONS[data["distribution"]]
    assert typed == uq.distribution(data)
    u = np.array([0.1, 0.5, 0.9])
    assert uq.ppf(typed, u) == pytest.approx(uq.ppf(data, u), rel=1e-15)
