"""Early warning: mu* error and interval coverage over seeds, ours against the paper's rule,
and the overdamped boundary layer where the FFT collapses.

    python bench/warn.py [--quick] [--seeds N]

Part 1 (sweeps): for each actuation, damping xi and SNR, ``warn`` on the Euler beam over seeds;
reports median |error| of mu*, coverage of the 95 % interval, the type found, the number of
impulse responses, and the paper's rule (T > 10 T0, two-point extrapolation) on the same data.

Part 2 (boundary layer): symmetric actuation with heavy damping xi = 1, so that the
fundamental is overdamped for dmu < xi^2 / (4 b1) ~ 3e-5. At each dmu, sigma^2 from the pole
detector (sigma^2 = -s1 s2) and from the FFT peak, against the beam's exact sigma^2; then the
classification from the pole measurements inside the layer.

Writes bench/results/warn.csv, warn_layer.csv and warn.png.
"""

from __future__ import annotations

import argparse
import csv
import math
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from service.analysis.detect import detect  # noqa: E402
from service.analysis.pipeline import warn  # noqa: E402
from service.analysis.predict import predict  # noqa: E402
from sim import simulate  # noqa: E402
from sim.euler_beam import bifurcation, spectrum  # noqa: E402
from sim.scene import Scene  # noqa: E402

OUT = ROOT / "bench" / "results"
ACTS = ("asymmetric", "symmetric", "antisymmetric")


def part_sweeps(seeds: int, xis, snrs) -> list[dict]:
    rows = []
    for act in ACTS:
        for xi in xis:
            for snr in snrs:
                for seed in range(seeds):
                    t0 = time.perf_counter()
                    res = warn(act, damping=xi, snr_db=snr, seed=1000 * seed + 7)
                    t = res.truth or {}
                    rows.append({
                        "actuation": act, "xi": xi, "snr_db": snr, "seed": seed,
                        "n": len(res.measurements), "stopped": res.stopped,
                        "transition": res.prediction.transition if res.prediction
                        else "undetermined",
                        "correct": t.get("transition_correct"),
                        "error": t.get("error", math.nan), "covered": t.get("covered"),
                        "baseline_error": t.get("baseline_error", math.nan),
                        "crossed": t.get("max_mu_measured", -1) >= t.get("mu_star", math.inf),
                        "seconds": time.perf_counter() - t0,
                    })  # fmt: skip
                    r = rows[-1]
                    print(f"{act:13} xi={xi:<7g} snr={snr:<4g} seed={seed} n={r['n']:2d} "
                          f"{r['transition']:24} err={r['error']:+.2e} cov={r['covered']} "
                          f"paper={r['baseline_error']:+.2e} ({r['seconds']:.1f} s)",
                          flush=True)  # fmt: skip
    return rows


