"""Where the detector's methods fail: error / Cramer-Rao bound and failure rate over
per-sample SNR x record length (cycles) x damping, for the FFT peak (plain and parabolic),
ESPRIT and variable projection.

    python bench/atlas_detector.py            # full grid (a few minutes on two cores)
    python bench/atlas_detector.py --quick    # small grid, under a minute

The record, in the units of a lab: a fundamental of angular frequency omega = 2 pi rad/s (1 Hz)
with two higher modes at the ratios of a clamped strip (2.76 and 5.40, amplitudes 0.4 and 0.2 of
the fundamental; modes above 0.8 x Nyquist left out), all with the same damping ratio
``zeta = gamma / omega``, random phases, a static level, white Gaussian noise, N = 4096 samples.
The grid: the fundamental's per-sample SNR ``A^2 / (2 s^2)`` (dB), the number of fundamental
periods in the record (``cycles``: the step is ``cycles / (f N)``; each trial moves the
frequency by a random fraction of an FFT bin) and ``zeta``.

Per method and cell, over the trials:

* ``ratio_omega`` = RMSE of the fundamental's omega / the Cramer-Rao bound of the same records
  (:mod:`service.analysis.crb`, squared bounds averaged over the trials), every trial counted;
  1 is the best any unbiased estimator can do.
* ``failure_rate`` = fraction of trials where the method returns no fundamental or one more
  than 10 % away from omega (a wrong mode, a ghost, or nothing): the gross failures that the
  RMSE ratio mixes with the small errors.

Writes ``bench/results/atlas_detector.csv``, one heatmap figure per quantity
(``atlas_detector_ratio_omega.png``, ``atlas_detector_failure_rate.png``: rows = methods,
columns = damping ratios, each panel SNR x cycles with a colour scale) and a headline
(``atlas_detector.txt``). ``run(quick)`` returns those paths (``bench/atlas.py`` calls it).
"""

from __future__ import annotations

import os

for _v in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

import argparse  # noqa: E402
import csv  # noqa: E402
import math  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from service.analysis.crb import Underdamped, crb, synthesize  # noqa: E402
from service.analysis.detect import detect  # noqa: E402

RESULTS = ROOT / "bench" / "results"
OMEGA = 2 * math.pi  # the fundamental, rad/s (1 Hz)
N = 4096
STATIC = 0.3
AMPLITUDE = 1e-3
RATIOS = (1.0, 2.76, 5.40)
AMPS = (1.0, 0.4, 0.2)
FAIL_REL = 0.1  # a fundamental more than 10 % off (or none) is a failure
METHODS = ("fft", "fft-parabolic", "esprit", "varpro")

FULL = {
    "snr_db": (-10.0, 0.0, 10.0, 20.0, 30.0, 40.0),
    "cycles": (1.0, 2.0, 3.0, 10.0, 30.0, 100.0, 300.0),
    "zeta": (1e-4, 1e-3, 1e-2, 5e-2),
    "trials": 40,
}
QUICK = {
    "snr_db": (0.0, 20.0, 40.0),
    "cycles": (2.0, 10.0, 100.0),
    "zeta": (1e-3, 3e-2),
    "trials": 6,
}


def cell(job: tuple[float, float, float, int, int]) -> list[dict[str, object]]:
    """All methods on the same ``trials`` records of one grid cell."""
    snr_db, cycles, zeta, trials, seed = job
    rng = np.random.default_rng(seed)
    noise = AMPLITUDE / math.sqrt(2.0) / 10 ** (snr_db / 20)
    dt = cycles / (OMEGA / (2 * math.pi) * N)
    t = np.arange(N) * dt
    nyq = math.pi / dt
    err = {m: [] for m in METHODS}
    fail = dict.fromkeys(METHODS, 0)
    cpu = {m: [] for m in METHODS}
    bound_sq = []
    for _ in range(trials):
        om = OMEGA * (1.0 + rng.uniform(-0.5, 0.5) / cycles)  # off the FFT grid
        modes = [
            Underdamped(r * om, zeta * r * om, a * AMPLITUDE, float(rng.uniform(-math.pi, math.pi)))
            for r, a in zip(RATIOS, AMPS, strict=True)
            if r * om < 0.8 * nyq
        ]
        w = synthesize(t, modes, STATIC) + noise * rng.standard_normal(N)
        bound_sq.append(float(crb(t, modes, noise).omega_std[0]) ** 2)
        for m in METHODS:
            c0 = time.process_time()
            det = detect(w, dt=dt, method=m)
            cpu[m].append(time.process_time() - c0)
            f = det.fundamental
            e = om if f is None else f.omega - om  # no fundamental: the error is omega itself
            err[m].append(e)
            fail[m] += f is None or abs(e) > FAIL_REL * om
    crb_om = math.sqrt(float(np.mean(bound_sq)))
    rec_snr = record_snr_db(snr_db, zeta * OMEGA * dt, N)
    rows = []
    for m in METHODS:
        rmse = math.sqrt(float(np.mean(np.square(err[m]))))
        rows.append(
            {
                "method": m,
                "snr_db": snr_db,
                "cycles": cycles,
                "zeta": zeta,
                "record_snr_db": rec_snr,
                "trials": trials,
                "n_samples": N,
                "rmse_omega": rmse,
                "crb_omega": crb_om,
                "ratio_omega": rmse / crb_om if crb_om > 0 else math.nan,
                "failure_rate": fail[m] / trials,
                "cpu_ms_median": 1e3 * float(np.median(cpu[m])),
            }
        )
    return rows


