"""Real processes for the live-sweep tests: uvicorn servers on loopback over one database."""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import time
import uuid
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path

import httpx2
import pytest

ROOT = Path(__file__).resolve().parents[2]


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@dataclass
class Uvicorn:
    url: str
    proc: subprocess.Popen
    log: Path

    def stop(self) -> None:
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGTERM)
            try:
                self.proc.wait(15)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait(5)

    def output(self) -> str:
        return self.log.read_text(errors="replace") if self.log.exists() else ""


def start_uvicorn(db_url: str, tmp: Path, *, workers: int = 1, timeout: float = 90.0) -> Uvicorn:
    """``uvicorn --factory service.api.app:app_from_env`` on a free loopback port."""
    port = free_port()
    env = dict(os.environ)
    env.pop("SNAPWARN_API_KEY", None)
    env.update(
        {
            "SNAPWARN_DB_URL": db_url,
            "SNAPWARN_ANALYSIS_WORKERS": str(workers),
            "SNAPWARN_JOB_WORKERS": "1",
            "SNAPWARN_LOG_LEVEL": "warning",
            "PYTHONUNBUFFERED": "1",
            "PYTHONPATH": str(ROOT),
        }
    )
    log = tmp / f"uvicorn-{port}-{uuid.uuid4().hex[:6]}.log"
    cmd = [sys.executable, "-m", "uvicorn", "--factory", "service.api.app:app_from_env",
           "--host", "127.0.0.1", "--port", str(port), "--log-level", "warning"]  # fmt: skip
    fh = open(log, "wb")  # noqa: SIM115 - closed with the process
    proc = subprocess.Popen(cmd, cwd=tmp, env=env, stdout=fh, stderr=subprocess.STDOUT)
    server = Uvicorn(f"http://127.0.0.1:{port}", proc, log)
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if proc.poll() is not None:
            raise RuntimeError(f"uvicorn exited with {proc.returncode}:\n{server.output()}")
        try:
            if httpx2.get(server.url + "/healthz", timeout=1.0).status_code == 200:
                return server
        except httpx2.HTTPError:
            pass
        time.sleep(0.1)
    server.stop()
    raise RuntimeError(f"uvicorn did not answer in {timeout} s:\n{server.output()}")


@pytest.fixture(scope="module")
def live_db(tmp_path_factory: pytest.TempPathFactory) -> str:
    return f"sqlite:///{tmp_path_factory.mktemp('live') / 'live.db'}"


@pytest.fixture(scope="module")
def server_factory(
    tmp_path_factory: pytest.TempPathFactory,
) -> Iterator[Callable[..., Uvicorn]]:
    started: list[Uvicorn] = []
    tmp = tmp_path_factory.mktemp("uvicorn")

    def start(db_url: str, **kw: object) -> Uvicorn:
        s = start_uvicorn(db_url, tmp, **kw)
        started.append(s)
        return s

    yield start
    for s in started:
        s.stop()


@pytest.fixture(scope="module")
def server(server_factory: Callable[..., Uvicorn], live_db: str) -> Uvicorn:
    """One uvicorn (two analysis workers, so concurrent records really race)."""
    return server_factory(live_db, workers=2)
