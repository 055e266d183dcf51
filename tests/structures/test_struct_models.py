"""The independent structures checked against references of their own: Newton's method and
energy minimisation for the equilibria, finite differences of the energy for the stiffness, a
joint solve of ``V' = V'' = 0`` and Koiter's two-thirds law for the folds, the truss's closed-form
snap load, the sign of the energy's fourth derivative for the pitchfork's type."""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import pytest
from scipy import integrate, optimize

sys.path.insert(0, str(Path(__file__).parent))

from _struct_models import (  # noqa: E402
    AsymmetricTruss,
    CoupledColumns,
    LinkColumn,
    VonMisesTruss,
    coupled_least_stiffness,
)
from _struct_plans import KINDS, impulse_record, random_plan, write_records  # noqa: E402

SOFT = [
    LinkColumn("lateral", k=100.0, L=1.0, inertia=0.1),
    LinkColumn("rotational", k=100.0, L=1.0, inertia=0.1, beta=-0.5),
    LinkColumn("rotational", k=250.0, L=1.7, inertia=0.3, beta=-1.5),
]
STIFF = [
    LinkColumn("rotational", k=100.0, L=1.0, inertia=0.1, beta=0.0),
    LinkColumn("rotational", k=40.0, L=0.6, inertia=0.02, beta=0.8),
]


def _with_eps(c: LinkColumn, eps: float) -> LinkColumn:
    return LinkColumn(c.spring, c.k, c.L, c.inertia, c.beta, eps)


def _fd2(f, x: float, h: float) -> float:
    """Fourth-order central second difference."""
    return (-f(x + 2 * h) + 16 * f(x + h) - 30 * f(x) + 16 * f(x - h) - f(x - 2 * h)) / (12 * h * h)


@pytest.mark.parametrize("col", SOFT + STIFF, ids=lambda c: f"{c.spring}{c.beta}")
@pytest.mark.parametrize("eps", [3e-3, 1e-4, -1e-3])
def test_column_equilibrium_newton_and_energy_minimum(col: LinkColumn, eps: float) -> None:
    c = _with_eps(col, eps)
    top = c.critical_load() or c.p_c
    x0 = eps
    for frac in (0.1, 0.5, 0.9, 0.99, 0.999):
        P = frac * top
        th = c.equilibrium(P)
        assert abs(c.dV(th, P)) <= 1e-12 * c.p_c * c.L
        # Newton on V' with V'' (analytic), continued from the last load's root: the same root
        x = optimize.newton(lambda t, P=P: c.dV(t, P), x0, fprime=lambda t, P=P: c.d2V(t, P),
                            tol=1e-13, maxiter=200)  # fmt: skip
        x0 = x
        assert x == pytest.approx(th, rel=1e-9, abs=1e-13)
        # a local minimum of the energy (bounded search between 0 and the fold / far beyond)
        hi = c.fold()[0] if c.fold() else math.copysign(1.5, eps)
        lo, hi = sorted((0.0, hi))
        res = optimize.minimize_scalar(lambda t, P=P: c.energy(t, P), bounds=(lo, hi),
                                       method="bounded", options={"xatol": 1e-12})  # fmt: skip
        assert res.x == pytest.approx(th, rel=1e-5, abs=1e-7)
        assert np.sign(th) == np.sign(eps) and abs(th) >= abs(eps)


@pytest.mark.parametrize("col", SOFT + STIFF, ids=lambda c: f"{c.spring}{c.beta}")
def test_column_stiffness_is_the_energys_curvature(col: LinkColumn) -> None:
    for eps in (0.0, 2e-3):
        c = _with_eps(col, eps)
        top = c.critical_load() or c.p_c
        for frac in (0.2, 0.8, 0.98):
            P = frac * top
            th = c.equilibrium(P)
            fd = _fd2(lambda t, P=P, c=c: c.energy(t, P), th, 1e-3)
            assert c.stiffness(P) == pytest.approx(fd, rel=1e-7, abs=1e-9 * c.p_c * c.L)
            assert c.omega2(P) == pytest.approx(c.stiffness(P) / c.inertia, rel=1e-15)
            if eps == 0.0:  # the trivial path: V'' = U''(0) - P L in closed form
                assert c.stiffness(P) == pytest.approx(c.p_c * c.L - P * c.L, rel=1e-12)


