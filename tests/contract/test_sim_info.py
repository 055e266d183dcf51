"""A simulated signal's ``metadata.info`` is typed: every backend's report converts (in
service.convert, the one seam) into ``SimulationInfo`` with the numerics' values; the API stores
and serves it typed (``SignalMeta.metadata`` is a ``SimulationMetadata``), the SDK returns it
typed, and signals stored before (plain dicts) are still served."""

from __future__ import annotations

import asyncio
import dataclasses
import json
import math
from typing import Any

import numpy as np
import pytest

import sim
from service import convert
from service.schemas import SignalMeta, SignalPage, SimulationResult
from service.schemas.sim import SimulationInfo, SimulationMetadata
from sim.results import ErrorEstimate, Resolution
from sim.select import Choice

#: (label, model, backend options, scene fields): each backend once, on a cheap scene
CASES = [
    ("normal-form", "normal-form", {}, {"mu": 0.5, "duration": 2.0}),
    ("euler-beam", "euler-beam", {}, {"mu": 0.5, "duration": 2.0}),
    ("euler-beam-nonlinear", "euler-beam", {"method": "nonlinear"}, {"mu": 0.5, "duration": 0.5}),
    ("cosserat", "cosserat", {}, {"mu": 0.5, "duration": 1.0, "elements": 8}),
    ("auto", "auto", {}, {"mu": 0.5, "duration": 2.0, "rtol": 0.05}),
]
_TYPED = ("resolution", "error", "auto")


@pytest.fixture(scope="module")
def signals() -> dict[str, sim.Signal]:
    return {label: sim.simulate(sim.Scene(actuation="asymmetric", **scene), model, **opts)
            for label, model, opts, scene in CASES}  # fmt: skip


def _wire_keys() -> set[str]:
    return {f.alias or name for name, f in SimulationInfo.model_fields.items()}


def _same_number(wire: Any, value: Any) -> None:
    v = float(value)
    assert wire == (v if math.isfinite(v) else None)


def _check_resolution(wire: Any, r: Resolution) -> None:
    assert (wire.model, wire.size, wire.rtol, wire.method) == (r.model, r.size, r.rtol, r.method)
    _same_number(wire.mu_star_error, r.mu_star_error)


def _check_error(wire: Any, e: ErrorEstimate) -> None:
    _same_number(wire.model, e.model)
    _same_number(wire.discretisation, e.discretisation)
    _same_number(wire.total, e.total)
    assert set(wire.details) == set(e.details)
    for k, v in e.details.items():
        _same_number(wire.details[k], v)


def _check_choice(wire: Any, c: Choice) -> None:
    assert (wire.model, wire.method, wire.reason, wire.met) == (c.model, c.method, c.reason, c.met)
    _same_number(wire.rtol, c.rtol)
    assert set(wire.estimates) == set(c.estimates)
    for k, v in c.estimates.items():
        _same_number(wire.estimates[k], v)
    _check_error(wire.error, c.estimate)


def _check_plain(wire: Any, value: Any) -> None:
    """A backend's own number, list or mapping, as on the wire (non-finite: None)."""
    if isinstance(value, (bool, str)) or value is None:
        assert wire == value and type(wire) is type(value)
    elif isinstance(value, (int, np.integer)):
        assert wire == int(value) and isinstance(wire, int) and not isinstance(wire, bool)
    elif isinstance(value, dict):
        assert set(wire) == set(value)
        for k, v in value.items():
            _check_plain(wire[k], v)
    elif isinstance(value, (list, tuple, np.ndarray)):
        assert len(wire) == len(value)
        for a, b in zip(wire, value, strict=True):
            _check_plain(a, b)
    else:
        _same_number(wire, value)


def check_info(
    info: SimulationInfo, numerics: dict[str, Any], *, unchecked: frozenset[str] = frozenset()
) -> None:
    """``info`` carries every key of the numerics' ``numerics`` with its value (the
    dataclasses field by field; not the ``unchecked`` keys), and null for what that backend
    does not report."""
    assert convert.simulation_info_problems(numerics) == []
    doc = info.model_dump(mode="json")  # by the wire names ("lambda")
    for key, value in numerics.items():
        if key in unchecked:
            continue
        wire = getattr(info, "lambda_" if key == "lambda" else key)
        if key == "resolution":
            _check_resolution(wire, value)
        elif key == "error":
            _check_error(wire, value)
        elif key == "auto":
            _check_choice(wire, value)
        else:
            _check_plain(wire, value)
            _check_plain(doc[key], value)
    for key in _wire_keys() - set(numerics):
        assert doc[key] in (None, []), key


