"""Statics of the Euler beam against closed forms, the paper, and an independent implementation."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.optimize import brentq, minimize_scalar

from sim.errors import SimulationError
from sim.euler_beam import (
    BeamError,
    bifurcation,
    equilibria,
    equilibrium,
    euler_eigenvalues,
    is_stable,
)

ACTS = ("asymmetric", "symmetric", "antisymmetric")
SLOPE = {"asymmetric": 0.0, "symmetric": -1.0, "antisymmetric": 1.0}


# ---- an independent reference: the paper's (A, B, C, D) basis with closed-form integrals ----
def _paper_mu(L: float, s: float) -> float:
    """mu on the generic branch at Lambda, from M v = b in the basis sin, cos, X, 1."""
    sL, cL = math.sin(L), math.cos(L)
    M = np.array([[0, 1, 0, 1], [sL, cL, 1, 1], [L, 0, 1, 0], [L * cL, -L * sL, 1, 0]])
    A, B, C, _ = np.linalg.solve(M, [0, 0, 1, s])
    s2 = math.sin(2 * L)
    J = (
        A * A * L * L * (0.5 + s2 / (4 * L))
        + B * B * L * L * (0.5 - s2 / (4 * L))
        + C * C
        - A * B * L * sL**2
        + 2 * A * C * sL
        - 2 * B * C * (1 - cL)
    )
    return math.sqrt(2.0 / J)


def _paper_fold(lo: float, hi: float, s: float) -> tuple[float, float]:
    res = minimize_scalar(lambda L: -_paper_mu(L, s), bounds=(lo, hi), method="bounded",
                          options={"xatol": 1e-12})  # fmt: skip
    return -res.fun, res.x


def test_euler_eigenvalues_are_the_classical_ones() -> None:
    vals = euler_eigenvalues(4)
    assert vals[0] == (pytest.approx(2 * math.pi, abs=1e-14), "sym")
    L2, kind = vals[1]
    assert kind == "anti" and math.tan(L2 / 2) == pytest.approx(L2 / 2, rel=1e-12)
    assert L2 == pytest.approx(8.986818916, abs=1e-9)
    assert vals[2][0] == pytest.approx(4 * math.pi, abs=1e-13)


@pytest.mark.parametrize("actuation", ACTS)
def test_mu_zero_closed_form(actuation: str) -> None:
    X = np.linspace(0, 1, 41)
    eqs = {e.branch: e for e in equilibria(actuation, 0.0)}
    assert set(eqs) == {"U_A", "U_B", "S_A", "S_B", "W_A", "W_B"}
    exact = (1 - np.cos(2 * math.pi * X)) / math.pi
    assert eqs["U_B"].lam == pytest.approx(2 * math.pi, abs=1e-13)
    np.testing.assert_allclose(eqs["U_B"].shape(X), exact, atol=1e-13)
    np.testing.assert_allclose(eqs["U_A"].shape(X), -exact, atol=1e-13)
    assert eqs["U_A"].energy == pytest.approx(eqs["U_B"].energy, rel=1e-13)
    # bending energy of (1 - cos 2 pi X)/pi: (1/2) int (4 pi cos 2 pi X)^2 = 4 pi^2
    assert eqs["U_B"].energy == pytest.approx(4 * math.pi**2, rel=1e-12)


@pytest.mark.parametrize("actuation", ACTS)
@pytest.mark.parametrize("mu", [0.3, 1.0, 1.7, 1.95])
def test_every_equilibrium_satisfies_bcs_and_constraint(actuation: str, mu: float) -> None:
    s = SLOPE[actuation]
    eqs = equilibria(actuation, mu)
    assert len(eqs) >= 2
    for e in eqs:
        ends = np.array([0.0, 1.0])
        np.testing.assert_allclose(e.shape(ends), 0.0, atol=1e-12)
        np.testing.assert_allclose(e.shape(ends, 1), [mu, s * mu], atol=1e-11)
        assert e.constraint == pytest.approx(2.0, rel=1e-12)
        # the ODE W'''' + Lambda^2 W'' = 0 by finite differences of W'' (independent check)
        X = np.linspace(0.1, 0.9, 9)
        h = 1e-3
        d4 = (e.shape(X + h, 2) - 2 * e.shape(X, 2) + e.shape(X - h, 2)) / h**2
        np.testing.assert_allclose(d4 + e.lambda2 * e.shape(X, 2), 0.0,
                                   atol=1e-4 * np.abs(d4).max())  # fmt: skip


@pytest.mark.parametrize("actuation", ACTS)
def test_every_branch_exists_at_tiny_mu(actuation: str) -> None:
    """Found by the API's fuzz pass: at 0 < |mu| < ~1e-11 J(Lambda) = 2 / mu^2 has its root
    within rounding of an Euler eigenvalue (branches vanished; at mu = 5e-324 2 / mu^2 divided
    by zero), and the direct solve loses digits as 1 / mu. The six branches exist at every tiny
    mu, satisfy the boundary conditions and the length constraint, and agree with the direct
    solve where it is well conditioned."""
    s = SLOPE[actuation]
    ends = np.array([0.0, 1.0])
    for mu in (5e-324, -5e-324, 1e-100, 1e-12, -1e-9, 9.9e-9):
        eqs = equilibria(actuation, mu)
        assert sorted(e.branch for e in eqs) == ["S_A", "S_B", "U_A", "U_B", "W_A", "W_B"], mu
        for e in eqs:
            assert e.mu == mu
            np.testing.assert_allclose(e.shape(ends), 0.0, atol=1e-12)
            np.testing.assert_allclose(e.shape(ends, 1), [mu, s * mu], atol=1e-12)
            assert e.constraint == pytest.approx(2.0, rel=1e-12)
    # the parabola (used below 1e-4) against the direct solve where that holds 3e-11
    from sim.euler_beam.statics import _near_zero

    direct = {e.branch: np.array(e.coeffs) for e in equilibria(actuation, 3e-4)}
    for e in _near_zero(actuation, 3e-4):
        np.testing.assert_allclose(e.coeffs, direct[e.branch], rtol=0, atol=2e-9)


def test_generic_branch_matches_the_papers_basis() -> None:
    """Lambda of each generic equilibrium gives back its mu in the paper's own formulation."""
    for actuation in ACTS:
        for mu in (0.4, 1.2, 1.75):
            for e in equilibria(actuation, mu):
                if e.kind == "generic" and e.lambda2 > 1.0:
                    assert _paper_mu(e.lam, SLOPE[actuation]) == pytest.approx(mu, rel=1e-10)


