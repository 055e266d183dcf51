"""Numba kernels of the planar discrete Cosserat rod (plain arrays, written in place).

Degrees of freedom (non-dimensional: length by L, B = EI = 1, mass per length rho A = 1)
----------------------------------------------------------------------------------------
``z`` has length ``N = 3 n + 2`` and interleaves nodes and elements::

    z[3 i]     = x_i,   z[3 i + 1] = y_i          (nodes i = 0 .. n, at s_i = i ds)
    z[3 e + 2] = theta_e                          (elements e = 0 .. n - 1, centre s = (e + 1/2) ds)

so that element ``e`` touches the contiguous block ``z[3e : 3e + 5]`` and every Hessian is a
band matrix with half-bandwidth ``KU = 4``.

Energy (Gazzola et al. 2018 restricted to the plane; strains per reference length ds = 1/n)::

    d_e   = (r_{e+1} - r_e) / ds
    a_e   = d_e . t(theta_e) - 1            (stretch; t = (cos, sin))
    b_e   = d_e . n(theta_e)                (shear;   n = (-sin, cos))
    E_s   = sum_e ds / 2 (EA a_e^2 + GA b_e^2)
    E_b   = sum_{e < n-1} B / (2 ds) (theta_{e+1} - theta_e)^2
            + kL / 2 (theta_0 - alphaL)^2 + kR / 2 (theta_{n-1} - alphaR)^2

``kL = kR = 2 B / ds`` is the node clamp (the prescribed angle acts at the end node s = 0,
half a Voronoi length from the first element centre); ``kL = kR = 0`` with theta_0, theta_{n-1}
held as Dirichlet values is the element clamp of PyElastica.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

KU = 4  # half bandwidth of every Hessian in the interleaved ordering


@njit(cache=True)
def energy(z, n, ds, EA, GA, B, kL, kR, aL, aR):
    """Total elastic energy (float). ``z`` shape (3n+2,)."""
    e_tot = 0.0
    for e in range(n):
        j = 3 * e
        dx = (z[j + 3] - z[j]) / ds
        dy = (z[j + 4] - z[j + 1]) / ds
        c = math.cos(z[j + 2])
        s = math.sin(z[j + 2])
        a = dx * c + dy * s - 1.0
        b = -dx * s + dy * c
        e_tot += 0.5 * ds * (EA * a * a + GA * b * b)
    for e in range(n - 1):
        dth = z[3 * e + 5] - z[3 * e + 2]
        e_tot += 0.5 * B / ds * dth * dth
    d0 = z[2] - aL
    d1 = z[3 * (n - 1) + 2] - aR
    e_tot += 0.5 * kL * d0 * d0 + 0.5 * kR * d1 * d1
    return e_tot


@njit(cache=True)
def gradient(z, n, ds, EA, GA, B, kL, kR, aL, aR, out):
    """Gradient of :func:`energy` (generalised internal forces), written into ``out`` (3n+2,)."""
    out[:] = 0.0
    for e in range(n):
        j = 3 * e
        dx = (z[j + 3] - z[j]) / ds
        dy = (z[j + 4] - z[j + 1]) / ds
        c = math.cos(z[j + 2])
        s = math.sin(z[j + 2])
        a = dx * c + dy * s - 1.0
        b = -dx * s + dy * c
        fx = EA * a * c - GA * b * s  # dE/d(dx) / ds
        fy = EA * a * s + GA * b * c
        out[j] -= fx
        out[j + 1] -= fy
        out[j + 3] += fx
        out[j + 4] += fy
        out[j + 2] += ds * b * (EA * a - GA * (a + 1.0))
    for e in range(n - 1):
        g = B / ds * (z[3 * e + 5] - z[3 * e + 2])
        out[3 * e + 2] -= g
        out[3 * e + 5] += g
    out[2] += kL * (z[2] - aL)
    out[3 * (n - 1) + 2] += kR * (z[3 * (n - 1) + 2] - aR)


@njit(cache=True)
def hessian_band(z, n, ds, EA, GA, B, kL, kR, ab):
    """Hessian of :func:`energy` in LAPACK general band storage, written into ``ab``.

    ``ab`` has shape (2 KU + 1, 3n+2) and holds ``H[i, j]`` at ``ab[KU + i - j, j]``
    (the layout of ``scipy.linalg.solve_banded((KU, KU), ab, b)``).
    """
    ab[:, :] = 0.0
    inv = 1.0 / ds
    Hg = np.zeros((3, 3))
    for e in range(n):
        j = 3 * e
        dx = (z[j + 3] - z[j]) / ds
        dy = (z[j + 4] - z[j + 1]) / ds
        c = math.cos(z[j + 2])
        s = math.sin(z[j + 2])
        a = dx * c + dy * s - 1.0
        b = -dx * s + dy * c
        # first derivatives of a, b with respect to (dx, dy, theta)
        a0, a1, a2 = c, s, b
        b0, b1, b2 = -s, c, -(a + 1.0)
        # second derivatives (only mixed with theta, and theta-theta, are non-zero)
        Hg[0, 0] = ds * (EA * a0 * a0 + GA * b0 * b0)
        Hg[0, 1] = ds * (EA * a0 * a1 + GA * b0 * b1)
        Hg[1, 1] = ds * (EA * a1 * a1 + GA * b1 * b1)
        Hg[0, 2] = ds * (EA * (a0 * a2 + a * (-s)) + GA * (b0 * b2 + b * (-c)))
        Hg[1, 2] = ds * (EA * (a1 * a2 + a * c) + GA * (b1 * b2 + b * (-s)))
        Hg[2, 2] = ds * (EA * (a2 * a2 - a * (a + 1.0)) + GA * (b2 * b2 - b * b))
        Hg[1, 0] = Hg[0, 1]
        Hg[2, 0] = Hg[0, 2]
        Hg[2, 1] = Hg[1, 2]
        # H_local = T^T Hg T with T = d(dx, dy, theta)/d(x_e, y_e, theta_e, x_e+1, y_e+1)
        i2 = inv * inv
        for p in range(2):
            for q in range(2):
                gpq = Hg[p, q] * i2
                ab[KU + p - q, j + q] += gpq  # (e, e)
                ab[KU + p - q - 3, j + q + 3] -= gpq  # (e, e+1)
                ab[KU + p + 3 - q, j + q] -= gpq  # (e+1, e)
                ab[KU + p - q, j + q + 3] += gpq  # (e+1, e+1)
        for p in range(2):
            gt = Hg[p, 2] * inv
            ab[KU + p - 2, j + 2] -= gt  # (node e, theta)
            ab[KU + 2 - p, j + p] -= gt
            ab[KU + p + 3 - 2, j + 2] += gt  # (node e+1, theta)
            ab[KU + 2 - p - 3, j + p + 3] += gt
        ab[KU, j + 2] += Hg[2, 2]
    kb = B / ds
    for e in range(n - 1):
        i0 = 3 * e + 2
        i1 = 3 * e + 5
        ab[KU, i0] += kb
        ab[KU, i1] += kb
        ab[KU + i0 - i1, i1] -= kb
        ab[KU + i1 - i0, i0] -= kb
    ab[KU, 2] += kL
    ab[KU, 3 * (n - 1) + 2] += kR


@njit(cache=True)
def band_factor(ab):
    """LU-factorise in place (no pivoting) a band matrix in LAPACK layout (2 KU + 1, N).

    Meant for the symmetric positive definite time-step Jacobians (mass term dominant)."""
    N = ab.shape[1]
    for k in range(N - 1):
        piv = ab[KU, k]
        iend = min(N, k + KU + 1)
        for i in range(k + 1, iend):
            l_ik = ab[KU + i - k, k] / piv
            ab[KU + i - k, k] = l_ik
            if l_ik != 0.0:
                for j in range(k + 1, iend):
                    ab[KU + i - j, j] -= l_ik * ab[KU + k - j, j]


@njit(cache=True)
def band_lusolve(ab, rhs):
    """Solve in place with the factors of :func:`band_factor`."""
    N = rhs.shape[0]
    for k in range(N - 1):
        for i in range(k + 1, min(N, k + KU + 1)):
            rhs[i] -= ab[KU + i - k, k] * rhs[k]
    for k in range(N - 1, -1, -1):
        acc = rhs[k]
        for j in range(k + 1, min(N, k + KU + 1)):
            acc -= ab[KU + k - j, j] * rhs[j]
        rhs[k] = acc / ab[KU, k]


@njit(cache=True)
def band_solve(ab, rhs):
    """Solve ``A x = rhs`` in place (no pivoting): ``ab`` is overwritten by its LU factors."""
    band_factor(ab)
    band_lusolve(ab, rhs)


@njit(cache=True)
def integrate(
    z,
    v,
    a,
    mass,
    fixed,
    n,
    ds,
    EA,
    GA,
    B,
    kL,
    kR,
    aL,
    aR,
    xi,
    dt,
    nsteps,
    every,
    probes,
    weights,
    rho_inf,
    tol,
    maxit,
    full_its,
    rec,
    stats,
):
    """Generalised-alpha (Chung-Hulbert) integration of M z'' + xi M z' + grad E(z) = 0.

    Parameters (all arrays are written in place)
    ----------
    z, v, a : (N,) positions, velocities, accelerations at t = 0; on return at the end.
    mass : (N,) lumped masses (ds on nodes, J ds on element angles).
    fixed : (N,) uint8, 1 where the dof is prescribed (its v, a stay 0).
    xi : damping (paper eq. beam_equation_damping) applied to every dof, rate xi.
    dt, nsteps, every : step, number of steps; a sample is recorded every ``every`` steps.
    probes, weights : (P, 2) int / float: recorded value p = sum_k weights[p, k] z[probes[p, k]].
    rho_inf : spectral radius at infinite frequency (1: trapezoidal rule, no dissipation).
    tol, maxit : Newton tolerance on the error left in max |z| (the last correction times
        theta / (1 - theta), theta its contraction) and iteration cap per step.
    full_its : the tangent is re-assembled and factorised for the first ``full_its``
        iterations of a step; otherwise the last factorisation is kept, across steps too
        (modified Newton), and refreshed when an iteration contracts the correction by less
        than a factor 10 (``full_its = 0``: that adaptive reuse from the first iteration;
        slower to converge on stiff, thin rods, so not the default).
    rec : (nsteps // every + 1, P) output samples; stats : (3,) float -> [steps done,
        total Newton iterations, 0 ok / 1 Newton failure].
    """
    N = z.shape[0]
    am = (2.0 * rho_inf - 1.0) / (rho_inf + 1.0)
    af = rho_inf / (rho_inf + 1.0)
    gam = 0.5 - am + af
    beta = 0.25 * (1.0 - am + af) ** 2
    cm = (1.0 - am) / (beta * dt * dt)
    cc = (1.0 - af) * gam / (beta * dt)
    ab = np.zeros((2 * KU + 1, N))
    g = np.zeros(N)
    r = np.zeros(N)
    zn = z.copy()
    za = np.zeros(N)
    znew = z.copy()
    anew = np.zeros(N)
    vnew = np.zeros(N)
    P = probes.shape[0]
    for p in range(P):
        rec[0, p] = weights[p, 0] * z[probes[p, 0]] + weights[p, 1] * z[probes[p, 1]]
    k_rec = 1
    total_it = 0
    stats[2] = 0.0
    have_factor = False
    refresh = False
    for step in range(nsteps):
        for i in range(N):
            zn[i] = z[i]
            znew[i] = z[i] + dt * v[i]  # predictor: constant velocity (robust for stiff modes)
        converged = False
        prev = math.inf
        for it in range(maxit):
            for i in range(N):
                if fixed[i] == 0:
                    anew[i] = (znew[i] - zn[i] - dt * v[i]) / (beta * dt * dt) - (
                        0.5 - beta
                    ) / beta * a[i]
                    vnew[i] = v[i] + dt * ((1.0 - gam) * a[i] + gam * anew[i])
                else:
                    anew[i] = 0.0
                    vnew[i] = 0.0
                za[i] = (1.0 - af) * znew[i] + af * zn[i]
            gradient(za, n, ds, EA, GA, B, kL, kR, aL, aR, g)
            for i in range(N):
                if fixed[i] == 0:
                    am_i = (1.0 - am) * anew[i] + am * a[i]
                    vf_i = (1.0 - af) * vnew[i] + af * v[i]
                    r[i] = -(mass[i] * (am_i + xi * vf_i) + g[i])
                else:
                    r[i] = 0.0
            fresh = it < full_its or not have_factor or refresh
            if fresh:  # tangent refreshed; else the last factorisation is reused
                hessian_band(za, n, ds, EA, GA, B, kL, kR, ab)
                for j in range(N):
                    for d in range(2 * KU + 1):
                        ab[d, j] *= 1.0 - af
                    ab[KU, j] += (cm + xi * cc) * mass[j]
                for i in range(N):
                    if fixed[i] == 1:
                        for d in range(2 * KU + 1):
                            col = i + KU - d
                            if 0 <= col < N:
                                ab[d, col] = 0.0  # row i
                            ab[d, i] = 0.0  # column i
                        ab[KU, i] = 1.0
                band_factor(ab)
                have_factor = True
                refresh = False
            band_lusolve(ab, r)
            dmax = 0.0
            for i in range(N):
                znew[i] += r[i]
                if not abs(r[i]) <= dmax:  # also catches NaN
                    dmax = abs(r[i]) if math.isfinite(r[i]) else math.inf
            total_it += 1
            # error left after this correction: theta / (1 - theta) * dmax, theta the
            # contraction of this step's last iteration (none at the first; a kept tangent
            # contracts irregularly: then only the correction itself counts)
            theta = dmax / prev if it > 0 and prev > 0.0 else 1.0
            if dmax < tol or (fresh and theta < 0.5 and theta / (1.0 - theta) * dmax < tol):
                converged = True
                break
            if not fresh and dmax > 0.1 * prev:
                refresh = True  # the kept tangent contracts too slowly: refresh it
            prev = dmax
        if not converged and dmax < 1e3 * tol:
            converged = True  # round-off floor of a stiff rod
        if not converged or not math.isfinite(dmax):
            stats[0] = step  # z, v, a keep the last converged state
            stats[1] = total_it
            stats[2] = 1.0
            return
        for i in range(N):
            if fixed[i] == 0:
                anew[i] = (znew[i] - zn[i] - dt * v[i]) / (beta * dt * dt) - (
                    0.5 - beta
                ) / beta * a[i]
                v[i] = v[i] + dt * ((1.0 - gam) * a[i] + gam * anew[i])
                a[i] = anew[i]
            z[i] = znew[i]
        if (step + 1) % every == 0:
            for p in range(P):
                rec[k_rec, p] = weights[p, 0] * z[probes[p, 0]] + weights[p, 1] * z[probes[p, 1]]
            k_rec += 1
    stats[0] = nsteps
    stats[1] = total_it
