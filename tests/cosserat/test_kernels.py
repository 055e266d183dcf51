"""Numba kernels against slow pure-numpy references written independently."""

from __future__ import annotations

import math

import numpy as np
import pytest
import scipy.linalg as sla

from sim.cosserat import _kernels as K
from sim.cosserat.dynamics import integrate
from sim.cosserat.rod import Rod, band_to_dense


def ref_energy(rod: Rod, z: np.ndarray, mu: float) -> float:
    """Energy from the definitions, vectorised numpy (no shared code with the kernels)."""
    x, y, th = z[0::3], z[1::3], z[2::3]
    d = np.stack([np.diff(x), np.diff(y)]) / rod.ds
    t = np.stack([np.cos(th), np.sin(th)])
    nrm = np.stack([-np.sin(th), np.cos(th)])
    a = np.sum(d * t, axis=0) - 1.0
    b = np.sum(d * nrm, axis=0)
    e = 0.5 * rod.ds * np.sum(rod.EA * a**2 + rod.GA * b**2)
    e += 0.5 / rod.ds * np.sum(np.diff(th) ** 2)
    aL, aR = rod.end_angles(mu)
    k = 2.0 / rod.ds if rod.clamp == "node" else 0.0
    return float(e + 0.5 * k * ((th[0] - aL) ** 2 + (th[-1] - aR) ** 2))


def ref_gradient(rod: Rod, z: np.ndarray, mu: float, h: float = 1e-6) -> np.ndarray:
    g = np.zeros_like(z)
    for i in range(z.size):
        e = np.zeros_like(z)
        e[i] = h
        g[i] = (ref_energy(rod, z + e, mu) - ref_energy(rod, z - e, mu)) / (2 * h)
    return g


def ref_hessian(rod: Rod, z: np.ndarray, h: float = 1e-6) -> np.ndarray:
    H = np.zeros((z.size, z.size))
    for i in range(z.size):
        e = np.zeros_like(z)
        e[i] = h
        H[:, i] = (rod.gradient(z + e, 0.0) - rod.gradient(z - e, 0.0)) / (2 * h)
    return H


