"""The committed OpenAPI document is app.openapi(); regenerate: python -m service.openapi_gen."""

from __future__ import annotations

import json

from pipeflow.schema.simulation import PAPER_EXAMPLE
from service import openapi_gen


def test_committed_document_is_current() -> None:
    committed = openapi_gen.DEFAULT_PATH.read_text()
    assert committed == openapi_gen.render(openapi_gen.document()), (
        "openapi/openapi.json is stale: run `python -m service.openapi_gen`"
    )


def test_operations_errors_and_example() -> None:
    doc = json.loads(openapi_gen.DEFAULT_PATH.read_text())
    ops = {
        (method.upper(), path): op
        for path, item in doc["paths"].items()
        for method, op in item.items()
    }
    assert {op["operationId"] for op in ops.values()} == {
        "runSimulation",
        "submitJob",
        "compareMethods",
        "runStability",
        "submitStabilityJob",
        "submitSimulationJob",
        "submitCompareJob",
        "submitSweep",
        "submitSweepJob",
        "submitStudy",
        "submitStudyJob",
        "runFrequencyResponse",
        "submitFrequencyResponseJob",
        "runStateSpace",
        "submitStateSpaceJob",
        "getJob",
        "cancelJob",
        "getResult",
        "getResultPlot",
        "getResultTable",
        "getResultReportHtml",
        "getResultReportPdf",
        "getResultModeShapeAnimation",
        "getHealth",
        "getReadiness",
        "getMetrics",
    }
    # every computing endpoint has the same pair: the result (or, for sweeps and studies,
    # which always run as jobs, the job), and the job form
    from service.routes.endpoints import endpoints

    for endpoint in endpoints():
        path = f"/v1/{endpoint.path}"
        assert ("POST", path) in ops and ("POST", path + "/jobs") in ops
        assert ops[("POST", path + "/jobs")]["responses"]["202"]
    for op in ops.values():
        for code, resp in op["responses"].items():
            if int(code) >= 400:
                assert list(resp["content"]) == ["application/problem+json"], (op, code)
        # an answer of several media types declares them all as bytes: a generated client
        # reads the answer as the first it knows (text/html beside application/pdf made it
        # read a PDF as text); a text answer has an operation of its own
        content = op["responses"].get("200", {}).get("content", {})
        if len(content) > 1:
            schemas = [c["schema"] for c in content.values()]
            assert all(c == {"type": "string", "format": "binary"} for c in schemas), op
    assert doc["info"]["title"] == "pipeflow API"
    sim = ops[("POST", "/v1/simulations")]
    assert {"413", "422", "503", "500"} <= set(sim["responses"])
    example = sim["requestBody"]["content"]["application/json"]["examples"]["paper"]["value"]
    assert example == PAPER_EXAMPLE
    assert "404" in ops[("GET", "/v1/results/{key}")]["responses"]
    assert "304" in ops[("GET", "/v1/results/{key}")]["responses"]


def test_the_client_paths_are_the_services_endpoint_table() -> None:
    """The client's name -> path table (it cannot import the service) agrees with the
    service's, and both cover the registry's served computations."""
    from pipeflow.computations.registry import SWEEP_KINDS
    from pipeflow_client.client import PATHS
    from pipeflow_client.client import SWEEP_KINDS as CLIENT_SWEEP_KINDS
    from service.routes.endpoints import ENDPOINTS, endpoints

    assert CLIENT_SWEEP_KINDS == SWEEP_KINDS
    assert set(PATHS) == set(ENDPOINTS)
    for name, (path, sync) in PATHS.items():
        assert path == f"/v1/{ENDPOINTS[name].path}", name
        assert sync == (ENDPOINTS[name].run_operation is not None), name
    # simulations, compare, stability, sweeps, studies, frequency responses, state space
    assert len(endpoints()) == 7
