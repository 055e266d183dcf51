"""numpy scalars are numbers everywhere the SDK takes one: ``live.add(control=np.float32(0.5))``
and the others are sent as plain JSON numbers, form fields and query values (``_core.plain``).

The calls are checked as built (no server), then end to end against a real uvicorn.
"""

from __future__ import annotations

import json

import httpx2
import numpy as np
import pytest
from _records import DT, record

from service.client import Client
from service.client import _core as core
from service.client import live as live_calls

F32 = np.float32(0.5)  # exactly 0.5
SCALARS = [np.float32(0.5), np.float64(0.5), np.float16(0.5), np.int64(3), np.int32(3),
           np.uint8(3), np.bool_(True), np.array(0.5), np.array(3)]  # fmt: skip


def _doc(call: core.Call) -> dict:
    return json.loads(call.content)


def _form(call: core.Call) -> dict[str, str]:
    return dict(call.data or {})


@pytest.mark.parametrize("value", SCALARS, ids=lambda v: f"{type(v).__name__}-{v.dtype}")
def test_plain_gives_the_python_number(value) -> None:  # noqa: ANN001
    out = core.plain(value)
    assert type(out) in (float, int, bool) and out == value.item()
    assert json.loads(core.dumps({"x": value}))["x"] == value.item()
    assert core.form_text(value) == ({True: "true"}.get(out) if type(out) is bool
                                     else repr(out))  # fmt: skip


def test_arrays_and_plain_values_pass() -> None:
    assert core.plain(np.array([[1, 2], [3, 4]], dtype=np.int16)) == [[1, 2], [3, 4]]
    assert core.plain("x") == "x" and core.plain(None) is None and core.plain(1.5) == 1.5
    with pytest.raises(TypeError, match="not JSON serializable"):
        core.dumps({"x": object()})


def test_live_add_with_a_float32_control() -> None:
    """The tester's case: a TypeError from json before the fix."""
    t, w = record(0.0)
    doc = _doc(live_calls.add_record("s1", w=w.astype(np.float32), t=t, control=F32))
    assert doc["control"] == 0.5 and type(doc["control"]) is float
    doc = _doc(live_calls.add_record("s1", signal_id="x", control=np.float64(0.25),
                                     dt=np.float32(0.25)))  # fmt: skip
    assert doc == {"control": 0.25, "signal_id": "x", "dt": 0.25}
    form = _form(live_calls.add_record("s1", b"t,w\n0,1\n", control=F32, dt=np.float64(0.1),
                                       channel=np.int64(2)))  # fmt: skip
    assert form == {"control": "0.5", "dt": "0.1", "channel": "2"}


def test_every_number_parameter_takes_numpy_scalars() -> None:
    f32, f64, i64 = np.float32(0.25), np.float64(0.1), np.int64(7)
    # JSON bodies
    control = {"name": "mu", "value": f32}
    d = _doc(core.upload_signal([f32, f64, 1.0], dt=f64, t0=f32, control=control,
                                metadata={"n": i64}))  # fmt: skip
    assert d["w"] == [0.25, 0.1, 1.0] and d["dt"] == 0.1 and d["t0"] == 0.25
    assert d["control"]["value"] == 0.25 and d["metadata"] == {"n": 7}
    assert _doc(core.detect(w=[1.0, 2.0], dt=f32))["dt"] == 0.25
    p = _doc(core.predict([f64, 0.2], [1.0, f32], w_static=[0.0, 0.1], w_static_std=f32,
                          damping=f32, level=np.float64(0.9)))  # fmt: skip
    assert (p["mu"], p["sigma2"], p["w_static_std"]) == ([0.1, 0.2], [1.0, 0.25], 0.25)
    assert (p["damping"], p["level"]) == (0.25, 0.9)
    s = _doc(core.create_sweep([("a", f32), ("b", i64), {"signal_id": "c", "control_value": f64}]))
    assert [m["control_value"] for m in s["measurements"]] == [0.25, 7, 0.1]
    assert _doc(core.simulate(model="normal-form", mu=f32, duration=i64))["duration"] == 7
    assert _doc(core.snap(dmu=f32))["dmu"] == 0.25
    live = _doc(live_calls.create_live_sweep("n", step=f32, margin=f64, budget=i64,
                                             target_width=f32))["live"]  # fmt: skip
    assert live == {"step": 0.25, "margin": 0.1, "budget": 7, "target_width": 0.25}
    assert type(live["budget"]) is int
    # multipart form fields (np.float64 is a float: its repr is 'np.float64(0.1)' in numpy 2)
    form = _form(core.upload_file(b"t,w\n0,1\n", control_value=f64, dt=f32,
                                  control_name="mu", resample=np.bool_(True)))  # fmt: skip
    assert form == {"control_value": "0.1", "dt": "0.25", "control_name": "mu",
                    "resample": "true"}  # fmt: skip
    # query values
    args = core.request_args(core.list_signals(limit=i64, offset=np.int32(2)))
    assert args["params"] == {"limit": 7, "offset": 2}
    assert type(args["params"]["limit"]) is int


