"""One scene through every door: the CLI, the REST API and the SDK give the same documents.

Lab files written as labs write them (rounded timestamps, other units, other layouts) are read
by the one reader (``service.recordings``) behind every door; the detections, the sweep
documents (mu*, its interval, the transition) and the errors (field and value) must be equal,
not merely close: the same numbers go through the same numerics.
"""

from __future__ import annotations

import asyncio
import datetime
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from _contract_helpers import run_cli, upload_file

pytestmark = pytest.mark.anyio

DT = 1.0 / 3000.0
MUS = np.linspace(0.0, 1.8, 8)


def _record(mu: float, seed: int, n: int = 4000) -> tuple[np.ndarray, np.ndarray]:
    """A ringdown of a mode whose sigma^2 = -1600 (2 - mu): a pitchfork at mu* = 2."""
    t = DT * np.arange(n)
    omega = 40.0 * np.sqrt(2.0 - mu)
    rng = np.random.default_rng(seed)
    w = 0.3 + 1e-2 * np.exp(-0.2 * t) * np.cos(omega * t) + rng.normal(0.0, 1e-5, n)
    return t, w


def _write_csv(path: Path, header: str, t: np.ndarray, w: np.ndarray, tfmt: str) -> Path:
    rows = [header] + [f"{tfmt % a},{b:.9g}" for a, b in zip(t.tolist(), w.tolist())]
    path.write_text("\n".join(rows) + "\n")
    return path


