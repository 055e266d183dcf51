"""Blind trials: the product on structures and labs nobody on the team tuned it on.

    python bench/blind.py --seeds 2                 # every family x plan, 2 campaigns each
    python bench/blind.py --families arch_fold --plans lab --seeds 1   # one cell, a smoke run
    python bench/blind.py --seeds 2 --out bench/results/blind

Campaigns come from tests/blind (``_blind_sweeps.campaign(family, plan, seed)``: shallow
arches perfect and imperfect, a column on an elastic foundation, a three-link column; lab
records at 500 Hz - 20 kHz with a double-exponential hammer, a geophone or a laser in inches or
degrees, 60 Hz hum, a 12-bit ADC, mid-ring starts; uneven steps with a repeat, sweeps that stop
at ``T/T0 = 1.6`` and sweeps with one record past the transition). Each is written to a
temporary folder and run through ``snapwarn sweep MANIFEST --json`` (a subprocess, one at a
time unless ``--jobs``), then judged by ``_blind_trials.judge``.

Prints, per family and plan: campaigns, right type / withheld / named early / wrong type,
intervals covering the truth, confident errors (a wrong type, or a miss with no caution flag),
records set aside or flagged wrongly, detector misreads, median |error| in interval widths.
Writes ``OUT.md`` (the table and every failure with its reproduction) and ``OUT.csv``.
"""

from __future__ import annotations

import argparse
import ast
import csv
import math
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests" / "blind"))

import _blind_sweeps as S  # noqa: E402
import _blind_trials as T  # noqa: E402


def _detector_table(n: int, out: Path | None) -> None:
    rows = []
    for row in T.DETECTOR_ROWS:
        for i in range(n):
            rows.append(T.detect_one(row, i))
            r = rows[-1]
            print(f"{row}/{i} {r['family']}: {r['outcome']} f_true {r['f_true_hz']:.4g} Hz "
                  f"f_det {r.get('f_det_hz', float('nan')):.4g} Hz ({r['samples']} samples) "
                  f"{r['flags']}", flush=True)  # fmt: skip
    lines = ["| row | n | right | withheld | wrong, flagged | wrong, SILENT | error |",
             "|---|---|---|---|---|---|---|"]
    for row in T.DETECTOR_ROWS:
        rs = [r for r in rows if r["row"] == row]
        c = {k: sum(r["outcome"] == k for r in rs) for k in ("right", "withheld", "flagged",
                                                            "silent", "error")}  # fmt: skip
        lines.append(f"| {row} | {len(rs)} | {c['right']} | {c['withheld']} | {c['flagged']} | "
                     f"{c['silent']} | {c['error']} |")
    table = "\n".join(lines)
    print(table)
    if out is not None:
        commit = subprocess.run(["git", "-C", str(ROOT), "rev-parse", "--short", "HEAD"],
                                capture_output=True, text=True).stdout.strip()  # fmt: skip
        with open(out.with_suffix(".csv"), "w", newline="") as fh:
            w = csv.DictWriter(fh, fieldnames=sorted({k for r in rows for k in r}))
            w.writeheader()
            w.writerows(rows)
        out.with_suffix(".md").write_text(
            f"# Blind records through the detector (commit {commit})\n\n"
            f"`python bench/blind.py --detector {n} --out {out}`: per row, {n} records of the "
            "blind lab (families " + ", ".join(T.DETECTOR_FAMILIES) + ", whose critical mode is "
            "the lowest line; a random control of a lab sweep; a 10 % pre-trigger unless "
            "`midring`), `service.analysis.detect.detect(y, dt)`. right: the fundamental's "
            "sqrt|sigma2| within 1 % of the critical mode's; wrong, flagged: with one of "
            "`WARNING_FLAGS`; wrong, SILENT: without.\n\n" + table + "\n")


#: a sweep that has not answered after this long is recorded as no answer (``--timeout``)
TIMEOUT_S = 900.0
#: ``OUT.partial.csv`` while a run with ``--out`` goes on
PARTIAL: Path | None = None
_LOCK = threading.Lock()
OVER: dict = {}  # --over key=value: the lab's recording (or damping) for every campaign


