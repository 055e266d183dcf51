"""Detector benchmark: RMSE / Cramer-Rao bound and time per call, every method side by side.

    python bench/detector.py            # full grid (a few minutes on one core)
    python bench/detector.py --quick    # smoke run

Signals: the beam-like impulse response of the detector's tests -- fundamental omega = 40
(rad per time unit), harmonics at 2.5x and 5x (amplitudes 1e-3, 4e-4, 2e-4, random phases),
every mode with gamma = xi/2, xi = 1e-2, static level 0.3, N = 10 000 samples -- over a grid of
record lengths (3 to 1000 fundamental cycles: dt = cycles * 2 pi / (40 N); each trial moves the
fundamental by a random fraction of an FFT bin, so that it does not sit on the FFT grid) and
per-sample SNR
of the fundamental, ``a1^2 / (2 noise^2)``, from 0 to 40 dB. Harmonics above 0.8 x Nyquist are
left out of the signal (the 5x mode sits at twice the 2.5x one, so the detector marks it as a
possible combination tone; the fundamental is unaffected). Plus an overdamped case: a kicked
overdamped fundamental (sigma^2 = -0.5, xi = 2, two real poles) under two underdamped modes,
where the FFT has no peak.

For each method and grid point: RMSE of the fundamental's omega, damping and sigma^2 over the
trials, divided by the Cramer-Rao bound of the same record (``service.analysis.crb``; the
common-damping bound for ``varpro+common``), the fraction of trials where the method's
fundamental is not the 40 rad/time mode (counted in the RMSE), and the time per call.

``--baseline REV`` also runs the detector of git revision ``REV`` (its ``service/analysis``
extracted to a temporary package) on the very same records, interleaved trial by trial, so that
before/after accuracy and time per call come from one run on one machine; its rows carry the
method name suffixed with ``@REV``.

BLAS is pinned to one thread (set before numpy is imported) so that timings are per core and
not spoiled by thread contention on a shared machine; cells run in ``--jobs`` processes (2 by
default), and both the wall time and the process CPU time per call are recorded.
Writes bench/results/detector.csv and bench/results/detector.png.
"""

from __future__ import annotations

import os

for _v in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

import argparse  # noqa: E402
import csv  # noqa: E402
import importlib  # noqa: E402
import io  # noqa: E402
import math  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import tarfile  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from collections.abc import Callable  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from service.analysis.crb import Overdamped, Underdamped, crb, synthesize  # noqa: E402
from service.analysis.detect import detect  # noqa: E402

RESULTS = ROOT / "bench" / "results"
OMEGA1 = 40.0
XI = 1e-2
N = 10_000
STATIC = 0.3
AMPS = (1e-3, 4e-4, 2e-4)
RATIOS = (1.0, 2.5, 5.0)

METHODS = {
    "fft": {"method": "fft"},
    "fft-parabolic": {"method": "fft-parabolic"},
    "esprit": {"method": "esprit"},
    "varpro": {"method": "varpro"},
    "varpro+common": {"method": "varpro", "common_damping": True},
}


#: Detectors to run: label -> detect function (the working tree's, plus a --baseline revision).
DETECTORS: dict[str, Callable[..., object]] = {"": detect}
_BASELINE_PKG = "snapwarn_baseline"


def load_baseline(rev: str, where: Path | None = None) -> Callable[..., object]:
    """The ``detect`` function of git revision ``rev``: its ``service/analysis`` is extracted
    into a temporary directory as the package ``snapwarn_baseline`` (imports rewritten), so it
    runs side by side with the working tree's detector in one process."""
    root = Path(where or tempfile.mkdtemp(prefix="snapwarn-baseline-"))
    pkg = root / _BASELINE_PKG
    if not pkg.exists():
        blob = subprocess.run(
            ["git", "-C", str(ROOT), "archive", rev, "service/analysis"],
            check=True, capture_output=True,
        ).stdout  # fmt: skip
        with tarfile.open(fileobj=io.BytesIO(blob)) as tar:
            tar.extractall(root / "_tar", filter="data")
        (root / "_tar" / "service" / "analysis").rename(pkg)
        for f in pkg.rglob("*.py"):
            f.write_text(f.read_text().replace("service.analysis", _BASELINE_PKG))
    if str(root) not in sys.path:
        sys.path.insert(0, str(root))
    return importlib.import_module(f"{_BASELINE_PKG}.detect").detect


def beam_modes(dt: float, om1: float, rng: np.random.Generator) -> list[Underdamped]:
    nyq = math.pi / dt
    out = []
    for r, a in zip(RATIOS, AMPS, strict=True):
        om = r * om1
        if om < 0.8 * nyq:
            out.append(Underdamped(om, XI / 2, a, float(rng.uniform(-math.pi, math.pi))))
    return out


