"""The engine's exact shortcuts: lower bounds that skip searches without changing a result.

* the term choice: the polynomial lower bound of a plain pitchfork law, the eigenvalue law's
  own minimum inside a joint fit with the static law, and 0 for a static law's chi^2;
* the window choice: a smaller window's minimum bounds a larger one's (K = 0), and the
  polynomial bound a plain pitchfork law's;
* the free exponent: the walk along the exponent grid stops where the profile has risen far.

Reference: the law's -2 log L evaluated by the kernels at every mu* of a fine grid (and the
profile search's minimum): the bound must lie below all of them, and close to them when the
data are a polynomial of the same degree (the bound is then attained in the limit mu* -> inf).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from service.analysis.predictor._kernels.laws import nll_fixed_u
from service.analysis.predictor.likelihood import (
    _Comp,
    _pack,
    _polynomial_bound,
    _profile,
    _sigma_exps,
)


@pytest.mark.parametrize("seed", range(6))
@pytest.mark.parametrize("K", [0, 1, 2, 3])
def test_bound_lies_below_the_law_at_every_mu_star(seed: int, K: int) -> None:
    rng = np.random.default_rng(seed)
    n = int(rng.integers(K + 4, 14))
    mu = np.sort(rng.uniform(0.0, 1.95, n))
    x = 2.0 - mu
    # a fold's data (not a pitchfork's): the plain pitchfork law misfits them
    y = 3.0 * np.sqrt(x) * (1 + 0.2 * x) * (1 + 1e-3 * rng.standard_normal(n))
    sd = 1e-3 * y
    comp = _Comp(y, 1.0 / sd, _sigma_exps(1.0, 1.0, K), True, True)
    lb = _polynomial_bound(mu, y, 1.0 / sd, K + 1)
    ms = mu[-1] + np.geomspace(1e-9, 1e3, 4000)
    nll = nll_fixed_u(ms, 0.0, *_pack(mu, [comp]), float(mu[-1]))
    assert lb <= nll.min()
    prof = _profile(mu, [comp], float(mu[-1] - mu[0]), with_interval=False)
    assert lb <= prof.nll


@pytest.mark.parametrize("K", [0, 1, 2])
def test_bound_is_tight_for_a_polynomial_far_from_mu_star(K: int) -> None:
    """Data exactly a polynomial of degree K + 1 with no constant term in x = mu0 - mu (mu0
    far away): the law at mu* = mu0 fits them, and the bound is (near) zero."""
    mu = np.linspace(0.0, 1.0, 12)
    x = 5.0 - mu
    y = sum(c * x ** (j + 1) for j, c in enumerate([1.0, 0.3, -0.05, 0.01][: K + 1]))
    wt = np.full(mu.size, 1e3)
    comp = _Comp(y, wt, _sigma_exps(1.0, 1.0, K), True, False)
    lb = _polynomial_bound(mu, y, wt, K + 1)
    at_mu0 = float(nll_fixed_u(np.array([5.0]), 0.0, *_pack(mu, [comp]), float(mu[-1]))[0])
    assert lb <= at_mu0 + 1e-9
    assert at_mu0 < 1e-6 and lb < 1e-6


@pytest.mark.parametrize("act", ["asymmetric", "symmetric", "antisymmetric"])
def test_term_choice_with_bounds_equals_the_exhaustive_choice(
    act: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The candidates' fits (terms, window, mu*, interval) are the same whether the term choice
    skips combinations by the lower bounds or searches every one (Euler beam, w given)."""
    from service.analysis.predictor import compare as _laws
    from service.analysis.predictor.sweep import prepare_sweep
    from sim.euler_beam import bifurcation, equilibrium, spectrum

    b = bifurcation(act)
    mu = b.mu_star - np.geomspace(0.999 * b.mu_star, 1e-3, 16)
    s2 = np.array([spectrum(act, m, "U_A", modes=1).sigma2[0] for m in mu])
    w = np.array([equilibrium(act, m, "U_A").w_quarter for m in mu])
    rng = np.random.default_rng(1)
    sw = prepare_sweep(mu, s2 * (1 + 1e-4 * rng.standard_normal(mu.size)),
                       sigma2_std=1e-4 * np.abs(s2), w_static=w + 1e-6 * rng.standard_normal(
                           mu.size), w_static_std=1e-6)  # fmt: skip
    _, fast, n_fast, _ = _laws.analyse(sw)
    monkeypatch.setattr(_laws, "_sigma_bound", lambda *a, **k: -np.inf)
    monkeypatch.setattr(_laws, "_sigma_floor", lambda *a, **k: -np.inf)
    monkeypatch.setattr(_laws, "_w_bound", lambda *a, **k: -np.inf)
    _, full, n_full, _ = _laws.analyse(sw)
    assert n_fast == n_full
    for f, g in zip(fast, full, strict=True):
        assert (f.name, f.n, f.K, f.Kw, f.conformal) == (g.name, g.n, g.K, g.Kw, g.conformal)
        assert f.profile == g.profile and f.weight == g.weight


