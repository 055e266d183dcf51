"""Helpers of the atlas tests (a module with a unique name: real processes, LocalCluster, dask)."""

from __future__ import annotations

import os
import socket
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
SNAPWARN = [sys.executable, "-c", "import sys; from service.cli import main; sys.exit(main())"]
ONE_THREAD = {"OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1",
              "NUMBA_NUM_THREADS": "1", "MPLBACKEND": "Agg"}
# mu* of the Cosserat rod moves by ~1e-10 from run to run: ARPACK (scipy's eigsh, used for the
# smallest Hessian eigenvalue) starts from a random vector drawn from a process-wide stream, so
# a result depends on what the process computed before. Comparisons allow 1e-8.
MU_ATOL = 1e-8


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def env_one_thread() -> dict[str, str]:
    env = dict(os.environ)
    env.update(ONE_THREAD)
    env["PYTHONPATH"] = str(REPO) + os.pathsep + env.get("PYTHONPATH", "")
    env.pop("SNAPWARN_DASK_SCHEDULER", None)
    return env