def _one(family: str, plan: str, seed: int, folder: Path) -> dict:
    camp = S.campaign(family, plan, seed, **OVER)
    truth = camp.write(folder / f"{family}_{plan}_{seed}")
    try:
        ans = T.cli_sweep(truth.manifest, timeout=TIMEOUT_S)
    except subprocess.TimeoutExpired:  # a door that does not answer: counted, the bench goes on
        ans = T.Answer("cli", False, error=f"no answer within {TIMEOUT_S:.0f} s",
                       seconds=TIMEOUT_S)  # fmt: skip
    v = T.judge(ans, truth)
    # the predictor alone on the exact measurements (0.1 % noise, static levels given)
    try:
        pa = T.cli_predict(truth.write_table(truth.manifest.parent / "table.csv"))
    except subprocess.TimeoutExpired:
        pa = T.Answer("predict", False, error="no answer within 600 s")
    pv = T.judge(pa, truth)
    row = {
        "family": family, "plan": plan, "seed": seed, "truth_kind": truth.kind,
        "mu_star": truth.mu_star, "t_ratio_last": truth.t_ratio_last,
        "n_records": len(truth.names), "said": ans.transition if ans.ok else f"ERROR {ans.error}",
        "mu_star_said": ans.mu_star, "lo": None if ans.interval is None else ans.interval[0],
        "hi": None if ans.interval is None else ans.interval[1], "verdict": v.type,
        "covered": v.covered, "err_widths": v.err_widths, "confident": v.confident,
        "late": v.late,
        "flags": " ".join(ans.flags), "problems": " | ".join(v.problems),
        "detector": " | ".join(v.bad_records), "seconds": round(ans.seconds, 1),
        "predict_said": pa.transition if pa.ok else f"ERROR {pa.error}",
        "predict_lo": None if pa.interval is None else pa.interval[0],
        "predict_hi": None if pa.interval is None else pa.interval[1],
        "predict_verdict": pv.type, "predict_covered": pv.covered,
        "predict_confident": pv.confident, "predict_flags": " ".join(pa.flags),
        "params": repr(truth.params),
        "repro": (f"python tests/blind/_blind_sweeps.py {family} {plan} {seed} "
                  f"/tmp/blind/{family}_{plan}_{seed} {_over_args()} && snapwarn sweep "
                  f"/tmp/blind/{family}_{plan}_{seed}/manifest.csv --json"),
    }  # fmt: skip
    _print(row)
    if PARTIAL is not None:  # each row as soon as it is known: a run that dies keeps its rows
        with _LOCK, open(PARTIAL, "a", newline="") as fh:
            w = csv.DictWriter(fh, fieldnames=list(row))
            if fh.tell() == 0:
                w.writeheader()
            w.writerow(row)
    return row


def _over_args() -> str:
    return " ".join(f"'{k}={v!r}'" for k, v in OVER.items())


def _print(r: dict) -> None:
    flag = "CONFIDENT " if r["confident"] else ""
    print(f"{r['family']}/{r['plan']}/{r['seed']}: {flag}{r['verdict']} said {r['said']} "
          f"[{r['lo']}, {r['hi']}] truth {r['truth_kind']} {r['mu_star']:.8g} "
          f"T/T0={r['t_ratio_last']:.2f} ({r['seconds']} s) {r['problems']} {r['detector']}; "
          f"predictor alone: {r['predict_verdict']} {r['predict_said']} "
          f"[{r['predict_lo']}, {r['predict_hi']}] covered={r['predict_covered']}",
          flush=True)  # fmt: skip


def _from_csv(path: Path) -> list[dict]:
    """Rows of a previous run's CSV with their types back (for ``--table-from``)."""
    def val(k: str, x: str):  # noqa: ANN202
        if x in ("True", "False"):
            return x == "True"
        if k in ("mu_star", "lo", "hi", "err_widths", "t_ratio_last", "seconds", "mu_star_said",
                 "predict_lo", "predict_hi"):
            return None if x == "" else float(x)
        return x

    with open(path, newline="") as fh:
        rows = [{k: val(k, v) for k, v in r.items()} for r in csv.DictReader(fh)]
    for r in rows:
        r["seed"] = int(r["seed"])
        if r.get("late") is None:
            r["late"] = r["lo"] is not None and r["lo"] > r["mu_star"]
    return rows