def _beam_sweep(
    act: str, n: int, rel: float, seed: int, with_w: bool = True, step: float = 0.05,
    stop: float = 0.004,
):
    """A lab's fixed grid on the Euler beam: ``n`` points ``step`` apart (those >= 0), the last
    ``stop`` before mu*, relative noise ``rel``."""
    from service.analysis.predictor.sweep import prepare_sweep
    from sim.euler_beam import bifurcation, equilibrium, spectrum

    b = bifurcation(act)
    mu = b.mu_star - stop - step * np.arange(n)[::-1]
    mu = mu[mu >= 0]
    n = mu.size
    s2 = np.array([spectrum(act, m, "U_A", modes=1).sigma2[0] for m in mu])
    rng = np.random.default_rng(seed)
    kw = {}
    if with_w:
        w = np.array([equilibrium(act, m, "U_A").w_quarter for m in mu])
        kw = {"w_static": w + 1e-6 * rng.standard_normal(n), "w_static_std": 1e-6}
    return prepare_sweep(mu, s2 + rel * np.abs(s2) * rng.standard_normal(n),
                         sigma2_std=rel * np.abs(s2), **kw)  # fmt: skip


# lab plans of random step, stop and noise (the last four: plans where a bound for K >= 1,
# whose law the correction constraint penalises, would have changed the window or terms)
_PLANS = [
    ("asymmetric", 0.05, 0.004, 1e-5, 3), ("symmetric", 0.05, 0.004, 1e-3, 3),
    ("antisymmetric", 0.05, 0.004, 1e-5, 3),
    ("antisymmetric", 0.05954623782252959, 0.029242560538343027, 6.473327501069738e-05,
     759638830),
    ("antisymmetric", 0.07982604057802213, 0.08693319460156938, 2.9585556200338437e-05,
     475832016),
    ("antisymmetric", 0.0922992223637698, 0.019235214558500538, 0.00013171923147033146,
     259384561),
    ("antisymmetric", 0.049583488199848716, 0.0010427637512936702, 2.5218566137230806e-05,
     314184469),
]


@pytest.mark.parametrize(("act", "step", "stop", "rel", "seed"), _PLANS)
def test_window_choice_with_the_nested_bound_equals_the_full_scan(
    act: str, step: float, stop: float, rel: float, seed: int, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The informative window and terms of both selection laws are the same whether a smaller
    window's minimum and the polynomial bound skip the searches they rule out or every search
    is run."""
    from service.analysis.predictor import windows as _windows
    from service.analysis.predictor.cache import profile_memo

    sw = _beam_sweep(act, 60, rel, seed, with_w=False, step=step, stop=stop)
    scale = float(sw.mu[-1] - sw.mu[0])
    calls = {"n": 0}
    real = _windows._profile

    def counted(*a, **k):
        calls["n"] += 1
        return real(*a, **k)

    monkeypatch.setattr(_windows, "_profile", counted)
    out = {}
    poly = _windows._polynomial_bound
    for nested in (0, -1):
        monkeypatch.setattr(_windows, "_NESTED_K", nested)
        monkeypatch.setattr(
            _windows, "_polynomial_bound", poly if nested == 0 else (lambda *a, **k: 0.0)
        )
        calls["n"] = 0
        with profile_memo():
            out[nested] = ([_windows.select_window(sw, p, h, scale) for p, h in
                            ((0.5, 0.5), (1.0, 1.0))], calls["n"])  # fmt: skip
    (fast, n_fast), (full, n_full) = out[0], out[-1]
    for f, g in zip(fast, full, strict=True):
        assert (f.n, f.K, f.accepted, f.conformal) == (g.n, g.K, g.accepted, g.conformal)
    assert n_fast <= n_full


def _plain_selection(sw, p: float, h: float, scale: float, patience: int = 4):
    """The window choice done the plain way: every window, every (K, variant) fewest
    corrections first, a screen (global, no continuation) and the full search where it
    fails, no bound, nothing put off. Returns ``(n, K, accepted, conformal)``."""
    from service.analysis.predictor.likelihood import _profile_screen, _sigma_comp, _variants
    from service.analysis.predictor.windows import _ALPHA, _KMAX, _chi2_sf, _window_sizes

    N = sw.mu.size
    best = fallback = None
    misses = 0
    for n in _window_sizes(N):
        idx = slice(N - n, N)
        ok = False
        for K in range(_KMAX + 1):
            for cf in _variants(p, h, K):
                dof = n - K - 2 - int(cf)
                if dof < 1:
                    break
                comp = _sigma_comp(sw, idx, p, h, K, cf)
                _, nll, _ = _profile_screen(sw.mu[idx], [comp], scale, None)
                if _chi2_sf(nll, dof) < _ALPHA:
                    nll = _profile(sw.mu[idx], [comp], scale, with_interval=False).nll
                pv = _chi2_sf(nll, dof)
                if fallback is None or pv > fallback[0]:
                    fallback = (pv, (n, K, False, cf))
                if pv >= _ALPHA:
                    best, ok = (n, K, True, cf), True
                    break
            if ok:
                break
        misses = 0 if ok else misses + 1
        if misses >= patience and (best is not None or n >= 8):
            break
    return best if best is not None else fallback[1]


@pytest.mark.parametrize(("act", "step", "stop", "rel", "seed"), _PLANS)
def test_window_choice_equals_the_plain_one(
    act: str, step: float, stop: float, rel: float, seed: int
) -> None:
    """The selection's shortcuts (bounds, the laws that held screened first by local searches,
    the full searches of fewer corrections put off to the window returned) leave the window
    and terms of the plain choice (:func:`_plain_selection`) on the lab plans and on the
    bench's geometric sweeps of every actuation."""
    from service.analysis.predictor import windows as _windows
    from service.analysis.predictor.cache import profile_memo

    sweeps = [_beam_sweep(act, 60, rel, seed, with_w=False, step=step, stop=stop)]
    if seed == 3:
        sweeps.append(_geometric_sweep(act))
    for sw in sweeps:
        scale = float(sw.mu[-1] - sw.mu[0])
        for p, h in ((0.5, 0.5), (1.0, 1.0)):
            with profile_memo():
                got = _windows.select_window(sw, p, h, scale)
            with profile_memo():
                ref = _plain_selection(sw, p, h, scale)
            assert (got.n, got.K, got.accepted, got.conformal) == ref


