"""numba kernels of the Euler beam (plain arrays in, results written in place).

Each kernel has a slow pure-numpy reference in the tests (dynamics:
tests/sim/test_beam_dynamics.py; the statics' basis: tests/sim/test_beam_statics.py).
"""

from __future__ import annotations

import cmath

import numpy as np
from numba import njit


@njit(cache=True)
def entire_basis(lam, X, C, S, S1, Co):  # pragma: no cover - compiled
    """The statics' entire basis functions of ``lam = Lambda^2`` at the points ``X`` (see
    :func:`sim.euler_beam.statics.basis`), complex arithmetic (complex-step derivatives):
    ``C = (1 - cos)/lam``, ``S = (Lambda X - sin)/(lam Lambda)``, ``S1 = sin(Lambda X)/Lambda``,
    ``Co = cos(Lambda X)``; an 18-term Taylor series in ``z = lam X^2`` where ``|z| <= 1``
    (error < 1e-17), the closed forms elsewhere. ``X`` float64 (n,); outputs complex128 (n,)."""
    L = cmath.sqrt(lam)
    for i in range(X.shape[0]):
        x = X[i]
        z = lam * x * x
        if abs(z) <= 1.0:
            co = 0j
            s1 = 0j
            c = 0j
            s = 0j
            term = 1.0 + 0j  # (-z)^k / (2k)!
            for k in range(18):
                co += term
                s1 += term / (2 * k + 1)
                c += term / ((2 * k + 1) * (2 * k + 2))
                s += term / ((2 * k + 1) * (2 * k + 2) * (2 * k + 3))
                term = term * (-z) / ((2 * k + 1) * (2 * k + 2))
            Co[i] = co
            S1[i] = s1 * x
            C[i] = c * x**2
            S[i] = s * x**3
        else:
            sn = cmath.sin(L * x)
            Co[i] = cmath.cos(L * x)
            S1[i] = sn / L
            h = cmath.sin(0.5 * L * x)
            C[i] = 2.0 * h * h / lam
            S[i] = (L * x - sn) / (lam * L)


@njit(cache=True)
def constraint_value(K2, k2, c0, a):  # pragma: no cover - compiled
    """c(a) = a.K2.a + 2 k2.a + c0 = integral of W'^2 for W = lift + phi.a."""
    n = a.shape[0]
    s = c0
    for i in range(n):
        acc = 0.0
        for j in range(n):
            acc += K2[i, j] * a[j]
        s += a[i] * (acc + 2.0 * k2[i])
    return s


@njit(cache=True)
def midpoint_integrate(
    M, K4, K2, k4, k2, c0, xi, dt, a, v, lam, nsteps, stride, probe, probe_lift, out_w, out_lam
):  # pragma: no cover - compiled
    """Integrate the constrained, damped beam with the discrete-gradient midpoint rule.

    Semi-discrete equations (Galerkin, W = lift + phi . a):

        M a'' + xi M a' + (K4 - lam K2) a + k4 - lam k2 = 0,   c(a) = 2,

    lam = Lambda^2 being the Lagrange multiplier. One step (d = a_{n+1} - a_n):

        [(2/dt + xi) M + dt/2 (K4 - lam K2)] d = 2 M v_n - dt [(K4 - lam K2) a_n + k4 - lam k2]
        c(a_n + d) = 2   (Newton on the scalar lam),   v_{n+1} = 2 d / dt - v_n.

    For a quadratic constraint the midpoint gradient is a discrete gradient: with xi = 0 the
    scheme conserves the energy exactly and the constraint to the Newton tolerance.

    Parameters
    ----------
    a, v : (n,) arrays, updated in place to the final state.
    lam : float, initial guess of Lambda^2.
    nsteps : int, number of steps; every ``stride``-th state is recorded.
    probe : (n,) basis values at the probe; probe_lift : lift value there.
    out_w, out_lam : (nsteps // stride + 1,) outputs: W(probe) and Lambda^2.

    Returns
    -------
    int
        Number of recorded samples (== len(out_w) when the run completed; fewer when Newton
        failed to converge, i.e. the motion left the model's range).
    """
    n = a.shape[0]
    A = np.empty((n, n))
    rhs = np.empty(n)
    rhs2 = np.empty(n)
    g = np.empty(n)
    out_w[0] = probe_lift + np.dot(probe, a)
    out_lam[0] = lam
    rec = 1
    for step in range(1, nsteps + 1):
        converged = False
        d = np.zeros(n)
        for _ in range(30):
            for i in range(n):
                acc = 0.0
                accm = 0.0
                for j in range(n):
                    kij = K4[i, j] - lam * K2[i, j]
                    A[i, j] = (2.0 / dt + xi) * M[i, j] + 0.5 * dt * kij
                    acc += kij * a[j]
                    accm += M[i, j] * v[j]
                rhs[i] = 2.0 * accm - dt * (acc + k4[i] - lam * k2[i])
            d = np.linalg.solve(A, rhs)
            F = constraint_value(K2, k2, c0, a + d) - 2.0
            if abs(F) <= 1e-14:
                converged = True
                break
            # dF/dlam: d(d)/dlam = A^{-1} dt (K2 (a + d/2) + k2); dF = 2 g . d(d)/dlam
            for i in range(n):
                acc = 0.0
                acc2 = 0.0
                for j in range(n):
                    acc += K2[i, j] * (a[j] + d[j])
                    acc2 += K2[i, j] * (a[j] + 0.5 * d[j])
                g[i] = acc + k2[i]
                rhs2[i] = dt * (acc2 + k2[i])
            dd = np.linalg.solve(A, rhs2)
            dF = 2.0 * np.dot(g, dd)
            if dF == 0.0:
                break
            lam -= F / dF
        if not converged:
            return rec
        for i in range(n):
            a[i] += d[i]
            v[i] = 2.0 * d[i] / dt - v[i]
        if step % stride == 0:
            out_w[rec] = probe_lift + np.dot(probe, a)
            out_lam[rec] = lam
            rec += 1
            if rec >= out_w.shape[0]:
                return rec
    return rec


@njit(cache=True)
def modal_sum(t, sigma2, xi, amp, out):  # pragma: no cover - compiled
    """out[k] = sum_m amp[m] eta_m(t[k]): unit-initial-velocity damped modal responses.

    eta'' + xi eta' - sigma2 eta = 0, eta(0) = 0, eta'(0) = 1, for every regime
    (underdamped, critically damped, overdamped, unstable).
    """
    nt = t.shape[0]
    for k in range(nt):
        out[k] = 0.0
    for m in range(sigma2.shape[0]):
        disc = sigma2[m] + 0.25 * xi * xi  # (s + xi/2)^2 = disc
        for k in range(nt):
            tk = t[k]
            if disc < 0.0:
                wd = np.sqrt(-disc)
                out[k] += amp[m] * np.exp(-0.5 * xi * tk) * np.sin(wd * tk) / wd
            elif disc > 0.0:
                # e^{-xi t/2} sinh(kd t)/kd without overflow or cancellation
                kd = np.sqrt(disc)
                x = 2.0 * kd * tk
                if x < 30.0:
                    f = np.exp(-(kd + 0.5 * xi) * tk) * np.expm1(x)
                else:
                    f = np.exp((kd - 0.5 * xi) * tk)
                out[k] += amp[m] * f / (2.0 * kd)
            else:
                out[k] += amp[m] * np.exp(-0.5 * xi * tk) * tk
