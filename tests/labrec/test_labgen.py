"""The lab-record generator against independent references: a least-squares fit of the
ring-down, scipy's ODE integrator during the contact, finite differences for the derivatives,
a DFT for the hum, the noise's variance for the SNR. Each reference is computed here, not in
the generator."""

from __future__ import annotations

import math
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.optimize import least_squares

sys.path.insert(0, str(Path(__file__).parent))
import labgen as L  # noqa: E402

OFF = {"pretrigger": False, "hum": False, "drift": False, "noise": False, "clipping": False,
       "repeats": False}  # fmt: skip


def _ode(modes: L.Modes, tau: float, t_end: float, t: np.ndarray) -> np.ndarray:
    """(x, x', x'') of every mode by solve_ivp (contact and free parts integrated apart, so the
    force's kink at tau is a step boundary): shape (3, modes, len(t))."""
    out = np.zeros((3, len(modes.f0_hz), t.size))
    for k, (f, z) in enumerate(zip(modes.f0_hz, modes.zeta, strict=True)):
        w0 = 2 * math.pi * f
        g = z * w0

        def rhs(s: float, x: np.ndarray, on: bool, g: float = g, w0: float = w0) -> list:
            force = math.sin(math.pi * s / tau) if on else 0.0
            return [x[1], force - 2 * g * x[1] - w0 * w0 * x[0]]

        a = solve_ivp(rhs, (0, tau), [0, 0], args=(True,), rtol=1e-11, atol=1e-16,
                      dense_output=True, method="DOP853")  # fmt: skip
        b = solve_ivp(rhs, (tau, t_end), a.y[:, -1], args=(False,), rtol=1e-11, atol=1e-16,
                      dense_output=True, method="DOP853")  # fmt: skip
        inside = t <= tau
        x = np.where(inside, a.sol(np.minimum(t, tau)), b.sol(np.maximum(t, tau)))
        force = np.where(inside, np.sin(np.pi * np.minimum(t, tau) / tau), 0.0)
        out[0, k], out[1, k] = x
        out[2, k] = force - 2 * g * x[1] - w0 * w0 * x[0]
    return out


@pytest.mark.parametrize("zeta", [0.003, 0.05, 1.7])  # light, heavy, overdamped
@pytest.mark.parametrize("tau", [2e-3, 30e-3])
def test_modal_response_matches_solve_ivp_during_and_after_contact(zeta: float, tau: float):
    modes = L.Modes((9.0, 31.0, 77.0), (zeta, 0.01, 0.02), (1.0, -0.6, 0.4))
    t = np.r_[np.linspace(0, tau, 201), np.linspace(tau, 0.4, 400)[1:]]
    ref = _ode(modes, tau, 0.4, t)
    for order in range(3):
        mine = np.array([L.modal_response(t, f, z, tau, order)
                         for f, z in zip(modes.f0_hz, modes.zeta, strict=True)])  # fmt: skip
        scale = np.max(np.abs(ref[order]), axis=1, keepdims=True)
        assert np.max(np.abs(mine - ref[order]) / scale) < 1e-7, order
        contact = t <= tau  # the forced part alone
        assert np.max(np.abs(mine - ref[order])[:, contact] / scale) < 1e-7
    # the probe's sum of modes
    y = L.response(t, modes, tau, 0)
    np.testing.assert_allclose(y, np.asarray(modes.coef) @ ref[0], atol=1e-7 * np.abs(y).max())


