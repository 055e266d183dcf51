"""docker-compose.yml's dask cluster: same image, one thread per worker process, health checks,
and the job worker pointed at the scheduler (SNAPWARN_DASK_SCHEDULER)."""

from __future__ import annotations

import yaml
from _atlas_helpers import REPO


def test_compose_has_a_dask_scheduler_and_workers() -> None:
    doc = yaml.safe_load((REPO / "docker-compose.yml").read_text())
    svc = doc["services"]
    sched, work, jobs = svc["dask-scheduler"], svc["dask-worker"], svc["worker"]
    image = svc["api"]["image"]
    assert sched["image"] == work["image"] == image
    assert sched["command"][:2] == ["dask", "scheduler"] and "8786" in sched["command"]
    assert work["command"][:3] == ["dask", "worker", "tcp://dask-scheduler:8786"]
    assert work["command"][work["command"].index("--nthreads") + 1] == "1"
    assert work["deploy"]["replicas"] >= 2
    for s in (sched, work):
        hc = s["healthcheck"]
        assert hc["test"][0] == "CMD" and "/health" in hc["test"][-1] and hc["retries"] >= 1
        for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS",
                    "NUMBA_NUM_THREADS"):
            assert s["environment"][var] == "1"
    port = work["command"][work["command"].index("--dashboard-address") + 1].lstrip(":")
    assert f":{port}/health" in work["healthcheck"]["test"][-1]
    assert jobs["environment"]["SNAPWARN_DASK_SCHEDULER"] == "tcp://dask-scheduler:8786"
    assert jobs["depends_on"]["dask-scheduler"]["condition"] == "service_healthy"
    assert work["depends_on"]["dask-scheduler"]["condition"] == "service_healthy"
