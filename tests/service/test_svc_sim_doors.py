"""One scene through both doors (CLI ``simulate --json`` and ``POST /v1/simulations`` on a real
uvicorn) gives the same backend, resolution and numbers; the budget charges what the chosen
backend costs; ``POST /v1/snaps`` is bounded at the door exactly as simulations; the atlas names
its real elements limit."""

from __future__ import annotations

import json
import time
from typing import Any

import httpx2
import pytest
from _svc_helpers import require_numerics

from service.cli import main


def _wait_job(h: httpx2.Client, job_id: str, timeout: float = 120.0) -> dict[str, Any]:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        doc = h.get(f"/v1/jobs/{job_id}").json()
        if doc["status"] in ("succeeded", "failed", "cancelled"):
            return doc
        time.sleep(0.05)
    raise AssertionError(f"job {job_id} did not finish in {timeout} s")


def _api_signal(h: httpx2.Client, body: dict[str, Any]) -> dict[str, Any]:
    r = h.post("/v1/simulations", json=body)
    assert r.status_code in (201, 202), r.text
    if r.status_code == 202:
        job = _wait_job(h, r.json()["job"]["id"])
        assert job["status"] == "succeeded", job
        sid = job["result"]["signal_id"]
    else:
        sid = r.json()["signal"]["id"]
    r = h.get(f"/v1/signals/{sid}")
    assert r.status_code == 200, r.text
    return r.json()


def _cli(args: list[str], capsys: pytest.CaptureFixture[str]) -> dict[str, Any]:
    capsys.readouterr()
    assert main(args) == 0
    return json.loads(capsys.readouterr().out)


@pytest.mark.parametrize(
    "extra",
    [
        {"model": "auto"},  # picks the rod at its rtol-chosen elements (not euler-beam)
        {"model": "cosserat", "rtol": 1e-3},  # elements from rtol (130), not 50
    ],
    ids=["auto", "cosserat-rtol"],
)
def test_the_cli_and_the_api_simulate_the_same_scene_alike(
    live_server, capsys, tmp_path, extra: dict[str, Any]  # noqa: ANN001
) -> None:
    require_numerics("sim", "simulate")
    scene = {"actuation": "asymmetric", "mu": 0.5, "duration": 1.0}
    args = ["simulate", "--actuation", "asymmetric", "--mu", "0.5", "--duration", "1.0",
            "--model", extra["model"], "--out", str(tmp_path / "w.csv"), "--json"]  # fmt: skip
    if "rtol" in extra:
        args += ["--rtol", str(extra["rtol"])]
    cli = _cli(args, capsys)
    with httpx2.Client(base_url=live_server.url, timeout=120) as h:
        api = _api_signal(h, {**scene, **extra})
    meta = api["metadata"]
    info = meta["info"]
    assert meta["model"] == cli["model"] == "cosserat"
    assert info["resolution"]["size"] == cli["resolution"]["size"]
    assert meta["scene"]["elements"] is None  # chosen from rtol, as the CLI does
    assert info["sigma2"][0] == pytest.approx(cli["sigma2"], rel=1e-9)
    assert meta["w_static"] == pytest.approx(cli["w_static"], rel=1e-12)
    assert api["n"] == cli["samples"]
    assert api["dt"] == pytest.approx(cli["dt"], rel=1e-12)
    if extra["model"] == "auto":
        assert info["auto"]["model"] == cli["auto"]["model"]


def _refused(h: httpx2.Client, path: str, body: dict[str, Any], field: str) -> str:
    t0 = time.perf_counter()
    r = h.post(path, json=body)
    assert r.status_code == 422, (body, r.status_code, r.text)
    err = r.json()["errors"][0]
    assert err["field"] == field, (body, r.json())
    assert time.perf_counter() - t0 < 10.0  # at the door, not after a run
    return r.json()["detail"]


def test_the_budget_charges_what_the_backend_costs(live_server) -> None:  # noqa: ANN001
    require_numerics("sim", "simulate")
    with httpx2.Client(base_url=live_server.url, timeout=120) as h:
        # the Euler beam's cost does not grow with elements: not charged for them
        r = h.post("/v1/simulations", json={"mu": 0.5, "model": "euler-beam", "duration": 400})
        assert r.status_code == 201, r.text
        assert r.json()["signal"]["duration"] == pytest.approx(400, rel=1e-3)
        # the rod's elements chosen from rtol (290 at the default) are charged: 100 x 290
        detail = _refused(h, "/v1/simulations",
                          {"mu": 0.5, "model": "cosserat", "duration": 100}, "duration")
        assert "elements=290" in detail and "SNAPWARN_MAX_SIM_WORK" in detail
        # ... and by model=auto when it picks the rod
        _refused(h, "/v1/simulations", {"mu": 0.5, "model": "auto", "duration": 100}, "duration")
        # an rtol whose elements exceed the setting, or the policy's cap: refused, naming rtol
        detail = _refused(h, "/v1/simulations", {"mu": 0.5, "model": "cosserat", "rtol": 1e-5},
                          "rtol")
        assert "SNAPWARN_MAX_ELEMENTS" in detail
        _refused(h, "/v1/simulations", {"mu": 0.5, "model": "cosserat", "rtol": 1e-9}, "rtol")
    # the rtol the refusal suggests is one the door takes (its elements within the limit)
    from service.api import limits
    from service.api.settings import Settings

    hint = float(detail.split("ask for rtol >= ")[1].split()[0])
    plan = limits.plan_scene({"mu": 0.5, "rtol": hint}, "cosserat")
    assert plan.model == "cosserat" and plan.field == "rtol"
    assert plan.elements is not None and plan.elements <= Settings().max_elements


