"""The detector on lab records it did not make: the fundamental right, flagged, or silently wrong.

    python bench/lab_records.py --n 300 --n-single 40 --jobs 2   # the committed table
    python bench/lab_records.py --quick         # 30 per row, a smoke run
    python bench/lab_records.py --n 500 --seed 7 --jobs 2

Records come from the independent generator of tests/labrec (``labgen.draw_record``: a 2-3
mode structure kicked by a half-sine hammer of 2-30 ms, sampled at 1-5 kHz). Each row switches
one impairment on alone (``clean``: a noise-free displacement record with none of them; the
sensor rows ``velocity``/``acceleration``; ``pretrigger`` 2-30 % at rest; ``hum`` 0.5-10 % of
the peak at 50/60 Hz with harmonics; ``drift`` offset + ramp + slow wobble; ``noise`` 15-40
dB; ``clipping`` at 60-90 % of the range; ``repeats`` 1-2 more kicks), ``all`` switches every
one on with a random sensor. Record ``i`` of every row has the same structure (modes drawn
first from the seed ``(seed, i)``).

Every row but ``noise`` and ``all`` has a sensor's noise floor of 40 dB (per-sample SNR of the
peak, the clean end of the issue's range; :data:`FLOOR_DB`): noise-free records are not what
labs record, and today's detector spends 100-300 s on each (7-70 s at 60 dB), a timing finding
of its own.

``service.analysis.detect.detect`` runs with its default options on ``(y, dt)`` in seconds.
Outcomes per record: ``right`` (the fundamental's undamped rate ``sqrt|sigma^2|`` within 1 %
of the truth ``omega0``), ``withheld`` (no fundamental), ``flagged`` (wrong, with a warning
flag: one of the detector's ``WARNING_FLAGS``), ``silent`` (wrong with only descriptive flags:
``stationary_line``, ``clipped``, ``drift``... say what was done, not that the fundamental may
be wrong),
``error`` (an exception). ``picked`` says what a wrong fundamental was: ``mode2``/``mode3``
(a higher mode, within 2 %), ``hum`` (a mains line), ``slow`` (below the truth), ``other``.

Writes bench/results/lab_records.md (the table, the product's commit) and .csv (per record).
"""

from __future__ import annotations

import os

for _v in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

import argparse  # noqa: E402
import csv  # noqa: E402
import math  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from concurrent.futures import ProcessPoolExecutor  # noqa: E402
from pathlib import Path  # noqa: E402
from typing import Any  # noqa: E402

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
for _p in (ROOT, ROOT / "tests" / "labrec"):
    if str(_p) not in sys.path:
        sys.path.insert(0, str(_p))

import labgen  # noqa: E402

from service.analysis.detect import WARNING_FLAGS, detect  # noqa: E402

#: Every row but ``noise`` and ``all`` carries a sensor's noise floor at this per-sample SNR:
#: today's detector takes 100-300 s per noise-free record and 7-70 s at 60 dB (2 cores shared
#: by 7 sessions), which makes 1000 records a matter of hours.
FLOOR_DB = 40.0
OFF: dict[str, Any] = {**{k: False for k in labgen.IMPAIRMENTS}, "noise": FLOOR_DB}
ROWS: dict[str, dict[str, Any]] = {
    "clean": {**OFF, "quantity": "displacement"},
    "velocity": {**OFF, "quantity": "velocity"},
    "acceleration": {**OFF, "quantity": "acceleration"},
    **{k: {**OFF, k: True, "quantity": "displacement"} for k in labgen.IMPAIRMENTS},
    "all": {k: True for k in labgen.IMPAIRMENTS},
}
TOL = 0.01
OUTCOMES = ("right", "withheld", "flagged", "silent", "error")
#: Warnings that say the fundamental may be wrong without saying which part of the record is
#: in doubt: a wrong fundamental warned only by these is also counted apart ("soft").
SOFT_FLAGS = frozenset({"nonlinear"})


def _picked(f_det: float, rec: labgen.LabRecord) -> str:
    f = rec.modes.f0_hz
    for k in range(1, len(f)):
        if abs(f_det / f[k] - 1) < 0.02:
            return f"mode{k + 1}"
    if rec.lab.hum > 0:
        for h, _ in labgen.hum_lines(rec.lab):
            if abs(f_det / h - 1) < 0.02:
                return "hum"
    return "slow" if f_det < f[0] else "other"


