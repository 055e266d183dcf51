"""The detector on clean and extreme records it did not make: noise-free lab files, combination
tones of a nonlinear response, unit changes over 24 decades, weak fast-decaying modes, and
parameter errors as data."""

from __future__ import annotations

import io
import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from service.analysis.detect import NOISE_FLOOR, detect
from service.analysis.errors import ParameterError

# --------------------------------------------------------------------------------------------
# Noise-free records written as a lab writes them
# --------------------------------------------------------------------------------------------


def lab_file(t: np.ndarray, w: np.ndarray) -> tuple[np.ndarray, float]:
    """Write ``t, w`` as a CSV with 9 significant digits (``%.9g``, what loggers write), read it
    back, and estimate the step by least squares on the rounded time column."""
    buf = io.StringIO()
    buf.write("time_s,deflection_m\n")
    for a, b in zip(t, w, strict=True):
        buf.write(f"{a:.9g},{b:.9g}\n")
    data = np.loadtxt(io.StringIO(buf.getvalue()), delimiter=",", skiprows=1)
    tt, ww = data[:, 0], data[:, 1]
    dt = float(np.polyfit(np.arange(tt.size), tt, 1)[0])
    return ww, dt


OMEGA_7HZ = 2 * math.pi * 7.0  # 43.98 rad/s


@pytest.mark.parametrize(
    ("fs", "gamma", "phase"),
    [
        (1000.0, 0.0, -math.pi / 2),  # the case: an undamped 7 Hz sine, no offset
        (1000.0, 0.5, -math.pi / 2),
        (500.0, 1.0, -math.pi / 2),  # was: fundamental 0.0 (an overdamped ghost of 2e-14)
        (4000.0, 0.2, -math.pi / 2),  # was: fundamental 7.48 (a ghost of amplitude 4e-11)
        (500.0, 0.2, 0.0),  # was: fundamental 30.8
        (100.0, 0.2, 0.0),  # was: the true mode twice at half amplitude
        (4000.0, 3.0, 0.0),
    ],
)
def test_noise_free_damped_sine_from_a_lab_file(fs: float, gamma: float, phase: float) -> None:
    n = 4000
    t = np.arange(n) / fs
    w, dt = lab_file(t, np.exp(-gamma * t) * np.cos(OMEGA_7HZ * t + phase))
    det = detect(w, dt=dt)
    assert len(det.modes) == 1, [(m.omega, m.amplitude) for m in det.modes]
    f = det.fundamental
    assert f.omega == pytest.approx(OMEGA_7HZ, rel=1e-7)
    assert f.damping == pytest.approx(gamma, abs=1e-6)
    assert det.modes[0].amplitude == pytest.approx(1.0, rel=1e-6)  # not twice at 0.5
    assert det.flag_codes == ()  # no "nonlinear" from rounding
    # the noise is at most the numerical floor (the file's %.9g rounding is below it)
    assert det.noise_std <= 1.01 * NOISE_FLOOR * np.std(w)


def test_noise_free_multi_mode_records_have_no_spurious_modes() -> None:
    """40 random noise-free records (1-3 modes, 3 to 9 decades of amplitude, offsets, lab
    rounding of t): exactly the modes put in, the fundamental at 7 Hz, no flag."""
    rng = np.random.default_rng(2026)
    ratios = np.array([1.0, 2.76, 5.40])  # a clamped strip's ratios: no sum or difference
    done = 0
    while done < 40:
        n = int(rng.choice([1000, 4000, 10000]))
        K = int(rng.integers(1, 4))
        fs = float(10 ** rng.uniform(2.0, 3.5))
        if 7.0 * ratios[K - 1] > 0.3 * fs or n / fs * 7.0 < 3:
            continue
        g = 10 ** rng.uniform(-3, 0, K)
        a = np.array([1.0, 0.4, 0.2])[:K] * 10 ** rng.uniform(-9, 9)
        ph = rng.uniform(0, 2 * math.pi, K)
        t = np.arange(n) / fs
        x = sum(
            a[k] * np.exp(-g[k] * t) * np.cos(2 * math.pi * 7.0 * ratios[k] * t + ph[k])
            for k in range(K)
        )
        w, dt = lab_file(t, float(rng.choice([0.0, 0.3, -50.0])) * a[0] + x)
        det = detect(w, dt=dt)
        assert len(det.modes) == K, (n, fs, K, [(m.omega, m.amplitude) for m in det.modes])
        assert det.fundamental.omega == pytest.approx(OMEGA_7HZ, rel=1e-6)
        assert det.flag_codes == ()
        done += 1