def part_layer(quick: bool) -> tuple[list[dict], dict]:
    act, xi = "symmetric", 1.0
    mu_star = bifurcation(act).mu_star
    dmus = np.geomspace(1e-3, 1e-7, 5 if quick else 9)
    rows = []
    ms, s2s, s2err, ws = [], [], [], []
    for k, d in enumerate(dmus):
        mu = mu_star - d
        exact = spectrum(act, mu, "U_A", modes=1).sigma2[0]
        sig = simulate(Scene(actuation=act, mu=mu, damping=xi, kick=1e-3, snr_db=40.0, seed=k))
        row = {"dmu": d, "exact_sigma2": exact, "regime_exact":
               "overdamped" if exact + xi**2 / 4 > 0 else "underdamped"}  # fmt: skip
        for method in ("varpro", "fft"):
            det = detect(sig.w, dt=sig.dt, method=method)
            f = det.fundamental
            s2 = f.sigma2 if f is not None else math.nan
            row[f"{method}_sigma2"] = s2
            row[f"{method}_rel_error"] = abs(s2 / exact - 1) if math.isfinite(s2) else math.inf
            if method == "varpro" and f is not None:
                ms.append(mu)
                s2s.append(s2)
                s2err.append(f.sigma2_std)
                ws.append(det.static_level)
        rows.append(row)
        print(f"dmu={d:.1e} exact sigma2={exact:+.4e} ({row['regime_exact']}): "
              f"poles {row['varpro_rel_error']:.1e}, FFT {row['fft_rel_error']:.1e}")  # fmt: skip
    p = predict(np.array(ms), np.array(s2s), sigma2_std=np.array(s2err), w_static=np.array(ws))
    summary = {"transition": p.transition, "mu_star": p.mu_star, "error": p.mu_star - mu_star,
               "interval": p.mu_star_interval}  # fmt: skip
    print(f"inside the layer: {p.transition}, mu* error {summary['error']:+.2e}")
    return rows, summary


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--seeds", type=int, default=None)
    args = ap.parse_args()
    seeds = args.seeds or (2 if args.quick else 10)
    xis = (2e-4,) if args.quick else (0.0, 2e-4, 1e-2)
    snrs = (40.0,) if args.quick else (20.0, 40.0, 60.0)
    OUT.mkdir(parents=True, exist_ok=True)
    rows = part_sweeps(seeds, xis, snrs)
    with (OUT / "warn.csv").open("w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    print("\nsummary (median |error|, coverage of the 95% interval, type right, crossed mu*):")
    for act in ACTS:
        for xi in xis:
            for snr in snrs:
                sel = [r for r in rows if (r["actuation"], r["xi"], r["snr_db"]) == (act, xi, snr)]
                err = np.median([abs(r["error"]) for r in sel])
                base = np.median([abs(r["baseline_error"]) for r in sel])
                cov = np.mean([bool(r["covered"]) for r in sel])
                ok = np.mean([bool(r["correct"]) for r in sel])
                crossed = sum(bool(r["crossed"]) for r in sel)
                print(f"  {act:13} xi={xi:<7g} snr={snr:<4g} |err| {err:.1e} (paper {base:.1e}, "
                      f"{base / max(err, 1e-300):.0f}x) coverage {cov:.0%} type {ok:.0%} "
                      f"crossed {crossed}")  # fmt: skip
    layer, summary = part_layer(args.quick)
    with (OUT / "warn_layer.csv").open("w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(layer[0]))
        w.writeheader()
        w.writerows(layer)
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        fig, ax = plt.subplots(1, 2, figsize=(11, 4))
        for act, mk in zip(ACTS, "os^"):
            sel = [r for r in rows if r["actuation"] == act]
            xb = [max(abs(r["baseline_error"]), 1e-12) for r in sel]
            yo = [max(abs(r["error"]), 1e-12) for r in sel]
            ax[0].loglog(xb, yo, mk, label=act, alpha=0.6)
        lim = [1e-12, 1e-1]
        ax[0].loglog(lim, lim, "k:", lw=0.8)
        ax[0].set_xlabel("|mu* error|, paper's rule")
        ax[0].set_ylabel("|mu* error|, snapwarn")
        ax[0].legend()
        ax[0].set_title("same measurements, two predictors")
        d = [r["dmu"] for r in layer]
        ax[1].loglog(d, [max(r["varpro_rel_error"], 1e-12) for r in layer], "o-", label="poles")
        ax[1].loglog(d, [min(max(r["fft_rel_error"], 1e-12), 1e2) for r in layer], "s-",
                     label="FFT peak")  # fmt: skip
        ax[1].axvline(1.0 / (4 * 7827.18), color="gray", ls=":", label="layer edge xi^2/(4 b1)")
        ax[1].set_xlabel("mu* - mu")
        ax[1].set_ylabel("relative error of sigma^2")
        ax[1].set_title("overdamped boundary layer (symmetric, xi = 1)")
        ax[1].legend()
        fig.tight_layout()
        fig.savefig(OUT / "warn.png", dpi=120)
    except ImportError:  # pragma: no cover
        pass
    print(f"wrote {OUT / 'warn.csv'}, {OUT / 'warn_layer.csv'}, {OUT / 'warn.png'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