def _geometric_sweep(act: str, n: int = 25, rel: float = 1e-4):
    """The bench's sweep (``bench/predict_speed.py``): 25 points approaching mu* geometrically
    to 1e-4, relative noise ``rel``."""
    from service.analysis.predictor.sweep import prepare_sweep
    from sim.euler_beam import bifurcation, spectrum

    b = bifurcation(act)
    mu = b.mu_star - np.geomspace(0.999 * b.mu_star, 1e-4, n)
    s2 = np.array([spectrum(act, m, "U_A", modes=1).sigma2[0] for m in mu])
    sd = rel * np.abs(s2)
    s2 = s2 + sd * np.random.default_rng(0).standard_normal(n)
    return prepare_sweep(mu, s2, sigma2_std=sd)


@pytest.mark.parametrize("act", ["asymmetric", "symmetric"])
def test_free_exponent_walk_equals_the_whole_grid(
    act: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The free exponent a and its standard error are the same when the exponent grid is
    walked from the law's exponent until the profile has risen ``_FAR`` as when every grid
    point is searched (reference: ``_FAR = inf``)."""
    from service.analysis.predictor import compare as _laws
    from service.analysis.predictor import exponents as _exponents
    from service.analysis.predictor.cache import profile_memo

    sw = _beam_sweep(act, 25, 1e-4, 5)
    _, fits, n_c, _ = _laws.analyse(sw)
    with profile_memo():
        walk = _laws.free_exponent_a(sw, fits[0], n_c)
    monkeypatch.setattr(_exponents, "_FAR", np.inf)
    with profile_memo():
        full = _laws.free_exponent_a(sw, fits[0], n_c)
    assert walk == pytest.approx(full, rel=1e-9, abs=1e-12)


def test_a_fit_searches_from_the_optimum_its_window_was_accepted_on() -> None:
    """A lab plan (symmetric beam, grid step 0.088, last point 0.0022 before mu*, noise
    3.9e-4) whose 21 nearest points the conformal pitchfork law with 2 corrections fits at
    chi^2 = 25.15 (a dense scan of mu* says so; the test passes below 26.3): the window choice
    finds that minimum by its local searches and hands it on; the full search started from
    the hint finds it too, where its scan's walk over the fold parameter's grid can pass over
    that valley. A hint never makes a search worse: from a far point it changes nothing."""
    from service.analysis.predictor import windows as _windows
    from service.analysis.predictor.cache import profile_memo
    from service.analysis.predictor.likelihood import _nll_u, _sigma_comp

    sw = _beam_sweep("symmetric", 60, 0.0003858145395579972, 853510190, with_w=False,
                     step=0.08807646349095118, stop=0.0021586462116093513)  # fmt: skip
    N = sw.mu.size
    scale = float(sw.mu[-1] - sw.mu[0])
    with profile_memo():
        sel = _windows.select_window(sw, 1.0, 1.0, scale)
    assert (sel.n, sel.K, sel.accepted, sel.conformal) == (21, 2, True, True)
    idx = slice(N - 21, N)
    comp = _sigma_comp(sw, idx, 1.0, 1.0, 2, True)
    mu_w = sw.mu[idx]
    ms = 2.0 + np.linspace(-3e-4, 3e-4, 601)  # the reference: every mu* of a dense grid
    ref = float(_nll_u(mu_w, [comp], ms)[0].min())
    hinted = _profile(mu_w, [comp], scale, with_interval=False, hint=(sel.t, sel.log_u))
    plain = _profile(mu_w, [comp], scale, with_interval=False)
    assert hinted.nll <= ref + 1e-6 and hinted.nll <= plain.nll
    assert abs(hinted.mu_star - ms[np.argmin(_nll_u(mu_w, [comp], ms)[0])]) < 2e-6
    far = math.log(0.05)  # mu* 0.05 beyond the last point: another, worse valley's side
    assert _profile(mu_w, [comp], scale, with_interval=False, hint=(far, math.nan)) == plain
