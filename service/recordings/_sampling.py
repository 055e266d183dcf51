"""Uniform sampling: rounding of written timestamps vs irregular steps; resampling."""

from __future__ import annotations

import math

import numpy as np

from service.analysis.common import Flag
from service.recordings._errors import RecordingError
from service.recordings._record import UNIFORM_RTOL_ENV

_MAX_DIGIT_CELLS = 20_000  # cells read to tell how many digits the timestamps were written with


def _sig_digits(cell: str) -> tuple[int, int | None]:
    """(significant digits, decimals or None with an exponent) of a written number."""
    s = cell.strip().lstrip("+-")
    mant, _, exp = s.partition("e") if "e" in s else s.partition("E")
    decimals = len(mant.split(".", 1)[1]) if "." in mant and not exp else None
    digits = mant.replace(".", "").lstrip("0")
    return max(len(digits), 1), decimals


def _quanta(t: np.ndarray, cells: list[str] | None, idx: np.ndarray) -> tuple[np.ndarray, str]:
    """Half a unit in the last written digit of ``t[idx]``, and how the column was written.

    The column is read as fixed decimals (the largest values written with as many decimals as
    any: ``%.6f``, a logger's format) or as significant digits (``%.9g``; the most digits of any
    sampled cell, so that stripped trailing zeros do not widen the rounding). Binary arrays are
    read through their shortest round-trip text (``repr``), so exact float64 times get a
    rounding near 1e-16 and nothing is excused.
    """
    n = t.size
    step = max(1, n // _MAX_DIGIT_CELLS)
    sample = np.unique(np.concatenate([np.arange(0, n, step), idx]))
    if cells is not None:
        texts = [cells[i] for i in sample]
    else:
        texts = [repr(float(t[i])) for i in sample]
    info = [_sig_digits(c) for c in texts]
    decimals = [d for _, d in info]
    if None not in decimals:
        # fixed decimals: the largest values carry as many decimals as any value (with %g the
        # decimals fall as the magnitude grows; stripped trailing zeros only lower a few)
        top = np.argsort(np.abs(t[sample]))[-max(1, len(sample) // 10) :]
        nd = max(decimals)  # type: ignore[type-var]
        if max(decimals[i] for i in top) == nd:  # type: ignore[type-var]
            return np.full(idx.size, 0.5 * 10.0 ** (-nd)), f"{nd} decimals"
    digits = max(d for d, _ in info)
    mag = np.abs(t[idx])
    with np.errstate(divide="ignore"):
        e = np.where(mag > 0, np.floor(np.log10(np.where(mag > 0, mag, 1.0))), -np.inf)
    return 0.5 * 10.0 ** (e - digits + 1), f"{digits} significant digits"


def _least_squares_line(t: np.ndarray) -> tuple[float, float]:
    """``(dt, t0)`` of the least-squares line ``t_k = t0 + k dt``."""
    n = t.size
    k = np.arange(n, dtype=np.float64)
    kc = k - (n - 1) / 2.0
    tm = float(np.mean(t))
    dt = float(np.dot(kc, t - tm) / np.dot(kc, kc))
    return dt, tm - dt * (n - 1) / 2.0


def _uniform_grid(
    w: np.ndarray,
    t: np.ndarray,
    *,
    t_name: str,
    rtol: float,
    cells: list[str] | None,
    resample: bool,
) -> tuple[np.ndarray, np.ndarray | None, float, float, tuple[Flag, ...]]:
    """Check that ``t`` is uniform (within rounding); ``(w, t, dt, t0, flags)``."""
    d = np.diff(t)
    if (d <= 0).any():
        i = int(np.argmax(d <= 0)) + 1
        hint = ""
        if d[i - 1] == 0 and (d > 0).any() and float(np.median(d[d > 0])) > 0:
            # equal neighbours in a rising column: its digits are coarser than its step
            hint = (
                f"; the times repeat: they are written with too few digits (near "
                f"{float(abs(t[i])):.4g} they move in steps of {float(np.median(d[d > 0])):.3g}, "
                "coarser than the sampling, as '%.6g' writes them): write more digits, or "
                "the sample step (dt) without a time column"
            )
        raise RecordingError(
            f"{t_name}[{i}]",
            float(t[i]),
            f"must be strictly increasing (previous {t_name}[{i - 1}] = {float(t[i - 1])!r})"
            + hint,
        )
    n = t.size
    mean_step = (float(t[-1]) - float(t[0])) / (n - 1)
    # float64 itself rounds every time to its spacing: at an epoch offset (1.7e9 s) that is
    # 2.4e-7 s, a visible share of a 1e-4 s step; it is excused unless it reaches half a step
    sp = np.spacing(np.abs(t))
    fp = sp[:-1] + sp[1:]
    fp = np.where(fp < 0.5 * mean_step, fp, 0.0)
    if float(np.max(np.abs(d - mean_step) - fp)) <= rtol * mean_step:
        return w, t, mean_step, float(t[0]), ()
    dt, t0 = _least_squares_line(t)
    dev = np.abs(d - dt)
    bad = np.flatnonzero(dev > rtol * dt + fp)
    if bad.size == 0:  # uniform within the tolerance about the least-squares line
        return w, t, dt, t0, ()
    q, written = _quanta(t, cells, np.concatenate([bad, bad + 1]))
    rounding = q[: bad.size] + q[bad.size :]
    allowed = fp[bad] + np.where(rounding < 0.5 * dt, rounding * (1 + 1e-9) + rtol * dt, rtol * dt)
    excess = dev[bad] - allowed
    if (excess <= 0).all():
        worst = float(np.max(dev[bad]))
        flag = Flag(
            "rounded_timestamps",
            f"the {t_name} column is written with {written}: its steps deviate from the "
            f"least-squares step {dt:.9g} by up to {worst / dt:.2g} of a step, within the "
            f"rounding of the written values (+-{float(np.max(q)):.2g}); dt and t0 are the "
            f"least-squares line through the {n} timestamps",
        )
        return w, t, dt, t0, (flag,)
    worst = int(np.argmax(excess))
    j = int(bad[worst])
    if rounding[worst] >= 0.5 * dt and not resample:
        raise RecordingError(
            f"{t_name}[{j + 1}]",
            float(t[j + 1]),
            f"is written too coarsely to tell the sampling: its rounding ({written}, "
            f"+-{float(rounding[worst]):.2g} over a step) is as large as half the step "
            f"{dt:.6g}, so a lost or doubled sample cannot be told from rounding; write the "
            "times with more digits, or drop the time column and give dt",
        )
    if resample:
        step = float(np.median(d))
        m = int(math.floor((float(t[-1]) - float(t[0])) / step * (1 + 1e-12))) + 1
        grid = float(t[0]) + step * np.arange(m, dtype=np.float64)
        wr = np.interp(grid, t, w)
        flag = Flag(
            "resampled",
            f"the {t_name} column is not uniform (worst step {t_name}[{j + 1}] - "
            f"{t_name}[{j}] = {float(d[j]):.6g} against a median step {step:.6g}): the record "
            f"was interpolated linearly onto {m} uniform samples",
        )
        return wr, None, step, float(t[0]), (flag,)
    raise RecordingError(
        f"{t_name}[{j + 1}]",
        float(t[j + 1]),
        f"is not uniformly sampled: the step {t_name}[{j + 1}] - {t_name}[{j}] = "
        f"{float(d[j])!r} differs from the least-squares step {dt!r} by "
        f"{float(dev[j]) / dt:.3g} of a step, more than the rounding of the written "
        f"timestamps ({written}, +-{float(rounding[worst]):.2g}) and the "
        f"tolerance {rtol:g} explain (setting {UNIFORM_RTOL_ENV}); resample it onto a uniform "
        "grid with resample=true (CLI: --resample)",
    )
