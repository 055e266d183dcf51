"""Dynamics: the Signal contract, frequency and damping against the linear spectrum,
second-order time convergence, and the released-indenter snap-through."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.optimize import least_squares

from sim.cosserat import simulate, snap_through, spectrum
from sim.scene import Scene, Signal


def fit_mode(t, w, omega0, n_modes_guess):
    """Least-squares fit of damped sinusoids (+ constant); returns (omega_1, decay_1)."""
    w = w - w.mean()
    om0 = list(n_modes_guess)

    def model(q):
        out = np.full_like(t, q[-1])
        for k in range(len(om0)):
            a, b, om, d = q[4 * k: 4 * k + 4]
            out += np.exp(-d * t) * (a * np.cos(om * t) + b * np.sin(om * t))
        return out

    cols = []
    for om in om0:
        cols += [np.cos(om * t), np.sin(om * t)]
    cols.append(np.ones_like(t))
    amp = np.linalg.lstsq(np.array(cols).T, w, rcond=None)[0]
    q0 = []
    for k, om in enumerate(om0):
        q0 += [amp[2 * k], amp[2 * k + 1], om, 0.0]
    q0.append(0.0)
    res = least_squares(lambda q: model(q) - w, np.array(q0), x_scale="jac", xtol=1e-14,
                        ftol=1e-14)
    return float(res.x[2]), float(res.x[3])


SCENE = Scene(elements=48, slenderness=1e-3, end_shortening=1e-2, damping=0.0, kick=1e-2,
              duration=1.0)


def test_simulate_returns_the_common_signal():
    sig = simulate(SCENE)
    assert isinstance(sig, Signal) and sig.model == "cosserat" and sig.scene is SCENE
    assert sig.t.shape == sig.w.shape and sig.t[0] == 0.0
    assert np.allclose(np.diff(sig.t), sig.dt)
    assert sig.t[-1] <= 1.0 + 1e-12 and sig.t[-1] > 1.0 - 2 * sig.dt
    # absolute position: the record starts at the static deflection, W(1/4) < 0 on U_A
    assert sig.w[0] == pytest.approx(sig.w_static, abs=1e-12)
    assert -0.4 < sig.w_static < -0.2
    assert sig.info["stop"] == "done"
    for key in ("lambda", "sigma2", "omega", "internal_dt", "cpu_s"):
        assert key in sig.info
    # the kick moves the probe: response amplitude ~ kick / omega
    resp = sig.w - sig.w_static
    assert 1e-5 < np.max(np.abs(resp)) < 1e-3


def test_signal_frequency_matches_the_linear_spectrum():
    sig = simulate(SCENE.with_(duration=2.0), steps_per_period=200)
    om_eig = [math.sqrt(-s) for s in sig.info["sigma2"][:3]]
    om, _ = fit_mode(sig.t, sig.w, om_eig[0], om_eig)
    # time-stepping error (omega dt)^2 / 12 ~ 8e-5 at 200 steps per period
    assert abs(om / om_eig[0] - 1) < 3e-4


def test_time_stepping_is_second_order():
    errs = []
    for spp in (25, 50, 100):
        sig = simulate(SCENE.with_(duration=2.0), steps_per_period=spp,
                       samples_per_period=min(50, spp))
        om_eig = [math.sqrt(-s) for s in sig.info["sigma2"][:3]]
        om, _ = fit_mode(sig.t, sig.w, om_eig[0], om_eig)
        errs.append(abs(om / om_eig[0] - 1))
    orders = np.log2(np.array(errs[:-1]) / np.array(errs[1:]))
    assert np.all(orders > 1.6), (errs, orders)


def test_damping_rate_is_xi_over_two():
    xi = 2.0
    sig = simulate(SCENE.with_(damping=xi, duration=2.0), steps_per_period=200)
    om_eig = [math.sqrt(-s) for s in sig.info["sigma2"][:3]]
    _, decay = fit_mode(sig.t, sig.w, om_eig[0], om_eig)
    assert decay == pytest.approx(xi / 2.0, rel=0.02)


def test_response_is_linear_in_the_kick_up_to_a_quadratic_term():
    def deviation(k):
        a = simulate(SCENE.with_(duration=0.3, kick=2 * k))
        b = simulate(SCENE.with_(duration=0.3, kick=k))
        ra, rb = a.w - a.w_static, b.w - b.w_static
        return np.max(np.abs(ra - 2 * rb)) / np.max(np.abs(ra)), b

    big, _ = deviation(1e-2)
    small, b = deviation(1e-3)
    assert small < 2e-3
    assert 0.05 < small / big < 0.2  # the buckled state's quadratic nonlinearity
    c = simulate(SCENE.with_(duration=0.3, kick=1e-3, snr_db=10.0, seed=1))
    assert not np.allclose(c.w, b.w) and c.w_static == b.w_static


def test_simulate_refuses_missing_branches():
    with pytest.raises(ValueError, match="branch"):
        simulate(SCENE.with_(branch="S_A"))


def test_spectrum_is_sorted_and_stable_on_u_a():
    s = spectrum("symmetric", 1.0, elements=48, modes=4)
    assert np.all(s.sigma2 < 0) and np.all(np.diff(s.sigma2) < 0)
    assert s.modes.shape == (49, 4)


def test_snap_through_reaches_u_b_and_slows_near_the_fold():
    near = snap_through(0.01, elements=32, duration=3.0)
    far = snap_through(0.05, elements=32, duration=3.0, mu_star=near.mu_star)
    assert near.info["stop"] == "done" and far.info["stop"] == "done"
    assert near.w_mid[0] < 0 < near.w_mid_final
    assert near.t_snap is not None and far.t_snap is not None
    # slower closer to the fold; saddle-node scaling t_snap ~ dmu^(-1/4): ratio 5^(1/4) ~ 1.5
    assert 1.3 < near.t_snap / far.t_snap < 1.8


def test_a_too_large_step_is_retried_not_returned_wrong():
    """A violent snap at dt = 8e-3 makes Newton fail; the run restarts with halved steps."""
    r = snap_through(0.05, elements=32, duration=1.0, dt=8e-3)
    assert r.info["stop"] == "done" and r.info["dt"] < 8e-3
    ref = snap_through(0.05, elements=32, duration=1.0, dt=r.info["dt"], mu_star=r.mu_star)
    k = int(round(8e-3 / r.info["dt"]))  # samples stay on the asked grid
    assert r.w_mid.shape == (126,) and np.allclose(r.w_mid, ref.w_mid[::k])


def test_critical_slowing_down_near_the_fold():
    ms = 1.7758894669  # the n = 50, h/L = 1e-3 rod's fold (bifurcation("asymmetric", elements=50))
    far = simulate(SCENE.with_(elements=50, duration=0.5))
    near = simulate(SCENE.with_(elements=50, mu=ms - 1e-3, duration=0.5))
    # saddle-node: omega ~ (mu* - mu)^(1/4) far from the overdamped layer
    assert near.info["omega"] < 0.35 * far.info["omega"]
    assert near.w_static > far.w_static  # pushed towards the fold, W(1/4) rises
