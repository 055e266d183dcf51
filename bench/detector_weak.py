"""Weak-mode detection: keep rate against record SNR, false modes per record, and the bound.

    python bench/detector_weak.py            # full run (about 5 minutes of CPU on one core)
    python bench/detector_weak.py --quick    # smoke run

Records (those of ``tests/analysis/test_detect_clean.py``): ``dt = 1e-3``, a strong mode
``exp(-0.5 t) cos(40 t + phi1)`` on a static level 0.3, and a weak mode
``0.5 exp(-gamma t) cos(100 t + phi2)`` (random phases), white noise of std ``s``. Cases:
``N = 4000, gamma = 3`` (the weak mode decays within a tenth of the record), ``N = 4000,
gamma = 0`` and ``N = 20000, gamma = 1``. The record SNR of the weak mode is its energy over
the noise variance, ``10 log10(A^2 N_eff / (2 s^2))`` with ``N_eff = sum_n exp(-2 gamma n dt)``
(the ``Mode.snr_db`` of an isolated mode). A mode is *kept* when the detection holds a mode
within 3 rad/s of 100; a *false mode* is any other mode than the two true ones, counted on
records without the weak mode (``one_mode``: strong mode plus noise at the noise level of the
15 dB records) and on pure noise.

Parts (rows of ``bench/results/detector_weak.csv``):

* ``snr``: the detector as it is, keep rate against record SNR (every case);
* ``trade``: at 15 dB, the detector's two detection thresholds swept around their defaults
  (``PEAK_FALSE_ALARM``, the candidate periodogram peaks' false-alarm probability per record,
  and ``ORDER_PENALTY``, the RSS drop a mode must bring in ``ln N`` noise variances): keep
  rate against false modes per record;
* ``snr_lowered``: keep rate against record SNR at lowered thresholds (``--lowered``; by
  default peak probability 0.3 and penalty 3 ln N, the most permissive pair of the ``trade``
  grid with which every detector test still passes: with every peak a candidate (1) an
  overdamped fundamental is split, with 2.5 ln N a 20 dB record gets 0.035 false modes per
  record; fresh seeds);

and of ``bench/results/detector_weak_bound.csv``:

* ``np_bound``: the best any detector can do. For a mode of *known* amplitude and damping,
  uniform phase and a frequency drawn uniformly from the band's grid (a 4x zero-padded FFT
  grid in ``(0.05, pi - 0.05)`` rad / sample: the detector is told nothing about where the
  mode is), the Neyman-Pearson test between noise and that mixture is the Gaussian
  likelihood ratio averaged over the frequencies and the phase (see :func:`_log_lr`). Its
  detection probability at a false-alarm probability ``P_FA`` bounds that of any detector
  whose false modes per record are at most ``P_FA`` (``P(one or more) <= E[count]``), and a
  detector that keeps the mode in 95 % of trials *at every frequency* has an average over
  frequencies of at least 95 %. The strong mode is left
  out (a detector cannot do better than one that knows it exactly);
* ``glrt``: the generalised likelihood ratio, the largest matched damped-sinusoid statistic
  ``T(omega) = 2 |sum_n r_n w_n e^{-i omega n}|^2 / sum_n w_n^2`` (``w_n = exp(-gamma n dt)``;
  ``chi2_2`` on noise at one frequency), with the damping searched (a filter bank over a
  geometric grid of ``gamma``, ratio 1.25) or known, against its threshold ``T``: the false-
  alarm probability and ``P(max T > thr) / exp(-thr/2)``, the effective number of independent
  cells the search tests.

BLAS is pinned to one thread; timings are process CPU time. Writes
bench/results/detector_weak.csv, detector_weak_bound.csv, detector_weak.png and
detector_weak.txt (the summary printed at the end).
"""

from __future__ import annotations

import os

for _v in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

import argparse  # noqa: E402
import contextlib  # noqa: E402
import csv  # noqa: E402
import functools  # noqa: E402
import math  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from collections.abc import Iterator  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
from scipy.special import logsumexp  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from service.analysis.detect import _spectral, _varpro, detect  # noqa: E402
from service.analysis.detect._results import ORDER_PENALTY, PEAK_FALSE_ALARM  # noqa: E402