@pytest.mark.parametrize("label", [c[0] for c in CASES])
def test_every_backends_info_converts_with_its_values(signals, label: str) -> None:  # noqa: ANN001
    sig = signals[label]
    assert isinstance(sig.info["resolution"], Resolution)
    assert isinstance(sig.info["error"], ErrorEstimate)
    info = convert.simulation_info(sig.info)
    check_info(info, sig.info)
    if label == "auto":
        assert isinstance(sig.info["auto"], Choice) and info.auto.model == sig.model
    else:
        assert info.auto is None
    assert info.method == sig.info.get("method")  # the beam's method, null elsewhere
    # strict JSON, and the same model back from it
    text = json.dumps(info.model_dump(mode="json"), allow_nan=False)
    assert SimulationInfo.model_validate_json(text) == info


def test_every_wire_field_comes_from_some_backend(signals) -> None:  # noqa: ANN001
    """No wire field without a source: each one is reported by one of the backends run."""
    reported = set().union(*(set(s.info) for s in signals.values()))
    assert _wire_keys() == reported


def test_a_numerics_key_without_a_wire_field_is_caught(signals) -> None:  # noqa: ANN001
    info = {**signals["normal-form"].info, "new_number": 1.0}
    assert convert.simulation_info_problems(info) == [
        "info['new_number'] has no field in SimulationInfo (add it)"
    ]
    assert "new_number" not in convert.simulation_info(info).model_dump()


def test_the_clis_simulation_document_is_the_infos(signals, tmp_path) -> None:  # noqa: ANN001
    """``snapwarn simulate --json`` types its resolution, error and choice by the same
    conversion."""
    sig = signals["auto"]
    doc = convert.simulation(sig, path=str(tmp_path / "s.csv"))
    info = convert.simulation_info(sig.info)
    assert (doc.resolution, doc.error, doc.auto) == (info.resolution, info.error, info.auto)
    assert doc.sigma2 == info.sigma2[0]


def test_an_upload_whose_metadata_looks_like_a_simulations_stays_its_own() -> None:
    meta = {"scene": {}, "model": "euler-beam", "w_static": 0.1, "info": {}, "mine": [1, 2]}
    base = {"id": "x", "n": 2, "dt": 1.0, "t0": 0.0, "duration": 1.0, "has_t": False,
            "sha256": "0", "created_at": "2026-01-01T00:00:00Z"}  # fmt: skip
    up = SignalMeta.model_validate({**base, "source": "json", "metadata": meta})
    assert up.metadata == meta and up.simulation is None
    simulated = SignalMeta.model_validate({**base, "source": "simulation", "metadata": meta})
    assert isinstance(simulated.metadata, SimulationMetadata)
    assert simulated.simulation is simulated.metadata


# ------------------------------------------------------------------------------ over HTTP
SCENE = {"actuation": "asymmetric", "mu": 0.5, "duration": 2.0}


async def _wait_job(api, job_id: str, timeout: float = 120.0) -> dict[str, Any]:  # noqa: ANN001
    for _ in range(int(timeout / 0.05)):
        doc = (await api.get(f"/v1/jobs/{job_id}")).json()
        if doc["status"] in ("succeeded", "failed", "cancelled"):
            return doc
        await asyncio.sleep(0.05)
    raise AssertionError(f"job {job_id} did not finish in {timeout} s")


async def _simulated_signal(api, body: dict[str, Any]) -> dict[str, Any]:  # noqa: ANN001
    r = await api.post("/v1/simulations", json=body)
    assert r.status_code in (201, 202), r.text
    res = SimulationResult.model_validate(r.json())
    if res.job is not None:
        job = await _wait_job(api, res.job.id)
        assert job["status"] == "succeeded", job
        sid = job["result"]["signal_id"]
    else:
        assert isinstance(res.signal.metadata, SimulationMetadata)  # the 201's own copy
        sid = res.signal.id
    r = await api.get(f"/v1/signals/{sid}")
    assert r.status_code == 200, r.text
    return r.json()


