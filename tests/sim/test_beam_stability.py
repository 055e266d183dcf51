"""Linear stability: Legendre-Galerkin spectrum against the paper's determinant method."""

from __future__ import annotations

import numpy as np
import pytest

from sim.euler_beam import bifurcation, equilibrium, spectrum, spectrum_of
from sim.euler_beam.stability import refine_by_determinant, roots_by_determinant

CASES = [
    ("asymmetric", 0.5, "U_A"),
    ("asymmetric", 1.7, "U_B"),
    ("symmetric", 1.9, "U_A"),
    ("symmetric", 1.0, "S_B"),  # unstable: one positive sigma^2
    ("antisymmetric", 2.3, "S_B"),
    ("antisymmetric", 1.5, "U_A"),
]


@pytest.mark.parametrize(("actuation", "mu", "branch"), CASES)
def test_galerkin_matches_determinant_method_for_ten_modes(actuation, mu, branch) -> None:
    eq = equilibrium(actuation, mu, branch)
    sp = spectrum_of(eq, modes=10)
    for s2 in sp.sigma2:
        ref = refine_by_determinant(eq, s2, rel=1e-6)
        assert abs(s2 - ref) <= 1e-8 * abs(ref), (s2, ref)


def test_determinant_scan_finds_exactly_the_galerkin_modes() -> None:
    """No mode missing or spurious: every sign change of det M_p in a window is a Galerkin mode."""
    eq = equilibrium("symmetric", 1.0, "S_B")
    sp = spectrum_of(eq, modes=6)
    lo, hi = -40000.0, 5000.0
    inside = np.sort(sp.sigma2[(sp.sigma2 > lo) & (sp.sigma2 < hi)])
    roots = np.sort(roots_by_determinant(eq, lo, hi, num=600))
    assert inside.size >= 3 and np.any(inside > 0)  # an unstable mode is in the window
    np.testing.assert_allclose(roots, inside, rtol=1e-9)


@pytest.mark.parametrize(("actuation", "mu", "branch"), CASES[:3])
def test_spectral_convergence_in_basis_size(actuation, mu, branch) -> None:
    eq = equilibrium(actuation, mu, branch)
    ref = spectrum_of(eq, modes=10, n=48).sigma2
    coarse = spectrum_of(eq, modes=10, n=16).sigma2
    mid = spectrum_of(eq, modes=10, n=32).sigma2
    err_coarse = np.abs(coarse - ref) / np.abs(ref)
    err_mid = np.abs(mid - ref) / np.abs(ref)
    assert err_mid.max() < 1e-10
    assert err_coarse.max() > 1e3 * err_mid.max()  # it does converge (spectrally)


def test_mode_shapes_are_mass_normalised_and_satisfy_constraint() -> None:
    eq = equilibrium("asymmetric", 1.0, "U_A")
    sp = spectrum_of(eq, modes=5)
    X = np.polynomial.legendre.leggauss(80)[0] * 0.5 + 0.5
    w = np.polynomial.legendre.leggauss(80)[1] * 0.5
    dWeq = eq.shape(X, 1)
    for k in range(5):
        assert np.sum(w * sp.shape(X, k) ** 2) == pytest.approx(1.0, rel=1e-10)
        assert abs(np.sum(w * dWeq * sp.shape(X, k, 1))) < 1e-10
        np.testing.assert_allclose(sp.shape(np.array([0.0, 1.0]), k), 0.0, atol=1e-12)


def _exponent(actuation: str, branch: str, side: float, stable_only=False, mu_star=None):
    """Local log-log slopes of sqrt|sigma^2| (smallest |sigma^2|, or smallest stable one)
    against |dmu| from 1e-6 to 1e-2."""
    mu_star = bifurcation(actuation).mu_star if mu_star is None else mu_star
    dmus = np.logspace(-6, -2, 9)
    om = []
    for d in dmus:
        s2 = spectrum(actuation, mu_star + side * d, branch, modes=4).sigma2
        if stable_only:
            s2 = s2[s2 < 0]
        om.append(np.sqrt(abs(s2[0])))
    slopes = np.diff(np.log(om)) / np.diff(np.log(dmus))
    return slopes


def test_scaling_exponent_saddle_node() -> None:
    slopes = _exponent("asymmetric", "U_A", -1.0)
    assert abs(slopes[0] - 0.25) < 0.003  # asymptotic end
    assert np.all(np.abs(slopes - 0.25) < 0.05)


def test_scaling_exponent_subcritical_pitchfork() -> None:
    slopes = _exponent("symmetric", "U_A", -1.0)
    assert abs(slopes[0] - 0.5) < 0.003
    # the unstable side (U_A past mu*) has the same exponent
    assert abs(_exponent("symmetric", "U_A", +1.0)[0] - 0.5) < 0.003


def test_scaling_exponent_supercritical_pitchfork() -> None:
    slopes = _exponent("antisymmetric", "U_A", -1.0)
    assert abs(slopes[0] - 0.5) < 0.003
    assert abs(_exponent("antisymmetric", "S_B", +1.0)[0] - 0.5) < 0.003


def test_secondary_saddle_node_of_the_symmetric_case_scales_as_a_quarter() -> None:
    """Paper: U_A's first harmonic vanishes at mu2* ~ 2.012 with the saddle-node exponent."""
    mu2 = bifurcation("symmetric").secondary[0].mu_star
    slopes = _exponent("symmetric", "U_A", -1.0, stable_only=True, mu_star=mu2)
    assert abs(slopes[0] - 0.25) < 0.005