RESULTS = ROOT / "bench" / "results"
DT = 1e-3
A_WEAK = 0.5
OM_WEAK, OM_STRONG = 100.0, 40.0
#: case -> (samples N, weak mode's damping gamma in 1 / time unit)
CASES = {"N4000_g3": (4000, 3.0), "N4000_g0": (4000, 0.0), "N20000_g1": (20000, 1.0)}
FALSE_BOUND = 0.03  # false modes per record allowed (the slow test's bound)
BAND_EDGE = 0.05  # rad / sample: the bound's frequency band is [edge, pi - edge]
PHASES = 64  # phase quadrature points of the bound's likelihood ratio


@contextlib.contextmanager
def thresholds(peak_false_alarm: float, order_penalty: float) -> Iterator[None]:
    """Run the detector with other detection thresholds (restored on exit).

    Parameters
    ----------
    peak_false_alarm : float
        False-alarm probability per record of the candidate periodogram peaks.
    order_penalty : float
        RSS drop a mode must bring, in ``ln N`` noise variances.
    """
    old = (_spectral.PEAK_FALSE_ALARM, _varpro.ORDER_PENALTY)
    _spectral.PEAK_FALSE_ALARM, _varpro.ORDER_PENALTY = peak_false_alarm, order_penalty
    try:
        yield
    finally:
        _spectral.PEAK_FALSE_ALARM, _varpro.ORDER_PENALTY = old


def noise_std(n: int, gamma: float, snr_db: float) -> float:
    """Noise std that gives the weak mode the record SNR ``snr_db`` (dB).

    Parameters
    ----------
    n : int
        Samples.
    gamma : float
        Weak mode's damping, 1 / time unit.
    snr_db : float
        Record SNR ``10 log10(A^2 N_eff / (2 s^2))``, dB.

    Returns
    -------
    float
        The noise std ``s`` (units of the record).
    """
    neff = float(np.sum(np.exp(-2 * gamma * np.arange(n) * DT)))
    return math.sqrt(A_WEAK**2 / 2 * neff / 10 ** (snr_db / 10))


def trials(
    n: int, gamma: float, snr_db: float, count: int, seed: int, content: str
) -> dict[str, float]:
    """Detect ``count`` records and count kept weak modes and false modes.

    Parameters
    ----------
    n, gamma, snr_db : int, float, float
        Samples, weak mode's damping (1 / time unit), its record SNR (dB; sets the noise).
    count : int
        Records.
    seed : int
        Seed of the phases and the noise.
    content : {"two_modes", "one_mode", "noise"}
        Strong and weak mode, the strong mode only, or noise only.

    Returns
    -------
    dict
        ``keep`` (fraction of records holding the weak mode), ``false`` (false modes per
        record) and ``cpu_ms`` (process CPU time per detection, ms).
    """
    rng = np.random.default_rng(seed)
    t = np.arange(n) * DT
    s = noise_std(n, gamma, snr_db)
    kept = false = 0
    cpu = 0.0
    for _ in range(count):
        w = np.zeros(n)
        if content != "noise":
            w += 0.3 + np.exp(-0.5 * t) * np.cos(OM_STRONG * t + rng.uniform(0, 2 * math.pi))
        if content == "two_modes":
            w += A_WEAK * np.exp(-gamma * t) * np.cos(OM_WEAK * t + rng.uniform(0, 2 * math.pi))
        w += s * rng.standard_normal(n)
        c0 = time.process_time()
        det = detect(w, dt=DT)
        cpu += time.process_time() - c0
        oms = [m.omega for m in det.modes]
        kept += any(abs(o - OM_WEAK) < 3.0 for o in oms)
        true = (OM_WEAK, OM_STRONG) if content != "noise" else ()
        false += sum(all(abs(o - x) >= 3.0 for x in true) for o in oms)
    return {"keep": kept / count, "false": false / count, "cpu_ms": 1e3 * cpu / count}


