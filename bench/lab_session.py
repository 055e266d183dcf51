"""One lab session that follows the advice: control, interval and alarm against record number.

    python bench/lab_session.py [--kind saddle-node] [--seed 1] [--bad-at 5]

The structure, its lab and the loop are tests/live/_lab_loop.py's (the independent generator
of tests/labrec; the same draws and the same loop as tests/live/test_lab_in_the_loop.py, which
runs them over HTTP): the lab starts at 0 deg with its step of 4 deg, records where the live
sweep (:mod:`service.analysis.live`, the one sweep policy) advises, with the record length it
suggests, and stops when the sweep says converged, gives no safe step, or after 30 records.
``--bad-at K`` replaces record K (0-based) by a missed hammer (noise alone).

Writes bench/results/lab_session[_<kind>][_bad].csv and docs/figures/lab_session[...].png (the
figure of docs/lab-guide.md).

    python bench/lab_session.py --ten-labs [--seeds 1-10]

runs the ten-lab sessions instead (each type, each seed, clean and with a missed hammer at
record 6: the cells of tests/live/test_lab_in_the_loop.py, in process), prints one line a
session and the criteria met per cell, and writes bench/results/lab_sessions.csv.
"""

from __future__ import annotations

import argparse
import csv
import math
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tests" / "live"))

import _lab_loop as LL  # noqa: E402

from service.analysis import live  # noqa: E402
from service.analysis.alarm import ALARM_LEVELS  # noqa: E402

OUT = ROOT / "bench" / "results"
FIGURES = ROOT / "docs" / "figures"
campaign = LL.campaign  # the structure and lab of tests/live/test_lab_in_the_loop.py


def session(camp: LL.F.Campaign, bad_at: int | None) -> list[dict]:
    """The lab of tests/live/_lab_loop.py following the live sweep in process; one row a
    record."""
    plan = live.LivePlan(step=LL.STEP)
    recs: list = []
    rows: list[dict] = []

    def add(k: int, y: np.ndarray, dt: float, mu: float) -> LL.Answer:
        u = live.update(recs, y, dt=dt, control=mu, plan=plan, time_unit="s")
        recs.append(u.record)
        p = u.prediction
        lo, hi = p.mu_star_interval if p is not None else (math.nan, math.nan)
        rows.append({"record": k + 1, "control": mu, "lo": lo, "hi": hi,
                     "mu_star": p.mu_star if p is not None else math.nan,
                     "level": u.alarm.level, "rank": u.alarm.rank,
                     "next": u.next_control, "set_aside": u.n_set_aside,
                     "converged": u.converged, "duration": (y.size - 1) * dt})  # fmt: skip
        return LL.Answer(u, u.converged, u.next_control, u.record_duration, u.record_dt)

    LL.follow(camp, add, bad_at)
    return rows