def run_cell(
    case: str,
    cycles: float,
    snr_db: float,
    trials: int,
    seed: int,
) -> list[dict[str, object]]:
    rng = np.random.default_rng(seed)
    if case == "beam":
        dt = cycles * 2 * math.pi / (OMEGA1 * N)
        noise = AMPS[0] / math.sqrt(2) / 10 ** (snr_db / 20)
        true_om, true_g = OMEGA1, XI / 2
        true_s2 = -(true_om**2 + true_g**2)
    else:  # overdamped fundamental
        dt = 2e-3
        noise = 1e-3 / math.sqrt(2) / 10 ** (snr_db / 20)
        od = Overdamped.kicked(-0.5, 2.0, 1e-3)
        true_om, true_g, true_s2 = 0.0, od.damping, od.sigma2
    t = np.arange(N) * dt
    names = [m + tag for tag in DETECTORS for m in METHODS]
    errs: dict[str, list[tuple[float, float, float]]] = {m: [] for m in names}
    times: dict[str, list[float]] = {m: [] for m in names}
    cpu: dict[str, list[float]] = {m: [] for m in names}
    miss = dict.fromkeys(names, 0)
    crb_sq_list: list[tuple[float, float, float]] = []
    crbc_sq_list: list[tuple[float, float, float]] = []
    for _ in range(trials):
        if case == "beam":
            # a random fraction of an FFT bin off the grid (whole cycles would favour the FFT)
            true_om = OMEGA1 * (1.0 + rng.uniform(-0.5, 0.5) / cycles)
            true_s2 = -(true_om**2 + true_g**2)
            modes = beam_modes(dt, true_om, rng)
        else:
            modes = [
                od,
                Underdamped(40.0, 1.0, 5e-4, float(rng.uniform(-math.pi, math.pi))),
                Underdamped(100.0, 1.0, 3e-4, float(rng.uniform(-math.pi, math.pi))),
            ]
        w = synthesize(t, modes, STATIC) + noise * rng.standard_normal(N)
        # the bound depends on the random phases: average the squared bounds over the trials
        b = crb(t, modes, noise)
        bc = crb(t, modes, noise, common_damping=True)
        crb_sq_list.append((b.omega_std[0] ** 2, b.damping_std[0] ** 2, b.sigma2_std[0] ** 2))
        crbc_sq_list.append((bc.omega_std[0] ** 2, bc.damping_std[0] ** 2, bc.sigma2_std[0] ** 2))
        # alternate which detector meets the fresh record first (cold caches cost the first)
        order = list(DETECTORS.items())
        if len(times[names[0]]) % 2:
            order.reverse()
        for name, kw, fn in ((m + tag, kw, fn) for tag, fn in order for m, kw in METHODS.items()):
            c0 = time.process_time()
            t0 = time.perf_counter()
            det = fn(w, dt=dt, **kw)
            times[name].append(time.perf_counter() - t0)
            cpu[name].append(time.process_time() - c0)
            f = det.fundamental
            if f is None:
                miss[name] += 1
                errs[name].append((true_om, true_g, true_s2))  # a miss: error = the value
                continue
            if case == "beam" and abs(f.omega - true_om) > 0.1 * true_om:
                miss[name] += 1
            if case == "overdamped" and f.regime != "overdamped":
                miss[name] += 1
            errs[name].append((f.omega - true_om, f.damping - true_g, f.sigma2 - true_s2))
    crb_sq = np.mean(crb_sq_list, axis=0)
    crbc_sq = np.mean(crbc_sq_list, axis=0)
    rows = []
    for name in names:
        e = np.asarray(errs[name])
        rmse = np.sqrt(np.mean(e**2, axis=0))
        ref = np.sqrt(crbc_sq if name.startswith("varpro+common") else crb_sq)
        ratio = np.where(ref > 0, rmse / np.where(ref > 0, ref, 1.0), np.nan)
        tt = np.asarray(times[name]) * 1e3
        rows.append(
            {
                "case": case,
                "cycles": cycles,
                "snr_db": snr_db,
                "dt": dt,
                "n_samples": N,
                "method": name,
                "trials": trials,
                "rmse_omega": rmse[0],
                "crb_omega": ref[0],
                "ratio_omega": ratio[0],
                "rmse_damping": rmse[1],
                "crb_damping": ref[1],
                "ratio_damping": ratio[1],
                "rmse_sigma2": rmse[2],
                "crb_sigma2": ref[2],
                "ratio_sigma2": ratio[2],
                "miss_rate": miss[name] / trials,
                "time_ms_mean": float(np.mean(tt)),
                "time_ms_median": float(np.median(tt)),
                "cpu_ms_median": float(np.median(np.asarray(cpu[name]) * 1e3)),
            }
        )
    return rows


