"""The service's JSON encoder follows pipeflow's one non-finite rule (json_safe -> null)."""

from __future__ import annotations

import json
import math

import numpy as np

from pipeflow.computations.registry import COMPUTATIONS
from pipeflow.io.json import json_safe
from pipeflow.schema.simulation import SimulationSpec
from service import encoding
from tests.service.conftest import SMALL


def test_non_finite_numbers_are_null_as_json_safe_says() -> None:
    data = {
        "a": [1.0, math.inf, -math.inf, math.nan, 0.1, 1e-5, 1e300, -0.0],
        "b": {"x": np.float64(np.inf), "y": np.float64(2.5), "n": np.int64(7)},
        "c": (np.float32(0.5), None, True, "s"),
        "d": np.array([1.0, np.nan, 3.0]),
        "e": np.arange(6.0).reshape(2, 3).T,  # not C-contiguous: written through tolist()
        "f": np.array([[np.inf, 1.0], [2.0, 3.0]])[:, 0],  # a strided view with an Inf
    }
    decoded = json.loads(encoding.dumps(data))
    expected = json_safe({**{k: data[k].tolist() for k in "def"}, **{k: data[k] for k in "abc"}})
    assert decoded == expected
    assert decoded["a"][1:4] == [None, None, None]
    assert decoded["b"]["x"] is None


def test_a_result_decodes_to_the_same_numbers_as_the_json_module() -> None:
    """Bit-for-bit: every float of a real result round-trips through both encoders (both
    write the shortest repr that reads back exactly), so the decoded documents are equal."""
    result = COMPUTATIONS["simulation"].execute(
        SimulationSpec.model_validate(SMALL), lambda fraction: None
    )
    ours = json.loads(encoding.dumps(result))
    reference = json.loads(json.dumps(result, allow_nan=False))
    assert ours == reference
    assert ours["tip_displacement"] == result["tip_displacement"]