def figure(rows: list[dict], camp: LL.F.Campaign, path: Path, bad_at: int | None) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    k = np.array([r["record"] for r in rows])
    fig, (ax, ax2) = plt.subplots(2, 1, figsize=(8, 6.5), sharex=True,
                                  gridspec_kw={"height_ratios": [3, 1]})  # fmt: skip
    lo, hi = np.array([r["lo"] for r in rows]), np.array([r["hi"] for r in rows])
    ax.fill_between(k, lo, np.minimum(hi, 1.5 * camp.mu_star), step="mid", color="tab:red",
                    alpha=0.2, label="95 % interval of theta*")  # fmt: skip
    ax.plot(k, [r["mu_star"] for r in rows], "x", color="tab:red", label="theta* (prediction)")
    ax.plot(k, [r["control"] for r in rows], "o-", color="tab:blue", label="control recorded")
    ax.plot(k + 1, [r["next"] for r in rows], ".", color="tab:green",
            label="next safe control advised")  # fmt: skip
    ax.axhline(camp.mu_star, color="k", lw=0.8, ls="--", label="true theta* (generator)")
    if bad_at is not None:
        ax.axvline(bad_at + 1, color="grey", lw=0.8, ls=":", label="bad record (set aside)")
    ax.set_ylabel("theta [deg]")
    ax.set_ylim(0, 1.3 * camp.mu_star)
    ax.legend(fontsize=8, loc="lower right")
    ax.set_title(f"{camp.kind}, seed {camp.seed}: a lab following the advice")
    ax2.step(k, [r["rank"] for r in rows], where="mid", color="tab:red")
    ax2.set_yticks(range(len(ALARM_LEVELS)), ALARM_LEVELS, fontsize=8)
    ax2.set_ylabel("alarm")
    ax2.set_xlabel("record number")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def ten_labs(seeds: list[int], bad_at: int = 6) -> list[dict]:
    """The ten-lab sessions: per type, per seed, clean and with a missed hammer at ``bad_at``;
    one row a session with the issue's criteria (never at or past mu*, covered, narrower than
    1 % of the distance travelled, within the budget)."""
    out = []
    for kind in LL.KINDS:
        for bad in (None, bad_at):
            for seed in seeds:
                camp = campaign(kind, seed)
                rows = session(camp, bad)
                ctr = [r["control"] for r in rows]
                last, travelled = rows[-1], max(ctr) - ctr[0]
                covered = bool(last["lo"] <= camp.mu_star <= last["hi"])
                width = last["hi"] - last["lo"]
                ok = (max(ctr) < camp.mu_star and covered and width < 0.01 * travelled
                      and len(rows) <= LL.BUDGET)  # fmt: skip
                out.append({"kind": kind, "bad_at": bad, "seed": seed, "mu_star": camp.mu_star,
                            "records": len(rows), "lo": last["lo"], "hi": last["hi"],
                            "covered": covered, "width_of_travel": width / travelled,
                            "converged": last["converged"], "ok": ok})  # fmt: skip
                r = out[-1]
                print(f"{kind:24s} bad={bad!s:4s} seed={seed:2d} records={len(rows):2d} "
                      f"[{r['lo']:.7f}, {r['hi']:.7f}] mu*={camp.mu_star:.7f} "
                      f"width/travel={r['width_of_travel']:.2e} ok={ok}", flush=True)
    for kind in LL.KINDS:
        for bad in (None, bad_at):
            cell = [r for r in out if r["kind"] == kind and r["bad_at"] == bad]
            n = [r["records"] for r in cell]
            print(f"{kind:24s} {'clean' if bad is None else 'bad':5s} criteria met "
                  f"{sum(r['ok'] for r in cell)}/{len(cell)}, records median "
                  f"{float(np.median(n)):.1f} max {max(n)}")
    print(f"total {sum(r['ok'] for r in out)}/{len(out)}")
    return out


def _seeds(text: str) -> list[int]:
    a, _, b = text.partition("-")
    return list(range(int(a), int(b) + 1)) if b else [int(v) for v in text.split(",")]


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--kind", default="saddle-node",
                    choices=["saddle-node", "subcritical-pitchfork", "supercritical-pitchfork"])
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--bad-at", type=int, default=None)
    ap.add_argument("--ten-labs", action="store_true")
    ap.add_argument("--seeds", default="1-10", help="the ten-lab seeds: 1-10 or 1,3,5")
    args = ap.parse_args()
    if args.ten_labs:
        out = ten_labs(_seeds(args.seeds))
        OUT.mkdir(parents=True, exist_ok=True)
        with open(OUT / "lab_sessions.csv", "w", newline="") as fh:
            w = csv.DictWriter(fh, fieldnames=list(out[0]))
            w.writeheader()
            w.writerows(out)
        print(f"wrote {OUT / 'lab_sessions.csv'}")
        return 0
    camp = campaign(args.kind, args.seed)
    rows = session(camp, args.bad_at)
    stem = "lab_session" + ("" if args.kind == "saddle-node" else f"_{args.kind}")
    stem += "_bad" if args.bad_at is not None else ""
    OUT.mkdir(parents=True, exist_ok=True)
    with open(OUT / f"{stem}.csv", "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    FIGURES.mkdir(parents=True, exist_ok=True)
    figure(rows, camp, FIGURES / f"{stem}.png", args.bad_at)
    last = rows[-1]
    travelled = max(r["control"] for r in rows)
    print(f"{camp.kind} seed {camp.seed}: true theta* = {camp.mu_star:.4f} deg")
    for r in rows:
        print(f"  {r['record']:2d} theta={r['control']:9.4f} [{r['lo']:9.4f}, {r['hi']:9.4f}] "
              f"{r['level']:12s} next={r['next']:9.4f} set aside={r['set_aside']}")
    print(f"records {len(rows)}, covered {last['lo'] <= camp.mu_star <= last['hi']}, width "
          f"{last['hi'] - last['lo']:.3g} deg = {(last['hi'] - last['lo']) / travelled:.2e} of "
          f"the {travelled:.3f} deg travelled, highest record {travelled:.4f} < "
          f"{camp.mu_star:.4f}: {travelled < camp.mu_star}")
    print(f"wrote {OUT / (stem + '.csv')}, {FIGURES / (stem + '.png')}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
