"""A real cluster: `dask scheduler` and two `dask worker` processes on loopback. The atlas runs
through `snapwarn atlas --scheduler`; one worker is SIGKILLed (by pid) while it computes a cell.
Every cell must then be persisted exactly once, with the results of a serial run."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from collections import Counter
from pathlib import Path

import pytest
from _atlas_helpers import MU_ATOL, REPO, SNAPWARN, env_one_thread, free_port

from service.atlas import parse_spec, run_atlas

DASK = str(Path(sys.executable).with_name("dask"))
SPEC = {
    "kind": "bifurcation", "name": "kill-test",
    "fixed": {"model": "cosserat", "elements": 40, "end_shortening": 1e-2},
    "grid": {"slenderness": [1e-3, 3e-3, 5e-3, 7e-3],
             "actuation": ["asymmetric", "symmetric", "antisymmetric"]},
}  # fmt: skip


def _stop(p: subprocess.Popen) -> None:
    if p.poll() is None:
        p.send_signal(signal.SIGTERM)
        try:
            p.wait(10)
        except subprocess.TimeoutExpired:
            p.kill()
            p.wait(10)


@pytest.mark.slow  # ~40 s on two idle cores (cluster start, 12 Cosserat cells, serial reference)
def test_worker_killed_mid_run_every_cell_once_same_results(tmp_path: Path) -> None:
    import distributed

    (tmp_path / "spec.json").write_text(json.dumps(SPEC))
    env = env_one_thread()
    port = free_port()
    addr = f"tcp://127.0.0.1:{port}"
    procs: list[subprocess.Popen] = []
    logs = []
    watcher = None
    try:
        log = open(tmp_path / "scheduler.log", "wb")  # noqa: SIM115
        logs.append(log)
        procs.append(subprocess.Popen(
            [DASK, "scheduler", "--host", "127.0.0.1", "--port", str(port), "--no-dashboard"],
            env=env, cwd=tmp_path, stdout=log, stderr=subprocess.STDOUT))  # fmt: skip
        for name in ("w1", "w2"):
            log = open(tmp_path / f"{name}.log", "wb")  # noqa: SIM115
            logs.append(log)
            procs.append(subprocess.Popen(
                [DASK, "worker", addr, "--nthreads", "1", "--no-nanny", "--host", "127.0.0.1",
                 "--no-dashboard", "--name", name, "--death-timeout", "60"],
                env=env, cwd=REPO, stdout=log, stderr=subprocess.STDOUT))  # fmt: skip
        watcher = distributed.Client(addr, timeout="60s")
        watcher.wait_for_workers(2, timeout=120)
        pids = watcher.run(os.getpid)  # worker address -> pid
        assert sorted(pids.values()) == sorted(p.pid for p in procs[1:])

        out = tmp_path / "out"
        atlas_log = open(tmp_path / "atlas.stderr", "w")  # noqa: SIM115
        logs.append(atlas_log)
        run = subprocess.Popen(
            [*SNAPWARN, "atlas", str(tmp_path / "spec.json"), "--scheduler", addr, "--out",
             str(out), "--json", "--no-progress"],
            env=env, cwd=REPO, stdout=subprocess.PIPE, stderr=atlas_log, text=True)  # fmt: skip
        procs.append(run)
        # wait until two cells are persisted, then kill a worker that is computing one
        killed, victim_keys = None, []
        end = time.monotonic() + 180
        while killed is None:
            assert run.poll() is None, "the atlas ended before a worker could be killed"
            assert time.monotonic() < end, "no cell was persisted in time"
            lines = (out / "cells.jsonl").read_text().splitlines() if (
                out / "cells.jsonl").exists() else []  # fmt: skip
            busy = {w: ks for w, ks in watcher.processing().items() if ks}
            if len(lines) >= 2 and busy:
                killed, victim_keys = next(iter(busy.items()))
                os.kill(pids[killed], signal.SIGKILL)
                done_before = len(lines)
            time.sleep(0.05)
        stdout, _ = run.communicate(timeout=300)
        assert run.returncode == 0, (tmp_path / "atlas.stderr").read_text()
    finally:
        if watcher is not None:
            watcher.close()
        for p in reversed(procs):
            _stop(p)
        for f in logs:
            f.close()

    assert done_before < len(parse_spec(SPEC).cells), "the kill came after the last cell"
    doc = json.loads(stdout)
    assert doc["summary"]["ok"] == 12 and doc["summary"]["missing"] == 0
    rows = [json.loads(x) for x in (out / "cells.jsonl").read_text().splitlines()]
    counts = Counter(r["key"] for r in rows)
    assert len(rows) == 12 and set(counts.values()) == {1}, counts
    # the cell(s) the killed worker was computing were recomputed by the survivor
    survivor = next(a for a in pids if a != killed)
    for task in victim_keys:
        key = str(task).removeprefix("snapwarn-bifurcation-")
        (row,) = [r for r in rows if r["key"] == key]
        assert row["worker"] == survivor
    # the same results as a plain loop
    serial = {r.key: r for r in run_atlas(parse_spec(SPEC), serial=True).rows}
    assert set(serial) == set(counts)
    for r in rows:
        ref = serial[r["key"]]
        assert r["inputs"] == ref.inputs
        assert r["results"]["transition"] == ref.results["transition"]
        assert r["results"]["mu_star"] == pytest.approx(ref.results["mu_star"], abs=MU_ATOL)