@pytest.mark.parametrize("col", SOFT, ids=lambda c: f"{c.spring}{c.beta}")
@pytest.mark.parametrize("eps", [1e-4, 1e-3, -3e-3])
def test_fold_is_the_joint_root_of_dV_and_d2V(col: LinkColumn, eps: float) -> None:
    c = _with_eps(col, eps)
    th_f, P_f = c.fold()
    assert P_f < c.p_c
    sol = optimize.fsolve(lambda z: [c.dV(z[0], z[1]) / c.k, c.d2V(z[0], z[1]) / c.k],
                          [1.5 * th_f, c.p_c], xtol=1e-13, full_output=True)  # fmt: skip
    (th2, P2), info, ier, msg = sol
    assert ier in (1, 3), msg  # 3: converged as far as floats allow
    assert th2 == pytest.approx(th_f, rel=1e-9)
    assert P2 == pytest.approx(P_f, rel=1e-12)
    # just below the fold the path exists and is stable; at and past it there is none
    assert c.omega2(P_f * (1 - 1e-9)) > 0
    with pytest.raises(ValueError, match="fold"):
        c.equilibrium(P_f * (1 + 1e-12))
    # the stiffness vanishes as sqrt(P_f - P) (the saddle-node's law): ratio of two distances
    r = c.stiffness(P_f * (1 - 1e-8)) / c.stiffness(P_f * (1 - 1e-10))
    assert r == pytest.approx(10.0, rel=1e-3)


@pytest.mark.parametrize("col", SOFT, ids=lambda c: f"{c.spring}{c.beta}")
def test_fold_converges_to_koiters_two_thirds_law(col: LinkColumn) -> None:
    """``1 - P_f/P_c = c eps^(2/3) (1 + C eps^(2/3) + ...)``: the ratio to Koiter's leading term
    tends to 1, and its deviation scaled by ``eps^(2/3)`` converges (the next term)."""
    epss = np.array([1e-8, 1e-7, 1e-6, 1e-5, 1e-4, 1e-3])
    ratio = np.array(
        [(1 - _with_eps(col, e).fold()[1] / col.p_c) / (col.koiter_c * e ** (2 / 3)) for e in epss]
    )
    dev = np.abs(ratio - 1)
    assert np.all(np.diff(dev) > 0)  # monotone convergence as eps -> 0
    assert dev[0] < 1e-4
    nxt = (ratio - 1) / epss ** (2 / 3)
    assert nxt[0] == pytest.approx(nxt[1], rel=1e-3)  # the next term's coefficient converged
    # the column: a 1e-3 rad stress-free angle on beta = -0.5 snaps at 98.704 N
    if col.spring == "rotational" and col.beta == -0.5:
        assert _with_eps(col, 1e-3).fold()[1] == pytest.approx(98.704, abs=5e-4)
    if col.spring == "lateral":
        # the classical Koiter/Thompson value of this model
        assert col.koiter_c == pytest.approx(1.5, rel=1e-15)


