"""Monte-Carlo checks: reported standard errors match the scatter, RMSE sits at the CRB."""

from __future__ import annotations

import math

import numpy as np
import pytest

from service.analysis.crb import Overdamped, Underdamped, crb, synthesize
from service.analysis.detect import detect
from service.analysis.detect._flags import _shifted_coefficients
from service.analysis.detect._kernels import model_values


def _trials(modes_fn, n, dt, noise, trials, seed, **kw):
    """Run ``trials`` noisy records; return errors, reported stds and CRB stds (fundamental)."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) * dt
    err, rep, bnd = [], [], []
    for _ in range(trials):
        modes = modes_fn(rng)
        w = synthesize(t, modes, 0.3) + noise * rng.standard_normal(n)
        det = detect(w, dt=dt, **kw)
        f = det.fundamental
        m0 = modes[0]
        true_om = m0.omega if isinstance(m0, Underdamped) else 0.0
        err.append((f.omega - true_om, f.damping - m0.damping, f.sigma2 - m0.sigma2))
        rep.append((f.omega_std, f.damping_std, f.sigma2_std))
        b = crb(t, modes, noise, common_damping=kw.get("common_damping", False))
        bnd.append((b.omega_std[0], b.damping_std[0], b.sigma2_std[0]))
    return np.array(err), np.array(rep), np.array(bnd)


def _beam(rng, om1=40.0, xi=1e-2, cycles=30.0):
    om = om1 * (1 + rng.uniform(-0.5, 0.5) / cycles)
    ph = rng.uniform(-math.pi, math.pi, 3)
    return [
        Underdamped(om, xi / 2, 1e-3, ph[0]),
        Underdamped(2.5 * om, xi / 2, 4e-4, ph[1]),
        Underdamped(5.0 * om, xi / 2, 2e-4, ph[2]),
    ]


def _noise(snr_db: float) -> float:
    return 1e-3 / math.sqrt(2) / 10 ** (snr_db / 20)


def test_shifted_coefficients_continue_the_same_response() -> None:
    p = np.array([2e-3, 0.01, 0.05])
    q = np.array([4e-2, 1e-5, 0.3])
    c = np.array([0.3, 1.0, -2.0, 0.5, 4.0, -1.0, 0.2])
    full = np.empty(900)
    model_values(p, q, c, full)
    h = 400
    c2 = _shifted_coefficients(p, q, c, h)
    tail = np.empty(500)
    model_values(p, q, c2, tail)
    np.testing.assert_allclose(tail, full[h:], rtol=0, atol=1e-9 * np.abs(full).max())


def test_reported_errors_match_the_scatter_quick() -> None:
    """40 records at 20 dB, 30 cycles: ratios within the sampling error of 40 trials."""
    n, dt = 4000, 30 * 2 * math.pi / (40.0 * 4000)
    err, rep, bnd = _trials(_beam, n, dt, _noise(20), 40, seed=100)
    rmse = np.sqrt(np.mean(err**2, axis=0))
    # 40 trials: the RMSE itself scatters by ~11 % (1 / sqrt(2 x 40))
    assert np.all(rmse / np.mean(bnd, axis=0) < 1.35)
    assert np.all(np.abs(np.mean(rep, axis=0) / rmse - 1) < 0.35)
    # the reported standard errors are the Cramer-Rao bound of each record
    np.testing.assert_allclose(rep, bnd, rtol=0.1)


@pytest.mark.slow
@pytest.mark.parametrize("snr_db", [0.0, 20.0, 40.0])
@pytest.mark.parametrize("cycles", [3.0, 100.0])
def test_rmse_at_the_cramer_rao_bound(snr_db: float, cycles: float) -> None:
    """400 records per cell: RMSE / CRB within 1.1 (sampling error ~3.5 %) for omega, damping
    and sigma^2, and the mean reported standard error within 25 % of the empirical scatter."""
    n = 10_000
    dt = cycles * 2 * math.pi / (40.0 * n)
    err, rep, bnd = _trials(
        lambda rng: _beam(rng, cycles=cycles), n, dt, _noise(snr_db), 400, seed=int(snr_db + cycles)
    )
    rmse = np.sqrt(np.mean(err**2, axis=0))
    crb_rms = np.sqrt(np.mean(bnd**2, axis=0))
    assert np.all(rmse / crb_rms < 1.1), rmse / crb_rms
    assert np.all(np.abs(np.sqrt(np.mean(rep**2, axis=0)) / rmse - 1) < 0.25)


@pytest.mark.slow
def test_common_damping_rmse_at_its_bound() -> None:
    n = 10_000
    dt = 30 * 2 * math.pi / (40.0 * n)
    err, rep, bnd = _trials(_beam, n, dt, _noise(10), 300, seed=7, common_damping=True)
    rmse = np.sqrt(np.mean(err**2, axis=0))
    crb_rms = np.sqrt(np.mean(bnd**2, axis=0))
    assert np.all(rmse / crb_rms < 1.1), rmse / crb_rms


@pytest.mark.slow
def test_overdamped_sigma2_at_the_bound() -> None:
    od = Overdamped.kicked(-0.5, 2.0, 1e-3)

    def modes(rng):
        ph = rng.uniform(-math.pi, math.pi, 2)
        return [od, Underdamped(40.0, 1.0, 5e-4, ph[0]), Underdamped(100.0, 1.0, 3e-4, ph[1])]

    err, rep, bnd = _trials(modes, 10_000, 2e-3, _noise(30), 300, seed=11)
    rmse_s2 = math.sqrt(np.mean(err[:, 2] ** 2))
    crb_s2 = math.sqrt(np.mean(bnd[:, 2] ** 2))
    assert rmse_s2 / crb_s2 < 1.1
    assert abs(math.sqrt(np.mean(rep[:, 2] ** 2)) / rmse_s2 - 1) < 0.25
