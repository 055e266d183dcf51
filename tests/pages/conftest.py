"""Fixtures of the page tests: a real uvicorn on loopback (keys on, two owners), a lab sweep
uploaded through the API, and Debian's headless Chromium driven over the DevTools protocol.

Screenshots go to ``$SNAPWARN_SCREENSHOTS`` when set (else a temporary folder).
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest
from _pages_cdp import Browser, find_chromium
from _pages_site import Site, free_port, lab_records, wait_health, wait_job


@pytest.fixture(scope="session")
def chromium() -> str:
    exe = find_chromium()
    if exe is None and os.environ.get("CI"):
        pytest.fail("Chromium is missing in CI: .ci/run must install it (apt-get install chromium)")
    if exe is None:
        pytest.skip(
            "Chromium is not installed (Debian: apt-get install -y chromium; .ci/run installs "
            "it), so the pages cannot be rendered in a real browser"
        )
    return exe


@pytest.fixture(scope="session")
def site(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Site]:
    """uvicorn on 127.0.0.1 (keys required), two owners, one lab sweep of owner A done."""
    from service.api.storage import Store

    tmp = tmp_path_factory.mktemp("pages")
    url = f"sqlite:///{tmp / 'pages.db'}"
    store = Store(url)
    store.migrate()
    key_a, _ = store.create_key("lab-a")
    key_b, _ = store.create_key("lab-b")
    store.dispose()
    port = free_port()
    env = {
        **os.environ,
        "SNAPWARN_DB_URL": url,
        "SNAPWARN_AUTH": "on",
        "SNAPWARN_ANALYSIS_WORKERS": "1",
        "SNAPWARN_JOB_WORKERS": "1",
        "SNAPWARN_JOB_POLL_S": "0.05",
        "SNAPWARN_LOG_LEVEL": "warning",
    }
    env.pop("SNAPWARN_API_KEY", None)
    log = tmp / "server.log"
    cmd = [sys.executable, "-m", "uvicorn", "--factory", "service.api.app:app_from_env",
           "--host", "127.0.0.1", "--port", str(port), "--log-level", "warning"]  # fmt: skip
    with log.open("wb") as fh:
        proc = subprocess.Popen(cmd, env=env, stdout=fh, stderr=subprocess.STDOUT)
    base = f"http://127.0.0.1:{port}"
    s = Site(base, key_a, key_b, proc, log)
    try:
        wait_health(base, proc, log)
        with s.client(key_a) as c:
            for theta, dt, w in lab_records():
                r = c.post("/v1/signals", json={
                    "dt": dt, "w": w.tolist(), "unit": "ms", "value_unit": "mm",
                    "name": f"theta {theta:.4f} deg",
                    "control": {"name": "theta", "value": theta, "unit": "deg"},
                })  # fmt: skip
                assert r.status_code == 201, r.text
                s.signals.append(r.json()["id"])
            r = c.post("/v1/sweeps", json={
                "name": "lab strip, theta sweep",
                "measurements": [{"signal_id": i} for i in s.signals],
            })  # fmt: skip
            assert r.status_code == 202, r.text
            s.sweep_id = r.json()["id"]
            wait_job(c, s.sweep_id)
        yield s
    finally:
        proc.send_signal(signal.SIGTERM)
        try:
            proc.wait(timeout=20)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait(timeout=10)


@pytest.fixture(scope="session")
def browser(chromium: str, tmp_path_factory: pytest.TempPathFactory) -> Iterator[Browser]:
    b = Browser(chromium, tmp_path_factory.mktemp("chromium"))
    yield b
    b.close()


@pytest.fixture(scope="session")
def shots(tmp_path_factory: pytest.TempPathFactory) -> Path:
    env = os.environ.get("SNAPWARN_SCREENSHOTS")
    p = Path(env) if env else tmp_path_factory.mktemp("screenshots")
    p.mkdir(parents=True, exist_ok=True)
    return p