@pytest.mark.parametrize("col", SOFT + STIFF, ids=lambda c: f"{c.spring}{c.beta}")
def test_perfect_pitchfork_type_from_the_post_buckling_curvature(col: LinkColumn) -> None:
    """``V''''(0; P_c)`` by finite differences of the energy carries the type: > 0
    supercritical (stable-symmetric), < 0 subcritical; its value is ``6 P_c L kappa``; the
    buckled branch ``P(theta)`` bends up or down with it."""
    c = _with_eps(col, 0.0)
    h = 2e-2
    v = [c.energy(j * h, c.p_c) for j in (-2, -1, 0, 1, 2)]
    d4 = (v[0] - 4 * v[1] + 6 * v[2] - 4 * v[3] + v[4]) / h**4
    assert d4 == pytest.approx(6 * c.p_c * c.L * c.kappa, rel=2e-3)
    assert (d4 > 0) == (not c.softening)
    p_branch = c.load_on_path(0.01)
    assert (p_branch > c.p_c) == (not c.softening)
    assert (p_branch / c.p_c - 1) / 0.01**2 == pytest.approx(c.kappa, rel=1e-3)
    # and the buckled branch is stable exactly when supercritical
    assert (c.stiffness_on_path(0.01) > 0) == (not c.softening)


@pytest.mark.parametrize("col", STIFF, ids=lambda c: f"{c.spring}{c.beta}")
@pytest.mark.parametrize("eps", [1e-4, -2e-3])
def test_stiffening_imperfect_column_never_loses_stability(col: LinkColumn, eps: float) -> None:
    c = _with_eps(col, eps)
    assert c.fold() is None and c.critical_load() is None
    th_m, P_m, K_m = c.least_stiffness()
    assert K_m > 0
    loads = np.linspace(0.5 * c.p_c, 1.5 * c.p_c, 2001)
    K = np.array([c.stiffness(float(P)) for P in loads])
    assert np.all(K > 0)
    assert K.min() >= K_m * (1 - 1e-12)  # the least one is the least
    j = int(np.argmin(K))
    assert abs(loads[j] - P_m) <= loads[1] - loads[0]
    # a stationary point of the stiffness along the load
    dP = 1e-5 * c.p_c
    assert abs(c.stiffness(P_m + dP) - c.stiffness(P_m - dP)) < 1e-6 * K_m
    assert c.stiffness(P_m + 100 * dP) > K_m and c.stiffness(P_m - 100 * dP) > K_m
    assert c.equilibrium(P_m) == pytest.approx(th_m, rel=1e-12)


@pytest.mark.parametrize("rise", [0.1, 0.2, 0.35])
def test_truss_snap_load_closed_form_and_equilibria(rise: float) -> None:
    t = VonMisesTruss(k=3.0e4, L0=1.3, rise=rise, mass=2.0)
    w_f, F_f = t.fold()
    assert F_f == pytest.approx(t.snap_load_closed_form(), rel=1e-12)
    # l^3 = L0 b^2 at the fold (closed form)
    assert math.hypot(t.b, t.h - w_f) == pytest.approx((t.L0 * t.b**2) ** (1 / 3), rel=1e-12)
    for frac in (0.1, 0.6, 0.99, 0.9999):
        F = frac * F_f
        w = t.equilibrium(F)
        assert abs(t.dV(w, F)) <= 1e-12 * F_f
        res = optimize.minimize_scalar(lambda x, F=F: t.energy(x, F), bounds=(0.0, w_f),
                                       method="bounded", options={"xatol": 1e-13})  # fmt: skip
        assert res.x == pytest.approx(w, rel=1e-5, abs=1e-8)
        fd = _fd2(lambda x, F=F: t.energy(x, F), w, 2e-3 * t.h)
        assert t.stiffness(F) == pytest.approx(fd, rel=1e-6, abs=1e-8 * t.k)
    assert t.omega2(0.0) == pytest.approx(2 * t.k * math.sin(rise) ** 2 / t.mass, rel=1e-13)
    r = t.stiffness(F_f * (1 - 1e-8)) / t.stiffness(F_f * (1 - 1e-10))
    assert r == pytest.approx(10.0, rel=1e-3)


TRUTH = {
    "perfect-softening": "subcritical-pitchfork",
    "perfect-stiffening": "supercritical-pitchfork",
    "imperfect-softening": "saddle-node",
    "imperfect-stiffening": "none",
    "truss": "saddle-node",
    "truss-asymmetric": "saddle-node",
    "coupled-softening": "saddle-node",
    "coupled-stiffening": "none",
}


