"""Design studies (pipeflow.schema.study and .study_runner): expansion, validation, summaries.

The summaries are checked against the standalone computations of the same cases, built
here by hand from the base dict (not by the study's override code) and run through the
registry: an identity, so equality is exact (same inputs, same process, deterministic
numerics).  The critical velocities are checked against the library call
:func:`pipeflow.stability.critical_velocities` directly, bypassing the schema layer.
"""

from __future__ import annotations

import copy
import csv
import io
from collections.abc import Mapping, Sequence
from typing import Any

import pytest
from pydantic import ValidationError

from pipeflow import parallel
from pipeflow.computations import registry
from pipeflow.computations import study_runner as study_module
from pipeflow.computations.registry import COMPUTATIONS
from pipeflow.errors import Cancelled
from pipeflow.io.export import available_tables, to_csv
from pipeflow.paper import PAPER_PIPE
from pipeflow.schema.keys import canonical_key
from pipeflow.schema.results import StudyResponse
from pipeflow.schema.simulation import PAPER_EXAMPLE, SimulationSpec
from pipeflow.schema.stability import PAPER_PIPE_JSON, StabilitySpec
from pipeflow.schema.study import MAX_CASES, StudySpec, field_unit
from pipeflow.stability import critical_velocities

#: a cheap simulation (2 modes, 0.05 s, 11 samples): milliseconds per case
BASE_SIM: dict[str, Any] = {
    "pipe": PAPER_EXAMPLE["pipe"],
    "flow": {"velocity": {"kind": "polynomial", "coefficients": [0.0, 0.4]}},
    "modes": 2,
    "time": {"t_end": 0.05, "samples": 11},
    "output": {"eigen_samples": 11},
    "method": "rk4",
}
SIM = {"kind": "simulation", "spec": BASE_SIM}


def study(**body: Any) -> StudySpec:
    return StudySpec.model_validate({"base": SIM, **body})


def errors(body: dict[str, Any]) -> list[tuple[tuple[Any, ...], str]]:
    """The errors of ``body``: its model validation, else its case check (both run by
    :func:`pipeflow.computations.registry.parse`, the service runs the check in a thread)."""
    with pytest.raises(ValidationError) as info:
        StudySpec.model_validate(body).check()
    return [(tuple(e["loc"]), e["msg"]) for e in info.value.errors()]


def test_case_check_is_separate_from_model_validation_and_parse_runs_both() -> None:
    bad = {"base": SIM, "cases": [{}, {"pipe.E": -1.0}]}
    spec = StudySpec.model_validate(bad)  # cheap structural validation only
    with pytest.raises(ValidationError) as info:
        spec.check()
    assert [tuple(e["loc"]) for e in info.value.errors()] == [("cases", 1, "pipe.E")]
    with pytest.raises(ValidationError):
        registry.parse("study", bad)


class DictMemo:
    """A memo in a dict, counting its batched calls."""

    def __init__(self) -> None:
        self.items: dict[str, dict[str, Any]] = {}
        self.gets: list[int] = []
        self.puts: list[int] = []

    def get_many(self, keys: Sequence[str]) -> dict[str, dict[str, Any]]:
        self.gets.append(len(keys))
        return {k: copy.deepcopy(self.items[k]) for k in keys if k in self.items}

    def put_many(self, results: Mapping[str, dict[str, Any]]) -> None:
        self.puts.append(len(results))
        self.items.update(copy.deepcopy(dict(results)))


@pytest.fixture
def counted(monkeypatch: pytest.MonkeyPatch) -> list[Any]:
    """The requests of every case computation (the serial host runs them here)."""
    calls: list[Any] = []
    run_case = study_module.run_case

    def counting(base: Any, request: Any) -> dict[str, Any]:
        calls.append(request)
        return run_case(base, request)

    monkeypatch.setattr(study_module, "run_case", counting)
    return calls


# -- expansion -----------------------------------------------------------------------------