def snr_rows(
    part: str, cases: list[str], snrs: list[float], count: int, seed: int,
    pfa: float = PEAK_FALSE_ALARM, pen: float = ORDER_PENALTY,
) -> list[dict[str, object]]:  # fmt: skip
    """Keep rate against record SNR (rows of part ``part``) at the thresholds ``pfa, pen``."""
    rows: list[dict[str, object]] = []
    with thresholds(pfa, pen):
        for ci, case in enumerate(cases):
            n, g = CASES[case]
            for si, snr in enumerate(snrs):
                r = trials(n, g, snr, count, seed + 1000 * ci + si, "two_modes")
                rows.append(_row(part, case, snr, pfa, pen, count, r["keep"], r["false"],
                                 math.nan, math.nan, r["cpu_ms"]))  # fmt: skip
            print(f"{part} {case}: " + " ".join(
                f"{r['snr_db']:g}dB={r['keep']:.3f}" for r in rows if r["case"] == case
            ), flush=True)  # fmt: skip
    return rows


def _row(part, case, snr, pfa, pen, count, keep, spur, f1, f0, cpu) -> dict[str, object]:
    return {
        "part": part, "case": case, "snr_db": snr, "peak_false_alarm": pfa,
        "order_penalty": pen, "trials": count, "keep": keep, "spurious_two_modes": spur,
        "false_one_mode": f1, "false_noise": f0, "cpu_ms": cpu,
    }  # fmt: skip


def trade_rows(
    cases: list[str], pfas: list[float], pens: list[float], count: int, seed: int
) -> list[dict[str, object]]:
    """At 15 dB, keep rate and false modes per record over a grid of the two thresholds."""
    rows: list[dict[str, object]] = []
    for case in cases:
        n, g = CASES[case]
        for pfa in pfas:
            for pen in pens:
                with thresholds(pfa, pen):
                    r2 = trials(n, g, 15.0, count, seed, "two_modes")
                    r1 = trials(n, g, 15.0, count, seed + 1, "one_mode")
                    r0 = trials(n, g, 15.0, count, seed + 2, "noise")
                rows.append(_row("trade", case, 15.0, pfa, pen, count, r2["keep"], r2["false"],
                                 r1["false"], r0["false"], r2["cpu_ms"]))  # fmt: skip
                print(f"trade {case} pfa={pfa:g} pen={pen:g}: keep {r2['keep']:.3f} false "
                      f"{r1['false']:.3f} / {r0['false']:.3f}", flush=True)  # fmt: skip
    return rows


def _band(r: np.ndarray, g: float, pad: int = 4) -> tuple[np.ndarray, np.ndarray, float]:
    """The band's frequencies ``omega`` (rad / sample, a ``pad``-times zero-padded FFT grid in
    ``(BAND_EDGE, pi - BAND_EDGE)``), ``Z(omega) = sum_n r_n w_n e^{-i omega n}`` there and
    ``S0 = sum_n w_n^2``, ``w_n = exp(-g n)`` (``g`` per sample)."""
    n = r.size
    w = np.exp(-g * np.arange(n))
    X = np.fft.rfft(r * w, pad * n)
    om = np.arange(X.size) * 2 * math.pi / (pad * n)
    sel = (om > BAND_EDGE) & (om < math.pi - BAND_EDGE)
    return om[sel], X[sel], float(w @ w)


def _matched_stat(r: np.ndarray, g: float, pad: int = 4) -> np.ndarray:
    """The matched damped-sinusoid statistic ``T(omega) = 2 |Z(omega)|^2 / S0`` on the band
    (``chi2_2`` on unit-variance white noise at any one frequency; see :func:`_band`)."""
    _, Z, s0 = _band(r, g, pad)
    return 2 * (Z.real**2 + Z.imag**2) / s0