@pytest.mark.parametrize(
    ("body", "field"),
    [
        ({"dmu": 0.01, "model": "cosserat", "elements": 100_000}, "elements"),
        ({"dmu": 0.01, "model": "cosserat", "elements": 1000}, "elements"),  # > the setting
        ({"dmu": 0.01, "model": "cosserat", "elements": 7}, "elements"),
        ({"dmu": 0.01, "model": "cosserat", "elements": 2}, "elements"),
        ({"dmu": 0.01, "model": "cosserat", "rtol": 1e-12}, "rtol"),
        ({"dmu": 0.01, "model": "cosserat", "rtol": 1e-5}, "rtol"),  # 1290 elements > 400
        ({"dmu": 0.01, "model": "cosserat", "rtol": 0.5}, "rtol"),
        ({"dmu": 0.01, "model": "euler-beam", "damping": 1e9}, "damping"),
        ({"dmu": 0.01, "model": "euler-beam", "end_shortening": -1.0}, "end_shortening"),
        ({"dmu": 0.01, "model": "euler-beam", "poisson": 0.7}, "poisson"),
        ({"dmu": 0.01, "model": "cosserat", "slenderness": 0.5}, "width"),  # Scene's rule
    ],
)
def test_snaps_are_refused_at_the_door_as_simulations(
    live_server, body: dict[str, Any], field: str  # noqa: ANN001
) -> None:
    require_numerics("sim.snap", "snap")
    with httpx2.Client(base_url=live_server.url, timeout=60) as h:
        before = h.get("/v1/jobs", params={"limit": 500}).json()["total"]
        detail = _refused(h, "/v1/snaps", body, field)
        assert h.get("/v1/jobs", params={"limit": 500}).json()["total"] == before  # no job
        value = body.get(field)
        if value is not None and field != "width":
            assert f"{value!r}"[:4] in detail or f"{value:g}" in detail, detail
        if field in ("elements", "rtol") and body["model"] == "cosserat":
            if body.get("elements") == 1000 or body.get("rtol") == 1e-5:
                assert "SNAPWARN_MAX_ELEMENTS" in detail, detail
        # the same body (less dmu) at /v1/simulations is refused on the same field
        sim_body = {k: v for k, v in body.items() if k != "dmu"} | {"mu": 0.5}
        _refused(h, "/v1/simulations", sim_body, field)


def test_snaps_and_simulations_share_their_field_bounds() -> None:
    from service.schemas.simulations import SimulationRequest
    from service.schemas.snaps import SnapRequest

    sims = SimulationRequest.model_json_schema()["properties"]
    snaps = SnapRequest.model_json_schema()["properties"]
    for name in ("damping", "end_shortening", "slenderness", "poisson", "elements"):
        assert snaps[name] == sims[name], name
    bounds = ("exclusiveMinimum", "exclusiveMaximum", "type")
    assert {k: snaps["rtol"]["anyOf"][0][k] for k in bounds} == {k: sims["rtol"][k]
                                                                  for k in bounds}
    assert SimulationRequest().elements is None  # the CLI's and sim.Scene's default


def test_a_snap_within_the_bounds_is_still_a_job(live_server) -> None:  # noqa: ANN001
    require_numerics("sim.snap", "snap")
    with httpx2.Client(base_url=live_server.url, timeout=60) as h:
        r = h.post("/v1/snaps", json={"dmu": 0.01, "model": "cosserat", "elements": 8,
                                      "duration": 0.5})  # fmt: skip
        assert r.status_code == 202, r.text
        job = _wait_job(h, r.json()["job"]["id"])
        assert job["status"] == "succeeded", job
        assert job["result"]["resolution"]["size"] == 8


def test_the_atlas_names_its_real_elements_limit(live_server) -> None:  # noqa: ANN001
    from service.api.settings import Settings

    limit = Settings().max_elements
    spec = {"kind": "bifurcation", "fixed": {"model": "cosserat", "elements": 5000},
            "grid": {"actuation": ["asymmetric"]}}  # fmt: skip
    with httpx2.Client(base_url=live_server.url, timeout=60) as h:
        for n in (5000, 2 * limit):
            spec["fixed"]["elements"] = n
            r = h.post("/v1/atlases", json={"spec": spec})
            assert r.status_code == 422, r.text
            detail = r.json()["detail"]
            assert f"{limit}" in detail and "4000" not in detail, detail
            assert "SNAPWARN_MAX_ELEMENTS" in detail, detail