def _table(rows: list[dict]) -> str:
    head = ("| family | plan | n | right | withheld | early | wrong | covered | confident "
            "errors | late misses | record problems | detector misreads | median abs err "
            "(widths) | predictor alone: right/withheld/wrong | predictor alone: covered |")
    out = [head, "|" + "---|" * 15]
    keys = sorted({(r["family"], r["plan"]) for r in rows},
                  key=lambda k: (S.FAMILIES.index(k[0]), S.PLANS.index(k[1])))  # fmt: skip
    tot = {k: 0 for k in ("n", "right", "withheld", "early", "wrong", "no-answer", "cov", "conf",
                          "rec", "det", "late")}  # fmt: skip
    for fam, plan in keys:
        rs = [r for r in rows if r["family"] == fam and r["plan"] == plan]
        c = {k: sum(r["verdict"] == k for r in rs) for k in ("right", "withheld", "early",
                                                            "wrong", "no-answer")}  # fmt: skip
        cov = sum(bool(r["covered"]) for r in rs)
        conf = sum(bool(r["confident"]) for r in rs)
        late = sum(bool(r["late"]) for r in rs)
        rec = sum(("set aside" in r["problems"] or "past_transition" in r["problems"])
                  for r in rs)  # fmt: skip
        det = sum(bool(r["detector"]) for r in rs)
        errs = [abs(r["err_widths"]) for r in rs if r["err_widths"] is not None
                and math.isfinite(r["err_widths"])]  # fmt: skip
        med = f"{statistics.median(errs):.2f}" if errs else "-"
        wrong = c["wrong"] + c["no-answer"]
        pr = sum(r.get("predict_verdict") == "right" for r in rs)
        pw = sum(r.get("predict_verdict") == "withheld" for r in rs)
        px = len(rs) - pr - pw
        pc = sum(bool(r.get("predict_covered")) for r in rs)
        out.append(f"| {fam} | {plan} | {len(rs)} | {c['right']} | {c['withheld']} | "
                   f"{c['early']} | {wrong} | {cov}/{len(rs)} | {conf} | {late} | {rec} | "
                   f"{det} | {med} | {pr}/{pw}/{px} | {pc}/{len(rs)} |")
        for k in ("right", "withheld", "early", "wrong", "no-answer"):
            tot[k] += c[k]
        tot["n"] += len(rs)
        tot["cov"] += cov
        tot["conf"] += conf
        tot["late"] += late
        tot["rec"] += rec
        tot["det"] += det
    out.append(f"| **all** | | {tot['n']} | {tot['right']} | {tot['withheld']} | {tot['early']} | "
               f"{tot['wrong'] + tot['no-answer']} | {tot['cov']}/{tot['n']} | {tot['conf']} | "
               f"{tot['late']} | "
               f"{tot['rec']} | {tot['det']} | | | |")
    return "\n".join(out)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--families", default=",".join(S.FAMILIES))
    ap.add_argument("--plans", default=",".join(S.PLANS))
    ap.add_argument("--seeds", type=int, default=2)
    ap.add_argument("--seed0", type=int, default=0)
    ap.add_argument("--jobs", type=int, default=1)
    ap.add_argument("--out", default=None, help="write OUT.md and OUT.csv")
    ap.add_argument("--detector", type=int, default=0, metavar="N",
                    help="instead: N records per impairment row through the detector alone")
    ap.add_argument("--table-from", default=None, metavar="CSV",
                    help="only print (and with --out write) the table of a previous run's CSV")
    ap.add_argument("--over", action="append", default=[], metavar="KEY=VALUE",
                    help="override the lab's recording for every campaign (a Python literal: "
                         "damping=0.3, second_hit=(0.25,0.5), sensor='accel', unit='g')")
    ap.add_argument("--timeout", type=float, default=900.0,
                    help="seconds one sweep may take before it counts as no answer (900)")
    a = ap.parse_args()
    global TIMEOUT_S, PARTIAL
    TIMEOUT_S = a.timeout
    if a.out and not a.table_from and not a.detector:
        PARTIAL = Path(a.out).with_suffix(".partial.csv")
        PARTIAL.unlink(missing_ok=True)
    for kv in a.over:
        k, v = kv.split("=", 1)
        OVER[k] = ast.literal_eval(v)
    if a.detector:
        sys.path.insert(0, str(ROOT))
        _detector_table(a.detector, Path(a.out) if a.out else None)
        return
    if a.table_from:
        rows = _from_csv(Path(a.table_from))
        print(_table(rows))
        if a.out:
            _write(rows, a, Path(a.out), note=f"(table of {a.table_from})")
        return
    cells = [(f, p, s) for f in a.families.split(",") for p in a.plans.split(",")
             for s in range(a.seed0, a.seed0 + a.seeds)]  # fmt: skip
    t0 = time.time()
    with tempfile.TemporaryDirectory(prefix="blind-") as tmp:
        with ThreadPoolExecutor(a.jobs) as ex:
            rows = list(ex.map(lambda c: _one(*c, Path(tmp)), cells))
    print(_table(rows))
    print(f"({len(rows)} campaigns, {time.time() - t0:.0f} s wall)")
    if a.out:
        _write(rows, a, Path(a.out), note=f"{time.time() - t0:.0f} s wall")
        if PARTIAL is not None:
            PARTIAL.unlink(missing_ok=True)


