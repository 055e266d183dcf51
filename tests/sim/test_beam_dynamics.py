"""Impulse responses: kernels against slow references, modal against nonlinear, scene plumbing."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sim import simulate
from sim.euler_beam import _kernels, equilibrium, spectrum_of
from sim.euler_beam.dynamics import (
    _kick_velocity,
    discretize,
    impulse_response,
    modal_response,
    nonlinear_response,
    snap_through,
)
from sim.scene import Scene, SceneError


# ---------------------------------------------------------------- slow references
def _ref_midpoint_step(D, a, v, lam, dt, xi):
    """Pure-numpy discrete-gradient midpoint step with Newton on Lambda^2 (the kernel's spec)."""
    B = D.basis
    for _ in range(50):
        K = B.K4 - lam * B.K2
        A = (2 / dt + xi) * B.M + 0.5 * dt * K
        d = np.linalg.solve(A, 2 * B.M @ v - dt * (K @ a + D.k4 - lam * D.k2))
        F = D.constraint(a + d) - 2.0
        if abs(F) <= 1e-14:
            break
        dd = np.linalg.solve(A, dt * (B.K2 @ (a + 0.5 * d) + D.k2))
        lam -= F / (2 * (B.K2 @ (a + d) + D.k2) @ dd)
    return a + d, 2 * d / dt - v, lam


def _ref_modal(t, sigma2, xi, amp):
    out = np.zeros_like(t)
    for s2, A in zip(sigma2, amp):
        roots = np.roots([1.0, xi, -s2]).astype(complex)
        if abs(roots[0] - roots[1]) < 1e-12:
            out += A * t * np.exp(roots[0].real * t)
        else:
            out += A * ((np.exp(roots[0] * t) - np.exp(roots[1] * t)) / (roots[0] - roots[1])).real
    return out


def test_midpoint_kernel_matches_slow_reference() -> None:
    eq = equilibrium("symmetric", 1.2, "U_A")
    D = discretize(eq)
    B = D.basis
    a0 = D.a_eq.copy()
    v0 = _kick_velocity(D, a0, 0.05, 0.25, 0.0)
    dt, xi, steps = 2e-4, 1e-2, 40
    a, v, lam = a0.copy(), v0.copy(), D.lam_eq
    probe = B.eval(np.array([0.3]))[0]
    ref_w = [float(D.lift(np.array([0.3]))[0] + probe @ a)]
    for _ in range(steps):
        a, v, lam = _ref_midpoint_step(D, a, v, lam, dt, xi)
        ref_w.append(float(D.lift(np.array([0.3]))[0] + probe @ a))
    ak, vk = a0.copy(), v0.copy()
    out_w, out_l = np.zeros(steps + 1), np.zeros(steps + 1)
    rec = _kernels.midpoint_integrate(
        B.M, B.K4, B.K2, D.k4, D.k2, D.c0, xi, dt, ak, vk, D.lam_eq, steps, 1, probe,
        float(D.lift(np.array([0.3]))[0]), out_w, out_l,
    )  # fmt: skip
    assert rec == steps + 1
    np.testing.assert_allclose(out_w, ref_w, rtol=0, atol=1e-12)
    np.testing.assert_allclose(ak, a, atol=1e-11)
    assert out_l[-1] == pytest.approx(lam, rel=1e-9)
    assert D.constraint(ak) == pytest.approx(2.0, abs=1e-13)


@pytest.mark.parametrize("xi", [0.0, 2e-4, 0.5, 80.0])
def test_modal_sum_kernel_matches_reference_in_every_regime(xi: float) -> None:
    t = np.linspace(0, 3, 301)
    sigma2 = np.array([-1600.0, -100.0, -1.0, 0.0, 2.0])  # includes critical and unstable
    amp = np.array([1.0, -0.5, 0.2, 0.1, 0.01])
    out = np.empty_like(t)
    _kernels.modal_sum(t, sigma2, xi, amp, out)
    np.testing.assert_allclose(out, _ref_modal(t, sigma2, xi, amp), rtol=1e-9, atol=1e-12)


def test_modal_sum_does_not_overflow_when_overdamped_for_long() -> None:
    t = np.array([0.0, 1e3, 1e6])
    out = np.empty(3)
    _kernels.modal_sum(t, np.array([-1e-6]), 1e-2, np.array([1.0]), out)
    assert np.all(np.isfinite(out))


def test_nonlinear_matches_modal_with_second_order_convergence() -> None:
    """Same Galerkin space, initial velocity on the first six modes: the nonlinear integrator
    converges to the exact modal sum as dt^2 (small kick: the nonlinearity is negligible)."""
    eq = equilibrium("asymmetric", 0.5, "U_A")
    D = discretize(eq)
    B = D.basis
    sp = spectrum_of(eq, modes=6)
    c = np.array([1, 0.5, 0.3, 0.2, 0.1, 0.05]) * 1e-4
    t = np.arange(0, 0.5, 1e-3)
    xi = 2e-4
    probe = B.eval(np.array([0.25]))[0]
    ref = np.empty_like(t)
    _kernels.modal_sum(t, sp.sigma2.copy(), xi, c * (probe @ sp.coeffs), ref)
    w_static = eq.shape(np.array([0.25]))[0]
    errs = []
    for sub in (4, 8, 16):
        a, v = D.a_eq.copy(), sp.coeffs @ c
        out_w, out_l = np.full(t.size, np.nan), np.full(t.size, np.nan)
        _kernels.midpoint_integrate(
            B.M, B.K4, B.K2, D.k4, D.k2, D.c0, xi, 1e-3 / sub, a, v, D.lam_eq,
            (t.size - 1) * sub, sub, probe, float(D.lift(np.array([0.25]))[0]), out_w, out_l,
        )  # fmt: skip
        errs.append(np.max(np.abs(out_w - w_static - ref)) / np.max(np.abs(ref)))
    assert errs[-1] < 3e-4
    assert 3.0 < errs[0] / errs[1] < 5.0 and 3.0 < errs[1] / errs[2] < 5.0


def _mode_amplitudes(t, w, sigma2, xi, k=6):
    """Linear least squares on known modal responses: the amplitude of each of k modes."""
    cols = []
    for s2 in sigma2[:k]:
        col = np.empty_like(t)
        _kernels.modal_sum(t, np.array([s2]), xi, np.array([1.0]), col)
        cols.append(col)
    return np.linalg.lstsq(np.array(cols).T, w, rcond=None)[0]


def test_point_kick_modal_and_nonlinear_agree_on_the_fundamental() -> None:
    eq = equilibrium("symmetric", 1.5, "U_A")
    t = np.arange(0, 1.0, 5e-4)
    resp, _ = modal_response(eq, t, kick=1e-3, damping=2e-4)
    w, info = nonlinear_response(eq, t, kick=1e-3, damping=2e-4)
    assert info["completed"]
    sp = spectrum_of(eq, modes=20)
    w_static = eq.shape(np.array([0.25]))[0]
    am = _mode_amplitudes(t, resp, sp.sigma2, 2e-4, k=20)
    an = _mode_amplitudes(t, w - w_static, sp.sigma2, 2e-4, k=20)
    # theory for the fundamental: kick * Phi_1(1/4)^2
    theory = 1e-3 * sp.shape(np.array([0.25]), 0)[0] ** 2
    assert am[0] == pytest.approx(theory, rel=1e-6)
    assert an[0] == pytest.approx(theory, rel=2e-3)


def test_nonlinear_response_grows_nonlinear_for_large_kicks() -> None:
    """The fundamental's frequency shifts with amplitude (the model's geometric nonlinearity)."""
    eq = equilibrium("asymmetric", 1.7, "U_A")
    sp = spectrum_of(eq, modes=1)
    period = 2 * math.pi / math.sqrt(-sp.sigma2[0])
    t = np.linspace(0, 20 * period, 4001)

    def freq(kick):
        w, _ = nonlinear_response(eq, t, kick=kick, damping=0.0, kick_width=0.1)
        x = w - w.mean()
        spec = np.abs(np.fft.rfft(x * np.hanning(x.size), 16 * x.size))
        return np.argmax(spec)

    assert abs(freq(0.5) - freq(1e-4)) > 0.05 * freq(1e-4)
    assert abs(freq(1e-2) - freq(1e-4)) <= 1  # small kicks: linear


def test_impulse_response_scene_defaults_and_static_level() -> None:
    sig = impulse_response(Scene(actuation="asymmetric", mu=1.0, kick=1e-3))
    eq = equilibrium("asymmetric", 1.0, "U_A")
    assert sig.w_static == pytest.approx(eq.w_quarter, abs=1e-14)
    assert sig.t.size == 2001 and sig.t[0] == 0.0
    assert sig.w[0] == pytest.approx(sig.w_static, abs=1e-15)  # the kick is a velocity
    period = 2 * math.pi / math.sqrt(-spectrum_of(eq, 1).sigma2[0])
    assert sig.t[-1] == pytest.approx(40 * period, rel=1e-6)
    # the sample frequency resolves the kept modes: none above 0.8 x Nyquist
    nyq = math.pi / sig.dt
    assert max(math.sqrt(-s) for s in sig.info["sigma2"][: sig.info["modes"]]) <= 0.8 * nyq


def test_noise_has_the_requested_snr_and_is_seeded() -> None:
    scene = Scene(actuation="symmetric", mu=0.5, kick=1e-3, snr_db=20.0, seed=7)
    clean = simulate(scene.with_(snr_db=None))
    a, b = simulate(scene), simulate(scene)
    np.testing.assert_array_equal(a.w, b.w)
    noise = a.w - clean.w
    snr = 10 * np.log10(np.mean((clean.w - clean.w_static) ** 2) / np.mean(noise**2))
    assert snr == pytest.approx(20.0, abs=0.3)
    assert not np.array_equal(simulate(scene.with_(seed=8)).w, a.w)


def test_snap_through_asymmetric_reaches_U_B_and_slows_down_near_mu_star() -> None:
    def t_snap(dmu):
        st = snap_through("asymmetric", dmu, duration=4.0, dt=2e-3, probe=0.5)
        assert st.completed
        mid = (st.w_start + equilibrium("asymmetric", 1.7817 + dmu, "U_B").w_half) / 2
        return st.t[np.argmax(st.w > mid)], st

    t1, st = t_snap(1e-2)
    t2, _ = t_snap(1e-4)
    target = equilibrium("asymmetric", 1.7817760411567 + 1e-2, "U_B").w_half
    assert abs(np.mean(st.w[-200:]) - target) < 0.1  # oscillating about U_B, lightly damped
    # normal-form scaling of the snap time: T ~ dmu^(-1/4) (paper, Appendix A)
    ratio = t2 / t1
    assert ratio == pytest.approx(100**0.25, rel=0.15)


def test_scene_validation_names_the_field() -> None:
    with pytest.raises(SceneError, match="probe"):
        Scene(probe=1.5)
    with pytest.raises(SceneError, match="damping"):
        Scene(damping=-1.0)
    with pytest.raises(SceneError, match="mu"):
        Scene(mu=float("inf"))


def test_unstable_equilibrium_is_refused_not_overflowed() -> None:
    """Past the subcritical pitchfork U_A still exists but is unstable: the strip would snap."""
    with pytest.raises(ValueError, match="unstable"):
        impulse_response(Scene(actuation="symmetric", mu=2.005, kick=1e-3, duration=100.0))
    short = impulse_response(Scene(actuation="symmetric", mu=2.005, kick=1e-6, duration=0.5))
    assert np.all(np.isfinite(short.w))
