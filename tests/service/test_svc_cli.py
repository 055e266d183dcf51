"""`snapwarn serve`, `worker` and `openapi`: options checked at the door, one-line errors."""

from __future__ import annotations

import json
import subprocess

import pytest
from _svc_helpers import SNAPWARN


def _run(*args: str, timeout: float = 60) -> subprocess.CompletedProcess:
    return subprocess.run([*SNAPWARN, *args], capture_output=True, text=True, timeout=timeout)


@pytest.mark.parametrize(
    ("args", "needle"),
    [
        (("serve", "--port", "abc"), "--port: 'abc' is not an integer"),
        (("serve", "--port", "70000"), "--port: '70000' must be in [0, 65535]"),
        (("serve", "--workers", "0"), "--workers: '0' must be in [1, 64]"),
        (("serve", "--db", "not-a-url"), "--db: 'not-a-url' is not a database URL"),
        (("worker", "--jobs", "x"), "--jobs: 'x' is not an integer"),
    ],
)
def test_bad_options_are_one_line_errors(args: tuple[str, ...], needle: str) -> None:
    r = _run(*args)
    assert r.returncode == 2, r
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"snapwarn: error: {needle}"), lines
    assert r.stdout == ""


def test_bad_setting_from_the_environment() -> None:
    import os

    env = dict(os.environ, SNAPWARN_EXECUTOR="fork-bomb")
    r = subprocess.run([*SNAPWARN, "serve"], capture_output=True, text=True, timeout=60, env=env)
    assert r.returncode == 2 and "SNAPWARN_EXECUTOR" in r.stderr and "fork-bomb" in r.stderr


def test_openapi_to_stdout() -> None:
    r = _run("openapi", "--out", "-")
    assert r.returncode == 0, r.stderr
    doc = json.loads(r.stdout)
    assert doc["info"]["title"] == "snapwarn" and "/v1/detections" in doc["paths"]


def test_help_lists_the_service_commands() -> None:
    r = _run("--help")
    assert r.returncode == 0
    for cmd in ("serve", "worker", "openapi"):
        assert cmd in r.stdout