@pytest.mark.parametrize("kind", KINDS)
def test_random_plans_carry_their_truth(kind: str) -> None:
    rng = np.random.default_rng(5)
    for j in range(4):
        p = random_plan(rng, kind, index=j, static=True)
        assert np.all(np.diff(p.mu) > 0) and p.mu[0] >= 0 and 3 <= p.mu.size <= 40
        assert p.mu[-1] == pytest.approx(p.p_ref * (1 - p.stop), rel=1e-12)
        assert 1e-3 <= p.stop <= 1e-1
        om2 = np.array([p.model.omega2(float(m)) for m in p.mu])
        np.testing.assert_array_equal(om2, p.omega2_true)
        z = (-p.sigma2 - om2) / p.sigma2_std
        assert np.all(np.abs(z) < 6)
        assert p.transition == TRUTH[kind]
        if kind.startswith("imperfect"):
            assert 1e-4 <= abs(p.eps) <= 3e-3
        if kind == "imperfect-softening":
            assert p.critical < p.p_c
            assert np.all(np.sign(p.q_true) == np.sign(p.eps))
        if kind in ("imperfect-stiffening", "coupled-stiffening"):
            assert p.critical is None and p.least_stiffness_load is not None
            assert p.least_omega2 <= om2.min() * (1 + 1e-9)
        if kind == "coupled-softening":
            assert p.critical < p.p_c
        if kind.startswith("perfect"):
            assert p.critical == p.p_c and np.all(p.q_true == 0)
            # the pitchfork's stiffness is linear in the load: omega^2 (P_c - P)^-1 constant
            np.testing.assert_allclose(om2 / (p.p_c - p.mu), om2[0] / (p.p_c - p.mu[0]),
                                       rtol=1e-9)  # fmt: skip
        if kind == "truss":
            assert p.critical == pytest.approx(p.model.snap_load_closed_form(), rel=1e-12)
        if kind == "truss-asymmetric":  # the snap lies between the two symmetric arches'
            m = p.model
            lo = VonMisesTruss(k=m.k1, rise=m.rise).snap_load_closed_form()
            assert lo < p.critical < VonMisesTruss(k=m.k2, rise=m.rise).snap_load_closed_form()
        assert p.csv_text().splitlines()[0] == "mu,sigma2,sigma2_std,w_static,w_static_std"
    # a plan is a function of its generator's state
    a = random_plan(np.random.default_rng(9), kind)
    b = random_plan(np.random.default_rng(9), kind)
    np.testing.assert_array_equal(a.sigma2, b.sigma2)


def test_omega_tables_and_over_damped_rows() -> None:
    p = random_plan(np.random.default_rng(3), "truss", input="omega-no-std", rel=1e-12,
                    stop=1e-3, static=False)  # fmt: skip
    assert set(p.predict_kwargs()) == {"omega"}
    np.testing.assert_allclose(p.omega**2, p.omega2_true, rtol=1e-10)
    om_last = math.sqrt(p.omega2_true[-1])
    xi = 3.0 * om_last  # the last rows are over-damped
    q = random_plan(np.random.default_rng(3), "truss", input="omega", rel=1e-12, stop=1e-3,
                    damping=xi, static=False)  # fmt: skip
    assert q.predict_kwargs()["damping"] == xi
    over = np.sqrt(q.omega2_true) < xi / 2
    assert over[-1] and not over[0]
    # the slow pole r of s^2 + xi s + omega0^2 = 0: r (xi - r) = omega0^2
    np.testing.assert_allclose((q.omega * (xi - q.omega))[over], q.omega2_true[over], rtol=1e-8)
    np.testing.assert_allclose(q.omega[~over] ** 2, q.omega2_true[~over], rtol=1e-10)