def test_asymmetric_saddle_node_against_independent_maximisation() -> None:
    bif = bifurcation("asymmetric")
    mu_ref, L_ref = _paper_fold(2 * math.pi + 0.1, 8.9, 0.0)
    assert bif.transition == "saddle-node"
    assert abs(bif.mu_star - mu_ref) < 1e-10
    assert abs(bif.lambda_star - L_ref) < 1e-5  # the maximiser is flat: 1e-5 in Lambda is exact
    assert set(bif.branches) == {"U_A", "S_B"}
    # the paper: 1.782 (Table 1), 1.7812 (Stability analysis)
    assert abs(bif.mu_star - 1.782) < 5e-4
    # U_A exists just below mu*, not above; S_B likewise; U_B survives
    below = {e.branch for e in equilibria("asymmetric", bif.mu_star - 1e-9)}
    above = {e.branch for e in equilibria("asymmetric", bif.mu_star + 1e-9)}
    assert {"U_A", "S_B", "U_B"} <= below
    assert "U_A" not in above and "S_B" not in above and "U_B" in above


def test_symmetric_subcritical_pitchfork_at_exactly_two_and_secondary_fold() -> None:
    bif = bifurcation("symmetric")
    assert bif.transition == "subcritical-pitchfork"
    assert abs(bif.mu_star - 2.0) < 1e-12
    assert bif.lambda_star == pytest.approx(euler_eigenvalues(2)[1][0], abs=1e-12)
    assert set(bif.branches) == {"U_A", "S_A", "S_B"}
    (sec,) = bif.secondary
    mu_ref, _ = _paper_fold(9.0, 4 * math.pi - 0.1, -1.0)
    assert sec.transition == "saddle-node" and set(sec.branches) == {"U_A", "W_B"}
    assert abs(sec.mu_star - mu_ref) < 1e-10
    assert abs(sec.mu_star - 2.012) < 5e-4
    # S_A and S_B exist up to mu* and merge on U_A: their W(1/4) -> U_A's
    e = {x.branch: x for x in equilibria("symmetric", 2.0 - 1e-8)}
    assert abs(e["S_A"].w_quarter - e["U_A"].w_quarter) < 1e-3
    assert abs(e["S_B"].w_quarter - e["U_A"].w_quarter) < 1e-3
    assert "S_A" not in {x.branch for x in equilibria("symmetric", 2.0 + 1e-8)}


def test_antisymmetric_supercritical_pitchfork() -> None:
    bif = bifurcation("antisymmetric")
    assert bif.transition == "supercritical-pitchfork"
    assert abs(bif.mu_star - 2.0) < 1e-12
    assert bif.lambda_star == pytest.approx(2 * math.pi, abs=1e-13)
    assert set(bif.branches) == {"U_A", "U_B", "S_B"}
    e = {x.branch: x for x in equilibria("antisymmetric", 2.0 - 1e-8)}
    assert is_stable(e["U_A"]) and is_stable(e["U_B"]) and not is_stable(e["S_B"])
    after = {x.branch: x for x in equilibria("antisymmetric", 2.0 + 1e-6)}
    assert "U_A" not in after and is_stable(after["S_B"])


