"""CPU time of the command line's first steps: ``snapwarn --help`` and a warm ``snapwarn detect``
of a 2,000-sample CSV (the numba cache already filled), user + sys of the whole process.

    python bench/cli_startup.py                       # 5 runs each, this tree
    python bench/cli_startup.py --baseline ef78811    # and a git revision, interleaved

Each command runs in a fresh interpreter (``subprocess``); its CPU time is the children's
``getrusage`` difference, so the figure is the work done whatever else runs on the machine (the
load average is printed). With ``--baseline REV`` the revision's ``service`` and ``sim`` are
extracted to a temporary directory and put first on ``PYTHONPATH``; one untimed run fills its
numba cache, then the two trees alternate run by run. Both trees get their bytecode written
first (``compileall``, as ``make setup`` does). Targets (issue 31): detect <= 0.5 s,
``--help`` <= 0.3 s. Writes bench/results/cli_startup.json.
"""

from __future__ import annotations

import argparse
import io
import json
import os
import resource
import statistics
import subprocess
import sys
import tarfile
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "bench" / "results"
SNAPWARN = [sys.executable, "-c", "import sys; from service.cli import main; sys.exit(main())"]


def record(path: Path) -> None:
    """The record of tests/test_cli_imports.py: 2,000 samples, one ringing mode, a static level."""
    t = np.arange(2000) * 0.01
    w = 0.2 + np.exp(-0.1 * t) * np.cos(6 * t) + 1e-3 * np.random.default_rng(0).normal(size=t.size)
    np.savetxt(path, np.c_[t, w], delimiter=",", header="t,w", comments="")


def cpu_of(argv: list[str], env: dict[str, str], cwd: Path) -> float:
    """User + sys seconds of one run of ``argv`` (a fresh interpreter)."""
    r0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    r = subprocess.run(argv, env=env, cwd=cwd, capture_output=True, text=True, timeout=600)
    r1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    if r.returncode != 0:
        raise SystemExit(f"{argv[3:]} failed: {r.stderr[-400:]}")
    return (r1.ru_utime - r0.ru_utime) + (r1.ru_stime - r0.ru_stime)


def extract(rev: str, where: Path) -> Path:
    """``service`` and ``sim`` of git revision ``rev`` under ``where``."""
    data = subprocess.run(["git", "-C", str(ROOT), "archive", rev, "service", "sim"],
                          capture_output=True, check=True).stdout  # fmt: skip
    with tarfile.open(fileobj=io.BytesIO(data)) as tar:
        tar.extractall(where, filter="data")
    compile_bytecode(where)
    return where


def compile_bytecode(tree: Path) -> None:
    """Python's bytecode of ``tree``'s ``service`` and ``sim``, as ``make setup`` writes it (where
    PYTHONDONTWRITEBYTECODE is set, a tree without it compiles every module on every run)."""
    subprocess.run([sys.executable, "-m", "compileall", "-q", "service", "sim"], cwd=tree,
                   capture_output=True, check=True)  # fmt: skip


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--runs", type=int, default=5)
    ap.add_argument("--baseline", default=None, help="git revision measured alongside")
    args = ap.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        tmpd = Path(tmp)
        rec = tmpd / "r.csv"
        record(rec)
        trees = {"this tree": ROOT}
        compile_bytecode(ROOT)
        if args.baseline:
            trees[args.baseline] = extract(args.baseline, tmpd / "base")
        commands = {"--help": ["--help"], "detect r.csv": ["detect", str(rec)]}
        envs = {name: dict(os.environ, PYTHONPATH=str(path)) for name, path in trees.items()}
        for name in trees:  # untimed: fills a fresh tree's numba cache
            cpu_of(SNAPWARN + commands["detect r.csv"], envs[name], tmpd)
        runs: dict[str, dict[str, list[float]]] = {n: {c: [] for c in commands} for n in trees}
        for _ in range(args.runs):
            for c, extra in commands.items():
                for name in trees:
                    runs[name][c].append(cpu_of(SNAPWARN + extra, envs[name], tmpd))
    load = os.getloadavg()
    doc = {
        "runs": args.runs,
        "cpu_s_median": {
            n: {c: statistics.median(v) for c, v in r.items()} for n, r in runs.items()
        },
        "cpu_s_all": runs,
        "targets_s": {"--help": 0.3, "detect r.csv": 0.5},
        "load_average": list(load),
        "cpus": os.cpu_count(),
        "python": sys.version.split()[0],
    }
    RESULTS.mkdir(parents=True, exist_ok=True)
    (RESULTS / "cli_startup.json").write_text(json.dumps(doc, indent=2) + "\n")
    print(f"CLI start-up, user + sys CPU per run (median of {args.runs}; load average "
          f"{load[0]:.2f} {load[1]:.2f} {load[2]:.2f} on {os.cpu_count()} cpus)")
    for name, r in runs.items():
        cells = "   ".join(f"{c} {statistics.median(v):.2f} s" for c, v in r.items())
        print(f"  {name:12s} {cells}")
    print("  targets: --help <= 0.3 s, detect <= 0.5 s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
