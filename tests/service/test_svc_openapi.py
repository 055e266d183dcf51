"""The checked-in OpenAPI document is the one the app serves (a drift fails here)."""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

import pytest
from _svc_helpers import REPO, SNAPWARN

from service.api import export_openapi, openapi_document
from service.api.app import render_openapi

CHECKED_IN = REPO / "openapi" / "openapi.json"
FIX = "run `snapwarn openapi` (or `make openapi`) and commit openapi/openapi.json"


def test_checked_in_document_matches_the_app() -> None:
    assert CHECKED_IN.exists(), FIX
    assert CHECKED_IN.read_text() == render_openapi(openapi_document()), FIX


@pytest.mark.anyio
async def test_served_document_matches_the_checked_in_file(asgi) -> None:  # noqa: ANN001
    _, client = asgi
    r = await client.get("/openapi.json")
    assert r.status_code == 200
    assert r.json() == json.loads(CHECKED_IN.read_text()), FIX


def test_live_server_serves_the_same_document(live_server) -> None:  # noqa: ANN001
    import httpx2

    served = httpx2.get(live_server.url + "/openapi.json").json()
    assert served == json.loads(CHECKED_IN.read_text()), FIX


def test_document_covers_every_resource() -> None:
    doc = json.loads(CHECKED_IN.read_text())
    paths = doc["paths"]
    for path, method in [
        ("/healthz", "get"),
        ("/v1/signals", "post"),
        ("/v1/signals", "get"),
        ("/v1/jobs", "get"),
        ("/v1/signals/{signal_id}", "get"),
        ("/v1/signals/{signal_id}", "delete"),
        ("/v1/signals/{signal_id}/data", "get"),
        ("/v1/signals/{signal_id}/plot.png", "get"),
        ("/v1/simulations", "post"),
        ("/v1/detections", "post"),
        ("/v1/sweeps", "post"),
        ("/v1/sweeps/{sweep_id}", "get"),
        ("/v1/sweeps/{sweep_id}/plot.png", "get"),
        ("/v1/sweeps/{sweep_id}/plot.svg", "get"),
        ("/v1/jobs/{job_id}", "get"),
    ]:
        assert method in paths.get(path, {}), (path, method)
    body = paths["/v1/signals"]["post"]["requestBody"]["content"]
    assert set(body) == {"application/json", "multipart/form-data"}
    refs = json.dumps(doc)
    for name in ("Problem", "SignalIn", "FieldError", "Control"):
        assert name in doc["components"]["schemas"]
    # every $ref resolves
    import re

    for ref in set(re.findall(r'"\$ref": "#/components/schemas/([^"]+)"', refs)):
        assert ref in doc["components"]["schemas"], ref
    assert "application/problem+json" in json.dumps(paths["/v1/detections"]["post"]["responses"])


def test_export_and_cli_write_the_same_file(tmp_path: Path) -> None:
    a = export_openapi(tmp_path / "a" / "openapi.json")
    out = tmp_path / "b.json"
    r = subprocess.run(
        [*SNAPWARN, "openapi", "--out", str(out), "--json"],
        capture_output=True,
        text=True,
        timeout=120,
        cwd=tmp_path,
    )
    assert r.returncode == 0, r.stderr
    assert json.loads(r.stdout)["path"] == str(out)
    assert a.read_text() == out.read_text() == CHECKED_IN.read_text()
