"""The foreign lab files through the three doors: the CLI, a real uvicorn on loopback (REST)
and the SDK give one document, equal to the generated truth; broken files give one error
(422 problem naming the field; CLI exit 2), never a 5xx or a traceback. A recorded sweep whose
control is in degrees gives mu* in degrees through the manifest and through the API."""

from __future__ import annotations

import math
import os
import signal
import socket
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import httpx2
import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).parent))
sys.path.insert(0, str(Path(__file__).parents[1] / "contract"))
from _contract_helpers import run_cli  # noqa: E402
from _foreign import bad_records, lab_records  # noqa: E402

pytestmark = pytest.mark.slow

SNAPWARN = [str(Path(sys.executable).with_name("snapwarn"))]


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


@pytest.fixture(scope="module")
def server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[str]:
    """`snapwarn serve` on a free loopback port, a SQLite file; stopped by its pid."""
    tmp = tmp_path_factory.mktemp("foreign-server")
    port = _free_port()
    env = {**os.environ, "SNAPWARN_ANALYSIS_WORKERS": "1", "SNAPWARN_JOB_WORKERS": "1",
           "SNAPWARN_JOB_POLL_S": "0.05", "SNAPWARN_LOG_LEVEL": "warning"}  # fmt: skip
    env.pop("SNAPWARN_API_KEY", None)
    log = open(tmp / "server.log", "wb")  # noqa: SIM115 - closed below
    proc = subprocess.Popen(
        [*SNAPWARN, "serve", "--host", "127.0.0.1", "--port", str(port),
         "--db", f"sqlite:///{tmp / 'api.db'}"],
        cwd=tmp, env=env, stdout=log, stderr=subprocess.STDOUT,
    )  # fmt: skip
    url = f"http://127.0.0.1:{port}"
    deadline = time.monotonic() + 90
    while True:
        try:
            if httpx2.get(f"{url}/healthz", timeout=2).status_code == 200:
                break
        except httpx2.HTTPError:
            pass
        if proc.poll() is not None or time.monotonic() > deadline:
            proc.kill()
            raise RuntimeError((tmp / "server.log").read_text())
        time.sleep(0.2)
    yield url
    proc.send_signal(signal.SIGTERM)
    try:
        proc.wait(timeout=30)
    finally:
        if proc.poll() is None:
            proc.kill()
        log.close()


@pytest.fixture(scope="module")
def files(tmp_path_factory: pytest.TempPathFactory) -> dict:
    d = tmp_path_factory.mktemp("foreign-files")
    return {"good": lab_records(d), "bad": bad_records(d)}


def _api(url: str, path: Path) -> tuple[int, dict]:
    with httpx2.Client(base_url=url, timeout=60) as c:
        r = c.post("/v1/signals", files={"file": (path.name, path.read_bytes())})
        if r.status_code != 201:
            return r.status_code, r.json()
        r = c.post("/v1/detections", json={"signal_id": r.json()["id"]})
        return r.status_code, r.json()


def test_every_foreign_file_gives_one_detection_in_three_doors(server, files) -> None:  # noqa: ANN001
    from service.client import Client

    with Client(server) as sdk:
        for name, (path, omega) in files["good"].items():
            rc, cli_doc, err = run_cli("detect", str(path), "--json")
            assert rc == 0, (name, err)
            status, api_doc = _api(server, path)
            assert status == 200, (name, api_doc)
            sdk_doc = sdk.detect(sdk.upload_file(path).id).model_dump(mode="json")
            assert cli_doc == api_doc == sdk_doc, name
            assert cli_doc["fundamental"]["omega"] == pytest.approx(omega, rel=1e-4), name


def test_every_broken_file_gives_one_error_in_three_doors(server, files) -> None:  # noqa: ANN001
    from service.client import Client
    from service.client.errors import ApiError

    with Client(server) as sdk:
        for name, (path, field) in files["bad"].items():
            rc, cli_doc, err = run_cli("detect", str(path), "--json")
            assert rc == 2 and "Traceback" not in err, (name, err)
            status, api_doc = _api(server, path)
            assert status == 422 == cli_doc["status"], (name, api_doc)
            assert cli_doc["field"] == api_doc["errors"][0]["field"] == field, name
            assert cli_doc["value"] == api_doc["errors"][0]["value"], name
            with pytest.raises(ApiError) as e:
                sdk.upload_file(path)
            assert e.value.status == 422


def _record(mu_rad: float, seed: int) -> str:
    """A ringdown of damped frequency ``40 sqrt(2 - mu)`` and decay rate 0.2: its undamped
    ``sigma^2 = -(1600 (2 - mu) + 0.2^2)`` vanishes at mu* = 2 + 0.04/1600 rad (114.59 deg);
    written with an oscilloscope's units row and comment lines."""
    t = np.arange(4000) / 3000.0
    rng = np.random.default_rng(seed)
    w = 0.3 + 1e-2 * np.exp(-0.2 * t) * np.cos(40.0 * np.sqrt(2.0 - mu_rad) * t)
    w = w + rng.normal(0.0, 1e-5, t.size)
    rows = "\n".join(f"{a:.9g},{b:.9g}" for a, b in zip(1e3 * t, w))
    return f"# scope export\nTime,Channel A\n(ms),(mm)\n{rows}\n"


def test_a_sweep_in_degrees_gives_mu_star_in_degrees_in_three_doors(server, tmp_path) -> None:  # noqa: ANN001
    from service.client import Client

    mus = np.linspace(0.0, 1.8, 8)
    deg = np.degrees(mus)
    for k, mu in enumerate(mus):
        (tmp_path / f"r{k}.csv").write_text(_record(float(mu), k))
    manifest = "\ufeffpath;control [deg]\n" + "".join(
        f"r{k}.csv;{float(d)!r}\n" for k, d in enumerate(deg)
    )
    (tmp_path / "manifest.csv").write_text(manifest)
    rc, cli_doc, err = run_cli("sweep", str(tmp_path / "manifest.csv"), "--json", "--no-progress")
    assert rc == 0, err
    with Client(server) as sdk:
        sigs = [sdk.upload_file(tmp_path / f"r{k}.csv", control_value=float(d), control_unit="deg")
                for k, d in enumerate(deg)]  # fmt: skip
        done = sdk.wait(sdk.create_sweep([(s.id, float(d)) for s, d in zip(sigs, deg)]),
                        timeout=180)  # fmt: skip
    p = done.result.prediction
    c = cli_doc["prediction"]
    assert p.transition == c["transition"]
    assert p.mu_star == c["mu_star"]
    truth = math.degrees(2.0 + 0.04 / 1600.0)
    assert abs(c["mu_star"] - truth) < math.degrees(1e-4)
    lo, hi = c["mu_star_interval"]
    assert lo < truth < hi
