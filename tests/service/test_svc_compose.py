"""docker-compose.yml is valid, and its api and worker commands work when started natively
(no docker engine here): same commands, same environment, database and port swapped."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import httpx2
import pytest
import yaml
from _svc_helpers import REPO, SNAPWARN, free_port

from service.api.storage import Store

COMPOSE = REPO / "docker-compose.yml"


@pytest.fixture(scope="module")
def compose() -> dict:
    return yaml.safe_load(COMPOSE.read_text())


def test_compose_structure(compose: dict) -> None:
    services = compose["services"]
    assert set(services) >= {"api", "worker", "db"}
    db = services["db"]
    assert db["image"].startswith("postgres")
    assert any(v.startswith("pgdata:") for v in db["volumes"]) and "pgdata" in compose["volumes"]
    for name in ("db", "api", "worker"):
        hc = services[name]["healthcheck"]
        assert hc["test"] and hc["interval"] and hc["retries"] >= 1, name
    for name in ("api", "worker"):
        svc = services[name]
        env = svc["environment"]
        assert env["SNAPWARN_DB_URL"].startswith("postgresql+psycopg://")
        assert "@db:5432/" in env["SNAPWARN_DB_URL"]
        assert svc["command"][0] == "snapwarn"
        assert svc["depends_on"]["db"]["condition"] == "service_healthy"
    assert services["api"]["command"][:2] == ["snapwarn", "serve"]
    assert "--no-jobs" in services["api"]["command"]  # the worker runs the jobs
    assert services["worker"]["command"][:2] == ["snapwarn", "worker"]
    assert services["api"]["build"] == "." and (REPO / "Dockerfile").exists()
    assert any(p.endswith(":8000") for p in services["api"]["ports"])


def test_dockerfile_installs_and_serves() -> None:
    text = (REPO / "Dockerfile").read_text()
    assert "pip install" in text and ".[postgres]" in text
    assert 'CMD ["snapwarn", "serve"]' in text and "HEALTHCHECK" in text


def _native(cmd: list[str]) -> list[str]:
    if cmd[0] == "snapwarn":
        return [*SNAPWARN, *cmd[1:]]
    if cmd[0] == "python":
        return [sys.executable, *cmd[1:]]
    return cmd


def _healthcheck(svc: dict, env: dict[str, str]) -> int:
    test = svc["healthcheck"]["test"]
    assert test[0] == "CMD"
    return subprocess.run(_native(test[1:]), env=env, timeout=30).returncode


@pytest.mark.slow  # ~35 s on a loaded 2-core machine; CI runs it with `make test-slow`
def test_compose_commands_run_natively(compose: dict, new_db, tmp_path: Path) -> None:  # noqa: ANN001
    db_url = new_db("compose")
    port = free_port()
    procs: dict[str, subprocess.Popen] = {}
    envs: dict[str, dict[str, str]] = {}
    try:
        for name in ("api", "worker"):
            svc = compose["services"][name]
            env = dict(os.environ)
            env.update({k: str(v) for k, v in svc["environment"].items()})
            env.update(
                {
                    "SNAPWARN_DB_URL": db_url,
                    "SNAPWARN_HOST": "127.0.0.1",
                    "SNAPWARN_PORT": str(port),
                    "SNAPWARN_HEARTBEAT_FILE": str(tmp_path / f"{name}.alive"),
                    "SNAPWARN_ANALYSIS_WORKERS": "1",
                    "SNAPWARN_WARM_POOL": "false",
                    "SNAPWARN_JOB_HEARTBEAT_S": "0.3",
                    "SNAPWARN_JOB_POLL_S": "0.05",
                    "SNAPWARN_LOG_LEVEL": "warning",
                }
            )
            envs[name] = env
            log = open(tmp_path / f"{name}.log", "wb")  # noqa: SIM115
            procs[name] = subprocess.Popen(
                _native(svc["command"]), env=env, cwd=tmp_path, stdout=log, stderr=subprocess.STDOUT
            )
            if name == "api":  # the worker starts once the api is healthy (depends_on)
                end = time.monotonic() + 90
                while _healthcheck(svc, env) != 0:
                    assert procs["api"].poll() is None, (tmp_path / "api.log").read_text()
                    assert time.monotonic() < end, "api never became healthy"
                    time.sleep(0.3)
        url = f"http://127.0.0.1:{port}"
        end = time.monotonic() + 60
        while httpx2.get(url + "/healthz").json()["workers"] < 1:
            assert procs["worker"].poll() is None, (tmp_path / "worker.log").read_text()
            assert time.monotonic() < end, "the worker never reported"
            time.sleep(0.2)
        assert _healthcheck(compose["services"]["worker"], envs["worker"]) == 0
        # the api does not run jobs (--no-jobs): the worker does
        store = Store(db_url)
        job = store.create_job("diagnostic-sleep", {"seconds": 0.3, "echo": "compose"})
        end = time.monotonic() + 60
        while (doc := httpx2.get(f"{url}/v1/jobs/{job.id}").json())["status"] != "succeeded":
            assert doc["status"] != "failed", doc
            assert time.monotonic() < end, doc
            time.sleep(0.1)
        assert doc["result"]["pid"] != procs["api"].pid
        store.dispose()
    finally:
        for p in procs.values():
            if p.poll() is None:
                p.send_signal(signal.SIGTERM)
        for name, p in procs.items():
            try:
                p.wait(20)
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait(5)
                raise AssertionError(f"{name} did not stop on SIGTERM") from None
