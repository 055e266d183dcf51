"""Helpers of the service tests (a module with a unique name, imported by conftest and tests)."""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import time
import uuid
from dataclasses import dataclass
from pathlib import Path

import httpx2
import pytest

from service.api import Settings

REPO = Path(__file__).resolve().parents[2]
PG_ENV = "SNAPWARN_TEST_PG_URL"
#: The `snapwarn` command (the console script's entry point, run by this interpreter).
SNAPWARN = [sys.executable, "-c", "import sys; from service.cli import main; sys.exit(main())"]


def alive(pid: int) -> bool:
    """Whether process ``pid`` exists and is not a zombie (Linux /proc)."""
    try:
        with open(f"/proc/{pid}/stat") as fh:
            return fh.read().rsplit(")", 1)[1].split()[0] != "Z"
    except OSError:
        return False


def numerics_has(module: str, attr: str) -> bool:
    """Whether a numerics entry point exists (tests of routes that need it skip otherwise)."""
    import importlib

    try:
        return hasattr(importlib.import_module(module), attr)
    except ImportError:
        return False


def require_numerics(module: str, attr: str) -> None:
    """``pytest.importorskip`` on an attribute: skip until the numerics land."""
    mod = pytest.importorskip(module)
    if not hasattr(mod, attr):
        pytest.skip(f"{module}.{attr} does not exist yet")


def test_settings(db_url: str, **kw: object) -> Settings:
    base = dict(
        db_url=db_url,
        analysis_workers=1,
        job_workers=1,
        job_poll_s=0.05,
        job_heartbeat_s=0.3,
        job_lease_s=3.0,
        api_key=None,
    )
    base.update(kw)
    return Settings(**base)


test_settings.__test__ = False  # not a test


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _create_pg_database(base_url: str, name: str) -> str:
    """Create database ``name`` on the server of ``base_url``; its URL."""
    import psycopg
    from sqlalchemy.engine import make_url

    u = make_url(base_url)
    conninfo = u.set(drivername="postgresql").render_as_string(hide_password=False)
    with psycopg.connect(conninfo, autocommit=True) as conn:
        conn.execute(f'CREATE DATABASE "{name}"')
    return u.set(database=name).render_as_string(hide_password=False)


class DbFactory:
    """Fresh, empty databases of one kind (a SQLite file, or a new PostgreSQL database)."""

    def __init__(self, kind: str, tmp: Path, pg_url: str | None) -> None:
        self.kind, self.tmp, self.pg_url = kind, tmp, pg_url

    def __call__(self, label: str = "db") -> str:
        tag = f"{label}_{uuid.uuid4().hex[:8]}"
        if self.kind == "sqlite":
            return f"sqlite:///{self.tmp / (tag + '.db')}"
        assert self.pg_url is not None
        return _create_pg_database(self.pg_url, f"snapwarn_{tag}")


@dataclass
class Server:
    """A `snapwarn serve` subprocess on 127.0.0.1."""

    url: str
    db_url: str
    proc: subprocess.Popen
    log: Path

    def stop(self, sig: int = signal.SIGTERM, timeout: float = 15.0) -> int:
        if self.proc.poll() is None:
            self.proc.send_signal(sig)
            try:
                self.proc.wait(timeout)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait(5)
        return self.proc.returncode

    def output(self) -> str:
        return self.log.read_text(errors="replace") if self.log.exists() else ""


def start_server(
    db_url: str,
    tmp: Path,
    *,
    extra_env: dict[str, str] | None = None,
    args: list[str] | None = None,
    timeout: float = 60.0,
) -> Server:
    """Start `snapwarn serve` on a free loopback port and wait until /healthz answers."""
    port = free_port()
    env = dict(os.environ)
    env.update(
        {
            "SNAPWARN_ANALYSIS_WORKERS": "1",
            "SNAPWARN_JOB_WORKERS": "1",
            "SNAPWARN_JOB_POLL_S": "0.05",
            "SNAPWARN_JOB_HEARTBEAT_S": "0.3",
            "SNAPWARN_JOB_LEASE_S": "3",
            "SNAPWARN_LOG_LEVEL": "warning",
            "PYTHONUNBUFFERED": "1",
        }
    )
    env.pop("SNAPWARN_API_KEY", None)
    env.update(extra_env or {})
    log = tmp / f"server-{port}-{uuid.uuid4().hex[:6]}.log"
    cmd = [
        *SNAPWARN,
        "serve",
        "--host",
        "127.0.0.1",
        "--port",
        str(port),
        "--db",
        db_url,
        *(args or []),
    ]
    fh = open(log, "wb")  # noqa: SIM115 - closed with the process
    proc = subprocess.Popen(cmd, cwd=tmp, env=env, stdout=fh, stderr=subprocess.STDOUT)
    url = f"http://127.0.0.1:{port}"
    server = Server(url=url, db_url=db_url, proc=proc, log=log)
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if proc.poll() is not None:
            raise RuntimeError(f"server exited with {proc.returncode}:\n{server.output()}")
        try:
            if httpx2.get(url + "/healthz", timeout=1.0).status_code == 200:
                return server
        except httpx2.HTTPError:
            pass
        time.sleep(0.1)
    server.stop(signal.SIGKILL)
    raise RuntimeError(f"server did not answer in {timeout} s:\n{server.output()}")
