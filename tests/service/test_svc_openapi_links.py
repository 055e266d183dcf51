"""The OpenAPI links a stateful fuzzer chains (``service.api.openapi_links``): each one in the
spec, its literal body a valid request of its target, and each chain followed on the real app
reaching the work behind the door: a detection and a sweep job of a stored signal, a live
record and its warning read back, an atlas job after a simulation, a prediction refitted."""

from __future__ import annotations

import json
import re
from pathlib import Path
from typing import Any

import pytest

from service.api.openapi_links import (
    EXAMPLE_ATLAS,
    EXAMPLE_PREDICTION,
    EXAMPLE_RECORD,
    EXAMPLE_SIGNAL,
    EXAMPLES,
    LINKS,
)

SPEC = Path(__file__).resolve().parents[2] / "openapi" / "openapi.json"


def _links(path: str, method: str, status: str) -> dict[str, Any]:
    spec = json.loads(SPEC.read_text())
    return spec["paths"][path][method]["responses"][status].get("links", {})


def test_every_link_is_in_the_committed_spec_and_resolves() -> None:
    spec = json.loads(SPEC.read_text())
    n = 0
    for (path, method, status), links in LINKS.items():
        got = _links(path, method, status)
        for name, (target, tmethod, params, body, _) in links.items():
            link = got[name]
            ref = link["operationRef"].removeprefix("#/paths/").rsplit("/", 1)
            assert ref[0].replace("~1", "/").replace("~0", "~") == target and ref[1] == tmethod
            assert tmethod in spec["paths"][target]
            assert link.get("parameters", {}) == params
            if body is not None:
                assert link["requestBody"] == body and not link["x-schemathesis"]["merge_body"]
            n += 1
    assert n == 8


def test_the_literal_bodies_are_valid_requests() -> None:
    from service.atlas.spec import parse_spec
    from service.schemas import PredictionRequest
    from service.schemas.atlases import AtlasRequest
    from service.schemas.live import LiveRecordIn
    from service.schemas.simulations import SimulationRequest
    from service.schemas.sweeps import SweepRequest

    PredictionRequest.model_validate_json(json.dumps(EXAMPLE_PREDICTION))
    LiveRecordIn.model_validate_json(json.dumps(EXAMPLE_RECORD))
    AtlasRequest.model_validate_json(json.dumps(EXAMPLE_ATLAS))
    assert len(parse_spec(EXAMPLE_ATLAS["spec"]).cells) == 3
    for ex in EXAMPLES["/v1/sweeps"].values():
        SweepRequest.model_validate_json(json.dumps(ex))
    SimulationRequest.model_validate_json(json.dumps(EXAMPLES["/v1/simulations"]["normal-form"]))
    spec = json.loads(SPEC.read_text())
    for path, examples in EXAMPLES.items():
        doc = spec["paths"][path]["post"]["requestBody"]["content"]["application/json"]
        assert {k: v["value"] for k, v in doc["examples"].items()} == examples, path


@pytest.mark.anyio
async def test_the_examples_are_answered_2xx(asgi) -> None:  # noqa: ANN001
    _, client = asgi
    live = (await client.post("/v1/sweeps", json={"mode": "live"})).json()["id"]
    for path, examples in EXAMPLES.items():
        for name, body in examples.items():
            r = await client.post(path.replace("{sweep_id}", live), json=body)
            assert 200 <= r.status_code < 300, (path, name, r.status_code, r.text[:300])


def _eval(expr: Any, request: dict[str, Any], response: dict[str, Any]) -> Any:
    """The runtime expressions the links use: $response.body#/x, $request.path.x,
    $request.body#/x (in nested literals too)."""
    if isinstance(expr, dict):
        return {k: _eval(v, request, response) for k, v in expr.items()}
    if isinstance(expr, list):
        return [_eval(v, request, response) for v in expr]
    if not isinstance(expr, str) or not expr.startswith("$"):
        return expr
    if m := re.fullmatch(r"\$response\.body#/(.+)", expr):
        return _pointer(response, m.group(1))
    if m := re.fullmatch(r"\$request\.body#/(.+)", expr):
        return _pointer(request["body"], m.group(1))
    if m := re.fullmatch(r"\$request\.path\.(\w+)", expr):
        return request["path"][m.group(1)]
    raise AssertionError(expr)


def _pointer(doc: Any, ptr: str) -> Any:
    for part in ptr.split("/"):
        doc = doc[int(part)] if isinstance(doc, list) else doc[part]
    return doc


async def _follow(client, source: tuple[str, str, str], name: str, request: dict, answer: dict):  # noqa: ANN001, ANN202
    target, method, params, body, _ = LINKS[source][name]
    values = {k: _eval(v, request, answer) for k, v in params.items()}
    url = target.format(**values)
    sent = _eval(body, request, answer) if body is not None else None
    r = await client.request(method.upper(), url, json=sent)
    return r, {"path": values, "body": sent}


@pytest.mark.anyio
async def test_the_chains_reach_the_work(asgi) -> None:  # noqa: ANN001
    _, client = asgi
    sig_req = {"body": EXAMPLE_SIGNAL, "path": {}}
    sig = await client.post("/v1/signals", json=sig_req["body"])
    assert sig.status_code == 201, sig.text[:300]
    src = ("/v1/signals", "post", "201")
    det, _ = await _follow(client, src, "post_detection", sig_req, sig.json())
    assert det.status_code == 200 and det.json()["modes"], det.text[:300]
    sweep, _ = await _follow(client, src, "post_sweep", sig_req, sig.json())
    assert sweep.status_code == 202 and sweep.json()["job"], sweep.text[:300]

    live_req = {"body": {"mode": "live"}, "path": {}}
    live = await client.post("/v1/sweeps", json=live_req["body"])
    assert live.status_code == 201, live.text[:300]
    rec, rec_req = await _follow(client, ("/v1/sweeps", "post", "201"), "post_record_inline",
                                 live_req, live.json())  # fmt: skip
    assert rec.status_code == 201 and rec.json()["seq"] == 1, rec.text[:300]
    src = ("/v1/sweeps/{sweep_id}/records", "post", "201")
    got, _ = await _follow(client, src, "get_record", rec_req, rec.json())
    assert got.status_code == 200 and got.json()["seq"] == 1, got.text[:300]
    closed, _ = await _follow(client, src, "post_close", rec_req, rec.json())
    assert closed.status_code == 200, closed.text[:300]

    pred_req = {"body": EXAMPLE_PREDICTION, "path": {}}
    pred = await client.post("/v1/predictions", json=EXAMPLE_PREDICTION)
    assert pred.status_code == 200, pred.text[:300]
    refit, _ = await _follow(client, ("/v1/predictions", "post", "200"), "post_refit",
                             pred_req, pred.json())  # fmt: skip
    assert refit.status_code == 200 and refit.json()["transition"] == "saddle-node", refit.text

    sim_req = {"body": {"model": "normal-form", "mu": -0.5}, "path": {}}
    sim = await client.post("/v1/simulations", json=sim_req["body"])
    assert sim.status_code == 201, sim.text[:300]
    atlas, _ = await _follow(client, ("/v1/simulations", "post", "201"), "post_atlas",
                             sim_req, sim.json())  # fmt: skip
    assert atlas.status_code == 202 and atlas.json()["job"], atlas.text[:300]
