"""/v1/signals in-process (ASGI, lifespan run) on SQLite and PostgreSQL: every format in,
every format out, and each bad input answered with a clear 4xx while stored data stay intact."""

from __future__ import annotations

import io
import json

import numpy as np
import pytest
from _svc_signals import csv_bytes, mat_bytes, npy_bytes, npz_bytes, ringdown, wav_bytes

pytestmark = pytest.mark.anyio
PROBLEM = "application/problem+json"


async def _post_json(client, doc: dict | str, path: str = "/v1/signals"):  # noqa: ANN001
    body = doc if isinstance(doc, str) else json.dumps(doc, allow_nan=True)
    return await client.post(
        path, content=body.encode(), headers={"content-type": "application/json"}
    )


async def _npy(client, sid: str) -> np.ndarray:  # noqa: ANN001
    r = await client.get(f"/v1/signals/{sid}/data", params={"format": "npy"})
    assert r.status_code == 200, r.text
    return np.load(io.BytesIO(r.content))


async def test_json_upload_round_trips_exactly(asgi) -> None:  # noqa: ANN001
    _, client = asgi
    t, w = ringdown(1000)
    r = await _post_json(
        client,
        {
            "dt": 0.01,
            "w": w.tolist(),
            "unit": "s",
            "control": {"name": "angle", "value": 0.25, "unit": "rad"},
            "metadata": {"rig": "A"},
            "name": "run 1",
        },
    )
    assert r.status_code == 201, r.text
    meta = r.json()
    assert r.headers["location"] == f"/v1/signals/{meta['id']}"
    assert meta["n"] == 1000 and meta["dt"] == 0.01 and meta["unit"] == "s"
    assert meta["control"] == {"name": "angle", "value": 0.25, "unit": "rad"}
    assert meta["metadata"] == {"rig": "A"} and meta["source"] == "json"
    r = await client.get(f"/v1/signals/{meta['id']}")
    assert r.status_code == 200 and r.json()["id"] == meta["id"]
    a = await _npy(client, meta["id"])
    assert a.shape == (1000, 2) and a[:, 1].tobytes() == w.tobytes()
    j = (await client.get(f"/v1/signals/{meta['id']}/data")).json()
    assert np.array_equal(np.array(j["w"]), w)  # JSON floats round-trip exactly too
    c = await client.get(f"/v1/signals/{meta['id']}/data", headers={"accept": "text/csv"})
    assert c.headers["content-type"].startswith("text/csv")
    back = np.loadtxt(io.StringIO(c.text), delimiter=",", skiprows=1)
    assert back[:, 1].tobytes() == w.tobytes()


async def test_explicit_times_are_kept(asgi) -> None:  # noqa: ANN001
    _, client = asgi
    t = 5.0 + np.arange(50) * 0.001
    w = np.sin(t)
    r = await _post_json(client, {"t": t.tolist(), "w": w.tolist()})
    assert r.status_code == 201, r.text
    meta = r.json()
    assert meta["has_t"] and meta["t0"] == 5.0 and meta["dt"] == pytest.approx(0.001)
    a = await _npy(client, meta["id"])
    assert a[:, 0].tobytes() == t.tobytes()


@pytest.mark.parametrize("fmt", ["csv", "npy", "npy2", "npz", "mat", "wav", "tsv"])
async def test_file_uploads(asgi, fmt: str) -> None:  # noqa: ANN001
    _, client = asgi
    t, w = ringdown(500, dt=0.002)
    data: dict[str, str] = {"control_value": "1.25", "control_name": "load", "control_unit": "N"}
    if fmt == "csv":
        files = {"file": ("run.csv", csv_bytes(t, w))}
    elif fmt == "tsv":
        text = (
            "# lab export\ntime\tsignal (V)\n"
            + "\n".join(f"{float(a)!r}\t{float(b)!r}" for a, b in zip(t, w))
            + "\n"
        )
        files = {"file": ("run.tsv", text.encode())}
    elif fmt == "npy":
        files = {"file": ("run.npy", npy_bytes(w))}
        data["dt"] = "0.002"
    elif fmt == "npy2":
        files = {"file": ("run.npy", npy_bytes(np.column_stack([t, w])))}
    elif fmt == "npz":
        files = {"file": ("run.npz", npz_bytes(w=w, dt=np.float64(0.002)))}
    elif fmt == "mat":
        files = {"file": ("run.mat", mat_bytes(t=t, w=w))}
    else:
        wi = (w * 1000).astype(np.int16)
        files = {"file": ("run.wav", wav_bytes(500, wi))}
        w = wi.astype(np.float64)
    r = await client.post("/v1/signals", files=files, data=data)
    assert r.status_code == 201, r.text
    meta = r.json()
    assert meta["n"] == 500 and meta["dt"] == pytest.approx(0.002, rel=1e-9)
    assert meta["control"] == {"name": "load", "value": 1.25, "unit": "N"}
    a = await _npy(client, meta["id"])
    assert a[:, 1].tobytes() == w.tobytes(), fmt
    if fmt == "csv":
        assert meta["unit"] == "s" and meta["value_unit"] == "mm"
    if fmt == "tsv":
        assert meta["value_unit"] == "V"


