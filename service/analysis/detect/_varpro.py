"""Variable-projection Levenberg-Marquardt on the poles, MDL pruning and refit checks.

Everything here works in sample units on the normalised record ``y`` (rms 1). A mode is the
pair ``(p, q)`` of ``x'' + p x' + q x = 0`` (see :mod:`service.analysis.detect._kernels`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from service.analysis.detect._kernels import model_gram, model_values
from service.analysis.detect._linalg import _pinv_psd, _solve_gram
from service.analysis.detect._results import ORDER_PENALTY, RSS_TOL, S2_FLOOR


@dataclass
class _Eval:
    p: np.ndarray
    q: np.ndarray
    G: np.ndarray  # Gram of [1, u1_0, u2_0, ..., y]
    c: np.ndarray  # linear coefficients [c0, c1_0, c2_0, c1_1, ...]
    rss: float


def _rss_tol(ev: _Eval) -> float:
    """Resolution of an RSS computed from a Gram matrix: ``RSS_TOL`` times the record's
    energy ``sum y^2`` (the cancellation in ``y.y - c.Phi^T y``); RSS differences below it are
    rounding, not signal."""
    return RSS_TOL * float(ev.G[-1, -1])


def _order_threshold(n: int) -> float:
    """RSS drop (in noise variances) a mode must bring to be kept in a record of ``n``
    samples: :data:`ORDER_PENALTY` ``x ln n`` (MDL)."""
    return ORDER_PENALTY * math.log(n)


def _growth_ok(p: np.ndarray, q: np.ndarray, n: int) -> bool:
    """Finite poles, none growing by more than ``e^40`` over the record, ``|p| < 20``."""
    for pk, qk in zip(p.tolist(), q.tolist(), strict=True):
        if not (math.isfinite(pk) and math.isfinite(qk)) or abs(pk) >= 20.0:
            return False
        if (-0.5 * pk + math.sqrt(max(0.25 * pk * pk - qk, 0.0))) * n >= 40.0:
            return False
    return True


def _block_energy(c: np.ndarray, Ginv: np.ndarray, j: int) -> float:
    """``c_b^T (Ginv_bb)^-1 c_b`` for the 2x2 block ``b = (j, j+1)``: the RSS rise when the
    two columns are removed (closed form; pseudo-inverse when the block is singular)."""
    a, b, d = float(Ginv[j, j]), float(Ginv[j, j + 1]), float(Ginv[j + 1, j + 1])
    c0, c1 = float(c[j]), float(c[j + 1])
    det = a * d - b * b
    if a > 0 and d > 0 and det > 1e-12 * a * d:
        return (d * c0 * c0 - 2.0 * b * c0 * c1 + a * c1 * c1) / det
    cb = c[j : j + 2]
    return float(cb @ _pinv_psd(Ginv[j : j + 2, j : j + 2]) @ cb)


_NO_C = np.zeros(1)


def _evaluate(y: np.ndarray, p: np.ndarray, q: np.ndarray) -> _Eval | None:
    """Gram matrix and projected (variable-projection) linear solve at ``(p, q)``."""
    N = y.shape[0]
    K = p.shape[0]
    if not _growth_ok(p, q, N):
        return None
    m = 2 * K + 2
    G = np.empty((m, m))
    model_gram(y, p, q, _NO_C, False, False, G)
    if not math.isfinite(float(G.sum())):
        return None
    c, rss = _solve_gram(G)
    return _Eval(p, q, G, c, rss)


def _theta(p: np.ndarray, q: np.ndarray, common: bool) -> np.ndarray:
    if common:
        return np.concatenate(([np.mean(p)], q))
    return np.column_stack((p, q)).ravel()


def _unpack(theta: np.ndarray, K: int, common: bool) -> tuple[np.ndarray, np.ndarray]:
    if common:
        return np.full(K, theta[0]), theta[1:].copy()
    return theta[0::2].copy(), theta[1::2].copy()


@dataclass
class _Fit:
    ev: _Eval
    cov: np.ndarray  # covariance of [theta, c] (sample units, normalised amplitude)
    ntheta: int
    s2: float  # noise variance estimate
    iterations: int
    common: bool


def _heavy_pass(
    y: np.ndarray, p: np.ndarray, q: np.ndarray, c: np.ndarray, common: bool
) -> np.ndarray | None:
    """Gram of ``[J_theta(c), Phi, y]`` at ``(p, q)`` (one fused pass over the record)."""
    if not _growth_ok(p, q, y.shape[0]):
        return None
    K = p.shape[0]
    nth = K + 1 if common else 2 * K
    B = np.empty((nth + 2 * K + 2, nth + 2 * K + 2))
    model_gram(y, p, q, c, common, True, B)
    if not math.isfinite(float(B.sum())):  # one reduction: a NaN or inf anywhere
        return None
    return B


def _step_small(dth: np.ndarray, var: np.ndarray) -> bool:
    """Every component of the step below 2 % of its standard error."""
    return bool(np.all(np.abs(dth) <= 2e-2 * np.sqrt(np.maximum(var, 1e-300))))


def _normal_equations(
    B: np.ndarray, c: np.ndarray, nth: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``J^T J``, the gradient ``J^T r`` (``r = y - Phi c``, ``c`` exact at theta) and the
    Marquardt scaling (the diagonal, zeros replaced by 1) from a heavy-pass Gram ``B``."""
    A = B[:-1, :-1]
    g = B[:-1, -1] - B[:-1, nth:-1] @ c
    dA = np.diag(A).copy()
    dA[dA == 0] = 1.0
    return A, g, dA