@pytest.mark.parametrize("xi_ratio", [0.05, 3.0])
def test_impulse_record_solves_the_oscillator(xi_ratio: float) -> None:
    p = random_plan(np.random.default_rng(2), "imperfect-softening", stop=1e-2)
    i = p.mu.size - 1
    om0 = math.sqrt(p.omega2_true[i])
    xi = xi_ratio * om0
    dt = 2 * math.pi / om0 / 40
    w = impulse_record(p, i, dt=dt, n=800, damping=xi, noise=0.0)
    sol = integrate.solve_ivp(lambda t, y: [y[1], -xi * y[1] - om0**2 * y[0]], (0, 799 * dt),
                              [0.0, 1.0], t_eval=dt * np.arange(800), rtol=1e-11,
                              atol=1e-14)  # fmt: skip
    np.testing.assert_allclose(w - p.q_true[i], sol.y[0], atol=1e-8 * np.abs(sol.y[0]).max())


def test_records_and_manifest_for_the_sweep_door(tmp_path: Path) -> None:
    p = random_plan(np.random.default_rng(8), "truss", grid="coarse", stop=1e-2)
    m = write_records(p, tmp_path, max_samples=3000, seed=1)
    rows = m.read_text().splitlines()
    assert rows[0] == "path,control" and len(rows) == p.mu.size + 1
    name, ctrl = rows[-1].split(",")
    assert float(ctrl) == p.mu[-1]
    data = np.loadtxt(tmp_path / name, delimiter=",", skiprows=1)
    assert data.shape[1] == 2 and 100 < data.shape[0] <= 3000
    dt = data[1, 0] - data[0, 0]
    # the noise-free response about the static level, written to 9 digits
    xi = 2 * 0.01 * math.sqrt(p.omega2_true[0])
    w = impulse_record(p, p.mu.size - 1, dt=dt, n=data.shape[0], damping=xi, noise=0.0)
    peak = np.abs(w - p.q_true[-1]).max()
    assert np.max(np.abs(data[:, 1] - w)) < 6 * 1e-3 * peak


def test_asymmetric_truss_reduces_to_the_symmetric_one() -> None:
    a = AsymmetricTruss(k1=2.0e4, k2=2.0e4, rise=0.25, mass=1.5)
    t = VonMisesTruss(k=2.0e4, rise=0.25, mass=1.5)
    assert a.critical_load() == pytest.approx(t.snap_load_closed_form(), rel=1e-11)
    for F in (0.0, 0.5 * t.critical_load(), 0.99 * t.critical_load()):
        assert a.equilibrium(F) == pytest.approx(t.equilibrium(F), rel=1e-10, abs=1e-15)
        assert abs(a.u_on_path(a.equilibrium(F))) < 1e-12
        assert a.omega2(F) == pytest.approx(t.omega2(F), rel=1e-9)