def _state(rod: Rod, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return rod.guess("U_A", 0.4) + 1e-2 * rng.standard_normal(rod.N)


@pytest.mark.parametrize("clamp", ["node", "element"])
@pytest.mark.parametrize("actuation", ["asymmetric", "symmetric", "antisymmetric"])
def test_energy_and_gradient_match_reference(clamp, actuation):
    rod = Rod(elements=8, slenderness=0.05, actuation=actuation, clamp=clamp)
    z = _state(rod)
    assert rod.energy(z, 0.4) == pytest.approx(ref_energy(rod, z, 0.4), rel=1e-12)
    g = rod.gradient(z, 0.4)
    gr = ref_gradient(rod, z, 0.4)
    assert np.max(np.abs(g - gr)) < 1e-6 * np.max(np.abs(gr))


def test_hessian_matches_finite_differences_and_is_symmetric():
    rod = Rod(elements=8, slenderness=0.05, actuation="symmetric")
    z = _state(rod, 1)
    H = rod.hessian(z)
    Hr = ref_hessian(rod, z)
    assert np.max(np.abs(H - Hr)) < 1e-7 * np.max(np.abs(H))
    assert np.array_equal(H, H.T)
    # the band layout really is LAPACK's: solve_banded agrees with a dense solve
    ab = rod.hessian_band(z) + 0.0
    ab[K.KU] += 1e3  # make it comfortably non-singular
    b = np.arange(rod.N, dtype=float)
    x = sla.solve_banded((K.KU, K.KU), ab, b)
    assert np.allclose(band_to_dense(ab) @ x, b)


def test_band_solve_matches_scipy():
    rng = np.random.default_rng(3)
    N = 40
    ab = rng.standard_normal((2 * K.KU + 1, N))
    ab[K.KU] += 20.0  # diagonally dominant: no pivoting needed
    b = rng.standard_normal(N)
    x_ref = sla.solve_banded((K.KU, K.KU), ab, b)
    x = b.copy()
    K.band_solve(ab.copy(), x)
    assert np.allclose(x, x_ref, rtol=1e-12, atol=1e-12)


def _ref_integrate(rod, z, v, mu, xi, dt, nsteps, rho):
    """Generalised-alpha with dense Newton and the numpy reference energy's gradient."""
    am = (2 * rho - 1) / (rho + 1)
    af = rho / (rho + 1)
    gam = 0.5 - am + af
    beta = 0.25 * (1 - am + af) ** 2
    m = rod.mass()
    fixed = rod.fixed_mask()
    free = ~fixed
    a = np.where(fixed, 0.0, -ref_gradient(rod, z, mu) / m - xi * v)
    out = []
    for _ in range(nsteps):
        zn = z + dt * v + 0.5 * dt * dt * a
        for _ in range(30):
            an = (zn - z - dt * v) / (beta * dt * dt) - (0.5 - beta) / beta * a
            vn = v + dt * ((1 - gam) * a + gam * an)
            za = (1 - af) * zn + af * z
            r = m * ((1 - am) * an + am * a + xi * ((1 - af) * vn + af * v)) + ref_gradient(
                rod, za, mu)
            J = (1 - af) * ref_hessian(rod, za) + np.diag(
                ((1 - am) / (beta * dt * dt) + xi * (1 - af) * gam / (beta * dt)) * m)
            dz = np.zeros_like(z)
            dz[free] = np.linalg.solve(J[np.ix_(free, free)], -r[free])
            zn = zn + dz
            if np.max(np.abs(dz)) < 1e-12:
                break
        an = (zn - z - dt * v) / (beta * dt * dt) - (0.5 - beta) / beta * a
        v = np.where(fixed, 0.0, v + dt * ((1 - gam) * a + gam * an))
        a = np.where(fixed, 0.0, an)
        z = zn
        out.append(z[rod.interp_weights(0.25)[0][0]])
    return z, v, np.array(out)


def test_integrate_matches_numpy_reference():
    rod = Rod(elements=6, slenderness=0.1, actuation="asymmetric")
    z0 = rod.apply_bc(rod.guess("U_A", 0.3), 0.3)
    v0 = np.zeros(rod.N)
    v0[1::3] = 0.05 * np.sin(np.linspace(0, math.pi, rod.n + 1))
    v0[rod.fixed_mask()] = 0.0
    run = integrate(rod, z0, v0, 0.3, xi=0.3, dt=2e-3, nsteps=5, rho_inf=0.7,
                    probes=[(rod.interp_weights(0.25)[0], (1.0, 0.0))])
    z_ref, v_ref, rec_ref = _ref_integrate(rod, z0.copy(), v0.copy(), 0.3, 0.3, 2e-3, 5, 0.7)
    assert run.stop == "done"
    assert np.max(np.abs(run.z - z_ref)) < 1e-8
    assert np.max(np.abs(run.v - v_ref)) < 1e-5 * max(1.0, np.max(np.abs(v_ref)))
    assert np.allclose(run.rec[1:, 0], rec_ref, atol=1e-8)


def test_wrappers_validate_their_inputs():
    with pytest.raises(ValueError, match="elements"):
        Rod(elements=7)
    with pytest.raises(ValueError, match="end_shortening"):
        Rod(end_shortening=0.0)
    with pytest.raises(ValueError, match="slenderness"):
        Rod(slenderness=-1.0)
    with pytest.raises(ValueError, match="actuation"):
        Rod(actuation="sideways")
    with pytest.raises(ValueError, match="clamp"):
        Rod(clamp="glue")
    rod = Rod(elements=8)
    with pytest.raises(ValueError, match="shape"):
        rod.gradient(np.zeros(5), 0.0)
    with pytest.raises(ValueError, match="dt"):
        integrate(rod, rod.guess("U_A"), np.zeros(rod.N), 0.0, xi=0.0, dt=-1.0, nsteps=3)
    with pytest.raises(ValueError, match="xi"):
        integrate(rod, rod.guess("U_A"), np.zeros(rod.N), 0.0, xi=-1.0, dt=1e-3, nsteps=3)
