"""The per-call memo of profile fits: equal answers with and without it, nothing outlives a call."""

from __future__ import annotations

import numpy as np

from service.analysis.predict import predict
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
    with lk.profile_memo():
        first = lk._profile(mu, [comp], 1.0)
        again = lk._profile(mu, [comp], 1.0)
        assert again is first  # computed once inside a scope
        other = lk._profile(mu, [comp], 1.0, with_interval=False)
        assert other is not first  # options are part of the key
    assert first == plain
    assert lk._MEMO.get() is None  # nothing outlives the scope


def test_predict_twice_gives_the_same_answer() -> None:
    mu, s2 = _sweep()
    a = predict(mu, -s2, sigma2_std=1e-3 * np.abs(s2))
    assert lk._MEMO.get() is None
    b = predict(mu, -s2, sigma2_std=1e-3 * np.abs(s2))
    assert a.mu_star == b.mu_star and a.mu_star_interval == b.mu_star_interval
    assert a.probabilities == b.probabilities