def test_list_mode_overrides_the_named_fields_and_keeps_the_rest() -> None:
    s = study(
        cases=[
            {},
            {"pipe.E": 7.0e9, "rotation.omega0.value": 50},  # rotation left to its default
            {"flow.velocity.coefficients.1": 0.8, "modes": 3},
        ]
    )
    cases = s.expand()
    assert [c.index for c in cases] == [0, 1, 2]
    assert s.paths() == ["pipe.E", "rotation.omega0.value", "flow.velocity.coefficients.1", "modes"]
    base = SimulationSpec.model_validate(BASE_SIM)
    assert cases[0].request == base
    r1 = cases[1].request
    assert isinstance(r1, SimulationSpec)
    assert (r1.pipe.E, r1.rotation.omega0.value, r1.pipe.L) == (7.0e9, 50, base.pipe.L)
    r2 = cases[2].request
    assert isinstance(r2, SimulationSpec)
    assert r2.flow.velocity.coefficients == [0.0, 0.8] and r2.modes == 3  # type: ignore[union-attr]


def test_grid_mode_is_the_cartesian_product_in_sorted_field_order() -> None:
    grid = {"pipe.M2": [1e-5, 2e-5, 3e-5], "pipe.L": [0.02, 0.025]}
    s = study(grid=grid)
    assert s.count() == 6 and s.paths() == ["pipe.L", "pipe.M2"]
    got = [(c.request.pipe.L, c.request.pipe.M2) for c in s.expand()]  # type: ignore[attr-defined]
    assert got == [(L, m) for L in (0.02, 0.025) for m in (1e-5, 2e-5, 3e-5)]
    # JSON objects are unordered: the other order is the same study, with the same key
    other = study(grid=dict(reversed(list(grid.items()))))
    assert canonical_key("study", other.canonical()) == canonical_key("study", s.canonical())
    assert [c.overrides for c in other.expand()] == [c.overrides for c in s.expand()]
    # the normal form is a valid request again (a job is recovered from it)
    assert StudySpec.model_validate(s.canonical()).canonical() == s.canonical()


def test_field_units_come_from_the_field_descriptions() -> None:
    assert field_unit(SimulationSpec, "pipe.E") == "Pa"
    assert field_unit(SimulationSpec, "pipe.M2") == "kg/m"
    assert field_unit(SimulationSpec, "rotation.omega0.value") == "rad/s"
    assert field_unit(SimulationSpec, "flow.velocity.coefficients.0") == "m/s"
    assert field_unit(SimulationSpec, "flow.velocity.coefficients.2") == "(m/s) s^-2"
    assert field_unit(SimulationSpec, "modes") == "-"
    assert field_unit(StabilitySpec, "velocity_range.1") == "m/s"


# -- validation --------------------------------------------------------------------------


def test_an_invalid_value_names_the_case_and_its_field() -> None:
    [(loc, msg)] = errors({"base": SIM, "cases": [{"pipe.E": 7e9}, {"pipe.E": -1.0}]})
    assert loc == ("cases", 1, "pipe.E")
    assert msg.startswith("case 1 (pipe.E = -1.0): pipe.E:") and "greater than 0" in msg
    [(loc, msg)] = errors({"base": SIM, "grid": {"pipe.L": [0.02, 0.03, 0.0]}})
    assert loc == ("grid", "pipe.L", 2)
    [(loc, _)] = errors({"base": SIM, "grid": {"pipe.L": [0.02], "pipe.M2": [1e-5, -1.0]}})
    assert loc == ("grid", "pipe.M2", 1)
    # an integer field given a fraction: refused by the base model (strict), not rounded
    [(loc, msg)] = errors({"base": SIM, "cases": [{"modes": 2.5}]})
    assert loc == ("cases", 0, "modes") and "valid integer" in msg


