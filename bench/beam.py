"""Euler-beam backend: time against accuracy for the spectrum and the impulse response.

    python bench/beam.py [--quick]

Spectrum: the Legendre-Galerkin solver at several basis sizes n against the paper's
determinant method (the reference, refined by Brent to round-off), error = max relative error
of the 10 smallest |sigma^2|. Impulse response: modal superposition and nonlinear integration
(several substeps) against a converged modal response (n = 48), error = max abs error over the
record / response amplitude. Writes bench/results/beam.csv and beam.png.
"""

from __future__ import annotations

import argparse
import csv
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from sim.euler_beam import equilibrium, spectrum_of  # noqa: E402
from sim.euler_beam.dynamics import modal_response, nonlinear_response  # noqa: E402
from sim.euler_beam.stability import refine_by_determinant  # noqa: E402

OUT = ROOT / "bench" / "results"


def best_time(fn, repeat: int) -> float:
    fn()  # warm (numba compile, caches)
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return min(times)


def bench_spectrum(rows: list, quick: bool) -> None:
    eq = equilibrium("symmetric", 1.9, "U_A")
    ref_guess = spectrum_of(eq, modes=10, n=40).sigma2
    t0 = time.perf_counter()
    ref = np.array([refine_by_determinant(eq, s, rel=1e-6) for s in ref_guess])
    t_det = (time.perf_counter() - t0) / 10
    rows.append(("spectrum", "determinant (paper), per mode", 0, t_det, 0.0))
    for n in (12, 16, 20, 24, 32, 40, 48):
        sp = spectrum_of(eq, modes=10, n=n)
        err = float(np.max(np.abs(sp.sigma2 - ref) / np.abs(ref)))
        t = best_time(lambda n=n: spectrum_of(eq, modes=10, n=n), 3 if quick else 10)
        rows.append(("spectrum", f"galerkin n={n}", n, t, err))


def bench_response(rows: list, quick: bool) -> None:
    eq = equilibrium("asymmetric", 1.5, "U_A")
    t = np.arange(0.0, 1.0 if quick else 3.0, 1e-3)
    kw = dict(kick=1e-3, damping=2e-4, kick_width=0.1)
    ref, _ = modal_response(eq, t, n=48, **kw)
    scale = np.max(np.abs(ref))
    for n in (12, 16, 24, 32):
        r, _ = modal_response(eq, t, n=n, **kw)
        tt = best_time(lambda n=n: modal_response(eq, t, n=n, **kw), 3)
        rows.append(("response", f"modal n={n}", n, tt, float(np.max(np.abs(r - ref)) / scale)))
    w_static = eq.shape(np.array([0.25]))[0]
    for sub in (2, 8) if quick else (2, 4, 8, 16, 32):
        w, info = nonlinear_response(eq, t, substeps=sub, **kw)
        tt = best_time(lambda sub=sub: nonlinear_response(eq, t, substeps=sub, **kw), 1)
        err = float(np.max(np.abs(w - w_static - ref)) / scale)
        rows.append(("response", f"nonlinear n=32 substeps={sub}", sub, tt, err))


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="short smoke run")
    args = ap.parse_args()
    rows: list = []
    bench_spectrum(rows, args.quick)
    bench_response(rows, args.quick)
    OUT.mkdir(parents=True, exist_ok=True)
    with (OUT / "beam.csv").open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["task", "method", "resolution", "seconds", "relative_error"])
        w.writerows(rows)
    print(f"{'task':9} {'method':34} {'time [ms]':>10} {'rel. error':>11}")
    for task, method, _, sec, err in rows:
        print(f"{task:9} {method:34} {1e3 * sec:10.3f} {err:11.2e}")
    det = next(r for r in rows if r[1].startswith("determinant"))
    g32 = next(r for r in rows if r[1] == "galerkin n=32")
    print(f"\nGalerkin n=32 (10 modes) vs determinant (per mode x 10): "
          f"{10 * det[3] / g32[3]:.0f}x faster at error {g32[4]:.1e}")  # fmt: skip
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        fig, axes = plt.subplots(1, 2, figsize=(10, 4))
        for ax, task in zip(axes, ("spectrum", "response")):
            for prefix, marker in (("galerkin", "o-"), ("modal", "o-"), ("nonlinear", "s-")):
                pts = [
                    (r[3], max(r[4], 1e-16))
                    for r in rows
                    if r[0] == task and r[1].startswith(prefix)
                ]
                if pts:
                    x, y = zip(*pts)
                    ax.loglog(np.array(x) * 1e3, y, marker, label=prefix)
            ax.set_xlabel("time per call [ms]")
            ax.set_ylabel("relative error")
            ax.set_title(f"Euler beam: {task}")
            ax.grid(True, which="both", alpha=0.3)
            ax.legend()
        fig.tight_layout()
        fig.savefig(OUT / "beam.png", dpi=120)
        print(f"wrote {OUT / 'beam.csv'} and {OUT / 'beam.png'}")
    except ImportError:  # pragma: no cover
        print("matplotlib missing: chart skipped")
    return 0


if __name__ == "__main__":
    sys.exit(main())
