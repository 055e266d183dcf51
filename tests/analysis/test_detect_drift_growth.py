"""A slow drift is a trend, never the fundamental; a growing record is always flagged unstable.

Lab cases: a clean damped oscillation plus a drift of a few micrometres over the record (the
slowest fitted "mode" was the drift, sigma^2 ~ -1e-7, and the true mode came second); growing
records past the transition (a single exp(+0.3 t) came back as a stable overdamped mode, a
growing oscillation without a flag, a 400x growth as ``no_mode``).
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from service.analysis.detect import FLAG_CODES, Mode, detect

DT, N = 0.5e-3, 8000  # 4 s at 2 kHz
T = np.arange(N) * DT
OMEGA, GAMMA = 2 * math.pi * 3.0, 0.5  # a few Hz
SIGMA2 = -(OMEGA**2 + GAMMA**2)


def _oscillation(seed: int, noise: float = 2e-3) -> np.ndarray:
    """200 um damped oscillation on a 1.7 mm offset with 2 um noise (mm)."""
    rng = np.random.default_rng(seed)
    return 0.2 * np.exp(-GAMMA * T) * np.sin(OMEGA * T) + 1.7 + noise * rng.standard_normal(N)


@pytest.mark.parametrize("drift", [4e-3, 1e-2, 2e-2])
@pytest.mark.parametrize("seed", [1, 2])
def test_a_slow_drift_is_a_trend_not_the_fundamental(drift: float, seed: int) -> None:
    """drift: mm over the 4 s record (4 um is 2 % of the amplitude)."""
    w = _oscillation(seed) + drift * T / T[-1]
    det = detect(w, dt=DT)
    f = det.fundamental
    assert f is not None and f.regime == "underdamped"
    assert abs(f.sigma2 - SIGMA2) < 5 * f.sigma2_std
    assert f.damping == pytest.approx(GAMMA, rel=0.01)
    assert "trend" in det.flag_codes and "trend" in FLAG_CODES
    assert not {"few_periods", "overdamped", "unstable"} & set(det.flag_codes)
    msg = next(x.message for x in det.flags if x.code == "trend")
    assert "set aside" in msg and "modes[1]" in msg
    assert det.modes[0] is f.mode


def test_a_drift_below_the_noise_changes_nothing() -> None:
    """0.6 um over the record (3e-3 of the amplitude): no trend mode, the same fundamental."""
    w = _oscillation(1) + 0.2 * 3e-3 * T / T[-1]
    det = detect(w, dt=DT)
    assert det.flag_codes == ()
    assert abs(det.fundamental.sigma2 - SIGMA2) < 5 * det.fundamental.sigma2_std


def test_drift_is_a_trend_at_any_scale() -> None:
    """The trend rule reads noise variances and rate x record length: equivariant."""
    w = _oscillation(3) + 4e-3 * T / T[-1]
    ref = detect(w, dt=DT)
    assert "trend" in ref.flag_codes
    for k, c in ((1e-6, 1e3), (2.0**40, 1e-5)):
        det = detect(k * w, dt=c * DT)
        assert det.flag_codes == ref.flag_codes
        assert det.fundamental.sigma2 == pytest.approx(ref.fundamental.sigma2 / c**2, rel=1e-9)


def test_when_every_mode_is_a_trend_there_is_no_fundamental() -> None:
    """A slow mode (|s| T = 0.4) made of a line is a trend; alone it is no fundamental."""
    from service.analysis.detect._modes import _fundamental, _trends

    slow = Mode(omega=0.1, frequency=0.1 / (2 * math.pi), damping=0.0, sigma2=-0.01,
                amplitude=0.1, phase=-math.pi / 2, omega_std=0.0, damping_std=0.0,
                sigma2_std=0.0)  # fmt: skip
    assert _trends([slow], n=N, dt=DT, noise_std=2e-3) == frozenset({0})
    # the same mode 10x faster completes 6 cycles: not a candidate
    fast = replace(slow, omega=1.0 * 2 * math.pi * 1.5, sigma2=-((2 * math.pi * 1.5) ** 2))
    assert _trends([fast], n=N, dt=DT, noise_std=2e-3) == frozenset()
    modes, order = _fundamental([slow], n=N, dt=DT, trend=frozenset({0}))
    assert order == [0] and modes == [slow]


def test_a_clean_record_has_no_trend() -> None:
    det = detect(_oscillation(5), dt=DT)
    assert det.flag_codes == ()


def test_a_slow_overdamped_fundamental_that_decays_is_kept() -> None:
    """Poles -0.4 and -5 (1/s) over 4 s: the slow one decays by e^-1.6 within the record,
    sqrt|sigma^2| T = 5.7 < 2 pi: a candidate, but far from a quadratic: still the
    fundamental."""
    rng = np.random.default_rng(6)
    r1, r2 = 0.4, 5.0
    w = 1.7 + 0.2 * (np.exp(-r1 * T) - np.exp(-r2 * T)) + 2e-3 * rng.standard_normal(N)
    det = detect(w, dt=DT)
    f = det.fundamental
    assert f is not None and f.regime == "overdamped"
    assert f.sigma2 == pytest.approx(-r1 * r2, rel=0.05)
    assert "trend" not in det.flag_codes and "unstable" not in det.flag_codes


def _message(det, code: str) -> str:
    return next(x.message for x in det.flags if x.code == code)


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_a_growing_exponential_is_unstable(seed: int) -> None:
    """0.1 exp(+0.3 t): was a stable overdamped mode with sigma^2 = -0.09 and no flag."""
    rng = np.random.default_rng(seed)
    w = 0.1 * np.exp(0.3 * T) + 2e-3 * rng.standard_normal(N)
    det = detect(w, dt=DT)
    assert "unstable" in det.flag_codes
    assert "equilibrium is unstable" in _message(det, "unstable")
    assert det.fundamental is not None


@pytest.mark.parametrize("seed", [1, 2])
def test_a_growing_oscillation_is_unstable(seed: int) -> None:
    rng = np.random.default_rng(seed)
    w = 0.1 * np.exp(0.5 * T) * np.sin(OMEGA * T) + 2e-3 * rng.standard_normal(N)
    det = detect(w, dt=DT)
    assert "unstable" in det.flag_codes
    f = det.fundamental
    assert f.damping == pytest.approx(-0.5, rel=0.01)


@pytest.mark.parametrize("growth", [400.0, 3e4])
def test_a_strongly_growing_record_is_found_and_unstable(growth: float) -> None:
    """A record growing 400x (e^6) was 'no_mode': ESPRIT candidates growing by more than e^5
    were dropped as window artefacts."""
    rng = np.random.default_rng(7)
    w = 0.01 * np.exp(math.log(growth) * T / T[-1]) + 2e-3 * rng.standard_normal(N)
    det = detect(w, dt=DT)
    assert det.fundamental is not None
    assert "unstable" in det.flag_codes and "no_mode" not in det.flag_codes


def test_decaying_records_are_not_unstable() -> None:
    for seed in range(4):
        det = detect(_oscillation(seed, noise=2e-2), dt=DT)
        assert "unstable" not in det.flag_codes


@pytest.mark.parametrize(("size", "tau"), [(0.002, 0.5), (0.02, 2.0), (0.08, 2.0), (0.2, 1.0)])
def test_a_relaxation_read_as_the_fundamental_is_flagged(size: float, tau: float) -> None:
    """A settling offset (creep, temperature: ``A exp(-t / tau)``, 1-40 % of the oscillation)
    does not complete a cycle and decays within the record: no quadratic absorbs it, so it is
    a mode, the slowest, and was read as the fundamental (an overdamped one at sigma^2 ~ 0, or
    an oscillation at 0.02-0.5 rad/s) with no word of the 3 Hz mode ringing beside it. When
    the slow component is the fundamental it carries ``relaxation``, which names the ringing
    mode; a kicked overdamped fundamental (two terms from rest) does not."""
    w = _oscillation(3) + size * np.exp(-T / tau)
    det = detect(w, dt=DT)
    if det.fundamental.omega < 1.0:  # the relaxation was taken for the fundamental
        assert "relaxation" in det.flag_codes, det.flag_codes
        msg = next(f.message for f in det.flags if f.code == "relaxation")
        assert f"{math.sqrt(-SIGMA2):.4g}"[:4] in msg
    else:
        assert det.fundamental.omega == pytest.approx(OMEGA, rel=1e-3)
    # an overdamped fundamental kicked from rest beside a ringing mode: no relaxation
    s1, s2 = 0.4, 3.0
    kicked = 0.3 * (np.exp(-s1 * T) - np.exp(-s2 * T)) + _oscillation(4, noise=2e-4) - 1.7
    det = detect(kicked, dt=DT)
    assert det.fundamental.regime == "overdamped"
    assert "relaxation" not in det.flag_codes, det.flags