@pytest.mark.anyio
@pytest.mark.parametrize("model", ["normal-form", "euler-beam", "auto"])
async def test_a_simulated_signal_serves_its_typed_info(api, model: str) -> None:  # noqa: ANN001
    body = {**SCENE, "model": model, "rtol": 0.05, "background": False}
    doc = await _simulated_signal(api, body)
    meta = SignalMeta.model_validate(doc)
    typed = meta.simulation
    assert typed is not None and SimulationMetadata.model_validate(doc["metadata"]) == typed
    asked = {k: v for k, v in body.items() if k not in ("model", "background")}
    assert {k: typed.scene[k] for k in asked} == asked
    scene = sim.Scene(**typed.scene)
    sig = sim.simulate(scene, model)  # the same scene run here: the same report
    check_info(typed.info, sig.info)
    assert typed.model == sig.model and typed.w_static == float(sig.w_static)
    assert "lambda" in doc["metadata"]["info"] and "lambda_" not in doc["metadata"]["info"]
    page = SignalPage.model_validate((await api.get("/v1/signals?limit=100")).json())
    listed = next(s for s in page.items if s.id == meta.id)
    assert listed.simulation == typed


@pytest.mark.anyio
async def test_a_cosserat_job_stores_the_typed_info(api) -> None:  # noqa: ANN001
    body = {**SCENE, "duration": 1.0, "model": "cosserat", "elements": 8, "background": True}
    doc = await _simulated_signal(api, body)
    typed = SignalMeta.model_validate(doc).simulation
    assert typed is not None and typed.model == "cosserat"
    sig = sim.simulate(sim.Scene(**typed.scene), "cosserat")
    # cpu_s, a timing, differs from run to run
    check_info(typed.info, sig.info, unchecked=frozenset({"cpu_s"}))
    assert typed.info.cpu_s is not None and typed.info.cpu_s > 0
    assert typed.info.elements == 8 == typed.info.resolution.size


def _old_row(api, metadata: dict[str, Any]) -> str:  # noqa: ANN001
    store = api.app.state.snapwarn.store
    w = np.linspace(0.0, 1.0, 16)
    row = store.add_signal(w=w, dt=0.1, t0=0.0, t=None, source="simulation",
                           control={"name": "mu", "value": 0.5, "unit": None},
                           metadata=metadata)  # fmt: skip
    return row.id


@pytest.mark.anyio
async def test_signals_stored_before_are_still_served(api, signals) -> None:  # noqa: ANN001
    # what the route stored before the info was typed: convert.plain of the backend's info
    sig = signals["euler-beam"]
    old = {"scene": dataclasses.asdict(sig.scene), "model": sig.model, "w_static": sig.w_static,
           "info": {**convert.plain(dict(sig.info)), "lambda2": [1.0]}}  # fmt: skip
    r = await api.get(f"/v1/signals/{_old_row(api, old)}")
    assert r.status_code == 200, r.text
    typed = SignalMeta.model_validate(r.json()).simulation
    assert typed is not None
    check_info(typed.info, sig.info)
    assert "lambda2" not in r.json()["metadata"]["info"]  # a key no backend reports now
    # a document the model cannot read (an even older or a foreign one): served as stored
    odd = {"model": "euler-beam", "info": {"error": {"model": 1.0}}}
    r = await api.get(f"/v1/signals/{_old_row(api, odd)}")
    assert r.status_code == 200, r.text
    assert r.json()["metadata"] == odd
    assert SignalMeta.model_validate(r.json()).simulation is None
    r = await api.get("/v1/signals?limit=100")
    assert r.status_code == 200, r.text


@pytest.mark.anyio
async def test_the_sdk_returns_the_typed_info(api) -> None:  # noqa: ANN001
    from service.client import AsyncClient

    async with AsyncClient("http://asgi", transport=api._transport) as sdk:
        res = await sdk.simulate(**SCENE, model="normal-form", background=False)
        assert res.signal is not None and res.signal.simulation is not None
        got = await sdk.get_signal(res.signal.id)
    assert isinstance(got.simulation, SimulationMetadata)
    assert isinstance(got.simulation.info, SimulationInfo)
    assert got.simulation == res.signal.simulation
    sig = sim.simulate(sim.Scene(**SCENE), "normal-form")
    check_info(got.simulation.info, sig.info)
    assert got.simulation.info.coefficients == convert.plain(sig.info["coefficients"])