# --------------------------------------------------------------------------------------------
# Combination tones of a quadratic nonlinearity
# --------------------------------------------------------------------------------------------


@pytest.mark.parametrize("noise", [0.0, 1e-5])
def test_quadratic_product_tone_is_marked_and_never_the_fundamental(noise: float) -> None:
    """Two modes (30 and 42 rad/s) plus eps x1 x2: the record also holds 12 = 42 - 30 and
    72 = 42 + 30 rad/s. The slowest line (12) is a combination tone, not the fundamental."""
    n, dt = 8000, 2e-3
    t = np.arange(n) * dt
    x1 = 1.0e-2 * np.exp(-0.05 * t) * np.cos(30.0 * t + 0.4)
    x2 = 0.7e-2 * np.exp(-0.08 * t) * np.cos(42.0 * t + 1.9)
    w = 0.1 + x1 + x2 + 8.0 * x1 * x2
    w = w + noise * np.random.default_rng(3).standard_normal(n)
    det = detect(w, dt=dt)
    om = [m.omega for m in det.modes]
    assert abs(det.fundamental.omega - 30.0) <= 5 * det.fundamental.omega_std + 3e-5
    k12 = int(np.argmin(np.abs(np.array(om) - 12.0)))
    k72 = int(np.argmin(np.abs(np.array(om) - 72.0)))
    for k, target in ((k12, 12.0), (k72, 72.0)):  # within 5 of the detector's own errors
        assert abs(om[k] - target) <= 5 * det.modes[k].omega_std + 1e-6 * target
    k30, k42 = om.index(det.fundamental.omega), int(np.argmin(np.abs(np.array(om) - 42.0)))
    assert det.modes[k12].combination == f"omega[{k42}] - omega[{k30}]"
    assert det.modes[k72].combination == f"omega[{k42}] + omega[{k30}]"
    assert det.modes[k30].combination is None and det.modes[k42].combination is None
    assert "combination_tone" in det.flag_codes
    # the linear record: no tone, no flag
    lin = detect(0.1 + x1 + x2 + noise * np.random.default_rng(3).standard_normal(n), dt=dt)
    assert len(lin.modes) == 2 and "combination_tone" not in lin.flag_codes


@pytest.mark.parametrize("noise", [0.0, 1e-5])
def test_quadratic_square_offset_and_tones_are_not_the_fundamental(noise: float) -> None:
    """eps (x1 + x2)^2 adds, besides the tones, a mean shift decaying at 2 gamma_1, 2 gamma_2
    and gamma_1 + gamma_2 (the zero-frequency difference tones): fitted as an overdamped pair,
    it must be marked and not taken for an overdamped fundamental."""
    n, dt = 8000, 2e-3
    t = np.arange(n) * dt
    x1 = 1.0e-2 * np.exp(-0.05 * t) * np.cos(30.0 * t + 0.4)
    x2 = 0.7e-2 * np.exp(-0.08 * t) * np.cos(42.0 * t + 1.9)
    w = 0.1 + x1 + x2 + 8.0 * (x1 + x2) ** 2
    det = detect(w + noise * np.random.default_rng(4).standard_normal(n), dt=dt)
    assert det.fundamental.regime == "underdamped"
    assert abs(det.fundamental.omega - 30.0) <= 5 * det.fundamental.omega_std + 3e-5
    slow = [m for m in det.modes if m.regime == "overdamped"]
    assert slow and all(m.combination is not None and "decaying offset" in m.combination
                        for m in slow)  # fmt: skip
    tones = {round(m.omega): m.combination for m in det.modes if m.regime == "underdamped"}
    assert tones[30] is None and tones[42] is None
    assert all(tones[k] is not None for k in (12, 60, 72))
    assert "overdamped" not in det.flag_codes and "unstable" not in det.flag_codes


