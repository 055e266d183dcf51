"""Where the predictor fails, for users: ours against the paper's rule over lab plans.

    python bench/atlas_predictor.py [--quick]

Each cell is a lab plan of :mod:`calibration` (a fixed grid of control values with step ``h``
stopping ``d`` before mu*, relative noise ``r`` on sigma^2, ``sigma2_std`` given, no static
data) on the Euler beam's exact spectrum, over seeds. Reported per (actuation, d, h, r): median
|mu* error| of ours and of the paper's two-point rule (true exponent), their ratio, the coverage
of our 95 % interval, the share of plans whose type was named right, and the shares of plans
where ours is worse than the rule: in all, without a flag, and by more than our own standard
error.

Writes bench/results/atlas_predictor.csv and atlas_predictor.png (one heatmap per actuation and
noise: log10 of our error over the rule's; each cell annotated with the coverage).
"""

from __future__ import annotations

import argparse
import csv
import multiprocessing as mp
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parent))

import calibration as cal  # noqa: E402

OUT = HERE / "results"
STOPS = (1e-1, 1e-2, 1e-3)
STEPS = (0.02, 0.05, 0.1)
NOISES = (1e-5, 1e-3)
SEEDS = 8  # plans per cell (noise seeds): coverage and the share worse than the rule per cell
QUICK = {"stops": (3e-2, 3e-3), "steps": (0.05, 0.1), "noises": (1e-4,), "seeds": 1}


def _cells(quick: bool) -> tuple[list[cal.Plan], int]:
    stops, steps, noises, seeds = (
        (QUICK["stops"], QUICK["steps"], QUICK["noises"], QUICK["seeds"])
        if quick
        else (STOPS, STEPS, NOISES, SEEDS)
    )
    plans = []
    for act in cal.ACTS:
        for d in stops:
            for h in steps:
                for r in noises:
                    for s in range(seeds):
                        plans.append(cal.Plan(len(plans), "euler-beam", act, h, d, r, False,
                                              1000 * s + 17))  # fmt: skip
    return plans, seeds


def run(quick: bool = False, workers: int = 2) -> list[Path]:
    """Compute the atlas; return the paths written (CSV, PNG)."""
    plans, _ = _cells(quick)
    t0 = time.perf_counter()
    rows = []
    with mp.get_context("fork").Pool(workers) as pool:
        for k, r in enumerate(pool.imap_unordered(cal.run_plan, plans, chunksize=1)):
            rows.append(r)
            if (k + 1) % 10 == 0 or k + 1 == len(plans):
                print(f"[atlas predictor {k + 1}/{len(plans)}] {time.perf_counter() - t0:.0f} s",
                      flush=True)  # fmt: skip
    cells: dict[tuple, list[dict]] = {}
    for r in rows:
        cells.setdefault((r["actuation"], r["stop"], r["step"], r["rel"]), []).append(r)
    table = []
    for (act, d, h, rel), g in sorted(cells.items()):
        e = float(np.median([abs(x["error"]) for x in g]))
        er = float(np.median([abs(x["rule_error"]) for x in g]))
        table.append({
            "actuation": act, "stop": d, "step": h, "noise": rel, "plans": len(g),
            "median_err": e, "median_rule_err": er, "ratio": e / er if er > 0 else np.nan,
            "coverage": sum(x["covered"] for x in g) / len(g),
            "type_right": sum(x["right"] for x in g) / len(g),
            "confident_wrong": sum(x["confident_wrong"] for x in g),
            "worse": sum(x["worse"] for x in g) / len(g),
            "worse_unflagged": sum(x["worse"] and not x["flagged"] for x in g) / len(g),
            "worse_beyond_std": sum(x["worse_beyond_std"] for x in g) / len(g),
        })  # fmt: skip
    OUT.mkdir(parents=True, exist_ok=True)
    stem = "atlas_predictor_quick" if quick else "atlas_predictor"
    csv_path = OUT / f"{stem}.csv"
    with open(csv_path, "w", newline="") as fh:
        wr = csv.DictWriter(fh, fieldnames=list(table[0]))
        wr.writeheader()
        wr.writerows(table)
    png_path = OUT / f"{stem}.png"
    _plot(table, png_path)
    return [csv_path, png_path]


def _plot(table: list[dict], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    acts = [a for a in cal.ACTS if any(t["actuation"] == a for t in table)]
    noises = sorted({t["noise"] for t in table})
    stops = sorted({t["stop"] for t in table}, reverse=True)
    steps = sorted({t["step"] for t in table})
    fig, axes = plt.subplots(len(acts), len(noises), figsize=(3.6 * len(noises) + 1, 3.0 *
                             len(acts)), squeeze=False, constrained_layout=True)  # fmt: skip
    im = None
    for i, act in enumerate(acts):
        for j, r in enumerate(noises):
            ax = axes[i][j]
            Z = np.full((len(stops), len(steps)), np.nan)
            C = np.full_like(Z, np.nan)
            for t in table:
                if t["actuation"] == act and t["noise"] == r:
                    a, b = stops.index(t["stop"]), steps.index(t["step"])
                    Z[a, b] = np.log10(t["ratio"]) if t["ratio"] > 0 else np.nan
                    C[a, b] = t["coverage"]
            im = ax.imshow(Z, cmap="RdBu_r", vmin=-3, vmax=3, aspect="auto")
            for a in range(len(stops)):
                for b in range(len(steps)):
                    if np.isfinite(C[a, b]):
                        ax.text(b, a, f"{100 * C[a, b]:.0f}%", ha="center", va="center",
                                fontsize=8)  # fmt: skip
            ax.set_xticks(range(len(steps)), [f"{s:g}" for s in steps])
            ax.set_yticks(range(len(stops)), [f"{s:g}" for s in stops])
            ax.set_xlabel("grid step h")
            ax.set_ylabel("stop d before mu*")
            ax.set_title(f"{act}, noise {r:g}", fontsize=9)
    if im is not None:
        fig.colorbar(im, ax=axes, label="log10(|err ours| / |err paper's rule|)")
    fig.suptitle("Predictor vs the paper's rule (numbers: coverage of our 95 % interval)")
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--workers", type=int, default=2)
    args = ap.parse_args(argv)
    for p in run(args.quick, args.workers):
        print(p)


if __name__ == "__main__":
    main()