def _finish(
    B: np.ndarray, p: np.ndarray, q: np.ndarray, c: np.ndarray, rss: float, nth: int,
    it: int, common: bool, N: int,
) -> _Fit:  # fmt: skip
    """The fit at convergence: Gauss-Newton covariance ``s^2 (J^T J)^-1`` with the noise
    variance ``s^2`` at least the numerical floor."""
    npar = nth + c.size  # theta, the static level and two amplitudes per mode
    s2 = max(rss / max(N - npar, 1), S2_FLOOR)
    cov = _pinv_psd(B[:-1, :-1]) * s2
    ev = _Eval(p, q, np.ascontiguousarray(B[nth:, nth:]), c, rss)
    return _Fit(ev, cov, nth, s2, it, common)


def _levenberg_marquardt(
    y: np.ndarray,
    p0: np.ndarray,
    q0: np.ndarray,
    *,
    common: bool,
    max_iter: int,
    c0: np.ndarray | None = None,
) -> _Fit | None:
    """Variable-projection Levenberg-Marquardt on ``theta``, one record pass per trial step.

    Each pass returns the Gram of ``[J_theta, Phi, y]``: its ``[Phi, y]`` block gives the
    projected coefficients ``c(theta)`` and the RSS exactly; ``J_theta`` is built with the
    previous iterate's ``c`` (a lagged Kaufman Jacobian, consistent at convergence). A last
    pass with the final ``c`` gives the Gauss-Newton covariance.
    """
    N = y.shape[0]
    K = p0.shape[0]
    p = np.full(K, float(np.mean(p0))) if common else p0.astype(float).copy()
    q = q0.astype(float).copy()
    nth = K + 1 if common else 2 * K
    if c0 is None:
        ev0 = _evaluate(y, p, q)
        if ev0 is None:
            return None
        c0 = ev0.c
    c = c0
    B = _heavy_pass(y, p, q, c, common)
    if B is None:
        return None
    c, rss = _solve_gram(B[nth:, nth:])
    theta = _theta(p, q, common)
    lam = 1e-4
    it = 0
    small = False
    lagged = False  # B's Jacobian built with an earlier iterate's c
    for it in range(1, max_iter + 1):  # noqa: B007
        A, g, dA = _normal_equations(B, c, nth)
        accepted = False
        while lam < 1e12:
            Ainv = _pinv_psd(A + lam * np.diag(dA))
            dth = (Ainv @ g)[:nth]
            p_new, q_new = _unpack(theta + dth, K, common)
            B_new = _heavy_pass(y, p_new, q_new, c, common)
            if B_new is not None:
                c_new, rss_new = _solve_gram(B_new[nth:, nth:])
                if rss_new <= rss * (1.0 + 1e-13):
                    accepted = True
                    lam_used = lam
                    break
            if lagged:
                # retry with the exact Jacobian before damping the step
                B_ex = _heavy_pass(y, p, q, c, common)
                if B_ex is None:
                    break
                B, lagged = B_ex, False
                A, g, dA = _normal_equations(B, c, nth)
                continue
            lam *= 8.0
        if not accepted:
            break
        gain = rss - rss_new
        theta = theta + dth
        p, q, B, c, rss = p_new, q_new, B_new, c_new, rss_new
        lagged = True
        lam = max(lam / 10.0, 1e-9)
        # converged: an undamped step far below the statistical resolution, or no gain left
        # (a step shrunk by a large lambda says nothing about convergence)
        s2 = max(rss / max(N - nth - 1 - 2 * K, 1), S2_FLOOR)
        if lam_used <= 1e-2:
            # the step's (lightly damped) inverse bounds the covariance from below: a step
            # small against it is small against the Gauss-Newton covariance; otherwise ask
            # the exact one (ill-conditioned directions are damped far below their variance)
            small = _step_small(dth, np.diag(Ainv)[:nth] * s2)
            if not small:
                small = _step_small(dth, np.diag(_pinv_psd(A))[:nth] * s2)
            if small or gain <= 1e-12 * rss:
                break
        else:
            small = False
    else:
        small = False
    # a last pass with the final c, unless the last step was negligible (then the lagged
    # Jacobian differs from the exact one by O(step) and the covariance is already accurate)
    if max_iter == 0 or not small:
        B_fin = _heavy_pass(y, p, q, c, common)
        if B_fin is not None:
            B = B_fin
    return _finish(B, p, q, c, rss, nth, it, common, N)


