"""Atlas engine: speed-up on 1 and 2 dask workers, and the engine's overhead per cell.

Two atlases, each run three ways in one process, warm (imports and numba caches loaded in the
loop's process and in every worker before the clock starts):

1. 16 Cosserat bifurcation cells of about 1 s each (asymmetric fold, n = 200 elements,
   h/L from 1e-3 to 1.6e-2): a plain loop, a LocalCluster of 1 worker, of 2 workers.
   The wall-time ratio 1 worker / 2 workers is the scaling (target >= 1.8 on 2 cores).
2. 200 Euler-beam bifurcation cells of about 2 ms: a plain loop and 1 worker. There the cell
   costs nothing, so (wall(1 worker) - wall(loop)) / cells is the engine's cost per cell:
   submit, schedule, run the task wrapper, send the result back, persist nothing.

The machine's load average is printed with the numbers, and a control: the cores that one and
two busy-loop processes obtain together (a shared or capped machine bounds any engine's
speed-up by that ratio).

    .venv/bin/python bench/atlas_scaling.py [--quick]

writes bench/results/atlas_scaling.json.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
# bench/service.py would shadow the service package: the repository root goes first
sys.path[:] = [str(ROOT)] + [p for p in sys.path if Path(p or ".").resolve() != ROOT / "bench"]

from service.atlas import JsonlSink, dask_client, parse_spec, run_atlas  # noqa: E402

OUT = ROOT / "bench" / "results"


def _warm() -> int:
    """Load the Cosserat and beam kernels in this process (numba caches, imports)."""
    from sim import cosserat
    from sim.euler_beam import bifurcation

    cosserat.bifurcation("asymmetric", elements=8, slenderness=1e-3)
    bifurcation("asymmetric")
    return os.getpid()


def _burn(seconds: float) -> float:
    """A busy loop: the CPU seconds this process obtained in ``seconds`` of wall time."""
    t0, c0 = time.perf_counter(), time.process_time()
    while time.perf_counter() - t0 < seconds:
        pass
    return time.process_time() - c0


def cores_obtainable(n: int, seconds: float = 4.0) -> float:
    """Cores that n busy processes obtain together right now (the machine's own limit)."""
    import multiprocessing as mp

    with mp.get_context("spawn").Pool(n) as pool:
        t0 = time.perf_counter()
        cpu = sum(pool.map(_burn, [seconds] * n))
        return cpu / (time.perf_counter() - t0)


def _spec(cells: int, kind: str) -> dict:
    if kind == "cosserat":
        return {"kind": "bifurcation", "name": "scaling-cosserat",
                "fixed": {"model": "cosserat", "actuation": "asymmetric", "elements": 200},
                "grid": {"slenderness": {"from": 1e-3, "to": 1.6e-2, "num": cells}}}  # fmt: skip
    # Euler-beam cells: the same computation in every cell, keyed apart by an unused
    # parameter (the rod's slenderness does not enter the beam model)
    return {"kind": "bifurcation", "name": "overhead-beam",
            "fixed": {"model": "euler-beam", "actuation": "asymmetric"},
            "grid": {"slenderness": {"from": 1e-4, "to": 1e-2, "num": cells}}}  # fmt: skip


def _timed(fn) -> tuple[float, object]:  # noqa: ANN001
    t0 = time.perf_counter()
    out = fn()
    return time.perf_counter() - t0, out


def measure(n_cells: int, n_tiny: int) -> dict:
    os.environ.update({"OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1"})
    heavy = parse_spec(_spec(n_cells, "cosserat"))
    tiny = parse_spec(_spec(n_tiny, "beam"))
    _warm()
    load0 = os.getloadavg()
    doc_control = {f"busy_{n}_cores": cores_obtainable(n) for n in (1, 2)}
    doc: dict = {"cells": n_cells, "tiny_cells": n_tiny, "cpus": os.cpu_count(),
                 "python": platform.python_version()}  # fmt: skip
    wall, res = _timed(lambda: run_atlas(heavy, serial=True))
    doc["loop_wall_s"] = wall
    doc["loop_cpu_s_sum"] = res.summary.cpu_seconds
    doc["loop_cell_s_median"] = res.summary.cell_seconds_median
    wall, res = _timed(lambda: run_atlas(tiny, serial=True))
    doc["tiny_loop_wall_s"] = wall
    for workers in (1, 2):
        with dask_client(workers=workers) as client:
            client.run(_warm)
            wall, res = _timed(lambda: run_atlas(heavy, client=client))  # noqa: B023
            assert res.summary.ok == n_cells, res.summary
            doc[f"dask{workers}_wall_s"] = wall
            doc[f"dask{workers}_cell_s_sum"] = res.summary.cell_seconds
            doc[f"dask{workers}_cpu_s_sum"] = res.summary.cpu_seconds
            # CPU-seconds of cells per wall second: the cores the atlas actually got
            doc[f"dask{workers}_cores_used"] = res.summary.cpu_seconds / wall
            doc[f"dask{workers}_workers_used"] = len(res.summary.workers)
            if workers == 1:
                wall, res = _timed(lambda: run_atlas(tiny, client=client))  # noqa: B023
                assert res.summary.ok == n_tiny
                doc["tiny_dask1_wall_s"] = wall
                doc["tiny_dask1_cell_s_sum"] = res.summary.cell_seconds
                with tempfile.TemporaryDirectory() as tmp:  # + one fsynced JSON line per cell
                    wall, res = _timed(lambda: run_atlas(  # noqa: B023
                        tiny, client=client, sink=JsonlSink(Path(tmp) / "cells.jsonl")))
                doc["tiny_dask1_jsonl_wall_s"] = wall
    doc.update(doc_control)
    doc["machine_ratio_2_over_1"] = doc["busy_2_cores"] / doc["busy_1_cores"]
    doc["load_average_before"] = list(load0)
    doc["load_average_after"] = list(os.getloadavg())
    doc["speedup_2_over_1"] = doc["dask1_wall_s"] / doc["dask2_wall_s"]
    doc["speedup_2_over_loop"] = doc["loop_wall_s"] / doc["dask2_wall_s"]
    tiny_extra = doc["tiny_dask1_wall_s"] - doc["tiny_loop_wall_s"]
    doc["overhead_per_cell_ms"] = 1e3 * tiny_extra / n_tiny
    jsonl_extra = doc["tiny_dask1_jsonl_wall_s"] - doc["tiny_loop_wall_s"]
    doc["overhead_per_cell_with_jsonl_ms"] = 1e3 * jsonl_extra / n_tiny
    doc["cores_used_ratio_2_over_1"] = doc["dask2_cores_used"] / doc["dask1_cores_used"]
    return doc


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true", help="8 heavy cells, 50 tiny cells")
    args = ap.parse_args()
    doc = measure(8 if args.quick else 16, 50 if args.quick else 200)
    OUT.mkdir(exist_ok=True)
    (OUT / "atlas_scaling.json").write_text(json.dumps(doc, indent=2) + "\n")
    la = doc["load_average_before"]
    print(f"{doc['cells']} Cosserat cells (median {doc['loop_cell_s_median']:.2f} s in the loop), "
          f"{doc['cpus']} CPUs, load average before {la[0]:.2f} {la[1]:.2f} {la[2]:.2f}, "
          f"after {doc['load_average_after'][0]:.2f}")
    print(f"  plain loop     {doc['loop_wall_s']:8.2f} s")
    for w in (1, 2):
        print(f"  dask {w} worker{'s' if w > 1 else ' '} {doc[f'dask{w}_wall_s']:8.2f} s   "
              f"(cells: {doc[f'dask{w}_cell_s_sum']:.2f} s wall, {doc[f'dask{w}_cpu_s_sum']:.2f} "
              f"s CPU; cores obtained {doc[f'dask{w}_cores_used']:.2f})")
    print(f"  speed-up 2 workers vs 1: {doc['speedup_2_over_1']:.2f}x (target >= 1.8); "
          f"vs the loop: {doc['speedup_2_over_loop']:.2f}x")
    print(f"{doc['tiny_cells']} Euler-beam cells: loop {doc['tiny_loop_wall_s']:.3f} s, "
          f"dask 1 worker {doc['tiny_dask1_wall_s']:.3f} s -> engine overhead "
          f"{doc['overhead_per_cell_ms']:.2f} ms per cell, "
          f"{doc['overhead_per_cell_with_jsonl_ms']:.2f} ms with the fsynced JSON-lines sink")
    print(f"  cores obtained, 2 workers / 1 worker: {doc['cores_used_ratio_2_over_1']:.2f}; "
          f"control: 1 busy process got {doc['busy_1_cores']:.2f} cores, 2 got "
          f"{doc['busy_2_cores']:.2f} (the machine allows {doc['machine_ratio_2_over_1']:.2f}x)")


if __name__ == "__main__":
    main()
