"""The record advice keeps mains hum from aliasing onto or below the fundamental.

A lab sampling at 59.904 Hz with 60 Hz hum in its records sees the hum at 0.096 Hz, a line
slower than any mode. The reference here is independent of the formula in
:func:`service.analysis.sampling.mains_clear_dt`: each mains line is sampled at the advised
step and its apparent frequency read off a zero-padded periodogram.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from service.analysis.sampling import (
    MAINS_ALIAS_GUARD,
    MAINS_HARMONICS,
    MAINS_HZ,
    MAINS_MAX_SHORTENING,
    MAX_SAMPLES,
    mains_clear_dt,
)


def apparent_hz(f_hz: float, dt_s: float, n: int = 4096) -> float:
    """Where a line at ``f_hz`` sampled every ``dt_s`` seconds appears (periodogram peak)."""
    y = np.cos(2 * np.pi * f_hz * dt_s * np.arange(n) + 0.3)
    spec = np.abs(np.fft.rfft(y * np.hanning(n), 16 * n))
    return float(np.argmax(spec) / (16 * n * dt_s))


def lines_above(floor_hz: float) -> list[float]:
    return [m * f0 for f0 in MAINS_HZ for m in range(1, MAINS_HARMONICS + 1) if m * f0 > floor_hz]


@pytest.mark.parametrize(("f_fund", "fs", "spu"), [
    (1.198, 59.904, 1.0),      # the ten-lab session: 60 Hz seen at 0.096 Hz
    (0.5, 25.0, 1.0),          # 50 Hz on a multiple of fs: seen at 0 Hz
    (2.0, 100.0, 1.0),
    (1.198, 59.904, 1e-3),     # the same record written in milliseconds
    (7.3, 365.0, 1.0),
])  # fmt: skip
def test_every_mains_line_appears_above_the_fundamental(f_fund, fs, spu) -> None:
    dt = 1.0 / fs / spu
    omega = 2 * math.pi * f_fund * spu  # rad per time unit
    duration = 40 / f_fund / spu
    new = mains_clear_dt(dt, duration, omega, spu)
    assert dt / MAINS_MAX_SHORTENING <= new <= dt
    assert duration / new <= MAX_SAMPLES
    floor = MAINS_ALIAS_GUARD * f_fund
    for f in lines_above(floor):
        seen = apparent_hz(f, new * spu)
        assert seen > 0.95 * floor, (f, seen, floor)


def test_a_step_whose_aliases_are_already_clear_is_kept() -> None:
    # 1 kHz sampling leaves 50-300 Hz where they are, far above a 2 Hz fundamental
    dt = 1e-3
    assert mains_clear_dt(dt, 20.0, 2 * math.pi * 2.0, 1.0) == dt
    assert apparent_hz(60.0, dt) == pytest.approx(60.0, abs=0.05)


def test_no_line_above_the_fundamental_leaves_the_step() -> None:
    # a stiff structure at 400 Hz: every mains line lies below it, sampling cannot move them
    dt = 1.0 / 20_000
    assert mains_clear_dt(dt, 0.1, 2 * math.pi * 400.0, 1.0) == dt


def test_the_sample_budget_is_kept() -> None:
    # a record already at the most samples: no shorter step is allowed
    fs = 59.904
    dt = 1.0 / fs
    duration = MAX_SAMPLES * dt
    assert mains_clear_dt(dt, duration, 2 * math.pi * 1.198, 1.0) == dt


def test_nonsense_inputs_leave_the_step() -> None:
    assert mains_clear_dt(0.01, 10.0, 0.0, 1.0) == 0.01
    assert mains_clear_dt(0.01, 10.0, 5.0, 0.0) == 0.01
