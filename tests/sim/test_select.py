"""model="auto": the cheapest backend accurate enough, with its reasons."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sim import simulate
from sim.euler_beam import bifurcation, equilibrium, spectrum_of
from sim.euler_beam.dynamics import nonlinear_response
from sim.scene import Scene
from sim.select import NONLINEAR_SHIFT_COEFF, choose_model


def test_near_mu_star_small_kick_thin_strip_picks_the_normal_form() -> None:
    mu = bifurcation("symmetric").mu_star - 1e-5
    c = choose_model(Scene(actuation="symmetric", mu=mu, kick=1e-6, end_shortening=1e-5),
                     accuracy=1e-2)  # fmt: skip
    assert c.model == "normal-form" and "normal-form" in c.reason
    assert c.estimates["normal-form"] < 1e-2


def test_far_from_mu_star_picks_the_linear_beam() -> None:
    c = choose_model(Scene(actuation="asymmetric", mu=0.5, kick=1e-3, end_shortening=1e-4))
    assert (c.model, c.method) == ("euler-beam", "modal")
    assert c.estimates["normal-form"] > 1e-2  # far from mu*: the normal form is off


def test_large_kick_needs_the_nonlinear_beam() -> None:
    c = choose_model(Scene(actuation="asymmetric", mu=1.7, kick=0.5, end_shortening=1e-4))
    assert (c.model, c.method) == ("euler-beam", "nonlinear")


def test_finite_end_shortening_and_tight_accuracy_needs_the_rod() -> None:
    c = choose_model(Scene(actuation="asymmetric", mu=1.0, end_shortening=2e-2), accuracy=1e-3)
    assert c.model == "cosserat"
    assert "euler-beam" in c.reason  # says what it passed over


def test_bad_accuracy_is_named() -> None:
    with pytest.raises(ValueError, match="accuracy"):
        choose_model(Scene(), accuracy=2.0)


def test_auto_simulation_reports_its_choice() -> None:
    sig = simulate(Scene(actuation="asymmetric", mu=0.5, kick=1e-3, end_shortening=1e-4), "auto")
    assert sig.model == "euler-beam" and sig.info["auto"]["model"] == "euler-beam"


def test_nonlinear_shift_coefficient_is_what_the_beam_does() -> None:
    """Re-measure the amplitude-frequency coefficient the selector uses (within 30 %)."""
    eq = equilibrium("asymmetric", 1.7, "U_A")
    omega = math.sqrt(-spectrum_of(eq, modes=1).sigma2[0])
    t = np.linspace(0, 40 * 2 * math.pi / omega, 8001)

    def peak(kick):
        w, _ = nonlinear_response(eq, t, kick=kick, damping=0.0, kick_width=0.1)
        x = (w - w.mean()) * np.hanning(w.size)
        spec = np.abs(np.fft.rfft(x, 32 * x.size))
        k = np.argmax(spec)
        a, b, c = np.log(spec[k - 1 : k + 2])
        return k + 0.5 * (a - c) / (a - 2 * b + c)

    kick = 0.3
    shift = abs(peak(kick) / peak(1e-4) - 1)
    assert shift == pytest.approx(NONLINEAR_SHIFT_COEFF * (kick / omega) ** 2, rel=0.3)