def test_nonlinear_euler_beam_difference_tone_is_not_the_fundamental() -> None:
    """Euler beam, symmetric actuation, mu = 1.9, a large kick, nonlinear time integration
    (the simulator's own Galerkin integrator, not the detector's model): the quadratic coupling
    of the two lowest modes (19.17 and 22.81 rad/time) puts omega_2 - omega_1 = 3.6 into the
    probe's record. The fundamental stays the lowest eigenmode, the tone is marked."""
    from sim.euler_beam.dynamics import impulse_response
    from sim.scene import Scene

    om1 = 19.17  # linear fundamental at mu = 1.9 (symmetric, U_A)
    scene = Scene(
        actuation="symmetric", mu=1.9, kick=0.05, kick_position=0.3, probe=0.3,
        duration=15 * 2 * math.pi / om1,
    )  # fmt: skip
    sig = impulse_response(scene, method="nonlinear")
    lin = np.sqrt(-np.asarray(sig.info["sigma2"]))
    det = detect(sig.w, dt=float(sig.t[1] - sig.t[0]))
    f = det.fundamental
    # the nonlinear frequency shifts by ~1e-3 with this kick; the tone sits at 3.6
    assert f.omega == pytest.approx(lin[0], rel=3e-3)
    tone = [m for m in det.modes if abs(m.omega - (lin[1] - lin[0])) < 0.05 * lin[0]]
    assert len(tone) == 1 and tone[0].combination is not None
    assert "combination_tone" in det.flag_codes


# --------------------------------------------------------------------------------------------
# Units: exactly equivariant under w -> k w, t -> c t; no overflow at any finite magnitude
# --------------------------------------------------------------------------------------------


def _record(seed: int, noise: bool) -> tuple[np.ndarray, float]:
    rng = np.random.default_rng(seed)
    n = int(rng.integers(500, 4000))
    dt = 1e-3
    t = np.arange(n) * dt
    K = int(rng.integers(1, 4))
    w = np.full(n, rng.uniform(-1, 1))
    for k, r in enumerate((1.0, 2.76, 5.4)[:K]):
        w += (0.5**k) * np.exp(-rng.uniform(0, 2) * t) * np.cos(40.0 * r * t + rng.uniform(0, 6))
    if noise:
        w += 10 ** rng.uniform(-4, -1) * rng.standard_normal(n)
    return w, dt


@settings(max_examples=40, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.too_slow])  # fmt: skip
@given(
    seed=st.integers(0, 2**31 - 1),
    noise=st.booleans(),
    log_k=st.floats(-12, 12),
    log_c=st.floats(-12, 12),
)
def test_equivariant_under_units(seed: int, noise: bool, log_k: float, log_c: float) -> None:
    w, dt = _record(seed, noise)
    k, c = 10.0**log_k, 10.0**log_c
    a = detect(w, dt=dt)
    b = detect(k * w, dt=c * dt)
    assert b.flag_codes == a.flag_codes
    assert len(b.modes) == len(a.modes)
    for ma, mb in zip(a.modes, b.modes, strict=True):
        assert mb.omega == pytest.approx(ma.omega / c, rel=1e-9, abs=1e-300)
        assert mb.sigma2 == pytest.approx(ma.sigma2 / c**2, rel=1e-9)
        assert mb.damping == pytest.approx(ma.damping / c, rel=1e-6, abs=1e-9 * ma.omega / c)
        assert mb.amplitude == pytest.approx(ma.amplitude * k, rel=1e-6)
    assert b.static_level == pytest.approx(a.static_level * k, rel=1e-9)
    assert b.noise_std == pytest.approx(a.noise_std * k, rel=1e-3)