def test_a_rule_across_fields_is_a_failed_row_naming_the_case_and_the_base_field() -> None:
    """The bulk check at submission sees each value against its own field only; a rule
    across fields is the case's own validation, when the study runs: a failed row (no key)
    naming the field, the other cases computed.  ``expand`` (every case at once) raises."""
    base = {"kind": "simulation", "spec": {**BASE_SIM, "output": {"positions": [0.02]}}}
    body = {"base": base, "cases": [{}, {"pipe.L": 0.01}]}
    s = StudySpec.model_validate(body)
    s.check()  # accepted: 0.01 is a valid length on its own
    with pytest.raises(ValidationError) as info:
        s.expand()
    [err] = info.value.errors()
    assert err["loc"] == ("cases", 1)
    assert "case 1 (pipe.L = 0.01)" in err["msg"] and "output.positions[0]" in err["msg"]
    result = COMPUTATIONS["study"].execute(s)
    rows = [
        dict(zip([c["name"] for c in result["columns"]], row, strict=True))
        for row in result["rows"]
    ]
    assert [r["status"] for r in rows] == ["ok", "failed"]
    bad = rows[1]
    assert bad["key"] is None and bad["error_type"] == "invalid-input"
    assert bad["error_field"] == "output.positions" and "case 1" in bad["error_detail"]
    assert result["counts"]["failed"] == 1 and result["counts"]["computed"] == 1


@pytest.mark.parametrize(
    ("case", "where", "says"),
    [
        ({"pipe.X": 1.0}, ("cases", 0, "pipe.X"), "is not a field of the base simulation"),
        (
            {"flow.velocity.coefficients.5": 1.0},
            ("cases", 0, "flow.velocity.coefficients.5"),
            "not a field",
        ),
        ({"rotation.omega0.mean": 1.0}, ("cases", 0, "rotation.omega0.mean"), "not a field"),
        ({"flow.velocity.kind": 1.0}, ("cases", 0, "flow.velocity.kind"), "not a numeric field"),
        ({"pipe": 1.0}, ("cases", 0, "pipe"), "not a numeric field (it is object"),
        ({"method": 1.0}, ("cases", 0, "method"), "not a numeric field (it is str"),
    ],
)
def test_a_path_that_is_not_a_numeric_field_is_refused(
    case: dict[str, Any], where: tuple[Any, ...], says: str
) -> None:
    [(loc, msg)] = errors({"base": SIM, "cases": [{}, case]})
    assert loc == (where[0], 1, *where[2:]) and says in msg


def test_strings_are_never_evaluated() -> None:
    for value in ("7e9", "__import__('os').system('true')", True, None, [1.0]):
        [(loc, msg)] = errors({"base": SIM, "cases": [{"pipe.E": value}]})
        assert loc == ("cases", 0, "pipe.E") and "JSON number" in msg
    [(loc, _)] = errors({"base": SIM, "cases": [{"pipe.E.__class__()": 1.0}]})
    assert loc[:3] == ("cases", 0, "pipe.E.__class__()")


def test_the_case_count_is_bounded_before_any_case_is_validated() -> None:
    [(loc, msg)] = errors({"base": SIM, "cases": [{}] * (MAX_CASES + 1)})
    assert loc == ("cases",) and str(MAX_CASES) in msg
    # a grid of 101 x 100: refused by its product (the bad value in it is never reached)
    big = {"pipe.E": [7e9 + i for i in range(101)], "pipe.L": [-1.0] * 100}
    [(loc, msg)] = errors({"base": SIM, "grid": big})
    assert loc == () and msg.startswith("Value error, grid: 101 x 100 = 10100 cases")
    assert study(grid={"pipe.E": [7e9 + i for i in range(100)], "pipe.M2": [1e-5] * 100})


def test_exactly_one_of_cases_and_grid() -> None:
    for body in ({"base": SIM}, {"base": SIM, "cases": [{}], "grid": {"pipe.E": [1.0]}}):
        [(loc, msg)] = errors(body)
        assert loc == () and "cases: give exactly one of cases" in msg


# -- running -----------------------------------------------------------------------------


def _standalone(spec: dict[str, Any]) -> tuple[str, dict[str, Any]]:
    request = SimulationSpec.model_validate(spec)
    return canonical_key("simulation", request.canonical()), COMPUTATIONS["simulation"].execute(
        request
    )