async def test_delete(asgi) -> None:  # noqa: ANN001
    _, client = asgi
    sid = (await _post_json(client, {"dt": 1, "w": [1, 2, 3]})).json()["id"]
    assert (await client.delete(f"/v1/signals/{sid}")).status_code == 204
    r = await client.get(f"/v1/signals/{sid}")
    assert r.status_code == 404 and r.headers["content-type"] == PROBLEM
    assert r.json()["errors"][0] == {
        "field": "id",
        "value": sid,
        "message": f"no signal with id {sid!r}",
    }
    assert (await client.delete(f"/v1/signals/{sid}")).status_code == 404


async def test_signal_plot(asgi) -> None:  # noqa: ANN001
    _, client = asgi
    t, w = ringdown(30000)
    sid = (await _post_json(client, {"dt": 0.01, "w": w.tolist()})).json()["id"]
    r = await client.get(f"/v1/signals/{sid}/plot.png")
    assert r.status_code == 200 and r.headers["content-type"] == "image/png"
    assert r.content[:8] == b"\x89PNG\r\n\x1a\n"


BAD_JSON = [
    # (document, status, field, value)
    ('{"dt": 0.1, "w": [1, NaN, 3]}', 422, "w[1]", "NaN"),
    ('{"dt": 0.1, "w": [1, 2, Infinity]}', 422, "w[2]", "Infinity"),
    ('{"t": [0, 1, -Infinity], "w": [1, 2, 3]}', 422, "t[2]", "-Infinity"),
    ('{"dt": 0.1, "w": []}', 422, "w", []),
    ('{"dt": 0.1, "w": [1]}', 422, "w", [1.0]),
    ('{"t": [0, 1, 2], "w": [1, 2]}', 422, "t", "3 samples"),
    ('{"dt": 0.1, "w": [[1, 2], [3]]}', 422, "w[0]", [1, 2]),
    ('{"dt": 0.1, "w": [1, "a", 3]}', 422, "w[1]", "a"),
    ('{"t": [0, 2, 1], "w": [1, 2, 3]}', 422, "t[2]", 1.0),
    ('{"t": [0, 1, 1], "w": [1, 2, 3]}', 422, "t[2]", 1.0),
    ('{"t": [0, 1, 2, 3.5], "w": [1, 2, 3, 4]}', 422, "t[3]", 3.5),
    ('{"w": [1, 2, 3]}', 422, "dt", None),
    ('{"dt": -1, "w": [1, 2, 3]}', 422, "dt", -1.0),
    ('{"dt": NaN, "w": [1, 2, 3]}', 422, "dt", "NaN"),
    ('{"dt": 0.1, "t": [0, 1, 2], "w": [1, 2, 3]}', 422, "dt", 0.1),
    ('{"dt": 0.1, "w": [1, 2], "colour": "red"}', 422, "colour", "red"),
    ('{"dt": 0.1, "w": [1, 2], "control": {"value": NaN}}', 422, "control.value", "NaN"),
    ('{"dt": 0.1, "w": [1, 2', 422, "body", None),
]


async def _snapshot(client, sid: str) -> tuple[dict, bytes]:  # noqa: ANN001
    meta = (await client.get(f"/v1/signals/{sid}")).json()
    data = (await client.get(f"/v1/signals/{sid}/data", params={"format": "npy"})).content
    return meta, data