@pytest.mark.parametrize("k", [1e300, 1e-300, 2.0**1000, 1.7e308 / 2, 1.7e308])
def test_no_overflow_at_extreme_magnitudes(k: float) -> None:
    w, dt = _record(7, True)
    w = w / np.max(np.abs(w))
    a = detect(w, dt=dt)
    b = detect(w * k, dt=dt)
    assert "no_mode" not in b.flag_codes
    assert b.flag_codes == a.flag_codes
    assert b.fundamental.omega == pytest.approx(a.fundamental.omega, rel=1e-9)
    assert math.isfinite(b.noise_std) and math.isfinite(b.static_level)


# --------------------------------------------------------------------------------------------
# Weak modes: record SNR = per-sample SNR + 10 log10(N_eff)
# --------------------------------------------------------------------------------------------


def record_snr_db(amplitude: float, gamma: float, dt: float, n: int, noise: float) -> float:
    """``10 log10(A^2 N_eff / (2 s^2))``: the per-sample SNR ``A^2 / (2 s^2)`` in dB plus
    ``10 log10(N_eff)``, ``N_eff = sum_n exp(-2 gamma n dt)`` (the mode's energy over the
    noise variance, the ``Mode.snr_db`` of an isolated mode)."""
    neff = float(np.sum(np.exp(-2 * gamma * np.arange(n) * dt)))
    return 10 * math.log10(amplitude**2 / (2 * noise**2)) + 10 * math.log10(neff)


