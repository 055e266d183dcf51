"""Weak modes: the bound of bench/detector_weak.py against closed forms, its threshold knobs.

The bench bounds what any detector can keep of a weak mode at a given false-mode rate (the
Neyman-Pearson test between noise and a mode of known amplitude and damping whose frequency
and phase are unknown). These tests check its statistic against the chi-square laws it must
follow, its averaged likelihood ratio against a brute-force Gaussian likelihood, and (slow)
that the bound at 15 dB record SNR is indeed below 95 % at 0.03 false modes per record.
"""

from __future__ import annotations

import importlib.util
import math
import sys
from pathlib import Path
from types import ModuleType

import numpy as np
import pytest
from scipy import stats
from scipy.special import ive


def _bench() -> ModuleType:
    if "detector_weak" in sys.modules:
        return sys.modules["detector_weak"]
    path = Path(__file__).resolve().parents[2] / "bench" / "detector_weak.py"
    spec = importlib.util.spec_from_file_location("detector_weak", path)
    assert spec is not None and spec.loader is not None
    mod = importlib.util.module_from_spec(spec)
    sys.modules["detector_weak"] = mod
    spec.loader.exec_module(mod)
    return mod


def _stat_at(r: np.ndarray, g: float, omega: float) -> float:
    """The matched statistic at one frequency, by direct sums (no FFT)."""
    n = np.arange(r.size)
    w = np.exp(-g * n)
    z = np.sum(r * w * np.exp(-1j * omega * n))
    return float(2 * abs(z) ** 2 / np.sum(w * w))


def test_matched_statistic_is_chi2_with_two_dof_and_noncentral_with_the_record_snr() -> None:
    """At one known frequency the statistic is ``chi2_2`` on noise (``P(T > x) = e^{-x/2}``)
    and ``chi2_2(E)`` with a mode of energy ``E`` noise variances: the bound's ``E`` is the
    record SNR of the tests. The FFT statistic equals the direct sum on the FFT grid."""
    b = _bench()
    rng = np.random.default_rng(3)
    n, g, om, e = 512, 0.01, 2 * math.pi * 64 / (4 * 512), 10 ** 1.2
    t0 = np.array([_stat_at(rng.standard_normal(n), g, om) for _ in range(3000)])
    k = np.arange(n)
    a = math.sqrt(2 * e / float(np.sum(np.exp(-2 * g * k))))
    t1 = np.array([
        _stat_at(rng.standard_normal(n) + a * np.exp(-g * k) * np.cos(om * k + ph), g, om)
        for ph in rng.uniform(0, 2 * math.pi, 3000)
    ])  # fmt: skip
    for x in (2.0, 6.0, 10.0):
        p = math.exp(-x / 2)
        assert np.mean(t0 > x) == pytest.approx(p, abs=4 * math.sqrt(p * (1 - p) / t0.size))
    for x in (10.0, 20.0, 30.0):
        p = float(stats.ncx2.sf(x, 2, e))
        assert np.mean(t1 > x) == pytest.approx(p, abs=4 * math.sqrt(p * (1 - p) / t1.size))
    r = rng.standard_normal(n)
    full = b._matched_stat(r, g)
    grid = np.arange(4 * n // 2 + 1) * 2 * math.pi / (4 * n)
    band = grid[(grid > b.BAND_EDGE) & (grid < math.pi - b.BAND_EDGE)]
    j = 37
    assert full[j] == pytest.approx(_stat_at(r, g, float(band[j])), rel=1e-9)


@pytest.mark.parametrize(("g", "omega"), [(0.02, 1.3), (0.02, 0.08), (0.0, 0.6)])
def test_averaged_likelihood_ratio_equals_the_gaussian_likelihood_by_quadrature(
    g: float, omega: float
) -> None:
    """The bench's likelihood ratio (from the FFT ``Z`` and the closed form ``S2``, 64
    phases) against the Gaussian likelihood ratio of the damped cosine computed sample by
    sample, averaged over the band's grid frequencies and 128 phases, for a record holding a
    mode near the band's edge (where ``|S2| / S0`` is largest), inside it, and undamped."""
    b = _bench()
    rng = np.random.default_rng(4)
    n, e = 256, 10 ** 1.1
    k = np.arange(n)
    w = np.exp(-g * k)
    a = math.sqrt(2 * e / float(w @ w))
    r = rng.standard_normal(n) + a * w * np.cos(omega * k + 0.4)
    band = b._band(r, g)[0]
    phases = np.arange(128) * 2 * math.pi / 128
    terms = []
    for om in band:
        s = a * w[None, :] * np.cos(om * k[None, :] + phases[:, None])
        x = s @ r - 0.5 * np.sum(s * s, axis=1)
        terms.append(float(np.log(np.mean(np.exp(x - x.max()))) + x.max()))
    expected = float(np.logaddexp.reduce(terms)) - math.log(band.size)
    assert b._log_lr(r, g, e) == pytest.approx(expected, abs=1e-6)
    # the 2 omega term of |s|^2 matters: leaving it out (a Bessel I0 per frequency) is off
    T = b._matched_stat(r, g)
    x = np.sqrt(e * T)
    no_2om = float(np.logaddexp.reduce(x + np.log(ive(0, x)))) - math.log(band.size) - e / 2
    assert abs(no_2om - expected) > 1e-3 if g > 0 else abs(no_2om - expected) < 1e-2


def test_lowering_the_named_thresholds_keeps_more_weak_modes() -> None:
    """The bench's knobs reach the detector: at 16 dB record SNR (N = 4000, damping 3) the
    shipped thresholds keep the weak mode in about 30 % of records, the lowered pair of
    docs/charts.md (peak probability 0.3, 3 ln N) in about 71 % (bench/results/
    detector_weak.txt); on the same 40 records the difference is about 5 standard errors
    (0.1), the assertion asks for half of it. The defaults come back on exit."""
    b = _bench()
    from service.analysis.detect import _spectral, _varpro

    defaults = (_spectral.PEAK_FALSE_ALARM, _varpro.ORDER_PENALTY)
    assert defaults == (b.PEAK_FALSE_ALARM, b.ORDER_PENALTY)
    shipped = b.trials(4000, 3.0, 16.0, 40, 11, "two_modes")["keep"]
    with b.thresholds(0.3, 3.0):
        assert (_spectral.PEAK_FALSE_ALARM, _varpro.ORDER_PENALTY) == (0.3, 3.0)
        lowered = b.trials(4000, 3.0, 16.0, 40, 11, "two_modes")["keep"]
    assert (_spectral.PEAK_FALSE_ALARM, _varpro.ORDER_PENALTY) == defaults
    assert lowered - shipped >= 0.25


@pytest.mark.slow
def test_no_detector_keeps_95_percent_at_15_db_with_003_false_modes() -> None:
    """The issue asks for 95 % at 15 dB record SNR; the slow retention test allows 0.03 false
    modes per record. The Neyman-Pearson bound (known amplitude and damping, N = 4000,
    damping 3) keeps 91 % at that false-alarm rate (bench: 0.912 over 2000 records); 1500
    noise records and 800 mode records tell it from 95 % by about 4 standard deviations.
    At 17 dB the same bound is above 95 % (the chart's dotted line crosses 95 % near 15.6 dB)."""
    b = _bench()
    rows = b.bound_rows(["N4000_g3"], [15.0, 17.0], 1500, 800, [0.03], seed=99)
    pd15, pd17 = (r["pd"] for r in rows)
    assert 0.8 < pd15 < 0.95
    assert pd17 > 0.97