def test_simulation_summaries_are_the_standalone_computations() -> None:
    s = study(grid={"pipe.M2": [1.0e-5, 3.0e-5], "rotation.omega0.value": [0.0, 400.0]})
    result = COMPUTATIONS["study"].execute(s)
    StudyResponse.model_validate({"key": "k", "cached": False, **result})
    names = [c["name"] for c in result["columns"]]
    rows = [dict(zip(names, row, strict=True)) for row in result["rows"]]
    assert len(rows) == 4 and result["counts"] == {
        "total": 4, "ok": 4, "failed": 0, "cached": 0, "computed": 4
    }  # fmt: skip
    i = 0
    for m2 in (1.0e-5, 3.0e-5):
        for w0 in (0.0, 400.0):
            spec = copy.deepcopy(BASE_SIM)
            spec["pipe"]["M2"] = m2
            spec["rotation"] = {"omega0": {"kind": "constant", "value": w0}}
            key, alone = _standalone(spec)
            # the traces' last time: t_end, or the divergence time where the run stopped
            assert alone["eigenvalues"]["t"][-1] == alone["t"][-1]
            row = rows[i]
            assert (row["index"], row["pipe.M2"], row["rotation.omega0.value"]) == (i, m2, w0)
            assert row["key"] == key and row["status"] == "ok" and row["cached"] is False
            assert row["peak_tip_displacement"] == max(abs(u) for u in alone["tip_displacement"])
            assert row["final_sigma_1"] == alone["eigenvalues"]["modes"][0]["sigma"][-1]
            assert row["final_omega_1"] == alone["eigenvalues"]["modes"][0]["omega"][-1]
            assert row["method_used"] == alone["method_used"] == "rk4"
            assert row["result_status"] == alone["status"]
            i += 1
    # the spin changes the fundamental (so the rows are not one case repeated)
    assert rows[0]["final_omega_1"] != rows[1]["final_omega_1"]


@pytest.mark.slow  # a stability study against the library call per case, 8-16 s
def test_stability_summaries_are_the_library_critical_velocities() -> None:
    """The paper's pipe at w0 = 100 rad/s, 10 modes: flutter of mode 3 at 27.69 m/s
    (README, tests/pipeflow/stability/test_critical.py); here checked against the library call."""
    body = {
        "base": {
            "kind": "stability",
            "spec": {"pipe": PAPER_PIPE_JSON, "modes": 10, "velocity_range": [0.0, 60.0]},
        },
        "cases": [
            {"rotation.omega0.value": 100.0},
            {"rotation.omega0.value": 100.0, "pipe.M2": 0.0},
        ],
    }
    result = COMPUTATIONS["study"].execute(StudySpec.model_validate(body))
    names = [c["name"] for c in result["columns"]]
    rows = [dict(zip(names, row, strict=True)) for row in result["rows"]]
    paper = critical_velocities(PAPER_PIPE, omega0=100.0, velocity_range=(0.0, 60.0), modes=10)
    assert rows[0]["critical_velocity"] == paper.critical_velocity
    assert round(rows[0]["critical_velocity"], 2) == 27.69
    assert (rows[0]["critical_mode"], rows[0]["critical_kind"]) == (3, "flutter")
    # no fluid: no Coriolis coupling, so no flutter in the range
    assert rows[1]["status"] == "ok" and rows[1]["critical_velocity"] is None
    assert rows[1]["stable_throughout"] is True and rows[1]["critical_mode"] is None


def test_a_failing_case_is_reported_and_does_not_fail_the_study() -> None:
    s = study(cases=[{}, {"options.max_steps": 1}, {"pipe.E": 8e9}])
    result = COMPUTATIONS["study"].execute(s)
    names = [c["name"] for c in result["columns"]]
    rows = [dict(zip(names, row, strict=True)) for row in result["rows"]]
    assert [r["status"] for r in rows] == ["ok", "failed", "ok"]
    bad = rows[1]
    assert bad["error_type"] == "budget-exceeded" and bad["error_field"] == "options.max_steps"
    assert "max_steps" in bad["error_detail"] and bad["peak_tip_displacement"] is None
    assert result["counts"]["ok"] == 2 and result["counts"]["failed"] == 1
    assert result["warnings"] == ["1 of 3 cases failed (see error_detail)"]
    # the same refusal as the standalone request's, field for field
    with pytest.raises(Exception) as info:
        COMPUTATIONS["simulation"].execute(
            SimulationSpec.model_validate({**BASE_SIM, "options": {"max_steps": 1}})
        )
    assert getattr(info.value, "field", None) == "options.max_steps"
    assert getattr(info.value, "message", None) == bad["error_detail"]