def _mode_energy(ev: _Eval) -> np.ndarray:
    """Rise of the RSS when each mode is removed (others' amplitudes re-fitted), in y units^2."""
    K = ev.p.shape[0]
    Ginv = _pinv_psd(ev.G[:-1, :-1])
    out = np.empty(K)
    for k in range(K):
        out[k] = _block_energy(ev.c, Ginv, 1 + 2 * k)
    return out


def _prune(
    y: np.ndarray,
    p: np.ndarray,
    q: np.ndarray,
    noise_var: float,
    max_modes: int,
    G: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray | None]:
    """MDL backward elimination of modes at fixed poles (one record pass: the Gram matrix of
    all candidates is computed once, a removal deletes its columns).

    Returns the kept ``p, q``, their energies over the noise variance, and the coefficients.
    """
    N = y.shape[0]
    thr = _order_threshold(N)
    ev = None
    while p.size and G is None:
        ev = _evaluate(y, p, q)
        if ev is not None:
            break
        # drop the fastest-growing candidate and retry
        D = 0.25 * p * p - q
        k = int(np.argmax(-0.5 * p + np.sqrt(np.maximum(D, 0.0))))
        p, q = np.delete(p, k), np.delete(q, k)
    if G is None:
        if ev is None:
            return p, q, np.zeros(0), None
        G = ev.G
    active = list(range(p.size))
    while active:
        idx = [0] + [j for k in active for j in (1 + 2 * k, 2 + 2 * k)] + [G.shape[0] - 1]
        Gs = G[np.ix_(idx, idx)]
        c, rss = _solve_gram(Gs)
        Ginv = _pinv_psd(Gs[:-1, :-1])
        e = np.empty(len(active))
        for i in range(len(active)):
            e[i] = _block_energy(c, Ginv, 1 + 2 * i)
        npar = 1 + 4 * len(active)
        s2 = rss / max(N - npar, 1)
        s2 = max(s2, S2_FLOOR)
        i = int(np.argmin(e))
        if e[i] / s2 < thr or len(active) > max_modes:
            del active[i]
            continue
        return p[active], q[active], e / s2, c
    return p[:0], q[:0], np.zeros(0), None


def _merge_close_modes(y: np.ndarray, fit: _Fit, max_iter: int) -> _Fit:
    """Refit-based order check for suspicious modes: pairs closer than two FFT bins, growing
    oscillations (``p < 0``) and weak modes (energy below 10x the MDL threshold). The weaker
    mode of each is removed and the model refitted; the smaller model wins unless the bigger
    one lowers the RSS by more than the MDL penalty (``4 ln N`` noise variances per mode).
    Guards against local minima where two modes share one spectral line or a spurious mode
    holds part of another."""
    N = y.shape[0]
    thr = _order_threshold(N)
    for _ in range(4):
        p, q = fit.ev.p, fit.ev.q
        K = p.size
        if K < 2:
            return fit
        om = np.sqrt(np.maximum(q - 0.25 * p * p, 0.0))
        e = _mode_energy(fit.ev)
        suspects = set()
        for i in range(K):
            if p[i] < 0:  # s1 + s2 = -p > 0: energy gain, impossible for a passive structure
                suspects.add(i)
            if e[i] < 10.0 * thr * fit.s2:  # weak: may be a partner of a split mode
                suspects.add(i)
            for j in range(i + 1, K):
                if abs(om[i] - om[j]) < 2.0 * (2 * math.pi / N):
                    suspects.add(i if e[i] < e[j] else j)
        if not suspects:
            return fit
        base, s2 = _explicit_rss(y, fit)
        best, best_rss = None, math.inf
        for k in sorted(suspects, key=lambda k: e[k]):
            keep = [i for i in range(K) if i != k]
            f = _levenberg_marquardt(y, p[keep], q[keep], common=fit.common, max_iter=max_iter)
            if f is None:
                continue
            rss = _explicit_rss(y, f)[0]
            if rss - base < thr * s2 + _rss_tol(fit.ev) and rss < best_rss:
                best, best_rss = f, rss
        if best is None:
            return fit
        fit = best
    return fit