def test_wait_takes_numpy_poll_and_timeout() -> None:
    """``time.sleep(np.float32(...))`` is a TypeError: wait converts its numbers."""
    statuses = ["running", "succeeded"]

    def handle(request: httpx2.Request) -> httpx2.Response:
        return httpx2.Response(200, json={
            "id": "j1", "kind": "sweep-signals", "status": statuses.pop(0),
            "progress": {"fraction": 0.5, "message": ""}, "attempts": 1,
            "created_at": "2026-01-01T00:00:00Z"})  # fmt: skip

    with Client("http://x", transport=httpx2.MockTransport(handle)) as c:
        job = c.wait("j1", poll=np.float32(0.01), timeout=np.float64(30))
    assert job.status == "succeeded"


# --- against a real uvicorn (tests/live/conftest.py) ----------------------------------------
@pytest.fixture(scope="module")
def client(server) -> Client:  # noqa: ANN001
    with Client(server.url, timeout=120.0) as c:
        yield c


def test_live_sweep_with_numpy_numbers_over_http(client: Client, tmp_path) -> None:  # noqa: ANN001
    live = client.live_sweep("numpy", control="mu", step=np.float32(0.25),
                             budget=np.int64(20))  # fmt: skip
    t, w = record(0.0)
    u = live.add(t=t, w=w, control=np.float32(0.0))
    assert u.control == 0.0 and u.seq == 1
    t, w = record(0.5)
    u = live.add(t=t, w=w, control=F32)
    assert u.control == 0.5 and u.seq == 2
    t, w = record(0.25)
    path = tmp_path / "run.csv"
    path.write_text("t,w\n" + "".join(f"{float(a)!r},{float(b)!r}\n" for a, b in zip(t, w)))
    u = live.add(path, control=np.float64(0.25))
    assert u.control == 0.25 and u.seq == 3
    assert [r.control for r in live.records(after=np.int64(0)).items] == [0.0, 0.5, 0.25]
    live.close()


def test_uploads_with_numpy_numbers_over_http(client: Client) -> None:
    t, w = record(0.0)
    sig = client.upload_signal(w, dt=np.float64(DT), t0=np.float32(0.0),
                               control={"name": "mu", "value": np.float32(0.5)})  # fmt: skip
    assert sig.dt == pytest.approx(DT) and sig.control.value == 0.5
    csv = ("time [s],w\n" + "".join(f"{float(a)!r},{float(b)!r}\n" for a, b in zip(t, w))).encode()
    sig = client.upload_file(csv, filename="r.csv", control_name="mu",
                             control_value=np.float64(1.2))  # fmt: skip
    assert sig.control.value == 1.2
    assert client.list_signals(limit=np.int64(1)).items[0].id == sig.id