def one(row: str, seed: int, i: int) -> dict[str, Any]:
    """Draw record ``i`` of ``row`` and run the detector on it."""
    rec = labgen.draw_record(np.random.default_rng([seed, i]), **ROWS[row])
    tr = rec.truth
    out: dict[str, Any] = {"row": row, "i": i, **labgen.settings(rec),
                           "f1_hz": rec.modes.f0_hz[0], "zeta": tr.zeta}  # fmt: skip
    t0 = time.perf_counter()
    try:
        det = detect(rec.y, dt=rec.dt)
    except Exception as exc:  # noqa: BLE001 - an exception is an outcome here
        out.update(outcome="error", picked=type(exc).__name__, flags=str(exc)[:80],
                   f_det_hz=math.nan, rel_err=math.nan, time_ms=math.nan)  # fmt: skip
        return out
    out["time_ms"] = 1e3 * (time.perf_counter() - t0)
    codes = det.flag_codes
    out["flags"] = " ".join(codes)
    fund = det.fundamental
    if fund is None:
        out.update(outcome="withheld", picked="none", f_det_hz=math.nan, rel_err=math.nan)
        return out
    f_det = math.sqrt(abs(fund.sigma2)) / (2 * math.pi)
    rel = f_det * 2 * math.pi / tr.omega0 - 1
    out.update(f_det_hz=f_det, rel_err=rel)
    if abs(rel) <= TOL:
        out.update(outcome="right", picked="fundamental")
    else:
        warned = any(c in WARNING_FLAGS for c in codes)
        out.update(outcome="flagged" if warned else "silent", picked=_picked(f_det, rec))
    return out


def _one(args: tuple[str, int, int]) -> dict[str, Any]:
    return one(*args)


def _run(tasks: list[tuple[str, int, int]], jobs: int, path: Path) -> list[dict[str, Any]]:
    """Run every task, writing the CSV as results arrive (progress on stderr)."""
    rows: list[dict[str, Any]] = []
    with open(path, "w", newline="") as fh:
        writer: csv.DictWriter | None = None
        pool = ProcessPoolExecutor(jobs) if jobs > 1 else None
        results = pool.map(_one, tasks, chunksize=2) if pool else map(_one, tasks)
        try:
            for k, r in enumerate(results, 1):
                if writer is None:
                    writer = csv.DictWriter(fh, fieldnames=list(r))
                    writer.writeheader()
                writer.writerow(r)
                fh.flush()
                rows.append(r)
                if k % 10 == 0 or k == len(tasks):
                    print(f"{k}/{len(tasks)} {r['row']}", file=sys.stderr, flush=True)
        finally:
            if pool:
                pool.shutdown()
    return rows


def _read(path: Path) -> list[dict[str, Any]]:
    with open(path, newline="") as fh:
        rows: list[dict[str, Any]] = list(csv.DictReader(fh))
    for r in rows:
        r["time_ms"] = float(r["time_ms"] or "nan")
    return rows


def _commit() -> str:
    def git(*a: str) -> str:
        return subprocess.run(["git", "-C", str(ROOT), *a], capture_output=True, text=True,
                              check=False).stdout.strip()  # fmt: skip

    head = git("rev-parse", "--short=12", "HEAD")
    dirty = git("status", "--porcelain", "--", "service", "sim")
    return head + (" (service/ or sim/ modified)" if dirty else "")


