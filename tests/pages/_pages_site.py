"""Helpers of the page tests: the server under test and lab-like records."""

from __future__ import annotations

import math
import socket
import subprocess
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import httpx2
import numpy as np

THETA_STAR = 30.0  # deg: where the synthetic lab strip snaps (saddle-node)


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@dataclass
class Site:
    """The running server, its keys and what the tests uploaded."""

    base: str
    key_a: str
    key_b: str
    proc: subprocess.Popen
    log: Path
    signals: list[str] = field(default_factory=list)
    sweep_id: str = ""

    def client(self, key: str) -> httpx2.Client:
        return httpx2.Client(
            base_url=self.base, headers={"Authorization": f"Bearer {key}"}, timeout=60
        )


def lab_records(n: int = 8, seed: int = 3) -> list[tuple[float, float, np.ndarray]]:
    """Impulse responses as a lab writes them: control theta in degrees, time in ms, deflection
    in mm. Near a saddle-node at theta* the angular rate falls as (theta* - theta)^(1/4) and
    the static level moves as (theta* - theta)^(1/2); 40 periods, 50 samples per period,
    Gaussian noise."""
    rng = np.random.default_rng(seed)
    out = []
    for theta in THETA_STAR * (1 - np.geomspace(1, 0.01, n)):
        d = (THETA_STAR - theta) / THETA_STAR
        omega = 2 * math.pi * 0.05 * d**0.25  # rad/ms
        dt = (2 * math.pi / omega) / 50
        t = np.arange(2000) * dt
        w = -0.6 + 0.3 * (1 - math.sqrt(d)) + 0.01 * np.exp(-2e-4 * omega * t) * np.cos(
            omega * t + 0.3
        )
        out.append((float(theta), float(dt), w + 1e-4 * rng.standard_normal(t.size)))
    return out


def wait_health(base: str, proc: subprocess.Popen, log: Path) -> None:
    end = time.monotonic() + 90
    while time.monotonic() < end:
        if proc.poll() is not None:
            raise RuntimeError(f"server exited ({proc.returncode}):\n{log.read_text()[-3000:]}")
        try:
            if httpx2.get(f"{base}/healthz", timeout=2).status_code < 500:
                return
        except httpx2.HTTPError:
            pass
        time.sleep(0.2)
    raise RuntimeError(f"server did not answer:\n{log.read_text()[-3000:]}")


def wait_job(c: httpx2.Client, job_id: str, timeout: float = 180) -> dict[str, Any]:
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        j = c.get(f"/v1/jobs/{job_id}").json()
        if j["status"] in ("succeeded", "failed", "cancelled"):
            assert j["status"] == "succeeded", j
            return j
        time.sleep(0.2)
    raise AssertionError(f"job {job_id} did not finish in {timeout} s")