@pytest.fixture(scope="module")
async def keeper(asgi) -> str:  # noqa: ANN001
    """A stored signal that every bad request must leave untouched."""
    _, client = asgi
    t, w = ringdown(200)
    r = await _post_json(client, {"dt": 0.01, "w": w.tolist(), "name": "keeper"})
    return r.json()["id"]


@pytest.mark.parametrize(("doc", "status", "field", "value"), BAD_JSON)
async def test_bad_json_is_a_clear_4xx(asgi, keeper, doc, status, field, value) -> None:  # noqa: ANN001
    _, client = asgi
    before = await _snapshot(client, keeper)
    r = await _post_json(client, doc)
    assert r.status_code == status, r.text
    assert r.headers["content-type"] == PROBLEM
    p = r.json()
    assert p["status"] == status and p["type"].startswith("urn:snapwarn:problem:")
    assert p["title"] and p["detail"] and p["instance"] == "/v1/signals"
    assert p["errors"][0]["field"] == field, p
    if value is not None:
        assert p["errors"][0]["value"] == value, p
    assert await _snapshot(client, keeper) == before


BAD_FILES = [
    # (filename, bytes, extra form, status, field substring)
    ("run.csv", b"", {}, 422, "file"),
    ("run.csv", b"0,1\n1,2\n2,3\n", {}, 422, "file"),  # no header
    ("run.csv", b"t,w\n0,1\n1,2,5\n2,3\n", {}, 422, "line 3"),  # ragged
    ("run.csv", b"t,w\n0,1\n1,abc\n2,3\n", {}, 422, "line 3"),
    ("run.csv", b"t,w\n0,1\n1,nan\n2,3\n", {}, 422, "w[1]"),
    ("run.csv", b"t,w\n0,1\n2,2\n1,3\n", {}, 422, "t[2]"),
    ("run.csv", b"t,w\n0,1\n1,2\n2,3\n", {"dt": "0.5"}, 422, "dt"),
    ("run.csv", b"t,w\n0,1\n1,2\n2,3\n", {"column": "zz"}, 422, "column"),
    ("run.npy", b"not an npy", {"dt": "1"}, 422, "file"),
    ("run.npy", npy_bytes(np.ones((3, 3))), {}, 422, "file"),
    ("run.npy", npy_bytes(np.ones(5)), {}, 422, "dt"),
    ("run.npy", npy_bytes(np.ones(5) + 1j), {"dt": "1"}, 422, "w"),
    ("run.npz", npz_bytes(q=np.ones(3)), {}, 422, "file"),
    ("run.wav", b"RIFF....", {}, 422, "file"),
    ("run.xyz", b"1,2", {}, 415, "file"),
    ("run.csv", b"t,w\n0,1\n1,2\n", {"metadata": "{nope"}, 422, "metadata"),
    ("run.csv", b"t,w\n0,1\n1,2\n", {"control_value": "x"}, 422, "control_value"),
    ("run.csv", b"t,w\n0,1\n1,2\n", {"unit": "s" * 101}, 422, "unit"),
    ("run.csv", b"t,w\n0,1\n1,2\n", {"control_value": "inf"}, 422, "control_value"),
]


@pytest.mark.parametrize(("name", "data", "form", "status", "field"), BAD_FILES)
async def test_bad_files_are_a_clear_4xx(asgi, keeper, name, data, form, status, field) -> None:  # noqa: ANN001,E501
    _, client = asgi
    before = await _snapshot(client, keeper)
    r = await client.post("/v1/signals", files={"file": (name, data)}, data=form)
    assert r.status_code == status, r.text
    assert r.headers["content-type"] == PROBLEM
    p = r.json()
    assert field in p["errors"][0]["field"], p
    assert p["detail"]
    assert await _snapshot(client, keeper) == before


async def test_unsupported_content_type(asgi) -> None:  # noqa: ANN001
    _, client = asgi
    r = await client.post("/v1/signals", content=b"1,2,3", headers={"content-type": "text/csv"})
    assert r.status_code == 415 and r.json()["errors"][0]["field"] == "content-type"


async def test_unknown_route_and_method(asgi) -> None:  # noqa: ANN001
    _, client = asgi
    r = await client.get("/v1/nothing")
    assert r.status_code == 404 and r.headers["content-type"] == PROBLEM
    r = await client.put("/v1/signals")
    assert r.status_code == 405 and r.headers["content-type"] == PROBLEM