def test_memo_overlapping_studies_compute_only_the_new_cases(counted: list[Any]) -> None:
    memo = DictMemo()
    first = study(cases=[{"pipe.E": e} for e in (7.0e9, 7.5e9, 8.0e9, 8.5e9)])
    with parallel.hosting(memo=memo):
        a = COMPUTATIONS["study"].execute(first)
    assert len(counted) == 4 and a["counts"]["cached"] == 0 and a["counts"]["computed"] == 4
    assert all(k.startswith("study_case:") for k in memo.items) and len(memo.items) == 4
    second = study(cases=[{"pipe.E": e} for e in (8.0e9, 8.5e9, 9.0e9)])
    with parallel.hosting(memo=memo):
        b = COMPUTATIONS["study"].execute(second)
    assert len(counted) == 5  # only 9e9 was computed
    assert b["counts"] == {"total": 3, "ok": 3, "failed": 0, "cached": 2, "computed": 1}
    assert [row[3] for row in b["rows"]] == [True, True, False]  # the 'cached' column
    assert b["rows"][0][4:] == a["rows"][2][4:] and b["rows"][1][4:] == a["rows"][3][4:]
    assert memo.gets == [4, 3]  # one batched look-up per study


def test_cases_with_equal_keys_are_computed_once(counted: list[Any]) -> None:
    # rk4 does not read rtol: both cases normalise to the base request
    s = study(cases=[{}, {"options.rtol": 1e-6}, {"pipe.E": 8e9}])
    result = COMPUTATIONS["study"].execute(s)
    assert len(counted) == 2 and result["counts"]["computed"] == 2
    assert result["rows"][0][1] == result["rows"][1][1]  # same key
    assert result["rows"][0][6:] == result["rows"][1][6:]  # same summary (after 2 overrides)


def test_progress_is_the_exact_fraction_of_cases_done(counted: list[Any]) -> None:
    memo = DictMemo()
    with parallel.hosting(memo=memo):
        COMPUTATIONS["study"].execute(study(cases=[{"pipe.E": 7e9 + i} for i in range(10)]))
    seen: list[float] = []
    s = study(cases=[{"pipe.E": 7e9 + i} for i in range(40)])  # 10 cached, 30 to compute
    with parallel.hosting(memo=memo):
        COMPUTATIONS["study"].execute(s, seen.append)
    # 30 new cases in chunks of at most 16: 15 + 15
    assert seen == [10 / 40, 25 / 40, 40 / 40]
    assert memo.puts[-2:] == [15, 15]


def test_cancel_stops_between_chunks(counted: list[Any]) -> None:
    def cancel_after_first_chunk(fraction: float) -> None:
        if fraction > 0:
            raise Cancelled("cancelled by request")

    s = study(cases=[{"pipe.E": 7e9 + i} for i in range(40)])
    with pytest.raises(Cancelled):
        COMPUTATIONS["study"].execute(s, cancel_after_first_chunk)
    assert len(counted) == 14  # 40 cases in chunks of at most 16: 14 + 14 + 12


def test_csv_table_of_a_study() -> None:
    s = study(cases=[{"pipe.E": 7e9}, {"options.max_steps": 1}])
    result = COMPUTATIONS["study"].execute(s)
    assert available_tables(result) == ["study"]
    text = to_csv(result, "study")
    rows = list(csv.reader(io.StringIO(text)))
    assert rows[0][:6] == [
        "index [-]",
        "key",
        "status",
        "cached",
        "pipe.E [Pa]",
        "options.max_steps [-]",
    ]
    assert "peak_tip_displacement [m]" in rows[0] and "final_sigma_1 [1/s]" in rows[0]
    assert len(rows) == 3 and rows[1][:4] == ["0", result["rows"][0][1], "ok", "false"]
    peak = rows[0].index("peak_tip_displacement [m]")
    assert float(rows[1][peak]) == result["rows"][0][peak]  # shortest round-trip repr
    assert rows[2][2] == "failed" and rows[2][peak] == ""  # null: empty cell
    assert rows[2][rows[0].index("error_field")] == "options.max_steps"