def test_ring_down_frequency_and_decay_match_a_least_squares_fit():
    modes = L.Modes((13.0,), (0.012,), (1.0,))
    lab = L.Lab(quantity="displacement", fs=2000.0, duration=3.0, pulse_s=8e-3)
    rec = L.synthesize(modes, lab, np.random.default_rng(0))
    free = rec.t > lab.pulse_s
    t, y = rec.t[free], rec.y[free]

    def resid(p: np.ndarray) -> np.ndarray:
        a, g, w, ph = p
        return a * np.exp(-g * t) * np.cos(w * t + ph) - y

    # start from an FFT peak and a rough decay, not from the truth
    spec = np.abs(np.fft.rfft(y, 8 * y.size))
    w_fft = 2 * math.pi * np.argmax(spec) / (8 * y.size * rec.dt)
    fit = least_squares(resid, [np.abs(y).max(), 0.5, w_fft, 0.0], xtol=1e-14, ftol=1e-14)
    a, g, w, ph = fit.x
    tr = rec.truth
    assert w == pytest.approx(tr.omega, rel=1e-8)
    assert g == pytest.approx(tr.gamma, rel=1e-6)
    assert tr.omega == pytest.approx(2 * math.pi * tr.f_hz)
    assert tr.sigma2 == pytest.approx(-(tr.gamma**2 + tr.omega**2), rel=1e-12)
    assert tr.p == pytest.approx(2 * g, rel=1e-6)
    assert tr.zeta == pytest.approx(g / math.sqrt(g * g + w * w), rel=1e-6)


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_velocity_and_acceleration_are_the_derivatives_of_displacement(seed: int):
    rng = np.random.default_rng(seed)
    modes = L.draw_modes(rng)
    lab = L.Lab(fs=40000.0, duration=0.5, pulse_s=float(rng.uniform(2e-3, 30e-3)),
                pretrigger=0.1)  # fmt: skip
    d, v, a = (L.synthesize(modes, replace(lab, quantity=q), np.random.default_rng(0))
               for q in L.QUANTITIES)  # fmt: skip
    assert (d.unit, v.unit, a.unit) == ("mm", "mm/s", "m/s2")
    h = d.dt
    # 4th-order central differences, away from the force's kinks (the kick and its end)
    smooth = np.ones(d.y.size - 4, dtype=bool)
    for t_kink in (0.1 * lab.duration, 0.1 * lab.duration + lab.pulse_s):
        smooth[np.abs(d.t[2:-2] - t_kink) < 3 * h] = False
    assert smooth.sum() > 0.99 * smooth.size
    dv = (-d.y[4:] + 8 * d.y[3:-1] - 8 * d.y[1:-3] + d.y[:-4]) / (12 * h)
    np.testing.assert_allclose(dv[smooth], v.y[2:-2][smooth], atol=1e-5 * np.abs(v.y).max())
    da = (-v.y[4:] + 8 * v.y[3:-1] - 8 * v.y[1:-3] + v.y[:-4]) / (12 * h)
    np.testing.assert_allclose(1e-3 * da[smooth], a.y[2:-2][smooth],
                               atol=1e-5 * np.abs(a.y).max())  # fmt: skip


def test_the_pre_trigger_is_at_rest_and_the_kick_starts_after_it():
    rec = L.draw_record(5, **{**OFF, "pretrigger": 0.25}, quantity="velocity")
    k0 = rec.kick_index
    assert k0 == pytest.approx(0.25 * rec.y.size, abs=1)
    assert np.all(rec.y[:k0] == 0.0)
    assert np.abs(rec.y[k0 + 1 : k0 + 20]).max() > 0
    # the static deflection of a displacement record is its rest level
    modes = L.Modes((10.0,), (0.01,), (1.0,))
    lab = L.Lab(pretrigger=0.2, static_mm=1.25)
    rec = L.synthesize(modes, lab, np.random.default_rng(0))
    assert np.all(rec.y[: rec.kick_index] == 1.25)
    assert rec.truth.static == 1.25


def _dft_amp(y: np.ndarray, f: float, dt: float) -> float:
    """Amplitude of the line at f by a Hann-windowed DFT at that frequency."""
    w = np.hanning(y.size)
    n = np.arange(y.size)
    return float(2 * np.abs(np.sum(w * y * np.exp(-2j * np.pi * f * dt * n))) / np.sum(w))


@pytest.mark.parametrize("mains", [50.0, 60.0])
def test_hum_frequency_and_amplitude_from_a_dft(mains: float):
    rec = L.draw_record(7, **{**OFF, "pretrigger": 0.3, "hum": 0.08}, quantity="acceleration",
                        mains_hz=mains, fs=2000.0, duration=4.0)  # fmt: skip
    rest = rec.y[: rec.kick_index]  # hum alone
    pad = 16 * rest.size
    spec = np.abs(np.fft.rfft(np.hanning(rest.size) * rest, pad))
    f_peak = np.argmax(spec) / (pad * rec.dt)
    assert f_peak == pytest.approx(mains, abs=0.05)
    peak = np.abs(rec.y[rec.kick_index :] - rec.parts["hum"][rec.kick_index :]).max()
    assert _dft_amp(rest, mains, rec.dt) == pytest.approx(0.08 * peak, rel=0.02)
    third = dict(rec.lab.harmonics)[3]
    assert 0.2 <= third <= 0.6
    assert _dft_amp(rest, 3 * mains, rec.dt) == pytest.approx(third * 0.08 * peak, rel=0.02)


