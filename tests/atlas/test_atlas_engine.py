"""The atlas engine: serial loop, JSON-lines persistence and resume, failed cells as data,
an embedded LocalCluster (real worker processes) against the serial loop, the CLI."""

from __future__ import annotations

import json
import os
import subprocess
from pathlib import Path

import pytest
from _atlas_helpers import MU_ATOL, REPO, SNAPWARN, env_one_thread

from service.atlas import JsonlSink, parse_spec, run_atlas
from service.atlas.charts import heatmap, write_heatmaps

BEAM = {"kind": "bifurcation", "name": "beam", "fixed": {"model": "euler-beam"},
        "grid": {"actuation": ["asymmetric", "symmetric", "antisymmetric"]}}
ROD = {"kind": "bifurcation", "name": "rod", "fixed": {"model": "cosserat", "elements": 20},
       "grid": {"slenderness": [1e-3, 1e-2], "actuation": ["antisymmetric"]}}


def test_serial_beam_atlas_gives_the_papers_transitions() -> None:
    res = run_atlas(parse_spec(BEAM), serial=True)
    got = {r.inputs["actuation"]: (r.results["mu_star"], r.results["transition"]) for r in res.rows}
    # paper: saddle-node at 1.782; pitchforks at exactly mu* = 2 (closed form)
    assert got["asymmetric"][0] == pytest.approx(1.7818, abs=1e-4)
    assert got["symmetric"] == (pytest.approx(2.0, abs=1e-12), "subcritical-pitchfork")
    assert got["antisymmetric"] == (pytest.approx(2.0, abs=1e-12), "supercritical-pitchfork")
    s = res.summary
    assert (s.cells, s.ok, s.failed, s.missing, s.resumed) == (3, 3, 0, 0, 0)
    assert s.metrics["transitions"] == {"saddle-node": 1, "subcritical-pitchfork": 1,
                                        "supercritical-pitchfork": 1}
    assert all(r.worker == f"{os.uname().nodename}:{os.getpid()}" for r in res.rows)


def test_jsonl_sink_resumes_and_never_counts_a_cell_twice(tmp_path: Path) -> None:
    spec = parse_spec(BEAM)
    path = tmp_path / "cells.jsonl"
    first = run_atlas(spec, serial=True, sink=JsonlSink(path))
    lines = path.read_text().splitlines()
    assert len(lines) == 3
    # a crash after two cells, in the middle of writing the third line
    path.write_text(lines[0] + "\n" + lines[1] + "\n" + lines[2][: len(lines[2]) // 2])
    seen: list[int] = []
    again = run_atlas(spec, serial=True, sink=JsonlSink(path),
                      progress=lambda done, total, row: seen.append(done))
    assert again.summary.resumed == 2 and seen == [2, 3]
    assert [r.key for r in again.rows] == [r.key for r in first.rows]
    assert [r.results["mu_star"] for r in again.rows] == [r.results["mu_star"] for r in first.rows]
    good = []
    for line in path.read_text().splitlines():
        try:
            good.append(json.loads(line)["key"])
        except ValueError:
            pass
    assert sorted(good) == sorted(r.key for r in first.rows)  # each key once, torn line ignored
    # a third run computes nothing; a second put of a known key is refused
    sink = JsonlSink(path)
    third = run_atlas(spec, serial=True, sink=sink)
    assert third.summary.resumed == 3 and third.summary.engine.startswith("none")
    assert sink.put(first.rows[0]) is False


def test_a_failing_cell_is_a_row_with_its_error(tmp_path: Path) -> None:
    spec = parse_spec({"kind": "sweep", "cells": [{"manifest": "absent.csv"}]},
                      base_dir=tmp_path)
    res = run_atlas(spec, serial=True)
    (row,) = res.rows
    assert row.status == "failed" and row.results == {}
    assert row.error["parameter"] == "manifest" and "absent.csv" in row.error["value"]
    assert res.summary.failed == 1 and res.summary.ok == 0


def test_local_cluster_runs_the_cells_in_worker_processes_like_the_loop(tmp_path: Path) -> None:
    spec = parse_spec(ROD)
    serial = run_atlas(spec, serial=True)
    dask = run_atlas(spec, workers=2, sink=JsonlSink(tmp_path / "cells.jsonl"))
    assert dask.summary.ok == 2 and dask.summary.engine.startswith("dask tcp://127.0.0.1")
    assert all(r.worker.startswith("tcp://127.0.0.1:") for r in dask.rows)
    for a, b in zip(serial.rows, dask.rows):
        assert (a.key, a.index, a.results["transition"]) == (b.key, b.index,
                                                             b.results["transition"])
        assert b.results["mu_star"] == pytest.approx(a.results["mu_star"], abs=MU_ATOL)
    assert len((tmp_path / "cells.jsonl").read_text().splitlines()) == 2
    hm = heatmap(dask.rows, "slenderness", "actuation", "mu_star")
    assert hm.xs == (1e-3, 1e-2) and hm.ys == ("antisymmetric",)
    assert hm.values[0][0] == pytest.approx(serial.rows[0].results["mu_star"], abs=MU_ATOL)
    files = write_heatmaps(dask, "slenderness", "actuation", tmp_path)
    assert {f.name for f in files} == {"heatmap-mu_star.png", "heatmap-mu_star.csv",
                                       "heatmap-type.png", "heatmap-type.csv"}
    csv = (tmp_path / "heatmap-type.csv").read_text().splitlines()
    assert csv[0] == "actuation \\ slenderness,0.001,0.01"
    assert csv[1] == "antisymmetric,supercritical-pitchfork,supercritical-pitchfork"


def test_cli_atlas_json_and_errors(tmp_path: Path) -> None:
    spec = tmp_path / "beam.json"
    spec.write_text(json.dumps(BEAM))
    out = tmp_path / "out"
    r = subprocess.run([*SNAPWARN, "atlas", str(spec), "--serial", "--json", "--no-progress",
                        "--out", str(out)], capture_output=True, text=True, cwd=REPO,
                       env=env_one_thread(), timeout=300)  # fmt: skip
    assert r.returncode == 0, r.stderr
    doc = json.loads(r.stdout)
    assert doc["summary"]["ok"] == 3 and doc["varied"] == ["actuation"]
    assert [c["inputs"]["actuation"] for c in doc["cells"]] == BEAM["grid"]["actuation"]
    assert len((out / "cells.jsonl").read_text().splitlines()) == 3
    assert json.loads((out / "summary.json").read_text())["cells"] == 3
    bad = tmp_path / "bad.yaml"
    bad.write_text("kind: bifurcation\ngrid:\n  actuation: [asymmetric, sideways]\n")
    r = subprocess.run([*SNAPWARN, "atlas", str(bad), "--serial"], capture_output=True,
                       text=True, cwd=REPO, env=env_one_thread(), timeout=120)
    assert r.returncode == 2
    assert "grid.actuation[1]" in r.stderr and "'sideways'" in r.stderr


def test_time_bound_leaves_cells_missing_and_a_rerun_completes(tmp_path: Path) -> None:
    bounded = parse_spec({**BEAM, "timeout_s": 1e-9})
    sink = JsonlSink(tmp_path / "cells.jsonl")
    res = run_atlas(bounded, serial=True, sink=sink)
    assert res.summary.missing == 3 and len(res.missing) == 3 and res.rows == ()
    again = run_atlas(parse_spec(BEAM), serial=True, sink=JsonlSink(tmp_path / "cells.jsonl"))
    assert again.summary.missing == 0 and again.summary.ok == 3
