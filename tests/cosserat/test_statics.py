"""Statics of the rod: conventions, clamp convergence order, elastica and Euler-beam limits."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.optimize import brentq

from sim.cosserat import (
    ConvergenceError,
    bifurcation,
    equilibria,
    spectrum,
)
from sim.cosserat import elastica as E

# mu* of the inextensible elastica at dL/L = 1e-2, from sim.cosserat.elastica.mu_star
# (shooting, independent of the rod; re-computed in the slow test below).
ELASTICA_MU_STAR = {"asymmetric": 1.7823135860, "symmetric": 2.0018998184,
                    "antisymmetric": 2.0020885835}


def beam_fundamental_mu0() -> float:
    """omega_1 of the clamped Euler beam buckled in its first mode (Lambda = 2 pi), mu = 0:
    the lowest mode is antisymmetric, W'''' + Lambda^2 W'' = omega^2 W, clamped at +-1/2."""
    lam = 2.0 * math.pi

    def f(w):
        s = math.sqrt(lam**4 + 4 * w * w)
        a, b = math.sqrt((lam**2 + s) / 2), math.sqrt((-(lam**2) + s) / 2)
        return b * math.sin(a / 2) * math.cosh(b / 2) - a * math.cos(a / 2) * math.sinh(b / 2)

    return brentq(f, 30.0, 60.0, xtol=1e-13)


def test_u_a_convention_and_symmetries():
    eq = equilibria("asymmetric", 0.0, elements=48)
    assert eq.w[24] < -0.6  # U_A buckled to negative w, W(1/2) ~ -2/pi
    assert np.allclose(eq.w, eq.w[::-1], atol=1e-10)  # symmetric at mu = 0
    eq_b = equilibria("asymmetric", 0.0, elements=48, branch="U_B")
    assert np.allclose(eq_b.w, -eq.w, atol=1e-10)
    # a positive left slope pushes U_A towards the transition: |W(1/2)| decreases
    eq1 = equilibria("asymmetric", 1.0, elements=48)
    assert -0.6 < eq1.w[24] < eq.w[24] + 0.5
    assert eq1.theta[0] > 0.0
    # symmetric actuation keeps the mirror symmetry, antisymmetric the half-turn symmetry
    s = equilibria("symmetric", 1.0, elements=48)
    assert np.allclose(s.w, s.w[::-1], atol=1e-9)
    a = equilibria("antisymmetric", 1.0, elements=48)
    assert abs(a.w[24]) > 0.1 and eq.stable and s.stable and a.stable


def test_equilibria_raise_past_the_fold():
    with pytest.raises(ConvergenceError):
        equilibria("asymmetric", 1.80, elements=48)


@pytest.mark.parametrize("actuation", ["asymmetric", "symmetric", "antisymmetric"])
def test_equilibria_converge_to_the_elastica(actuation):
    X = np.array([0.25, 0.5, 0.75])
    w_el, lam_el = E.equilibrium_w(actuation, 1.0, X, end_shortening=1e-2)
    errs = []
    for n in (48, 96):
        eq = equilibria(actuation, 1.0, slenderness=1e-4, elements=n)
        errs.append(np.max(np.abs(np.interp(X, eq.s, eq.w) - w_el)))
        lam_err = abs(eq.lambda_ - lam_el)
    assert errs[1] < 2e-3
    assert errs[0] / errs[1] > 3.0  # second order in 1/n
    assert lam_err < 1e-2


def _omega1(n, clamp, h=1e-3, d=1e-2):
    s = spectrum("asymmetric", 0.0, end_shortening=d, slenderness=h, elements=n, modes=1,
                 clamp=clamp)
    return math.sqrt(-s.sigma2[0])


def test_clamp_convergence_orders():
    """Node clamp: second order; element clamp (PyElastica's): first order, bias ~ +2/n."""
    ns = [24, 48, 96]
    ref = _omega1(384, "node")
    ref = ref + (ref - _omega1(192, "node")) / 3.0
    e_node = [abs(_omega1(n, "node") / ref - 1) for n in ns]
    e_el = [_omega1(n, "element") / ref - 1 for n in ns]
    p_node = math.log2(e_node[1] / e_node[2])
    p_el = math.log2(e_el[1] / e_el[2])
    assert 1.8 < p_node < 2.3
    assert 0.8 < p_el < 1.4
    assert all(e > 0 for e in e_el)
    assert 1.0 < 48 * e_el[1] < 2.5  # the +2/n-like bias of the element clamp
    assert e_node[1] < 0.2 * e_el[1]


def test_fundamental_matches_the_beam_in_the_thin_small_shortening_limit():
    om_beam = beam_fundamental_mu0()
    assert om_beam == pytest.approx(44.3627, abs=1e-4)
    om = _omega1(192, "node", h=1e-4, d=1e-4)
    assert abs(om / om_beam - 1) < 5e-3  # target; measured 3e-4
    assert abs(om / om_beam - 1) < 1e-3
    try:
        from sim.euler_beam import spectrum as beam_spectrum
    except ImportError:  # pragma: no cover - the beam backend is optional here
        return
    s2 = beam_spectrum("asymmetric", 0.0, branch="U_A", modes=3).sigma2
    assert abs(om / math.sqrt(-s2[0]) - 1) < 1e-3


@pytest.mark.parametrize("actuation", ["asymmetric", "symmetric", "antisymmetric"])
def test_mu_star_converges_to_the_elastica(actuation):
    b = bifurcation(actuation, slenderness=1e-4, elements=200)
    assert abs(b.mu_star - ELASTICA_MU_STAR[actuation]) < 1e-3
    assert b.model == "cosserat" and b.elements == 200
    assert b.end_shortening is not None and b.slenderness == 1e-4
    assert b.transition == {"asymmetric": "saddle-node",
                            "symmetric": "subcritical-pitchfork",
                            "antisymmetric": "supercritical-pitchfork"}[actuation]
    if actuation == "symmetric":  # the secondary fold U_A / W_B (beam: ~2.012)
        assert 2.005 < b.secondary[0].mu_star < 2.02


def test_transition_types_are_what_the_branches_do():
    n = 48
    # symmetric: U_A survives mu* but is unstable (subcritical pitchfork)
    ms = bifurcation("symmetric", elements=n).mu_star
    assert not equilibria("symmetric", ms + 2e-3, elements=n).stable
    assert equilibria("symmetric", ms - 2e-3, elements=n).stable
    # antisymmetric: past mu* the single state left (S_B) is stable (supercritical)
    ma = bifurcation("antisymmetric", elements=n).mu_star
    past = equilibria("antisymmetric", ma + 0.02, elements=n)
    assert past.stable and abs(past.w[n // 2]) < 1e-6
    # asymmetric: U_A ends at the fold
    mf = bifurcation("asymmetric", elements=n).mu_star
    assert equilibria("asymmetric", mf - 1e-4, elements=n).stable
    with pytest.raises(ConvergenceError):
        equilibria("asymmetric", mf + 1e-3, elements=n)


def test_mu_star_tends_to_the_beam_as_the_shortening_vanishes():
    """dL/L = 1e-4, h/L = 1e-5 (h^2/dL small): the rod's mu* is the Euler beam's."""
    mus = [bifurcation("asymmetric", end_shortening=1e-4, slenderness=1e-5, elements=n).mu_star
           for n in (100, 200)]
    try:
        from sim.euler_beam import bifurcation as beam_bifurcation

        ref = beam_bifurcation("asymmetric").mu_star
    except ImportError:  # pragma: no cover
        ref = 1.78178  # inextensible elastica at dL/L = 1e-4 (sim.cosserat.elastica): 1.781782
    assert abs(mus[1] - ref) < 1e-3
    assert abs(mus[1] + (mus[1] - mus[0]) / 3.0 - ref) < 3e-5  # Richardson: 1e-6 measured


@pytest.mark.slow
@pytest.mark.parametrize("actuation", ["asymmetric", "symmetric", "antisymmetric"])
def test_elastica_reference_values(actuation):
    assert E.mu_star(actuation, 1e-2) == pytest.approx(ELASTICA_MU_STAR[actuation], abs=1e-8)


@pytest.mark.slow
def test_mu_star_second_order_convergence():
    mus = [bifurcation("asymmetric", slenderness=1e-4, elements=n).mu_star
           for n in (50, 100, 200, 400)]
    e = np.abs(np.diff(mus))
    assert np.all(np.log2(e[:-1] / e[1:]) > 1.8)
    rich = mus[-1] + (mus[-1] - mus[-2]) / 3.0
    assert abs(rich - ELASTICA_MU_STAR["asymmetric"]) < 1e-4


@pytest.mark.parametrize("actuation", ["asymmetric", "symmetric", "antisymmetric"])
def test_shape_and_spectrum_match_the_euler_beam_backend(actuation):
    """dL/L = 1e-4, h/L = 1e-5 at mu = 1: W(X) and sigma^2 of the rod -> the beam's."""
    eb = pytest.importorskip("sim.euler_beam")
    X = np.array([0.25, 0.5, 0.75])
    beam = eb.equilibrium(actuation, 1.0, "U_A")
    rod = equilibria(actuation, 1.0, end_shortening=1e-4, slenderness=1e-5, elements=192)
    assert np.max(np.abs(np.interp(X, rod.s, rod.w) - beam.shape(X))) < 2e-4
    assert rod.lambda_ == pytest.approx(beam.lam, abs=2e-3)
    s_beam = eb.spectrum(actuation, 1.0, "U_A", 3).sigma2
    s_rod = spectrum(actuation, 1.0, end_shortening=1e-4, slenderness=1e-5, elements=192,
                     modes=3).sigma2
    # fundamental frequency within 0.5% (target); measured ~4e-4 on sigma^2 (2e-4 on omega)
    assert abs(math.sqrt(s_rod[0] / s_beam[0]) - 1) < 5e-3
    assert np.all(np.abs(s_rod / s_beam - 1) < 3e-3)


def test_centre_clamp_is_second_order_in_frequency_and_meets_the_node_clamp():
    """The element-centre clamp (end elements straddling the clamp points) converges at second
    order with a smaller constant than the node clamp, to the same limit."""
    import math

    from sim.cosserat import statics as S
    from sim.cosserat.rod import Rod

    def omega(n, clamp):
        rod = Rod(elements=n, slenderness=1e-2, end_shortening=1e-2, clamp=clamp)
        return math.sqrt(-S.sigma2(rod, S.branch_state(rod, 0.0), 1)[0][0])

    c = [omega(n, "centre") for n in (48, 96, 192, 384)]
    nd = [omega(n, "node") for n in (96, 192)]
    assert math.log2((c[1] - c[0]) / (c[2] - c[1])) == pytest.approx(2.0, abs=0.15)
    lim_c = c[3] + (c[3] - c[2]) / 3
    lim_n = nd[1] + (nd[1] - nd[0]) / 3
    assert lim_c == pytest.approx(lim_n, rel=1e-5)
    assert abs(c[0] - lim_c) < 0.5 * abs(omega(48, "node") - lim_n)