@pytest.mark.parametrize("ratio", [1.05, 1.5])
def test_asymmetric_truss_energy_derivatives_and_fold(ratio: float) -> None:
    a = AsymmetricTruss(k1=1.0e4, k2=1.0e4 * ratio, rise=0.3, mass=0.7)
    w_f, F_f = a.fold()
    u, w = 0.3 * a.u_on_path(0.5 * w_f) + 1e-3, 0.4 * w_f
    h = 1e-6
    fd_g = [(a.energy(u + h, w, 7.0) - a.energy(u - h, w, 7.0)) / (2 * h),
            (a.energy(u, w + h, 7.0) - a.energy(u, w - h, 7.0)) / (2 * h)]  # fmt: skip
    np.testing.assert_allclose(a.gradient(u, w, 7.0), fd_g, rtol=1e-6, atol=1e-6)
    H = a.hessian(u, w)
    hh = 1e-4
    for i in range(2):
        e = np.eye(2)[i] * hh
        col = (a.gradient(u + e[0], w + e[1], 0.0) - a.gradient(u - e[0], w - e[1], 0.0)) / (2 * hh)
        np.testing.assert_allclose(H[:, i], col, rtol=1e-6, atol=1e-6 * np.abs(H).max())
    # the fold: the largest load the path carries (a second method) ...
    res = optimize.minimize_scalar(lambda x: -a.load_on_path(x), bounds=(0.5 * w_f, 1.5 * w_f),
                                   method="bounded", options={"xatol": 1e-12})  # fmt: skip
    assert -res.fun == pytest.approx(F_f, rel=1e-11)

    # ... and the joint root of the gradient and det V'' from another start (a third)
    def eqs(z: np.ndarray) -> list[float]:
        g = a.gradient(z[0], z[1], z[2])
        return [g[0] / a.k1, g[1] / a.k1, np.linalg.det(a.hessian(z[0], z[1])) / a.k1**2]

    z, _, ier, msg = optimize.fsolve(eqs, [0.0, 1.3 * w_f, 0.9 * F_f], xtol=1e-13,
                                     full_output=True)  # fmt: skip
    assert ier in (1, 3), msg
    assert z[1] == pytest.approx(w_f, rel=1e-8) and z[2] == pytest.approx(F_f, rel=1e-11)
    # unequal bars tilt the apex and lower the snap load below the symmetric arch's of the
    # softer bars (bounded above by the stiffer's)
    lo = VonMisesTruss(k=a.k1, rise=a.rise).snap_load_closed_form()
    hi = VonMisesTruss(k=a.k2, rise=a.rise).snap_load_closed_form()
    assert lo < F_f < hi and a.u_on_path(0.5 * w_f) != 0.0
    r = a.omega2(F_f * (1 - 1e-8)) / a.omega2(F_f * (1 - 1e-10))
    assert r == pytest.approx(10.0, rel=1e-3)


@pytest.mark.parametrize("beta", [-0.5, 0.5])
def test_coupled_columns_reduce_to_one_column(beta: float) -> None:
    """Equal bars with equal stress-free angles lean together: the spring between them stays
    unstretched, and each bar is the single column."""
    pair = CoupledColumns(k1=100.0, k2=100.0, c=70.0, L=1.0, inertia=0.1, beta=beta,
                          eps1=1e-3, eps2=1e-3)  # fmt: skip
    one = LinkColumn("rotational", k=100.0, L=1.0, inertia=0.1, beta=beta, eps=1e-3)
    assert pair.p_c == pytest.approx(one.p_c, rel=1e-13)
    if beta < 0:
        assert pair.critical_load() == pytest.approx(one.critical_load(), rel=1e-12)
    else:
        assert pair.critical_load() is None
        P, K = coupled_least_stiffness(pair)
        _, P1, K1 = one.least_stiffness()
        assert P == pytest.approx(P1, rel=1e-8) and K == pytest.approx(K1, rel=1e-10)
    for P in (10.0, 60.0, 0.97 * (one.critical_load() or one.p_c)):
        np.testing.assert_allclose(pair.equilibrium_angles(P), one.equilibrium(P), rtol=1e-10)
        assert pair.omega2(P) == pytest.approx(one.omega2(P), rel=1e-9)