def fmt(x: float) -> str:
    if not np.isfinite(x):
        return "  -  "
    return f"{x:7.3g}"


def print_table(rows: list[dict[str, object]]) -> None:
    names = list(dict.fromkeys(r["method"] for r in rows))
    head = f"{'case':<10} {'cyc':>5} {'SNR':>4} | " + " | ".join(f"{n:^27}" for n in names)
    print(head)
    print(
        f"{'':<10} {'':>5} {'dB':>4} | "
        + " | ".join(f"{'om/CRB':>7} {'g/CRB':>7} {'s2/CRB':>7}  " for _ in names)
    )
    keys = sorted({(r["case"], r["cycles"], r["snr_db"]) for r in rows}, key=str)
    keys = sorted(keys, key=lambda k: (k[0], float(k[1]), float(k[2])))
    for key in keys:
        cell = {r["method"]: r for r in rows if (r["case"], r["cycles"], r["snr_db"]) == key}
        line = f"{key[0]:<10} {key[1]:>5g} {key[2]:>4g} | "
        line += " | ".join(
            f"{fmt(cell[n]['ratio_omega'])} {fmt(cell[n]['ratio_damping'])} "
            f"{fmt(cell[n]['ratio_sigma2'])}  "
            for n in names
        )
        print(line)
    print()
    print("time per call, median over the beam cells (N = 10 000 samples, BLAS on 1 thread):")
    print(f"  {'method':<14} {'wall ms':>8} {'cpu ms':>8}")
    for n in names:
        sel = [r for r in rows if r["method"] == n and r["case"] == "beam"]
        tt = np.median([r["time_ms_median"] for r in sel])
        cc = np.median([r["cpu_ms_median"] for r in sel])
        print(f"  {n:<14} {tt:8.3f} {cc:8.3f}")
    print()
    print("worst RMSE/CRB over the beam grid (omega, damping, sigma2):")
    for n in names:
        sel = [r for r in rows if r["method"] == n and r["case"] == "beam"]
        print(
            f"  {n:<14} {max(r['ratio_omega'] for r in sel):9.3g} "
            f"{max(r['ratio_damping'] for r in sel):9.3g} "
            f"{max(r['ratio_sigma2'] for r in sel):9.3g}   "
            f"best omega {min(r['ratio_omega'] for r in sel):.3g}"
        )


def plot(rows: list[dict[str, object]], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(13, 5.2))
    colors = {
        "fft": "tab:red",
        "fft-parabolic": "tab:orange",
        "esprit": "tab:green",
        "varpro": "tab:blue",
        "varpro+common": "tab:purple",
    }
    for n, c in colors.items():
        sel = [r for r in rows if r["method"] == n and r["case"] == "beam"]
        x = [r["cpu_ms_median"] for r in sel]
        y = [r["ratio_omega"] for r in sel]
        ax1.scatter(x, y, s=14, color=c, alpha=0.45)
        ax1.scatter([np.median(x)], [np.median(y)], s=120, color=c, edgecolor="k", label=n)
        od = [r for r in rows if r["method"] == n and r["case"] == "overdamped"]
        if od:
            ax1.scatter(
                [r["cpu_ms_median"] for r in od],
                [r["ratio_sigma2"] for r in od],
                marker="x",
                s=60,
                color=c,
            )
    ax1.axhline(1.0, color="k", lw=0.8)
    ax1.axhline(1.1, color="k", lw=0.8, ls="--")
    ax1.set_xscale("log")
    ax1.set_yscale("log")
    ax1.set_xlabel("CPU time per call, ms (N = 10 000 samples, BLAS on 1 thread)")
    ax1.set_ylabel("RMSE / CRB: omega (dots), sigma^2 overdamped (x)")
    ax1.set_title("accuracy vs speed (dots: grid cells, big: median)")
    ax1.legend(loc="upper right", fontsize=8)
    cyc = sorted({r["cycles"] for r in rows if r["case"] == "beam"})
    cmap = plt.get_cmap("viridis")
    for i, cy in enumerate(cyc):
        col = cmap(i / max(len(cyc) - 1, 1))
        for n, ls in (("varpro", "-"), ("fft", ":")):
            sel = sorted(
                (r for r in rows if r["method"] == n and r["cycles"] == cy and r["case"] == "beam"),
                key=lambda r: r["snr_db"],
            )
            ax2.plot(
                [r["snr_db"] for r in sel],
                [r["ratio_omega"] for r in sel],
                ls,
                color=col,
                marker="o" if n == "varpro" else None,
                label=f"{n}, {cy:g} cycles" if n == "varpro" or i in (0, len(cyc) - 1) else None,
            )
    ax2.axhline(1.1, color="k", lw=0.8, ls="--")
    ax2.set_yscale("log")
    ax2.set_xlabel("per-sample SNR of the fundamental, dB")
    ax2.set_ylabel("RMSE / CRB of omega")
    ax2.set_title("varpro (solid) vs FFT peak (dotted) over the grid")
    ax2.legend(fontsize=7, ncol=2)
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def _warm(baseline: tuple[str, str] | None = None) -> None:
    """Load the numba kernels (compiled or from cache) outside the timings; with ``baseline``
    ``(rev, directory)`` also load that revision's detector."""
    if baseline is not None:
        DETECTORS["@" + baseline[0]] = load_baseline(baseline[0], Path(baseline[1]))
    w0 = synthesize(np.arange(N) * 1e-3, [Underdamped(40.0, 0.01, 1e-3)], STATIC)
    for fn in DETECTORS.values():
        for kw in METHODS.values():
            fn(w0 + 1e-6 * np.random.default_rng(0).standard_normal(N), dt=1e-3, **kw)


