"""Storage on a real SQLite file and a real PostgreSQL: lossless samples, jobs, recovery."""

from __future__ import annotations

import hashlib
import subprocess
import sys
import time

import numpy as np
import pytest

from service.api.storage import JobRow, SignalRow, Store, runner_identity


@pytest.fixture(scope="module")
def store(new_db) -> Store:  # noqa: ANN001
    s = Store(new_db("storage"))
    s.create_all()
    yield s
    s.dispose()


def test_samples_round_trip_bit_for_bit(store: Store) -> None:
    rng = np.random.default_rng(1)
    w = rng.standard_normal(1001) * 1e-300  # subnormal-ish and negative zero survive too
    w[0], w[1], w[2] = -0.0, 5e-324, np.nextafter(1.0, 2.0)
    t = np.cumsum(np.full(1001, 0.1)) - 0.1
    row = store.add_signal(w=w, dt=0.1, t0=0.0, t=t, source="json", metadata={"k": [1, 2]})
    back = store.get_signal(row.id)
    assert back is not None
    assert back.w.tobytes() == w.astype("<f8").tobytes()
    assert back.t is not None and back.t.tobytes() == t.astype("<f8").tobytes()
    assert back.row.sha256 == hashlib.sha256(w.astype("<f8").tobytes()).hexdigest()
    assert back.row.meta == {"k": [1, 2]}


def test_samples_are_binary_not_json_text(store: Store) -> None:
    w = np.linspace(0, 1, 100)
    row = store.add_signal(w=w, dt=1.0, t0=0.0, t=None, source="json")
    with store.session() as s:
        raw = s.get(SignalRow, row.id).w
    assert isinstance(raw, bytes) and len(raw) == 8 * 100  # 8 bytes a sample, no text


def test_delete_signal(store: Store) -> None:
    row = store.add_signal(w=np.ones(3), dt=1.0, t0=0.0, t=None, source="json")
    assert store.delete_signal(row.id)
    assert store.get_signal(row.id) is None
    assert not store.delete_signal(row.id)


def test_claim_is_exclusive_and_fenced(store: Store) -> None:
    job = store.create_job("diagnostic-sleep", {"seconds": 0})
    got = []
    for _ in range(3):
        c = store.claim_job("owner-a")
        while c is not None and c.id != job.id:  # other tests' jobs may be queued
            store.fail_job(c.id, c.attempts, {"title": "not mine"})
            c = store.claim_job("owner-a")
        if c is not None:
            got.append(c)
    assert len(got) == 1 and got[0].attempts == 1 and got[0].status == "running"
    # a stale attempt cannot write
    assert not store.finish_job(job.id, 0, {"x": 1})
    assert store.job_progress(job.id, 1, 0.5, "half")
    assert store.finish_job(job.id, 1, {"x": float("nan"), "y": 2})
    done = store.get_job(job.id)
    assert done.status == "succeeded" and done.result == {"x": None, "y": 2}
    # a finished job is never touched again
    assert not store.fail_job(job.id, None, {"title": "late"})
    assert store.get_job(job.id).status == "succeeded"


def _claim_mine(store: Store, job_id: str, owner: str) -> JobRow:
    c = store.claim_job(owner)
    while c is not None and c.id != job_id:
        store.fail_job(c.id, c.attempts, {"title": "not mine"})
        c = store.claim_job(owner)
    assert c is not None
    return c


def test_recovery_requeues_then_fails_after_max_attempts(store: Store) -> None:
    job = store.create_job("diagnostic-sleep", {"seconds": 0})
    for attempt in (1, 2):
        c = _claim_mine(store, job.id, "elsewhere:1:x")  # another host: only the lease counts
        assert c.attempts == attempt
        time.sleep(0.3)
        changed = dict(store.recover_jobs(lease_s=0.1, max_attempts=2))
        assert changed.get(job.id) == ("queued" if attempt == 1 else "failed")
    row = store.get_job(job.id)
    assert row.status == "failed"
    assert "giving up" in row.error["detail"] and row.error["title"] == "Job interrupted"


def test_recovery_is_immediate_when_the_owner_process_is_dead(store: Store) -> None:
    p = subprocess.Popen([sys.executable, "-c", "pass"])
    p.wait()
    import socket

    dead_owner = f"{socket.gethostname()}:{p.pid}:deadbeef"
    job = store.create_job("diagnostic-sleep", {"seconds": 0})
    _claim_mine(store, job.id, dead_owner)
    changed = dict(store.recover_jobs(lease_s=3600, max_attempts=3))
    assert changed.get(job.id) == "queued"
    live = store.create_job("diagnostic-sleep", {"seconds": 0})
    _claim_mine(store, live.id, runner_identity())  # this very process: alive
    assert live.id not in dict(store.recover_jobs(lease_s=3600, max_attempts=3))
    store.fail_job(live.id, None, {"title": "cleanup"})