@functools.lru_cache(maxsize=8)
def _phase_terms(n: int, g: float, energy: float, pad: int) -> tuple[float, np.ndarray]:
    """The record-independent part of :func:`_log_lr`: the amplitude ``a`` of a mode of
    ``energy`` noise variances and ``-(a^2 / 4) Re(e^{2 i phi} S2(omega))`` on the phases
    (rows) and the band's frequencies (columns), ``S2 = sum_n w_n^2 e^{2 i omega n}``."""
    om = _band(np.zeros(n), g, pad)[0]
    s0 = float(np.sum(np.exp(-2 * g * np.arange(n))))
    a = math.sqrt(2 * energy / s0)
    rho = np.exp(-2 * g + 2j * om)
    S2 = (1 - rho**n) / (1 - rho)
    phases = np.arange(PHASES) * 2 * math.pi / PHASES
    return a, -0.25 * a * a * (np.exp(2j * phases)[:, None] * S2[None, :]).real


def _log_lr(r: np.ndarray, g: float, energy: float, pad: int = 4) -> float:
    """Log of the Gaussian likelihood ratio of ``r`` (unit noise variance) between a damped
    cosine ``a w_n cos(omega n + phi)`` of ``energy`` noise variances (``a^2 S0 / 2``) and
    noise, averaged over the phase and the band's grid frequencies (the prior of
    :func:`_weak_record`). For each frequency the log ratio at phase ``phi`` is
    ``a Re(e^{i phi} conj Z) - (a^2 / 4) (S0 + Re(e^{2 i phi} S2))``; the phase average of its
    exponential is the :data:`PHASES`-point trapezoid rule, exact for a periodic analytic
    integrand up to its Fourier coefficients beyond that order (``~ I_64(A) / I_0(A)``,
    ``A = a |Z| < 60``: below 1e-8)."""
    _, Z, _ = _band(r, g, pad)
    a, quad = _phase_terms(r.size, g, energy, pad)
    phases = np.arange(PHASES) * 2 * math.pi / PHASES
    x = a * (np.exp(1j * phases)[:, None] * np.conj(Z)[None, :]).real + quad
    top = x.max(axis=0)
    per_om = top + np.log(np.mean(np.exp(x - top), axis=0))
    return float(logsumexp(per_om) - math.log(Z.size) - 0.5 * energy)


def _weak_record(rng: np.random.Generator, n: int, g: float, energy: float) -> np.ndarray:
    """Unit-variance noise plus a damped mode of ``energy`` noise variances (``g`` per
    sample), uniform phase, its frequency drawn uniformly from the band's grid (the prior the
    test of :func:`_log_lr` is optimal for)."""
    k = np.arange(n)
    w = np.exp(-g * k)
    a = math.sqrt(2 * energy / float(w @ w))
    grid = _band(np.zeros(n), g)[0]
    om = float(grid[rng.integers(grid.size)])
    return rng.standard_normal(n) + a * w * np.cos(om * k + rng.uniform(0, 2 * math.pi))


