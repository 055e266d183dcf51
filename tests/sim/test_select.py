"""model="auto": the cheapest backend accurate enough, with its reasons."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sim.euler_beam import equilibrium, spectrum_of
from sim.euler_beam.dynamics import nonlinear_response
from sim.scene import Scene
from sim.select import NONLINEAR_SHIFT_COEFF, choose_model


def test_bad_accuracy_is_named() -> None:
    with pytest.raises(ValueError, match="rtol"):
        choose_model(Scene(), accuracy=2.0)


def test_thick_strip_tight_accuracy_says_no_backend_meets_it() -> None:
    c = choose_model(Scene(mu=1.0, end_shortening=1e-2, slenderness=5e-2), accuracy=1e-4)
    assert not c.met and "no backend meets" in c.reason and c.estimate.total > 1e-4


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