def test_paper_pitchfork_value_in_closed_form() -> None:
    """At a compatible Euler mode mu_c = sqrt(2/J_p) = 2: check by the paper's basis too."""
    assert _paper_mu(2 * math.pi * (1 + 1e-9), 1.0) == pytest.approx(2.0, rel=1e-7)
    L_s = euler_eigenvalues(2)[1][0]
    assert _paper_mu(L_s * (1 + 1e-9), -1.0) == pytest.approx(2.0, rel=1e-7)


def test_stability_of_the_branches() -> None:
    for actuation in ACTS:
        e = {x.branch: x for x in equilibria(actuation, 0.5)}
        assert is_stable(e["U_A"]) and is_stable(e["U_B"])
        for b in ("S_A", "S_B", "W_A", "W_B"):
            assert not is_stable(e[b])


def test_mirror_symmetry_for_negative_mu() -> None:
    pos = {e.branch: e for e in equilibria("asymmetric", 0.8)}
    neg = {e.branch: e for e in equilibria("asymmetric", -0.8)}
    X = np.linspace(0, 1, 11)
    for b, e in pos.items():
        m = b[:2] + {"A": "B", "B": "A"}[b[2]]
        np.testing.assert_allclose(neg[m].shape(X), -e.shape(X), atol=1e-13)


def test_tension_branches_are_continuous_through_lambda_zero() -> None:
    """The symmetric U_B reaches Lambda = 0 near mu = 2.45 and goes on in tension."""
    mus = np.linspace(2.3, 2.7, 9)
    lam2 = [equilibrium("symmetric", m, "U_B").lambda2 for m in mus]
    assert lam2[0] > 0 > lam2[-1]
    assert np.all(np.diff(lam2) < 0)
    zero = brentq(lambda m: equilibrium("symmetric", m, "U_B").lambda2, 2.3, 2.7)
    assert _paper_mu(1e-3, -1.0) == pytest.approx(zero, rel=1e-5)


def test_errors_name_the_parameter() -> None:
    with pytest.raises(BeamError, match="actuation") as e:
        equilibria("sideways", 1.0)
    assert (e.value.parameter, e.value.value) == ("actuation", "sideways")
    with pytest.raises(SimulationError, match="U_A") as e:
        equilibrium("asymmetric", 1.9, "U_A")
    assert (e.value.parameter, e.value.value) == ("mu", 1.9)
    with pytest.raises(BeamError, match="mu") as e:
        equilibria("asymmetric", float("nan"))
    assert e.value.parameter == "mu"


# ---- the compiled entire basis against its slow numpy reference ----
def _basis_reference(lam: complex, X: np.ndarray) -> tuple[np.ndarray, ...]:
    """The basis in numpy (the statics' former implementation): 18 Taylor terms in z = lam X^2
    where |z| <= 1, the closed forms elsewhere."""
    X = np.asarray(X, dtype=float)
    z = complex(lam) * X * X
    out = [np.empty(X.shape, dtype=complex) for _ in range(4)]
    small = np.abs(z) <= 1.0
    Xs, zs = X[small], z[small]
    c, s, s1, co = (np.zeros_like(zs) for _ in range(4))
    term = np.ones_like(zs)
    for k in range(18):
        co += term
        s1 += term / (2 * k + 1)
        c += term / ((2 * k + 1) * (2 * k + 2))
        s += term / ((2 * k + 1) * (2 * k + 2) * (2 * k + 3))
        term = term * (-zs) / ((2 * k + 1) * (2 * k + 2))
    out[3][small], out[2][small], out[0][small], out[1][small] = co, s1 * Xs, c * Xs**2, s * Xs**3
    L, Xb = np.sqrt(complex(lam)), X[~small]
    sn, cs = np.sin(L * Xb), np.cos(L * Xb)
    out[3][~small], out[2][~small] = cs, sn / L
    out[0][~small] = 2.0 * np.sin(0.5 * L * Xb) ** 2 / lam
    out[1][~small] = (L * Xb - sn) / (lam * L)
    return tuple(out)


@pytest.mark.parametrize(
    "lam", [0.3, 5.0, 39.4784176, 80.0, -25.0, complex(40.0, 1e-30), complex(-3.0, 1e-30)]
)
def test_compiled_basis_matches_the_numpy_reference(lam: complex) -> None:
    """Both sides of |lam X^2| = 1 (series and closed forms), tension (lam < 0) and the
    complex step the derivatives take: values to round-off, and the complex step's
    imaginary part (the derivative) to the same relative accuracy."""
    from sim.euler_beam.statics import basis

    X = np.concatenate([np.linspace(0.0, 1.0, 41), [0.999, 1.0]]).reshape(43, 1)
    got, ref = basis(lam, X), _basis_reference(lam, X)
    for g, r in zip(got, ref, strict=True):
        assert g.shape == X.shape
        np.testing.assert_allclose(g.real, r.real, rtol=1e-13, atol=1e-15)
        np.testing.assert_allclose(g.imag, r.imag, rtol=1e-12, atol=1e-45)