def test_parquet_table_of_a_study_keeps_text_flags_and_floats() -> None:
    pq = pytest.importorskip("pyarrow.parquet")  # in the dev extra: CI runs this
    from pipeflow.io.export import to_parquet

    result = COMPUTATIONS["study"].execute(study(cases=[{"pipe.E": 7e9}, {"pipe.E": 8e9}]))
    t = pq.read_table(io.BytesIO(to_parquet(result, "study")))
    names = [c["name"] for c in result["columns"]]
    assert t.column_names == names
    assert t.schema.field("pipe.E").metadata == {b"unit": b"Pa"}
    assert str(t.schema.field("key").type) == "string"
    assert str(t.schema.field("cached").type) == "bool"
    peak = names.index("peak_tip_displacement")
    assert t.column("peak_tip_displacement").to_pylist() == [r[peak] for r in result["rows"]]


def test_an_lti_study_runs_batched_with_the_standalone_keys_and_summaries(
    counted: list[Any],
) -> None:
    """Constant flow and spin (``auto`` = cma): the chunk is summarised by one stacked
    computation (no case runs alone), each row equal to its standalone request's summary to
    1e-10 (sigma relative to the eigenvalue's modulus) and keyed as that request, integers
    given for float fields included; overriding ``modes`` (which the model normalises
    ``output.eigen_modes`` against) keys from the case's own canonical form."""
    base = {
        "pipe": PAPER_EXAMPLE["pipe"],
        "modes": 4,
        "time": {"t_end": 0.2, "samples": 51},
        "output": {"eigen_modes": 4},
    }
    grid = {"flow.velocity.value": [0, 10.0, 40.0], "rotation.omega0.value": [0, 150.0]}
    for extra in ({}, {"modes": [3, 4]}):
        s = StudySpec.model_validate(
            {"base": {"kind": "simulation", "spec": base}, "grid": {**grid, **extra}}
        )
        result = COMPUTATIONS["study"].execute(s)
        assert counted == []  # all batched
        names = [c["name"] for c in result["columns"]]
        statuses = set()
        for row in result["rows"]:
            r = dict(zip(names, row, strict=True))
            spec = copy.deepcopy(base)
            spec["flow"] = {"velocity": {"kind": "constant", "value": r["flow.velocity.value"]}}
            spec["rotation"] = {"omega0": {"kind": "constant", "value": r["rotation.omega0.value"]}}
            if "modes" in r:
                spec["modes"] = r["modes"]
            key, single = _standalone(spec)
            want = COMPUTATIONS["simulation"].summarize(single)  # type: ignore[misc]
            assert r["key"] == key
            assert (r["method_used"], r["result_status"]) == ("cma", want["result_status"])
            statuses.add(r["result_status"])
            peak = want["peak_tip_displacement"]
            assert abs(r["peak_tip_displacement"] - peak) <= 1e-10 * peak
            scale = abs(complex(want["final_sigma_1"], want["final_omega_1"]))
            for col in ("final_sigma_1", "final_omega_1"):
                assert abs(r[col] - want[col]) <= 1e-10 * scale
        assert statuses == {"ok", "diverged"}  # v = 40 m/s stops at the bound


class ShippingHost:
    """A host of width 2 that ships every piece and its result through pickle, as a
    cluster does, and runs it here (so the counting fixture sees the computations).  The
    memo a piece carries is this test's own object (a shared store, like the service's
    database), not a copy."""

    width = 2

    def __init__(self, memo: DictMemo | None = None) -> None:
        self.memo = memo
        self.pieces = 0

    def map(self, fn: Any, items: Sequence[Any]) -> Any:
        import pickle

        for i, item in enumerate(items):
            shipped = pickle.loads(pickle.dumps(item))
            if getattr(shipped, "memo", None) is not None:
                object.__setattr__(shipped, "memo", self.memo)
            self.pieces += 1
            yield i, pickle.loads(pickle.dumps(fn(shipped)))


