"""POST /v1/detections with a small inline signal runs whole in an analysis worker (a process:
parse, validate, detect, serialise): its answers and its errors cross the process boundary
unchanged (the in-process reference: the numerics and the one-piece validation)."""

from __future__ import annotations

import json

import numpy as np
import pytest
from _svc_helpers import require_numerics
from _svc_signals import ringdown

pytestmark = pytest.mark.anyio


async def _post(client, doc: dict | str):  # noqa: ANN001
    body = doc if isinstance(doc, str) else json.dumps(doc, allow_nan=True)
    return await client.post(
        "/v1/detections", content=body.encode(), headers={"content-type": "application/json"}
    )


async def test_the_worker_answers_the_reference_document(asgi) -> None:  # noqa: ANN001
    """Rounded timestamps: the reader's flag is listed first, as in the server-side path."""
    require_numerics("service.analysis.detect", "detect")
    from service import convert, recordings
    from service.analysis.detect import detect

    _, client = asgi
    t, w = ringdown(3000, dt=0.0123)
    t = np.round(t, 3)
    rec = recordings.from_arrays(w.tolist(), t.tolist(), uniform_rtol=1e-3)
    assert rec.flags  # the rounding is noticed
    notes = [convert.plain(f) for f in rec.flags]
    expected = convert.detection(detect(rec.w, dt=rec.dt), extra_flags=notes)
    r = await _post(client, {"t": t.tolist(), "w": w.tolist()})
    assert r.status_code == 200 and r.headers["content-type"] == "application/json", r.text
    assert r.json() == expected.model_dump(mode="json")


@pytest.mark.parametrize(
    ("doc", "status", "field", "value"),
    [
        ({"dt": 0.1, "w": [1, True, 3]}, 422, "w[1]", True),  # pydantic, in the worker
        ({"dt": 0.1, "w": [1, 2, 3], "method": "magic"}, 422, "method", "magic"),
        ('{"dt": 0.1, "w": [1, 2', 422, "body", None),
        ({"dt": 0.1, "w": [1, float("inf"), 3]}, 422, "w[1]", "Infinity"),  # RecordingError
        ({"dt": 1e-99, "t0": 1e100, "w": [1, 2, 3]}, 422, "t0", None),  # ApiProblem
        ({"t": [0, 1, 1.5], "w": [1, 2, 3]}, 422, "t[1]", 1.0),
        ({"signal_id": "missing"}, 404, "id", "missing"),  # back to the server: the store
        ({"signal_id": "x", "dt": 0.1, "w": [1, 2]}, 422, "signal_id", "x"),
    ],
)
async def test_errors_cross_the_process_boundary(asgi, doc, status, field, value) -> None:  # noqa: ANN001
    _, client = asgi
    r = await _post(client, doc)
    assert r.status_code == status, r.text
    assert r.headers["content-type"] == "application/problem+json"
    e = r.json()["errors"][0]
    assert e["field"] == field, r.text
    if value is not None:
        assert e["value"] == value, r.text


async def test_a_stored_signal_is_read_by_the_server(asgi) -> None:  # noqa: ANN001
    require_numerics("service.analysis.detect", "detect")
    _, client = asgi
    t, w = ringdown(2000, dt=0.01)
    sid = (await client.post("/v1/signals", json={"dt": 0.01, "w": w.tolist()})).json()["id"]
    stored = await _post(client, {"signal_id": sid, "method": "esprit"})
    inline = await _post(client, {"dt": 0.01, "w": w.tolist(), "method": "esprit"})
    assert stored.status_code == inline.status_code == 200
    assert stored.json() == inline.json()