def bound_rows(
    cases: list[str], snrs: list[float], n0: int, n1: int, pfas: list[float], seed: int
) -> list[dict[str, object]]:
    """The Neyman-Pearson bound: detection probability at each false-alarm probability."""
    rows: list[dict[str, object]] = []
    for ci, case in enumerate(cases):
        n, gamma = CASES[case]
        g = gamma * DT
        scale = 1 if n <= 4000 else 4  # fewer trials for long records
        for si, snr in enumerate(snrs):
            rng = np.random.default_rng(seed + 100 * ci + si)
            e = 10 ** (snr / 10)
            h0 = np.array([_log_lr(rng.standard_normal(n), g, e) for _ in range(n0 // scale)])
            h1 = np.array([_log_lr(_weak_record(rng, n, g, e), g, e)
                           for _ in range(n1 // scale)])  # fmt: skip
            for pfa in pfas:
                thr = float(np.quantile(h0, 1 - pfa))
                rows.append({"part": "np_bound", "case": case, "snr_db": snr, "pfa": pfa,
                             "threshold": thr, "pd": float(np.mean(h1 > thr)),
                             "trials_h0": h0.size, "trials_h1": h1.size})  # fmt: skip
            pd = [r["pd"] for r in rows[-len(pfas):]]
            print(f"np_bound {case} {snr:g} dB: " + " ".join(
                f"PFA {p:g}: {d:.3f}" for p, d in zip(pfas, pd, strict=True)), flush=True)
    return rows


def glrt_rows(case: str, n0: int, n1: int, seed: int) -> list[dict[str, object]]:
    """GLRT at 15 dB with the damping searched or known: false alarms, detection and the
    effective number of independent cells ``P_FA / exp(-thr/2)`` per threshold."""
    n, gamma = CASES[case]
    g = gamma * DT
    grid = np.concatenate(([0.0], 0.5 / n * 1.25 ** np.arange(60)))
    grid = grid[grid < 0.05]
    ig = int(np.argmin(np.abs(grid - g)))
    rng = np.random.default_rng(seed)

    def maxima(r: np.ndarray) -> np.ndarray:
        return np.array([_matched_stat(r, gg).max() for gg in grid])

    h0 = np.array([maxima(rng.standard_normal(n)) for _ in range(n0)])
    h1 = np.array([maxima(_weak_record(rng, n, g, 10**1.5)) for _ in range(n1)])
    rows: list[dict[str, object]] = []
    for search, m0, m1 in (("gamma_searched", h0.max(1), h1.max(1)),
                           ("gamma_known", h0[:, ig], h1[:, ig])):  # fmt: skip
        for thr in np.arange(14.0, 36.1, 1.0):
            pfa = float(np.mean(m0 > thr))
            rows.append({"part": f"glrt_{search}", "case": case, "snr_db": 15.0, "pfa": pfa,
                         "threshold": float(thr), "pd": float(np.mean(m1 > thr)),
                         "trials_h0": n0, "trials_h1": n1,
                         "cells": pfa / math.exp(-thr / 2)})  # fmt: skip
    return rows


def snr_for(rows: list[dict[str, object]], key: str, level: float = 0.95) -> float:
    """Record SNR (dB) where ``key`` first reaches ``level``, linear between grid points
    (``nan`` if never; the first SNR if already there)."""
    pts = sorted((float(r["snr_db"]), float(r[key])) for r in rows)
    for (s0, k0), (s1, k1) in zip(pts, pts[1:], strict=False):
        if k0 >= level:
            return s0
        if k1 >= level:
            return s0 + (level - k0) / (k1 - k0) * (s1 - s0)
    return pts[-1][0] if pts and pts[-1][1] >= level else math.nan


def summary(det: list[dict[str, object]], bound: list[dict[str, object]]) -> str:
    """The text summary: SNR needed for 95 %, the trade at 15 dB, the bound."""
    out = ["# Weak-mode detection (bench/detector_weak.py)", ""]
    for part in ("snr", "snr_lowered"):
        for case in CASES:
            rs = [r for r in det if r["part"] == part and r["case"] == case]
            if not rs:
                continue
            p = rs[0]
            out.append(
                f"{part:11s} {case:10s} thresholds ({p['peak_false_alarm']:g}, "
                f"{p['order_penalty']:g}): 95 % kept at {snr_for(rs, 'keep'):.1f} dB; "
                + " ".join(f"{float(r['snr_db']):g}:{float(r['keep']):.2f}" for r in rs)
            )
    out += ["", "trade at 15 dB: peak_false_alarm order_penalty -> keep, false modes per "
            "record (two-mode extra, one-mode, noise)"]  # fmt: skip
    for r in (r for r in det if r["part"] == "trade"):
        out.append(
            f"  {r['case']:10s} {float(r['peak_false_alarm']):7g} {float(r['order_penalty']):4g}"
            f" -> {float(r['keep']):.3f}  {float(r['spurious_two_modes']):.3f} "
            f"{float(r['false_one_mode']):.3f} {float(r['false_noise']):.3f}"
        )
    out += ["", "Neyman-Pearson bound (known amplitude and damping; frequency uniform on "
            "the band's grid):"]  # fmt: skip
    for case in CASES:
        rs = [r for r in bound if r["part"] == "np_bound" and r["case"] == case]
        if not rs:
            continue
        at03 = [r for r in rs if r["pfa"] == FALSE_BOUND]
        at15 = [r for r in rs if r["snr_db"] == 15.0]
        pd15 = next((r["pd"] for r in at03 if r["snr_db"] == 15.0), math.nan)
        out.append(
            f"  {case:10s} P_D at 15 dB, P_FA {FALSE_BOUND:g}: {pd15:.3f}; 95 % needs "
            f"{snr_for(at03, 'pd'):.1f} dB at P_FA {FALSE_BOUND:g}; at 15 dB: "
            + " ".join(f"P_FA {r['pfa']:g}->{r['pd']:.3f}" for r in at15)
        )
    for r in (r for r in bound if str(r["part"]).startswith("glrt")):
        if 0.02 <= r["pfa"] <= 0.05:
            out.append(
                f"  {r['part']} {r['case']}: thr {r['threshold']:g} P_FA {r['pfa']:.3f} "
                f"P_D {r['pd']:.3f} effective cells {r['cells']:.0f}"
            )
    return "\n".join(out) + "\n"


def plot(det: list[dict[str, object]], bound: list[dict[str, object]], path: Path) -> None:
    """Left: keep rate against record SNR (detector, lowered thresholds, bound at
    ``P_FA = 0.03``). Right: at 15 dB, keep rate against false modes per record."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax, bx) = plt.subplots(1, 2, figsize=(12, 4.8))
    colours = dict(zip(CASES, ("C0", "C1", "C2"), strict=True))
    for case, col in colours.items():
        for part, style, label in (("snr", "-o", "detector"),
                                   ("snr_lowered", "--s", "lowered thresholds")):  # fmt: skip
            rs = sorted((r for r in det if r["part"] == part and r["case"] == case),
                        key=lambda r: float(r["snr_db"]))  # fmt: skip
            if rs:
                if part == "snr_lowered":
                    label += (f" (peak P_FA {float(rs[0]['peak_false_alarm']):g}, "
                              f"{float(rs[0]['order_penalty']):g} ln N)")  # fmt: skip
                ax.plot([r["snr_db"] for r in rs], [r["keep"] for r in rs], style, color=col,
                        ms=4, label=f"{label} {case}")  # fmt: skip
        rs = sorted((r for r in bound if r["part"] == "np_bound" and r["case"] == case
                     and r["pfa"] == FALSE_BOUND), key=lambda r: r["snr_db"])  # fmt: skip
        if rs:
            ax.plot([r["snr_db"] for r in rs], [r["pd"] for r in rs], ":", color=col, lw=2,
                    label=f"bound (P_FA {FALSE_BOUND:g}) {case}")  # fmt: skip
    ax.axhline(0.95, color="k", lw=0.8)
    ax.axvline(15.0, color="grey", lw=0.8)
    ax.set(xlabel="record SNR of the weak mode (dB)", ylabel="fraction of records kept",
           title="weak mode kept")  # fmt: skip
    ax.legend(fontsize=6.5)
    floor = 1.0 / (2 * max(int(r["trials"]) for r in det))
    for case, col in colours.items():
        rs = [r for r in det if r["part"] == "trade" and r["case"] == case]
        for pen in sorted({float(r["order_penalty"]) for r in rs}):
            line = sorted((r for r in rs if float(r["order_penalty"]) == pen),
                          key=lambda r: float(r["peak_false_alarm"]))  # fmt: skip
            bx.plot([max(float(r["false_one_mode"]), float(r["false_noise"]), floor)
                     for r in line], [float(r["keep"]) for r in line], "-o", color=col, ms=3,
                    lw=0.8, alpha=0.4 + 0.12 * pen,
                    label=f"{case} penalty {pen:g} ln N (peak P_FA 1e-3 to 1)")  # fmt: skip
        rs = sorted((r for r in bound if r["part"] == "np_bound" and r["case"] == case
                     and r["snr_db"] == 15.0), key=lambda r: r["pfa"])  # fmt: skip
        if rs:
            bx.plot([r["pfa"] for r in rs], [r["pd"] for r in rs], ":", color=col, lw=2,
                    label=f"bound {case}")  # fmt: skip
    gl = sorted((r["pfa"], r["pd"]) for r in bound if r["part"] == "glrt_gamma_searched"
                and r["pfa"] > 0)  # fmt: skip
    if gl:
        bx.plot(*zip(*gl, strict=True), "-.", color="k", lw=1, label="ideal GLRT, N4000_g3")
    bx.axhline(0.95, color="k", lw=0.8)
    bx.axvline(FALSE_BOUND, color="grey", lw=0.8)
    bx.set_xscale("log")
    bx.set(xlabel=f"false modes per record (max of one-mode and noise records; {floor:g} = none)",
           ylabel="fraction of 15 dB records kept", title="trade at 15 dB record SNR")
    bx.legend(fontsize=6)
    fig.tight_layout()
    fig.savefig(path, dpi=120)


def _write(path: Path, rows: list[dict[str, object]]) -> None:
    keys: list[str] = []
    for r in rows:
        keys += [k for k in r if k not in keys]
    with path.open("w", newline="") as fh:
        wr = csv.DictWriter(fh, fieldnames=keys)
        wr.writeheader()
        wr.writerows(rows)


def _read(path: Path) -> list[dict[str, object]]:
    def conv(k: str, v: str) -> object:
        return v if k in ("part", "case") else (float(v) if v != "" else math.nan)

    with path.open() as fh:
        return [{k: conv(k, v) for k, v in r.items()} for r in csv.DictReader(fh)]


def main(argv: list[str] | None = None) -> int:
    """Run the parts, write the CSVs, the summary and the figure."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="smoke run: few trials, few points")
    ap.add_argument("--trials", type=int, default=None, help="records per detector point")
    ap.add_argument("--seed", type=int, default=20261123)
    ap.add_argument("--out", type=Path, default=RESULTS)
    ap.add_argument("--plot-only", action="store_true", help="re-read the CSVs and re-plot")
    ap.add_argument(
        "--lowered", nargs=2, type=float, default=(0.3, 3.0), metavar=("PFA", "PENALTY"),
        help="thresholds of the snr_lowered part (peak false alarm, penalty in ln N)",
    )  # fmt: skip
    args = ap.parse_args(argv)
    det_csv, bound_csv = args.out / "detector_weak.csv", args.out / "detector_weak_bound.csv"
    if args.plot_only:
        det, bound = _read(det_csv), _read(bound_csv)
    else:
        quick = args.quick
        count = args.trials or (20 if quick else 200)
        if count < 2:
            ap.error(f"--trials: {count!r} must be >= 2")
        snrs = [15.0, 20.0] if quick else [float(s) for s in range(12, 23)]
        pfas = [1e-3, 1e-1] if quick else [1e-3, 1e-2, 1e-1, 0.3, 1.0]
        pens = [ORDER_PENALTY, 2.5] if quick else [ORDER_PENALTY, 3.0, 2.5, 2.0, 1.5]
        cases = list(CASES)[:1] if quick else list(CASES)
        c0 = time.process_time()
        det = snr_rows("snr", cases, snrs, count, args.seed)
        trade = trade_rows(cases[:2], pfas, pens, count, args.seed + 7)
        det += trade
        pfa, pen = args.lowered
        det += snr_rows("snr_lowered", cases[:2], snrs, count, args.seed + 11, pfa, pen)
        n0, n1 = (200, 100) if quick else (4000, 2000)
        bound = bound_rows(cases, [13.0, 14.0, 15.0, 16.0, 17.0, 18.0], n0, n1,
                           [0.01, FALSE_BOUND, 0.05, 0.1, 0.3], args.seed + 13)  # fmt: skip
        bound += glrt_rows(cases[0], n0 // 4 if quick else 1000, n1 // 4 if quick else 500,
                           args.seed + 17)  # fmt: skip
        print(f"CPU {time.process_time() - c0:.0f} s", flush=True)
        args.out.mkdir(parents=True, exist_ok=True)
        _write(det_csv, det)
        _write(bound_csv, bound)
    text = summary(det, bound)
    print(text)
    (args.out / "detector_weak.txt").write_text(text)
    plot(det, bound, args.out / "detector_weak.png")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