def _retention(n, dt, gamma2, snr_db_record, trials, seed, weak=True):
    """Fraction of trials whose detection holds the 100 rad/s mode; spurious modes per trial."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) * dt
    a2 = 0.5
    neff = float(np.sum(np.exp(-2 * gamma2 * t)))
    noise = math.sqrt(a2 * a2 / 2 * neff / 10 ** (snr_db_record / 10))
    assert record_snr_db(a2, gamma2, dt, n, noise) == pytest.approx(snr_db_record)
    kept = spurious = 0
    for _ in range(trials):
        w = 0.3 + np.exp(-0.5 * t) * np.cos(40.0 * t + rng.uniform(0, 6.3))
        if weak:
            w += a2 * np.exp(-gamma2 * t) * np.cos(100.0 * t + rng.uniform(0, 6.3))
        det = detect(w + noise * rng.standard_normal(n), dt=dt)
        kept += any(abs(m.omega - 100.0) < 3.0 for m in det.modes)
        spurious += sum(abs(m.omega - 100.0) >= 3.0 and abs(m.omega - 40.0) >= 3.0
                        for m in det.modes)  # fmt: skip
    return kept / trials, spurious / trials


def test_weak_fast_decaying_mode_at_zero_db_per_sample_is_kept() -> None:
    """The issue's case: a second mode at 0 dB per-sample SNR that decays within the first
    tenth of the record (N = 4000, gamma = 3: N_eff = 167, record SNR 22.2 dB) was dropped in
    98 % of trials. 100 trials: kept in >= 95 %, no spurious mode on average over 0.05."""
    kept, spurious = _retention(4000, 1e-3, 3.0, 22.2, 100, seed=1)
    assert kept >= 0.95 and spurious <= 0.05


@pytest.mark.slow
@pytest.mark.parametrize(("n", "gamma2"), [(4000, 3.0), (4000, 0.0), (20000, 1.0)])
def test_weak_mode_retention_at_20_db_record_snr(n: int, gamma2: float) -> None:
    """200 trials per case at 20 dB record SNR: kept in >= 95 %; the same records without the
    weak mode carry at most 0.03 spurious modes per record. (At 15 dB the detector keeps 6-12 %
    and needs 19.3-19.6 dB for 95 %; no detector keeps 95 % at 15 dB with <= 0.03 false modes
    per record: the Neyman-Pearson bound keeps 83-91 % and needs 15.6-16.2 dB, see
    bench/detector_weak.py and tests/analysis/test_detect_weak.py.)"""
    kept, spurious = _retention(n, 1e-3, gamma2, 20.0, 200, seed=n + int(gamma2))
    assert kept >= 0.95
    _, false_modes = _retention(n, 1e-3, gamma2, 20.0, 200, seed=7, weak=False)
    assert spurious <= 0.03 and false_modes <= 0.03


# --------------------------------------------------------------------------------------------
# Parameter errors as data
# --------------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("kwargs", "parameter"),
    [
        ({"dt": 0.0}, "dt"),
        ({"dt": "0.1"}, "dt"),
        ({"dt": float("inf")}, "dt"),
        ({"dt": 0.1, "method": "music"}, "method"),
        ({"dt": 0.1, "kind": "step"}, "kind"),
        ({"dt": 0.1, "max_modes": 21}, "max_modes"),
        ({"dt": 0.1, "common_damping": 1}, "common_damping"),
        ({"dt": 0.1, "max_iter": -1}, "max_iter"),
        ({"dt": 0.1, "w": [1.0] * 3}, "w"),
        ({"dt": 0.1, "w": [1.0] * 20 + [math.nan]}, "w"),
    ],
)
def test_bad_parameters_raise_parameter_error_naming_the_field(kwargs, parameter) -> None:
    w = kwargs.pop("w", np.ones(32))
    with pytest.raises(ParameterError) as err:
        detect(w, **kwargs)
    assert err.value.parameter == parameter
    assert isinstance(err.value, ValueError)
    assert parameter in str(err.value)
    if parameter != "w":
        v = err.value.value
        expected = {**kwargs}[parameter]
        assert v == expected or (isinstance(v, float) and math.isnan(v) and math.isnan(expected))


@pytest.mark.slow
def test_noise_free_nonlinear_symmetric_sweep_has_no_combination_fundamental() -> None:
    """A noise-free symmetric sweep (Euler beam, nonlinear integration, kick 0.05, mu = 0 to
    1.95 in steps of 0.15, 15 periods per record): before, the tone omega_2 - omega_1 was taken
    for the fundamental at mu = 1.95 (4.0 instead of 15.2) and the sweep reported
    ``noise_underestimated`` and mu* = 1.950. Every fundamental is now the lowest eigenmode
    and the sweep's noise is not called underestimated."""
    from service.analysis.pipeline import sweep_from_signals
    from sim.euler_beam.dynamics import impulse_response
    from sim.euler_beam.stability import spectrum_of
    from sim.euler_beam.statics import equilibrium
    from sim.scene import Scene

    records = []
    for mu in np.arange(0.0, 1.96, 0.15):
        om1 = math.sqrt(-spectrum_of(equilibrium("symmetric", float(mu), "U_A"), modes=3).sigma2[0])
        scene = Scene(actuation="symmetric", mu=float(mu), kick=0.05,
                      duration=15 * 2 * math.pi / om1)  # fmt: skip
        sig = impulse_response(scene, method="nonlinear")
        dt = float(sig.t[1] - sig.t[0])
        assert detect(sig.w, dt=dt).fundamental.omega == pytest.approx(om1, rel=0.02)
        records.append((sig.w, dt, float(mu)))
    res = sweep_from_signals(records)
    assert res.prediction is not None
    assert "noise_underestimated" not in [f.code for f in res.prediction.flags]
    assert abs(res.prediction.mu_star - 2.0) < 1e-3