def _write(rows: list[dict], a: argparse.Namespace, out: Path, note: str) -> None:
    """``OUT.csv`` (every row) and ``OUT.md`` (the table, every failure with its
    reproduction, and the predictor-alone failures)."""
    commit = subprocess.run(["git", "-C", str(ROOT), "rev-parse", "--short", "HEAD"],
                            capture_output=True, text=True).stdout.strip()  # fmt: skip
    if not a.table_from:
        with open(out.with_suffix(".csv"), "w", newline="") as fh:
            w = csv.DictWriter(fh, fieldnames=list(rows[0]))
            w.writeheader()
            w.writerows(rows)
    fails = [r for r in rows if r["verdict"] in ("wrong", "early", "no-answer")
             or not r["covered"] or r["problems"]]  # fmt: skip
    cmd = (f"python bench/blind.py --seeds {a.seeds} --seed0 {a.seed0} --families {a.families} "
           f"--plans {a.plans}" + "".join(f" --over {k}={v!r}" for k, v in OVER.items()))
    lines = [f"# Blind trials (commit {commit})", "",
             f"`{cmd}`: {len(rows)} campaigns through `snapwarn sweep --json` ({note}); each "
             "campaign's exact measurements (0.1 % noise, static levels given) also through "
             "`snapwarn predict --json` (the predictor alone).", "",
             "Columns: right/withheld/early/wrong = the type verdict (`early`: a correct name on "
             "a sweep stopped at T/T0 = 1.6, where it must be withheld); covered = the 95 % "
             "interval holds the true mu*; confident errors = a wrong type, or a miss with no "
             "caution flag; late misses = the whole interval beyond the truth; record problems "
             "= an untrusted record (snapped branch, growing) neither set aside by name nor "
             "reported past the transition; detector misreads = campaigns where a usable "
             "record's fundamental sigma2 is off the critical mode's by > 10 %.", "",
             _table(rows), "", "## Failures of the sweep (each reproducible)", ""]  # fmt: skip
    for r in fails:
        lines += [f"- **{r['family']}/{r['plan']}/seed {r['seed']}** ({r['params']}): said "
                  f"`{r['said']}` mu* {r['mu_star_said']} [{r['lo']}, {r['hi']}], flags "
                  f"`{r['flags']}`; truth {r['truth_kind']} {r['mu_star']!r} (T/T0 at the "
                  f"last stable record {r['t_ratio_last']:.2f}). Problems: {r['problems']}. "
                  f"Detector: {r['detector'] or 'every usable record on the critical mode'}. "
                  f"Predictor alone on the exact table: {r['predict_said']} "
                  f"[{r['predict_lo']}, {r['predict_hi']}]. Reproduce: `{r['repro']}`"]
    pf = [r for r in rows if r.get("predict_verdict") not in ("right", "withheld")
          or not r.get("predict_covered")]  # fmt: skip
    lines += ["", "## Failures of the predictor alone on exact measurements", ""]
    for r in pf:
        lines += [f"- **{r['family']}/{r['plan']}/seed {r['seed']}**: `snapwarn predict "
                  f"table.csv` said `{r['predict_said']}` [{r['predict_lo']}, {r['predict_hi']}]"
                  f" flags `{r['predict_flags']}`; truth {r['truth_kind']} {r['mu_star']!r}. "
                  f"Reproduce: `python tests/blind/_blind_sweeps.py {r['family']} {r['plan']} "
                  f"{r['seed']} /tmp/blind/t && snapwarn predict /tmp/blind/t/table.csv --json`"]
    if not pf:
        lines.append("none")
    out.with_suffix(".md").write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