def test_a_shipped_study_gives_the_serial_hosts_table(counted: list[Any]) -> None:
    """On a host that ships its pieces every case is validated, keyed, looked up and
    computed in its piece: the same document as the serial host's, cell for cell (same
    process, same numerics: exact), invalid cases and equal keys included."""
    base = {"kind": "simulation", "spec": {**BASE_SIM, "output": {"positions": [0.02]}}}
    cases = [
        {},
        {"options.rtol": 1e-6},
        {"pipe.L": 0.01},
        *({"pipe.E": 7e9 + i} for i in range(30)),
    ]
    s = StudySpec.model_validate({"base": base, "cases": cases})
    serial = COMPUTATIONS["study"].execute(s)
    assert len(counted) == 31  # the two equal keys once, the invalid case never
    host = ShippingHost()
    with parallel.hosting(host=host):
        shipped = COMPUTATIONS["study"].execute(s)
    assert host.pieces == 7  # 33 cases in about 4 pieces per unit of width (of 5)
    assert len(counted) == 62
    assert shipped == serial
    assert shipped["rows"][2][1] is None and shipped["rows"][2][2] == "failed"


def test_a_shipped_study_uses_the_memo_in_its_pieces(counted: list[Any]) -> None:
    """Overlapping studies on a shipping host: each piece looks up its cases in one batch
    and writes the ones it computed in one batch; the rows say which were served."""
    memo = DictMemo()
    first = study(cases=[{"pipe.E": e} for e in (7.0e9, 7.5e9, 8.0e9, 8.5e9)])
    with parallel.hosting(host=ShippingHost(memo), memo=memo):
        a = COMPUTATIONS["study"].execute(first)
    assert len(counted) == 4 and a["counts"]["computed"] == 4 and len(memo.items) == 4
    second = study(cases=[{"pipe.E": e} for e in (8.0e9, 8.5e9, 9.0e9)])
    seen: list[float] = []
    with parallel.hosting(host=ShippingHost(memo), memo=memo):
        b = COMPUTATIONS["study"].execute(second, seen.append)
    assert len(counted) == 5  # only 9e9 was computed
    assert b["counts"] == {"total": 3, "ok": 3, "failed": 0, "cached": 2, "computed": 1}
    assert [row[3] for row in b["rows"]] == [True, True, False]
    assert b["rows"][0][4:] == a["rows"][2][4:] and b["rows"][1][4:] == a["rows"][3][4:]
    # one look-up per piece (of one case here: 4 pieces per unit of width), one write
    # per piece that computed something
    assert memo.gets == [1] * 7 and memo.puts == [1] * 5
    assert seen == [1 / 3, 2 / 3, 1.0]


def test_a_store_memo_travels_as_its_database(tmp_path: Any) -> None:
    """A piece's memo pickles as its store's URL and reopens there as that process's
    store of the same database: what one side writes, the other reads."""
    import pickle

    pytest.importorskip("sqlalchemy")
    from service.store import Store
    from service.store.memo import StoreMemo

    store = Store(tmp_path / "db.sqlite3", cache_max_bytes=10**6, memory_cache_bytes=0)
    memo = StoreMemo(store)
    blob = pickle.dumps(memo)
    assert b"db.sqlite3" in blob and len(blob) < 500  # the URL, not a connection
    there = pickle.loads(blob)
    assert there.store is not store and there.store.url == store.url
    there.put_many({"study_case:" + "a" * 64: {"status": "ok", "peak": 1.5}})
    assert memo.get_many(["study_case:" + "a" * 64]) == {
        "study_case:" + "a" * 64: {"status": "ok", "peak": 1.5}
    }
    assert pickle.loads(pickle.dumps(memo)).store is there.store  # one per process