@pytest.fixture(scope="module")
def lab(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    """Files as labs write them, and a sweep manifest over the CSV records."""
    d = tmp_path_factory.mktemp("lab")
    files: dict[str, Any] = {}
    for k, mu in enumerate(MUS):
        t, w = _record(float(mu), k)
        _write_csv(d / f"r{k}.csv", "time_s,accel_mV", t, w, "%.6g")
    t, w = _record(0.5, 99)
    files["ms_9g"] = _write_csv(d / "ms.csv", "t [ms], w [mm]", 1e3 * t, w, "%.9g")
    files["s_6g"] = d / "r0.csv"
    np.save(d / "one.npy", w)
    files["npy1d"] = d / "one.npy"
    np.save(d / "two.npy", np.column_stack([t, w]))
    files["npy2d"] = d / "two.npy"
    drop = np.ones(t.size, bool)
    drop[1000] = False
    files["dropped"] = _write_csv(d / "dropped.csv", "t,w", t[drop], w[drop], "%.9g")
    # a scope's file: ISO 8601 timestamps (microseconds) and 800 samples at rest before the kick
    rest = 0.3 + np.random.default_rng(7).normal(0.0, 1e-5, 800)
    start = datetime.datetime(2026, 11, 27, 9, 30, 0)
    stamps = [(start + datetime.timedelta(seconds=k * DT)).isoformat(timespec="microseconds")
              for k in range(800 + t.size)]  # fmt: skip
    body = "".join(f"{s},{v:.9g}\n" for s, v in zip(stamps, np.r_[rest, w].tolist()))
    (d / "scope.csv").write_text("Timestamp,w [mm]\n" + body)
    files["scope"] = d / "scope.csv"
    (d / "unknown.csv").write_text("foo,bar\n" + "".join(f"{k},{k}\n" for k in range(5)))
    files["unknown"] = d / "unknown.csv"
    manifest = d / "manifest.csv"
    rows = "".join(f"r{k}.csv,{float(mu)!r}\n" for k, mu in enumerate(MUS))
    manifest.write_text("path,control\n" + rows)
    files["manifest"] = manifest
    files["dir"] = d
    return files


async def _api_detect(api, path: Path, **form: Any) -> tuple[int, dict[str, Any]]:  # noqa: ANN001
    r = await api.post("/v1/signals", **upload_file(path, **form))
    if r.status_code != 201:
        return r.status_code, r.json()
    r = await api.post("/v1/detections", json={"signal_id": r.json()["id"]})
    return r.status_code, r.json()


@pytest.mark.parametrize(
    "name, dt, flagged",
    [("s_6g", None, True), ("ms_9g", None, False), ("npy1d", DT, False), ("npy2d", None, False),
     ("scope", None, True)],
)
async def test_a_lab_file_gives_one_detection_through_cli_and_api(api, lab, name, dt, flagged):  # noqa: ANN001
    path = lab[name]
    args = ["detect", str(path), "--json"] + (["--dt", repr(dt)] if dt else [])
    rc, cli_doc, err = run_cli(*args)
    assert rc == 0, err
    status, api_doc = await _api_detect(api, path, dt=dt)
    assert status == 200, api_doc
    assert api_doc == cli_doc
    codes = [f["code"] for f in cli_doc["flags"]]
    assert ("rounded_timestamps" in codes) == flagged
    omega = 40.0 * np.sqrt(2.0 - (0.0 if name == "s_6g" else 0.5))
    scale = 1e-3 if name == "ms_9g" else 1.0  # rad/ms for a record in milliseconds
    assert cli_doc["fundamental"]["omega"] == pytest.approx(omega * scale, rel=1e-4)
    # the document says the unit its numbers are in, as the file named it (none for .npy)
    units = {"ms_9g": ("ms", "mm"), "s_6g": ("s", "mV"), "scope": ("s", "mm")}.get(
        name, (None, None)
    )
    assert (cli_doc["time_unit"], cli_doc["value_unit"]) == units
    assert ("pretrigger" in codes) == (name == "scope")
    assert cli_doc["start"] == (800 if name == "scope" else 0)
    if name == "ms_9g":
        text = run_cli("detect", str(path))[1]
        assert "rad/ms" in text and "1/ms^2" in text, text


@pytest.mark.parametrize(
    "name, dt, field, status",
    [
        ("s_6g", 0.001, "dt", 422),  # a time column and a dt: loud, never an override
        ("npy1d", None, "dt", 422),  # no time at all: dt is required
        ("dropped", None, "t[1000]", 422),  # irregular: the worst step is named
        ("unknown", None, "file", 422),  # an unrecognised header lists the columns
    ],
)
async def test_a_bad_lab_file_gives_one_error_through_cli_and_api(api, lab, name, dt, field, status):  # noqa: ANN001,E501
    path = lab[name]
    args = ["detect", str(path), "--json"] + (["--dt", repr(dt)] if dt else [])
    rc, cli_doc, _ = run_cli(*args)
    assert rc == 2
    got, api_doc = await _api_detect(api, path, dt=dt)
    assert got == status == cli_doc["status"], api_doc
    assert cli_doc["field"] == api_doc["errors"][0]["field"] == field
    assert cli_doc["value"] == api_doc["errors"][0]["value"]
    assert cli_doc["type"] == api_doc["type"] and cli_doc["title"] == api_doc["title"]


def _without_names(doc: dict[str, Any]) -> dict[str, Any]:
    """The sweep document minus the records' labels (file names vs signal ids)."""
    out = dict(doc)
    out["detections"] = [{k: v for k, v in d.items() if k != "name"} for d in doc["detections"]]
    return out


async def _wait_sweep(api, sweep_id: str, timeout: float = 120.0) -> dict[str, Any]:  # noqa: ANN001
    for _ in range(int(timeout / 0.1)):
        doc = (await api.get(f"/v1/sweeps/{sweep_id}")).json()
        if doc["status"] in ("succeeded", "failed", "cancelled"):
            return doc
        await asyncio.sleep(0.1)
    raise AssertionError(f"sweep {sweep_id} did not finish in {timeout} s")


async def test_one_recorded_sweep_through_cli_api_and_sdk(api, lab) -> None:  # noqa: ANN001
    from service.client import AsyncClient
    from service.schemas import Sweep

    rc, cli_doc, err = run_cli("sweep", str(lab["manifest"]), "--json", "--no-progress")
    assert rc == 0, err
    ids = []
    for k, mu in enumerate(MUS):
        part = upload_file(lab["dir"] / f"r{k}.csv", control_value=repr(float(mu)))
        r = await api.post("/v1/signals", **part)
        assert r.status_code == 201, r.text
        ids.append(r.json()["id"])
    r = await api.post("/v1/sweeps", json={"measurements": [{"signal_id": i} for i in ids]})
    assert r.status_code == 202, r.text
    api_doc = await _wait_sweep(api, r.json()["id"])
    assert api_doc["status"] == "succeeded", api_doc["job"]
    assert _without_names(api_doc["result"]) == _without_names(cli_doc)
    for d in cli_doc["detections"]:  # the reader's note on the %.6g timestamps, in every door
        assert d["flags"][0]["code"] == "rounded_timestamps", d["flags"]
        assert d["time_unit"] == "s"  # the records' header 'time_s': omega in rad/s

    transport = api._transport  # the same app, through the SDK
    async with AsyncClient("http://asgi", transport=transport) as sdk:
        sigs = [await sdk.upload_file(lab["dir"] / f"r{k}.csv", control_value=float(mu))
                for k, mu in enumerate(MUS)]  # fmt: skip
        sweep = await sdk.create_sweep([(s.id, float(mu)) for s, mu in zip(sigs, MUS)])
        done = await sdk.wait(sweep, timeout=120)
    assert isinstance(done, Sweep) and done.result is not None
    assert _without_names(done.result.model_dump(mode="json")) == _without_names(cli_doc)
    p = done.result.prediction
    assert p is not None and p.transition == cli_doc["prediction"]["transition"]
    assert p.mu_star == cli_doc["prediction"]["mu_star"] == pytest.approx(2.0, abs=1e-3)
    lo, hi = p.mu_star_interval
    assert lo is not None and hi is not None and lo < p.mu_star < hi
    assert done.result.detections[0].fundamental.sigma2 < 0  # typed all the way down


async def test_one_simulated_sweep_through_cli_api_and_sdk(api) -> None:  # noqa: ANN001
    """``snapwarn warn --json`` and ``/v1/sweeps`` with ``simulate`` print one document."""
    from service.client import AsyncClient

    opts = {"model": "normal-form", "actuation": "asymmetric", "seed": 3,
            "max_measurements": 8, "damping": 2e-4, "snr_db": 40.0}  # fmt: skip
    rc, cli_doc, err = run_cli(
        "warn", "--model", "normal-form", "--actuation", "asymmetric", "--seed", "3",
        "--max-measurements", "8", "--damping", "2e-4", "--snr", "40", "--no-progress", "--json",
    )  # fmt: skip
    assert rc == 0, err
    r = await api.post("/v1/sweeps", json={"simulate": opts})
    assert r.status_code == 202, r.text
    api_doc = await _wait_sweep(api, r.json()["id"])
    assert api_doc["status"] == "succeeded", api_doc["job"]
    assert api_doc["result"] == cli_doc
    assert api_doc["prediction"] == cli_doc["prediction"]
    async with AsyncClient("http://asgi", transport=api._transport) as sdk:
        done = await sdk.wait(await sdk.create_sweep(simulate=opts), timeout=120)
    assert done.result.model_dump(mode="json") == cli_doc
    truth = done.result.truth
    assert truth is not None and truth.mu_star is not None
    lo, hi = done.result.prediction.mu_star_interval
    assert lo is not None and hi is not None


async def test_resampling_is_asked_for_and_said_the_same_way(api, lab) -> None:  # noqa: ANN001
    rc, cli_doc, err = run_cli("detect", str(lab["dropped"]), "--resample", "--json")
    assert rc == 0, err
    status, api_doc = await _api_detect(api, lab["dropped"], resample="true")
    assert status == 200 and api_doc == cli_doc
    assert cli_doc["flags"][0]["code"] == "resampled"
    assert cli_doc["fundamental"]["omega"] == pytest.approx(40.0 * np.sqrt(1.5), rel=1e-4)


async def test_rounded_times_sent_inline_read_as_from_the_file(api, lab) -> None:  # noqa: ANN001
    """The times of the %.6g file sent as JSON numbers: the same step, the same note."""
    rc, cli_doc, err = run_cli("detect", str(lab["s_6g"]), "--json")
    assert rc == 0, err
    rows = [line.split(",") for line in lab["s_6g"].read_text().splitlines()[1:]]
    t, w = [float(a) for a, _ in rows], [float(b) for _, b in rows]
    r = await api.post("/v1/detections", json={"t": t, "w": w})
    assert r.status_code == 200, r.text
    # the numbers alike; the units the file's header named are not in the JSON arrays
    inline = r.json()
    assert (inline.pop("time_unit"), inline.pop("value_unit")) == (None, None)
    assert inline == {k: v for k, v in cli_doc.items() if k not in ("time_unit", "value_unit")}