@pytest.mark.parametrize("beta", [-1.0, 0.4])
def test_coupled_columns_against_the_energy(beta: float) -> None:
    pair = CoupledColumns(k1=80.0, k2=110.0, c=40.0, L=1.3, inertia=0.2, beta=beta,
                          eps1=-2e-3, eps2=5e-4)  # fmt: skip
    th, P = np.array([0.03, -0.05]), 45.0
    h = 1e-6
    E = np.eye(2)
    g_fd = [(pair.energy(th + h * E[i], P) - pair.energy(th - h * E[i], P)) / (2 * h)
            for i in range(2)]  # fmt: skip
    np.testing.assert_allclose(pair.gradient(th, P), g_fd, rtol=1e-7, atol=1e-8)
    hh = 1e-5
    H_fd = np.array([(pair.gradient(th + hh * E[i], P) - pair.gradient(th - hh * E[i], P))
                     / (2 * hh) for i in range(2)])  # fmt: skip
    np.testing.assert_allclose(pair.hessian(th, P), H_fd, rtol=1e-7, atol=1e-6)
    top = pair.critical_load() or pair.p_c
    for frac in (0.3, 0.9, 0.99):
        Pl = frac * top
        eq = pair.equilibrium_angles(Pl)
        assert np.max(np.abs(pair.gradient(eq, Pl))) < 1e-10 * pair.k1
        # a local minimum of the energy, found by BFGS from the stress-free angles
        res = optimize.minimize(lambda t, Pl=Pl: pair.energy(t, Pl), [pair.eps1, pair.eps2],
                                jac=lambda t, Pl=Pl: pair.gradient(t, Pl), method="BFGS",
                                options={"gtol": 1e-12})  # fmt: skip
        np.testing.assert_allclose(res.x, eq, rtol=1e-6, atol=1e-9)
        assert pair.omega2(Pl) == pytest.approx(
            np.linalg.eigvalsh(H_fd_at(pair, eq, Pl))[0] / pair.inertia, rel=1e-6
        )
    if beta < 0:  # the fold: a joint root of V' = 0 and det V'' = 0 from another start
        th_f, P_f = pair.fold()

        def eqs(z: np.ndarray) -> list[float]:
            g = pair.gradient(z[:2], z[2]) / pair.k1
            return [g[0], g[1], np.linalg.det(pair.hessian(z[:2], z[2])) / pair.k1**2]

        z, _, ier, msg = optimize.fsolve(eqs, [1.3 * th_f[0], 1.3 * th_f[1], pair.p_c],
                                         xtol=1e-13, full_output=True)  # fmt: skip
        assert ier in (1, 3), msg
        assert z[2] == pytest.approx(P_f, rel=1e-11) and P_f < pair.p_c
        r = pair.omega2(P_f * (1 - 1e-8)) / pair.omega2(P_f * (1 - 1e-10))
        assert r == pytest.approx(10.0, rel=1e-3)
    else:
        assert pair.fold() is None
        P_m, K_m = coupled_least_stiffness(pair)
        loads = np.linspace(0.6 * pair.p_c, 1.1 * pair.p_c, 301)
        lam = [pair.omega2(float(x)) * pair.inertia for x in loads]
        assert min(lam) >= K_m * (1 - 1e-9) and min(lam) > 0


def H_fd_at(pair: CoupledColumns, th: np.ndarray, P: float) -> np.ndarray:
    """The Hessian by central differences of the analytic gradient."""
    hh, E = 1e-5, np.eye(2)
    return np.array([(pair.gradient(th + hh * E[i], P) - pair.gradient(th - hh * E[i], P))
                     / (2 * hh) for i in range(2)])  # fmt: skip


@pytest.mark.parametrize("col", STIFF, ids=lambda c: f"{c.spring}{c.beta}")
def test_least_stiffness_converges_to_its_asymptote(col: LinkColumn) -> None:
    """Near ``P_c`` the path is ``(1 - p) theta + kappa theta^3 = eps``; along it
    ``V''/k ~ 2 kappa theta^2 + eps/theta``, least at ``theta^3 = eps/(4 kappa)``:
    ``K_min = 6 kappa k theta^2`` at ``P_min/P_c = 1 - 3 kappa theta^2``."""
    kap = col.kappa
    epss = np.array([1e-9, 1e-8, 1e-7, 1e-6, 1e-5])
    rk, rp = [], []
    for e in epss:
        _, P_m, K_m = _with_eps(col, e).least_stiffness()
        th2 = (e / (4 * kap)) ** (2 / 3)
        rk.append(K_m / (6 * kap * col.p_c * col.L * th2))
        rp.append((1 - P_m / col.p_c) / (3 * kap * th2))
    for r in (np.array(rk), np.array(rp)):
        dev = np.abs(r - 1)
        assert np.all(np.diff(dev) > 0) and dev[0] < 1e-3, r