def _explicit_rss(y: np.ndarray, fit: _Fit) -> tuple[float, float]:
    """RSS of a fit from its residual (one pass) and the noise variance it implies. The Gram
    RSS loses the digits of a model whose columns cancel (a growing pole against a fast one):
    order decisions between fits compare these."""
    mv = np.empty(y.shape[0])
    model_values(fit.ev.p, fit.ev.q, fit.ev.c, mv)
    r = y - mv
    rss = float(r @ r)
    npar = fit.ntheta + fit.ev.c.size
    return rss, max(rss / max(y.shape[0] - npar, 1), S2_FLOOR)


def _repair_real_poles(y: np.ndarray, fit: _Fit, max_iter: int) -> _Fit:
    """Undo a split of one overdamped pair over two modes (a local minimum where each mode
    holds one true real pole and one spurious partner): for every two modes with real (or
    heavily damped, omega < gamma) poles, try one pair made of a pole of each; keep the best
    refit if it costs less than the MDL penalty of the mode it saves (``4 ln N`` noise
    variances)."""
    N = y.shape[0]
    thr = _order_threshold(N)
    for _ in range(3):
        p, q = fit.ev.p, fit.ev.q
        D = 0.25 * p * p - q
        pool = []
        for k in range(p.size):
            lam = math.sqrt(abs(D[k]))
            if D[k] >= 0 or lam < 0.5 * p[k]:
                pool.append((k, (-0.5 * p[k] - lam, -0.5 * p[k] + lam)))
        if len(pool) < 2:
            return fit
        base, s2 = _explicit_rss(y, fit)
        best, best_rss = None, math.inf
        for i in range(len(pool)):
            for j in range(i + 1, len(pool)):
                ki, si = pool[i]
                kj, sj = pool[j]
                keep = [k for k in range(p.size) if k not in (ki, kj)]
                for a in si:
                    for b in sj:
                        pn = np.append(p[keep], -(a + b))
                        qn = np.append(q[keep], a * b)
                        f = _levenberg_marquardt(y, pn, qn, common=fit.common, max_iter=max_iter)
                        if f is None:
                            continue
                        rss = _explicit_rss(y, f)[0]
                        if rss - base < thr * s2 + _rss_tol(fit.ev) and rss < best_rss:
                            best, best_rss = f, rss
        if best is None:
            return fit
        fit = best
    return fit


def _order(fit: _Fit, energy: np.ndarray) -> tuple[_Fit, np.ndarray]:
    """Reorder the modes of a fit by increasing |q| (slowest first)."""
    K = fit.ev.p.size
    order = np.argsort(np.abs(fit.ev.q), kind="stable")
    if np.all(order == np.arange(K)):
        return fit, energy
    ev = fit.ev
    cidx = [0] + [j for k in order for j in (1 + 2 * k, 2 + 2 * k)]
    if fit.common:
        tidx = [0] + [1 + k for k in order]
    else:
        tidx = [j for k in order for j in (2 * k, 2 * k + 1)]
    full = tidx + [fit.ntheta + j for j in cidx]
    gidx = cidx + [ev.G.shape[0] - 1]
    ev2 = _Eval(ev.p[order], ev.q[order], ev.G[np.ix_(gidx, gidx)], ev.c[cidx], ev.rss)
    cov = fit.cov[np.ix_(full, full)]
    return _Fit(ev2, cov, fit.ntheta, fit.s2, fit.iterations, fit.common), energy[order]
