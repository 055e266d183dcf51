"""The per-call memo of profile fits: equal answers with and without it, nothing outlives a call."""

from __future__ import annotations

import numpy as np

from service.analysis.predict import predict
from service.analysis.predictor import cache as fc
from service.analysis.predictor import likelihood as lk


def _sweep() -> tuple[np.ndarray, np.ndarray]:
    mu = 1.0 - np.geomspace(0.9, 1e-3, 14)
    x = 1.0 - mu
    rng = np.random.default_rng(5)
    s2 = x + 0.3 * x**2
    return mu, s2 * (1 + 1e-3 * rng.standard_normal(mu.size))


def test_memo_does_not_change_the_fit_and_is_scoped() -> None:
    mu, s2 = _sweep()
    comp = lk._Comp(s2, 1.0 / (1e-3 * np.abs(s2)), np.array([1.0, 2.0]), True, True)
    plain = lk._profile(mu, [comp], 1.0)
    with fc.profile_memo():
        first = lk._profile(mu, [comp], 1.0)
        again = lk._profile(mu, [comp], 1.0)
        assert again is first  # computed once inside a scope
        other = lk._profile(mu, [comp], 1.0, with_interval=False)
        assert other is not first  # options are part of the key
    assert first == plain
    assert fc._MEMO.get() is None  # nothing outlives the scope


def test_predict_twice_gives_the_same_answer() -> None:
    mu, s2 = _sweep()
    a = predict(mu, -s2, sigma2_std=1e-3 * np.abs(s2))
    assert fc._MEMO.get() is None
    b = predict(mu, -s2, sigma2_std=1e-3 * np.abs(s2))
    assert a.mu_star == b.mu_star and a.mu_star_interval == b.mu_star_interval
    assert a.probabilities == b.probabilities


def test_the_cache_is_a_value_the_scope_yields() -> None:
    """The scope yields its :class:`FitCache`: a nested scope shares it, the fits look it up
    (a repeated profile is a hit, each kind of entry counted), and none is current outside."""
    mu, s2 = _sweep()
    comp = lk._Comp(s2, 1.0 / (1e-3 * np.abs(s2)), np.array([1.0, 2.0]), True, True)
    assert fc.fit_cache() is None
    with fc.profile_memo() as cache:
        assert isinstance(cache, fc.FitCache) and fc.fit_cache() is cache and len(cache) == 0
        with fc.profile_memo() as inner:
            assert inner is cache
        lk._profile(mu, [comp], 1.0)
        n, hits = len(cache), cache.hits
        lk._profile(mu, [comp], 1.0)
        assert len(cache) == n and cache.hits == hits + 1
        kinds = cache.kinds()
        assert kinds.get("profile") == 1 and sum(kinds.values()) == n
    assert fc.fit_cache() is None
    with fc.profile_memo() as fresh:
        assert fresh is not cache and len(fresh) == 0
