"""``POST /v1/sweeps`` (batch) and the fields of a live sweep, over real HTTP.

A batch sweep of recorded signals honours ``control`` (the name and unit of its control
values: stored with the request, shown on its page and its charts); ``live`` options, and a
``control`` for a simulated sweep, are refused with a 422 naming the field and its value, never
silently ignored.
"""

from __future__ import annotations

import time
from typing import Any

import httpx2
import pytest
from _records import DT, record


@pytest.fixture(scope="module")
def http(server) -> httpx2.Client:  # noqa: ANN001
    with httpx2.Client(base_url=server.url, timeout=120.0) as c:
        yield c


def _signals(http: httpx2.Client, controls: list[float], control: dict | None) -> list[str]:
    ids = []
    for mu in controls:
        _, w = record(mu)
        doc: dict[str, Any] = {"dt": DT, "w": w.tolist(), "unit": "s"}
        if control is not None:
            doc["control"] = {**control, "value": mu}
        r = http.post("/v1/signals", json=doc)
        assert r.status_code == 201, r.text
        ids.append(r.json()["id"])
    return ids


def _field(r: httpx2.Response) -> tuple[str, Any]:
    assert r.status_code == 422, r.text
    doc = r.json()
    assert doc["errors"], doc
    return doc["errors"][0]["field"], doc["errors"][0].get("value")


def test_live_options_on_a_batch_sweep_are_refused(http: httpx2.Client) -> None:
    ids = _signals(http, [0.0, 0.3, 0.6], None)
    ms = [{"signal_id": i, "control_value": mu} for i, mu in zip(ids, [0.0, 0.3, 0.6])]
    r = http.post("/v1/sweeps", json={"measurements": ms, "live": {"margin": 0.05}})
    assert _field(r) == ("live", {"margin": 0.05})
    assert "live" in r.json()["detail"] and "mode" in r.json()["detail"]
    r = http.post("/v1/sweeps", json={"mode": "batch", "measurements": ms, "live": {"budget": 9}})
    assert _field(r) == ("live", {"budget": 9})
    r = http.post("/v1/sweeps", json={"simulate": {"actuation": "asymmetric"},
                                      "control": {"name": "angle", "unit": "deg"}})  # fmt: skip
    assert _field(r) == ("control", {"name": "angle", "unit": "deg"})
    # nothing was created by the refused requests
    names = [s["request"].get("live") for s in http.get("/v1/sweeps").json()["items"]]
    assert not any(names)


def test_a_unit_that_contradicts_the_stored_signals_is_refused(http: httpx2.Client) -> None:
    ids = _signals(http, [0.0, 0.3, 0.6], {"name": "load", "unit": "N"})
    ms = [{"signal_id": i} for i in ids]
    r = http.post("/v1/sweeps", json={"measurements": ms, "control": {"unit": "kN"}})
    assert _field(r) == ("control.unit", "kN")
    assert ids[0] in r.json()["detail"] and "'N'" in r.json()["detail"]
    # values given in the request are taken in control.unit: no contradiction
    ms = [{"signal_id": i, "control_value": 1e-3 * mu} for i, mu in zip(ids, [0.0, 0.3, 0.6])]
    r = http.post("/v1/sweeps", json={"measurements": ms, "control": {"unit": "kN"}})
    assert r.status_code == 202, r.text


def test_control_of_a_batch_sweep_is_stored_and_shown(http: httpx2.Client) -> None:
    controls = [0.0, 0.3, 0.6, 0.9, 1.2]
    ids = _signals(http, controls, None)  # stored without a control name or unit
    ms = [{"signal_id": i, "control_value": mu} for i, mu in zip(ids, controls)]
    r = http.post("/v1/sweeps", json={"name": "named control", "measurements": ms,
                                      "control": {"name": "angle", "unit": "deg"}})  # fmt: skip
    assert r.status_code == 202, r.text
    sweep = r.json()
    assert sweep["request"]["control"] == {"name": "angle", "unit": "deg"}
    end = time.monotonic() + 180
    while sweep["status"] not in ("succeeded", "failed"):
        assert time.monotonic() < end, sweep["job"]
        time.sleep(0.2)
        sweep = http.get(f"/v1/sweeps/{sweep['id']}").json()
    assert sweep["status"] == "succeeded", sweep["job"]
    svg = http.get(f"/v1/sweeps/{sweep['id']}/plot.svg")
    assert svg.status_code == 200
    assert "angle [deg]" in svg.text and "95 % interval of angle*" in svg.text
    page = http.get(f"/sweeps/{sweep['id']}")
    assert page.status_code == 200
    assert "angle [deg]" in page.text
    # only what the user named: a unit alone keeps the signals' own name
    ids = _signals(http, controls[:3], {"name": "theta"})
    r = http.post("/v1/sweeps", json={"measurements": [{"signal_id": i} for i in ids],
                                      "control": {"unit": "deg"}})  # fmt: skip
    assert r.status_code == 202, r.text
    assert r.json()["request"]["control"] == {"unit": "deg"}


def test_sdk_names_the_control_of_a_batch_sweep(server, http: httpx2.Client) -> None:  # noqa: ANN001
    """The SDK's ``create_sweep(control=..., unit=...)`` sends what the wire takes: the same
    stored request as the raw HTTP call, and only the keys the user named."""
    from service.client import Client
    from service.client.errors import InvalidInput

    ids = _signals(http, [0.0, 0.3, 0.6], None)
    with Client(server.url) as client:
        sweep = client.create_sweep(list(zip(ids, [0.0, 0.3, 0.6], strict=True)),
                                    control="angle", unit="deg")  # fmt: skip
        assert sweep.request["control"] == {"name": "angle", "unit": "deg"}
        sweep = client.create_sweep(list(zip(ids, [0.0, 0.3, 0.6], strict=True)), unit="deg")
        assert sweep.request["control"] == {"unit": "deg"}
        with pytest.raises(InvalidInput) as err:
            client.create_sweep(simulate={"actuation": "asymmetric"}, control="angle")
        assert err.value.status == 422 and err.value.field == "control"
