"""The user's hand on the detector at every door: quantity, start, notch (a record); the band and
an excluded record (a sweep). CLI and API give one document; the SDK sends the fields."""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path

import numpy as np
import pytest
from _contract_helpers import run_cli, upload_file

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "labrec"))
import labfiles  # noqa: E402
import labgen  # noqa: E402

from service.client import _core as core  # noqa: E402

pytestmark = pytest.mark.anyio


def _lab_record(tmp_path: Path, quantity: str = "velocity") -> tuple[Path, labgen.LabRecord]:
    off = {k: False for k in labgen.IMPAIRMENTS}
    rec = labgen.draw_record(np.random.default_rng([27, 31]), **{
        **off, "noise": 40.0, "hum": 0.05, "pretrigger": 0.15, "quantity": quantity})  # fmt: skip
    path = labfiles.write_record(rec, tmp_path / f"rec{labfiles.suffix('csv')}", "csv")
    return path, rec


async def test_detect_options_through_cli_and_api(api, tmp_path) -> None:  # noqa: ANN001
    path, rec = _lab_record(tmp_path)
    mains = [f for f, _ in labgen.hum_lines(rec.lab)]
    notch = ",".join(repr(f) for f in mains)
    start = (rec.kick_index + 20) * rec.dt
    rc, cli_doc, err = run_cli("detect", str(path), "--json", "--notch", notch,
                               "--start", repr(start))  # fmt: skip
    assert rc == 0, err
    r = await api.post("/v1/signals", **upload_file(path))
    assert r.status_code == 201, r.text
    r = await api.post("/v1/detections", json={"signal_id": r.json()["id"], "notch": mains,
                                               "start": start})  # fmt: skip
    assert r.status_code == 200, r.text
    assert r.json() == cli_doc
    # the file's unit (mm/s) says it is a velocity: no static level, said so
    assert cli_doc["quantity"] == "velocity" and cli_doc["static_level"] is None
    codes = [f["code"] for f in cli_doc["flags"]]
    assert {"start_given", "stationary_line", "no_static_level"} <= set(codes)
    assert cli_doc["start"] == rec.kick_index + 20
    f = cli_doc["fundamental"]
    assert abs(math.sqrt(-f["sigma2"]) / rec.truth.omega0 - 1) < 0.01
    # told otherwise, the record is read as a displacement
    # (a displacement has a static level unless its baseline moves: then the flag says why)
    rc, doc, _ = run_cli("detect", str(path), "--json", "--quantity", "displacement")
    codes = {f["code"] for f in doc["flags"]}
    assert doc["quantity"] == "displacement" and "no_static_level" not in codes
    assert doc["static_level"] is not None or "baseline_drift" in codes


async def test_bad_options_name_their_field(api, tmp_path) -> None:  # noqa: ANN001
    path, _ = _lab_record(tmp_path)
    rc, _, err = run_cli("detect", str(path), "--notch", "abc")
    assert rc == 2 and "--notch" in err
    r = await api.post("/v1/detections", json={"w": [0.0, 1.0] * 20, "dt": 1e-3,
                                               "quantity": "strain"})  # fmt: skip
    assert r.status_code == 422 and "quantity" in r.text
    r = await api.post("/v1/detections", json={"w": [0.0, 1.0] * 20, "dt": 1e-3,
                                               "notch": [1e6]})  # fmt: skip
    assert r.status_code == 422 and "notch" in r.text


def test_the_sdk_sends_the_options() -> None:
    call = core.detect(w=[0.0, 1.0, 0.0], dt=1e-3, quantity="acceleration", start=0.5, notch=50)
    doc = json.loads(call.content)
    assert doc["quantity"] == "acceleration" and doc["start"] == 0.5 and doc["notch"] == [50.0]
    call = core.create_sweep([("a", 1.0), ("b", 2.0), ("c", 3.0)], band=(1.0, 9.0),
                             notch=[50.0, 150.0], exclude=["b"])  # fmt: skip
    doc = json.loads(call.content)
    assert doc["band"] == [1.0, 9.0] and doc["notch"] == [50.0, 150.0]
    assert [m.get("exclude", False) for m in doc["measurements"]] == [False, True, False]


@pytest.fixture(scope="module")
def campaign(tmp_path_factory: pytest.TempPathFactory) -> labfiles.CampaignTruth:
    camp, style = labfiles.issue_campaigns()["supercritical-pitchfork"]
    controls = labfiles.controls_for(camp, n=6)
    return labfiles.write_campaign(camp, tmp_path_factory.mktemp("camp"), controls=controls,
                                   style=style)  # fmt: skip


def test_sweep_exclude_and_band_through_the_cli(campaign) -> None:  # noqa: ANN001
    man = str(campaign.manifest)
    name = campaign.records[2].name
    rc, doc, err = run_cli("sweep", man, "--json", "--no-progress", "--exclude", name)
    assert rc == 0, err
    aside = {a["name"]: a["reason"] for a in doc["set_aside"]}
    assert name in aside and "excluded by the user" in aside[name]
    assert doc["n_set_aside"] == len(doc["set_aside"])
    # a band that holds no fundamental: every record set aside, named, and no prediction
    rc, doc, err = run_cli("sweep", man, "--json", "--no-progress", "--band", "1e4,2e4")
    assert rc == 0, err
    assert doc["prediction"] is None and doc["n_set_aside"] == len(campaign.records)
    assert all("band" in a["reason"] for a in doc["set_aside"])
    rc, _, err = run_cli("sweep", man, "--exclude", "nope.csv")
    assert rc == 2 and "--exclude" in err and "nope.csv" in err
    # the manifest's own columns: exclude and quantity per record
    lines = Path(man).read_text().splitlines()
    rows = [lines[0] + ",exclude"] + [ln + (",1" if k == 3 else ",") for k, ln in
                                      enumerate(lines[1:])]  # fmt: skip
    man2 = Path(man).with_name("manifest2.csv")
    man2.write_text("\n".join(rows) + "\n")
    rc, doc, err = run_cli("sweep", str(man2), "--json", "--no-progress")
    assert rc == 0, err
    assert campaign.records[3].name in {a["name"] for a in doc["set_aside"]}