def record_snr_db(snr_db: float, gamma_dt: float, n: int) -> float:
    """The fundamental's record SNR: per-sample SNR ``A^2 / (2 s^2)`` in dB plus
    ``10 log10(N_eff)``, ``N_eff = sum_n exp(-2 gamma n dt)`` (its energy over the noise
    variance)."""
    x = math.exp(-2.0 * gamma_dt)
    neff = n if x == 1.0 else (1.0 - x**n) / (1.0 - x)
    return snr_db + 10.0 * math.log10(neff)


def _grid(quick: bool) -> tuple[dict[str, object], list[tuple[float, float, float, int, int]]]:
    g = QUICK if quick else FULL
    jobs = [
        (s, c, z, int(g["trials"]), 1000 * i + 7)
        for i, (s, c, z) in enumerate(
            (s, c, z) for s in g["snr_db"] for c in g["cycles"] for z in g["zeta"]
        )
    ]
    return g, jobs


def _warm() -> None:
    w = synthesize(np.arange(N) * 1e-3, [Underdamped(40.0, 0.01, 1e-3)], STATIC)
    for m in METHODS:
        detect(w + 1e-6 * np.random.default_rng(0).standard_normal(N), dt=1e-3, method=m)


def heatmaps(rows: list[dict[str, object]], key: str, path: Path, grid: dict[str, object]) -> Path:
    """One figure for one quantity: rows = methods, columns = damping ratios, each panel
    per-sample SNR (x) x cycles in the record (y), one colour scale for the figure."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.colors import LogNorm, Normalize

    snrs, cycs, zetas = list(grid["snr_db"]), list(grid["cycles"]), list(grid["zeta"])
    if key == "ratio_omega":
        norm = LogNorm(vmin=1.0, vmax=1e4)
        label = "RMSE(omega) / CRB (1 = efficient)"
        cmap = "magma_r"
    else:
        norm = Normalize(vmin=0.0, vmax=1.0)
        label = f"failure rate (no fundamental or > {FAIL_REL:.0%} off)"
        cmap = "Reds"
    fig, axes = plt.subplots(
        len(METHODS), len(zetas), figsize=(2.9 * len(zetas) + 1.6, 2.4 * len(METHODS)),
        squeeze=False, sharex=True, sharey=True,
    )  # fmt: skip
    im = None
    for i, m in enumerate(METHODS):
        for j, z in enumerate(zetas):
            ax = axes[i, j]
            Z = np.full((len(cycs), len(snrs)), np.nan)
            for r in rows:
                if r["method"] == m and r["zeta"] == z:
                    Z[cycs.index(r["cycles"]), snrs.index(r["snr_db"])] = float(r[key])
            shown = np.clip(Z, 1.0, 1e4) if key == "ratio_omega" else Z
            im = ax.imshow(shown, origin="lower", aspect="auto", norm=norm, cmap=cmap)
            for (yi, xi), v in np.ndenumerate(Z):
                if np.isfinite(v):
                    txt = f"{v:.2g}" if key == "ratio_omega" else f"{v:.0%}"
                    ax.text(xi, yi, txt, ha="center", va="center", fontsize=6,
                            color="white" if norm(shown[yi, xi]) > 0.6 else "black")  # fmt: skip
            ax.set_xticks(range(len(snrs)), [f"{s:g}" for s in snrs], fontsize=7)
            ax.set_yticks(range(len(cycs)), [f"{c:g}" for c in cycs], fontsize=7)
            if i == 0:
                ax.set_title(f"damping ratio zeta = {z:g}", fontsize=9)
            if j == 0:
                ax.set_ylabel(f"{m}\ncycles in the record", fontsize=8)
            if i == len(METHODS) - 1:
                ax.set_xlabel("per-sample SNR of the fundamental, dB", fontsize=8)
    fig.suptitle(f"detector atlas: {label}\nN = {N} samples, fundamental + 2 higher modes",
                 fontsize=10)  # fmt: skip
    fig.tight_layout(rect=(0, 0, 0.86, 1))
    cax = fig.add_axes((0.88, 0.1, 0.02, 0.78))
    fig.colorbar(im, cax=cax, label=label)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def headline(rows: list[dict[str, object]]) -> str:
    """Where each method fails. A cell fails when more than 5 % of its trials do. For each
    method: the fewest cycles from which it is reliable at a record SNR >= 30 dB, the record
    SNR below which it still fails from there on, and its median RMSE/CRB where reliable."""
    lines = [
        "A cell fails when > 5 % of its trials return no fundamental or one > 10 % off.",
        "record SNR = per-sample SNR + 10 log10(N_eff), N_eff = sum exp(-2 gamma n dt).",
        "",
        f"{'method':<14} {'failing cells':>13}  {'reliable from':>13}  {'fails below':>12}  "
        f"{'RMSE/CRB (median, reliable cells)':>34}",
    ]
    for m in METHODS:
        sel = [r for r in rows if r["method"] == m]
        cycs = sorted({float(r["cycles"]) for r in sel})
        start = None
        for c in cycs:
            tail = [r for r in sel if r["cycles"] >= c and r["record_snr_db"] >= 30.0]
            if tail and all(r["failure_rate"] <= 0.05 for r in tail):
                start = c
                break
        n_bad = sum(r["failure_rate"] > 0.05 for r in sel)
        if start is None:
            # failing although the record SNR is high: a mode that decays within the record
            # (2 pi zeta cycles nepers over the record) has too broad a peak for the method
            loud = [r for r in sel if r["record_snr_db"] >= 30.0 and r["failure_rate"] > 0.05]
            nepers = {id(r): 2 * math.pi * r["zeta"] * r["cycles"] for r in loud}
            short = max((r["cycles"] for r in loud if nepers[id(r)] < 0.1), default=0.0)
            decay = min((nepers[id(r)] for r in loud if r["cycles"] > short), default=math.inf)
            lines.append(
                f"{m:<14} {n_bad:>6d} / {len(sel):<4d}  {'never':>13}  (at record SNR >= 30 dB "
                f"it fails up to {short:g} cycles, and beyond when the record decays by "
                f">= {decay:.2g} nepers)"
            )
            continue
        region = [r for r in sel if r["cycles"] >= start]
        bad = [r for r in region if r["failure_rate"] > 0.05]
        below = max((r["record_snr_db"] for r in bad), default=-math.inf)
        good = [r for r in region if r["record_snr_db"] > below]
        ratio = float(np.median([r["ratio_omega"] for r in good])) if good else math.nan
        lines.append(
            f"{m:<14} {n_bad:>6d} / {len(sel):<4d}  {f'{start:g} cycles':>13}  "
            f"{('-' if not bad else f'{below:.0f} dB'):>12}  {ratio:>34.3g}"
        )
    return "\n".join(lines)


def run(quick: bool = False, *, out: Path = RESULTS, jobs: int = 2) -> list[Path]:
    """Run the atlas and write CSV, heatmaps and headline into ``out``; return their paths."""
    grid, todo = _grid(quick)
    t0 = time.perf_counter()
    rows: list[dict[str, object]] = []
    if jobs > 1:
        import multiprocessing as mp

        with mp.get_context("spawn").Pool(jobs, initializer=_warm) as pool:
            for i, part in enumerate(pool.imap_unordered(cell, todo)):
                rows += part
                print(f"[{i + 1}/{len(todo)}] ({time.perf_counter() - t0:.0f} s)",
                      file=sys.stderr, flush=True)  # fmt: skip
    else:
        _warm()
        for i, job in enumerate(todo):
            rows += cell(job)
            print(f"[{i + 1}/{len(todo)}] ({time.perf_counter() - t0:.0f} s)",
                  file=sys.stderr, flush=True)  # fmt: skip
    rows.sort(key=lambda r: (METHODS.index(r["method"]), r["zeta"], r["cycles"], r["snr_db"]))
    out.mkdir(parents=True, exist_ok=True)
    stem = "atlas_detector_quick" if quick else "atlas_detector"
    csv_path = out / f"{stem}.csv"
    with csv_path.open("w", newline="") as fh:
        wr = csv.DictWriter(fh, fieldnames=list(rows[0]))
        wr.writeheader()
        wr.writerows(rows)
    paths = [csv_path]
    for key in ("ratio_omega", "failure_rate"):
        paths.append(heatmaps(rows, key, out / f"{stem}_{key}.png", grid))
    text = headline(rows)
    txt = out / f"{stem}.txt"
    txt.write_text(
        f"{text}\n\n{len(todo)} cells x {grid['trials']} trials, N = {N}, "
        f"{time.perf_counter() - t0:.0f} s\n"
    )
    paths.append(txt)
    print(text)
    return paths


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="small grid, few trials (< 1 min)")
    ap.add_argument("--jobs", type=int, default=2, help="worker processes")
    ap.add_argument("--out", type=Path, default=RESULTS)
    args = ap.parse_args(argv)
    if args.jobs < 1:
        ap.error(f"--jobs: {args.jobs!r} must be >= 1")
    for p in run(args.quick, out=args.out, jobs=args.jobs):
        print(p)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