def _run_job(job: tuple[str, float, float, int, int]) -> list[dict[str, object]]:
    return run_cell(*job)


def _progress(i: int, n: int, row: dict[str, object], t_start: float) -> None:
    print(
        f"[{i + 1}/{n}] {row['case']} cycles={row['cycles']:g} snr={row['snr_db']:g} dB "
        f"({time.perf_counter() - t_start:.0f} s)",
        file=sys.stderr,
        flush=True,
    )


def _rel(path: Path) -> str:
    return str(path.relative_to(ROOT)) if path.is_relative_to(ROOT) else str(path)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="smoke run: small grid, few trials")
    ap.add_argument("--trials", type=int, default=None, help="trials per grid cell")
    ap.add_argument("--seed", type=int, default=20261121)
    ap.add_argument("--jobs", type=int, default=2, help="worker processes (cells run in parallel)")
    ap.add_argument("--out", type=Path, default=RESULTS)
    ap.add_argument(
        "--plot-only", action="store_true", help="re-read the CSV, print the table and re-plot"
    )
    ap.add_argument(
        "--baseline",
        metavar="REV",
        default=None,
        help="also run the detector of this git revision on the same records (before/after)",
    )
    args = ap.parse_args(argv)
    if args.plot_only:
        with (args.out / "detector.csv").open() as fh:
            rows = [
                {k: (v if k in ("case", "method") else float(v)) for k, v in r.items()}
                for r in csv.DictReader(fh)
            ]
        print_table(rows)
        plot(rows, args.out / "detector.png")
        return 0
    if args.quick:
        cycles, snrs, trials = (3, 100, 1000), (0, 40), args.trials or 8
        od_snrs = (40,)
    else:
        cycles, snrs, trials = (3, 10, 30, 100, 300, 1000), (0, 10, 20, 30, 40), args.trials or 150
        od_snrs = (20, 40)
    if trials < 2:
        ap.error(f"--trials: {trials!r} must be >= 2")
    baseline = None
    if args.baseline:
        rev = subprocess.run(
            ["git", "-C", str(ROOT), "rev-parse", "--short", args.baseline],
            check=True, capture_output=True, text=True,
        ).stdout.strip()  # fmt: skip
        baseline = (rev, tempfile.mkdtemp(prefix="snapwarn-baseline-"))
        load_baseline(rev, Path(baseline[1]))  # extract once, before the workers start
    _warm(baseline)
    rows: list[dict[str, object]] = []
    t_start = time.perf_counter()
    cells = [("beam", c, s) for c in cycles for s in snrs] + [
        ("overdamped", 0.0, s) for s in od_snrs
    ]
    jobs = [(case, c, s, trials, args.seed + i) for i, (case, c, s) in enumerate(cells)]
    if args.jobs > 1:
        import multiprocessing as mp

        ctx = mp.get_context("spawn")
        with ctx.Pool(args.jobs, initializer=_warm, initargs=(baseline,)) as pool:
            for i, part in enumerate(pool.imap_unordered(_run_job, jobs)):
                rows += part
                _progress(i, len(cells), part[0], t_start)
    else:
        for i, job in enumerate(jobs):
            part = _run_job(job)
            rows += part
            _progress(i, len(cells), part[0], t_start)
    args.out.mkdir(parents=True, exist_ok=True)
    csv_path = args.out / "detector.csv"
    with csv_path.open("w", newline="") as fh:
        wr = csv.DictWriter(fh, fieldnames=list(rows[0].keys()))
        wr.writeheader()
        for r in rows:
            wr.writerow(r)
    print_table(rows)
    png = args.out / "detector.png"
    plot(rows, png)
    print(
        f"\nwrote {_rel(csv_path)} and {_rel(png)} "
        f"({time.perf_counter() - t_start:.0f} s, {trials} trials per cell)"
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