@pytest.mark.parametrize("snr", [15.0, 25.0, 40.0])
def test_the_noise_has_the_snr_drawn(snr: float):
    rng = np.random.default_rng(9)
    modes = L.draw_modes(rng)
    lab = L.draw_lab(rng, modes, **{**OFF, "noise": snr})
    noisy = L.synthesize(modes, lab, np.random.default_rng(1))
    clean = L.synthesize(modes, replace(lab, snr_db=None), np.random.default_rng(1))
    noise = noisy.y - clean.y
    measured = 10 * np.log10(np.abs(clean.y).max() ** 2 / (2 * np.var(noise)))
    assert measured == pytest.approx(snr, abs=4 * 10 / np.log(10) / math.sqrt(noise.size / 2))
    assert abs(np.mean(noise)) < 5 * np.std(noise) / math.sqrt(noise.size)


def test_random_draws_stay_in_their_ranges_and_switches_force_them():
    for seed in range(40):
        rec = L.draw_record(seed, **{k: True for k in OFF})
        lab = rec.lab
        assert 0.02 <= lab.pretrigger <= 0.30 and 0.005 <= lab.hum <= 0.10
        assert lab.mains_hz in (50.0, 60.0) and 15 <= lab.snr_db <= 40
        assert 2e-3 <= lab.pulse_s <= 30e-3 and 1000 <= lab.fs <= 5000
        assert 1 <= len(lab.kicks) <= 2 and 0.6 <= lab.clip <= 0.9
        assert rec.clipped is not None and rec.clipped.any()
        assert np.abs(rec.y).max() == pytest.approx(lab.clip * np.abs(
            rec.parts["response"] + rec.parts["hum"] + rec.parts["drift"]
            + rec.parts["noise"]).max())  # fmt: skip
        assert rec.y.size <= L.RANGES["max_samples"]
        assert 2 <= len(rec.modes.f0_hz) <= 3 and rec.modes.f0_hz[0] < min(rec.modes.f0_hz[1:])
        # the highest mode and every hum line below 0.8 x Nyquist
        assert max(rec.modes.f0_hz) < 0.4 * lab.fs and 5 * lab.mains_hz < 0.4 * lab.fs
    rec = L.draw_record(3, **OFF)
    assert rec.lab == replace(rec.lab, pretrigger=0.0, hum=0.0, offset=0.0, ramp=0.0, wobble=0.0,
                              snr_db=None, clip=None, kicks=())  # fmt: skip
    # the same seed, the same record
    a, b = L.draw_record(17), L.draw_record(17)
    assert np.array_equal(a.y, b.y) and a.truth == b.truth


def test_repeated_kicks_superpose_and_drift_is_the_baseline():
    modes = L.Modes((8.0, 30.0), (0.01, 0.01), (1.0, 0.5))
    lab = L.Lab(quantity="velocity", duration=3.0, pretrigger=0.1)
    one = L.synthesize(modes, lab, np.random.default_rng(0))
    two = L.synthesize(modes, replace(lab, kicks=((0.5, 0.7),)), np.random.default_rng(0))
    k = int(round(0.5 * lab.duration * lab.fs))
    extra = two.y - one.y
    assert np.all(extra[: k + 1] == 0) and np.abs(extra[k + 2 :]).max() > 0
    # the second kick is the first, delayed and scaled
    n = one.y.size - k
    k0 = int(round(0.1 * lab.duration * lab.fs))
    np.testing.assert_allclose(extra[k:], 0.7 * one.y[k0 : k0 + n], atol=1e-9 * np.abs(one.y).max())
    drifted = L.synthesize(modes, replace(lab, offset=0.5, ramp=0.2, wobble=0.0),
                           np.random.default_rng(0))  # fmt: skip
    peak = np.abs(one.y).max()
    base = drifted.y - one.y
    np.testing.assert_allclose(base, peak * (0.5 + 0.2 * one.t / lab.duration), rtol=1e-12)