def table(rows: list[dict[str, Any]]) -> str:
    """The markdown table: per row the fractions of each outcome and the median time."""
    lines = ["| records | n | right | withheld | wrong, flagged | silent wrong | error | "
             "wrong, soft flags only | wrong picks (most common) | median ms |",
             "|---|---:|---:|---:|---:|---:|---:|---:|---|---:|"]  # fmt: skip
    for name in ROWS:
        sel = [r for r in rows if r["row"] == name]
        if not sel:
            continue
        n = len(sel)
        frac = {o: sum(r["outcome"] == o for r in sel) / n for o in OUTCOMES}
        picks: dict[str, int] = {}
        for r in sel:
            if r["outcome"] not in ("right",):
                picks[r["picked"]] = picks.get(r["picked"], 0) + 1
        top = ", ".join(f"{k} {v}" for k, v in sorted(picks.items(), key=lambda kv: -kv[1])[:3])
        times = [r["time_ms"] for r in sel if math.isfinite(r["time_ms"])]
        med = f"{np.median(times):.0f}" if times else "-"
        soft = sum(r["outcome"] == "flagged"
                   and not (set(r["flags"].split()) & WARNING_FLAGS) - SOFT_FLAGS
                   for r in sel) / n  # fmt: skip
        cells = " | ".join(f"{100 * frac[o]:.1f} %" for o in OUTCOMES)
        lines.append(f"| {name} | {n} | {cells} | {100 * soft:.1f} % | {top or '-'} | {med} |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--n", type=int, default=300, help="records per row (default 300)")
    ap.add_argument("--seed", type=int, default=2026)
    ap.add_argument(
        "--n-single",
        type=int,
        default=None,
        help="records per row of one impairment (default: --n)",
    )
    ap.add_argument("--quick", action="store_true", help="30 records per row")
    ap.add_argument("--jobs", type=int, default=1, help="worker processes (default 1)")
    ap.add_argument("--rows", default=",".join(ROWS), help="comma-separated rows to run")
    ap.add_argument("--only", default="",
                    help="comma-separated record indices to run (re-checking chosen records; "
                         "the CSV gives each record's flags, pick and error)")  # fmt: skip
    ap.add_argument(
        "--table-only",
        action="store_true",
        help="rewrite the .md from the existing .csv (a run stopped early)",
    )
    ap.add_argument("--out", default=str(ROOT / "bench" / "results" / "lab_records"),
                    help="output path without suffix (.md and .csv are written)")  # fmt: skip
    args = ap.parse_args(argv)
    n = 30 if args.quick else args.n
    n1 = 30 if args.quick else (args.n_single or n)
    names = [r for r in args.rows.split(",") if r]
    bad = [r for r in names if r not in ROWS]
    if bad:
        ap.error(f"--rows: unknown {bad} (rows: {list(ROWS)})")
    # record-major order: a run stopped early has every row equally far
    tasks = [(row, args.seed, i) for i in range(max(n, n1)) for row in names
             if i < (n if row == "all" else n1)]  # fmt: skip
    if args.only:
        keep = {int(v) for v in args.only.split(",") if v}
        tasks = [t for t in tasks if t[2] in keep]
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    commit = _commit()  # the code measured: read before the run (the worktree may move on)
    t0 = time.perf_counter()
    if args.table_only:
        rows = _read(out.with_suffix(".csv"))
        n, n1 = (sum(r["row"] == k for r in rows) for k in ("all", "clean"))
    else:
        rows = _run(tasks, args.jobs, out.with_suffix(".csv"))
    wall = time.perf_counter() - t0
    cmd = "python bench/lab_records.py " + " ".join(argv if argv is not None else sys.argv[1:])
    text = (
        "# The detector on independent lab records\n\n"
        f"Product commit: `{commit}`. Command: `{cmd.strip()}` "
        f"({n} records in `all`, {n1} per other row, seed {args.seed}, {wall:.0f} s wall on "
        f"{args.jobs} process(es)).\n\n"
        "Records: tests/labrec/labgen.py (`draw_record`); the detector: "
        "`service.analysis.detect.detect(y, dt=dt)` with its defaults. `right`: "
        f"`sqrt|sigma^2|` within {100 * TOL:g} % of the true undamped rate; `withheld`: no "
        "fundamental; `wrong, flagged`: wrong with a warning flag (the detector's "
        f"`WARNING_FLAGS`: {', '.join(sorted(WARNING_FLAGS))}); `silent wrong`: wrong with "
        "only descriptive flags (what was done: `stationary_line`, `clipped`, `drift`, "
        "`repeated_kick`, `combination_tone`...); `wrong, soft flags only`: the part of "
        "`wrong, flagged` whose only warning is `nonlinear`. Rows: one impairment alone on a "
        "displacement record with a "
        f"{FLOOR_DB:g} dB noise floor (`clean`: none), the two other sensors alone, and "
        "`all` impairments with a random sensor. See the module docstring for the ranges; "
        "per-record results in lab_records.csv.\n\n" + table(rows) + "\n"
    )  # fmt: skip
    out.with_suffix(".md").write_text(text)
    print(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
