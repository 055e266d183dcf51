"""A server killed with SIGKILL mid-job and restarted loses nothing completed, and resumes
the interrupted job (real uvicorn subprocesses on one SQLite file)."""

from __future__ import annotations

import os
import signal
import time

import httpx2
import pytest
from _svc_helpers import alive, start_server
from _svc_signals import ringdown

from service.api.storage import Store


def _job(url: str, jid: str) -> dict:
    r = httpx2.get(f"{url}/v1/jobs/{jid}", timeout=10)
    assert r.status_code == 200, r.text
    return r.json()


def _descendants(root: int) -> set[int]:
    parents = {}
    for entry in os.listdir("/proc"):
        if entry.isdigit():
            try:
                with open(f"/proc/{entry}/stat") as fh:
                    parents[int(entry)] = int(fh.read().rsplit(")", 1)[1].split()[1])
            except OSError:
                pass
    tree, grew = {root}, True
    while grew:
        grew = False
        for pid, ppid in parents.items():
            if ppid in tree and pid not in tree:
                tree.add(pid)
                grew = True
    return tree - {root}


def _until(pred, timeout: float, what: str):  # noqa: ANN001, ANN202
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        v = pred()
        if v:
            return v
        time.sleep(0.05)
    raise AssertionError(f"timed out waiting for {what}")


def test_sigkill_mid_job_loses_nothing_completed(tmp_path) -> None:  # noqa: ANN001
    db = f"sqlite:///{tmp_path / 'crash.db'}"
    a = start_server(db, tmp_path)
    try:
        t, w = ringdown(5000)
        r = httpx2.post(
            f"{a.url}/v1/signals",
            json={"dt": 0.01, "w": w.tolist(), "control": {"value": 1.5}},
            timeout=30,
        )
        assert r.status_code == 201
        sig = r.json()
        data_before = httpx2.get(f"{a.url}/v1/signals/{sig['id']}/data?format=npy").content

        store = Store(db)
        short = [
            store.create_job("diagnostic-sleep", {"seconds": 0.2, "echo": k}) for k in range(2)
        ]
        done = {
            j.id: _until(
                lambda j=j: (d := _job(a.url, j.id))["status"] == "succeeded" and d,
                60,
                "short jobs",
            )
            for j in short
        }
        long = store.create_job("diagnostic-sleep", {"seconds": 4.0, "steps": 40, "echo": "L"})
        _until(
            lambda: (
                (d := _job(a.url, long.id))["status"] == "running"
                and d["progress"]["fraction"] > 0.1
            ),
            60,
            "the long job to run",
        )

        workers = _descendants(a.proc.pid)
        assert workers, "the server runs its work in child processes"
        a.stop(signal.SIGKILL)
        assert a.proc.returncode == -signal.SIGKILL
        # its worker processes exit with it: nobody updates the job any more
        _until(lambda: not any(alive(p) for p in workers), 20, "orphans to exit")
        frozen = store.get_job(long.id)
        time.sleep(0.6)
        again = store.get_job(long.id)
        assert (again.fraction, again.message) == (frozen.fraction, frozen.message)
        assert again.status == "running"  # as the crash left it
    finally:
        a.stop(signal.SIGKILL)

    b = start_server(db, tmp_path)
    try:
        for jid, before in done.items():  # completed jobs: untouched
            after = _job(b.url, jid)
            assert after == before
        meta = httpx2.get(f"{b.url}/v1/signals/{sig['id']}").json()
        assert meta == sig
        assert httpx2.get(f"{b.url}/v1/signals/{sig['id']}/data?format=npy").content == data_before
        # the interrupted job is resumed at once (its owner is dead) and completes
        final = _until(
            lambda: (d := _job(b.url, long.id))["status"] in ("succeeded", "failed") and d,
            60,
            "the resumed job",
        )
        assert final["status"] == "succeeded", final
        assert final["attempts"] == 2 and final["result"]["echo"] == "L"
    finally:
        rc = b.stop()
    assert rc in (0, -signal.SIGTERM), b.output()


@pytest.mark.slow
def test_a_job_interrupted_too_often_fails_with_a_reason(tmp_path) -> None:  # noqa: ANN001
    db = f"sqlite:///{tmp_path / 'crash2.db'}"
    store = Store(db)
    store.create_all()
    job = store.create_job("diagnostic-sleep", {"seconds": 30, "steps": 300})
    env = {"SNAPWARN_JOB_MAX_ATTEMPTS": "2"}
    for attempt in (1, 2):
        s = start_server(db, tmp_path, extra_env=env)
        try:
            _until(
                lambda a=attempt, u=s.url: (
                    (d := _job(u, job.id))["status"] == "running" and d["attempts"] == a
                ),
                60,
                f"attempt {attempt}",
            )
        finally:
            s.stop(signal.SIGKILL)
    s = start_server(db, tmp_path, extra_env=env)
    try:
        final = _until(
            lambda: (d := _job(s.url, job.id))["status"] == "failed" and d, 30, "the job to fail"
        )
        assert final["error"]["title"] == "Job interrupted"
        assert "giving up" in final["error"]["detail"]
    finally:
        s.stop()


@pytest.mark.slow
def test_a_graceful_stop_hands_the_running_job_back(tmp_path) -> None:  # noqa: ANN001
    db = f"sqlite:///{tmp_path / 'graceful.db'}"
    a = start_server(db, tmp_path, extra_env={"SNAPWARN_JOB_LEASE_S": "600"})
    store = Store(db)
    job = store.create_job("diagnostic-sleep", {"seconds": 3.0, "steps": 30, "echo": "g"})
    try:
        _until(
            lambda: (
                (d := _job(a.url, job.id))["status"] == "running" and d["progress"]["fraction"] > 0
            ),
            60,
            "the job to run",
        )
    finally:
        rc = a.stop(signal.SIGTERM)
    assert rc in (0, -signal.SIGTERM), a.output()
    row = store.get_job(job.id)
    assert row.status == "queued" and "runner was stopped" in row.message
    # a long lease: only the hand-back (not the lease) lets the next server resume it at once
    b = start_server(db, tmp_path, extra_env={"SNAPWARN_JOB_LEASE_S": "600"})
    try:
        final = _until(
            lambda: (d := _job(b.url, job.id))["status"] in ("succeeded", "failed") and d,
            60,
            "the resumed job",
        )
        assert final["status"] == "succeeded" and final["attempts"] == 2
    finally:
        b.stop()
