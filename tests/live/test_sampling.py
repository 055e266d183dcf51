"""The record-length policy (``service.analysis.sampling``) against its statement in closed form,
and the one policy behind ``warn`` and a live sweep's advice."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest
from _records import DT, MU_STAR, record

from service.analysis import live, sampling, sweep_policy
from service.analysis.sampling import MAX_SAMPLES, next_record_sampling


def _m(mu: float, omega: float, regime: str = "underdamped", duration: float = 8.0,
       dt: float = 2e-3) -> SimpleNamespace:  # fmt: skip
    return SimpleNamespace(mu=mu, omega=omega, regime=regime, duration=duration, dt=dt)


def test_underdamped_forty_expected_periods_fifty_samples_per_previous_period() -> None:
    last = _m(1.0, 20.0)
    pred = SimpleNamespace(mu_star=1.8, a=0.25)
    duration, dt = next_record_sampling(last, 1.4, pred)
    omega_next = 20.0 * (0.4 / 0.8) ** 0.25  # the slowdown expected between 1.0 and 1.4
    assert duration == pytest.approx(40 * 2 * math.pi / omega_next, rel=1e-14)
    assert dt == pytest.approx(2 * math.pi / 20.0 / 50, rel=1e-14)
    # without a prediction (or one not beyond mu_next) the previous frequency is expected again
    for p in (None, SimpleNamespace(mu_star=math.nan, a=0.25),
              SimpleNamespace(mu_star=1.3, a=0.25)):  # fmt: skip
        assert next_record_sampling(last, 1.4, p) == pytest.approx(
            (40 * 2 * math.pi / 20.0, 2 * math.pi / 20.0 / 50)
        )


def test_sample_cap_widens_the_step() -> None:
    last = _m(1.0, 20.0)
    pred = SimpleNamespace(mu_star=1.8, a=0.5)
    mu_next = 1.8 - 1e-9
    duration, dt = next_record_sampling(last, mu_next, pred)
    assert duration / dt == pytest.approx(MAX_SAMPLES, rel=1e-12)
    ratio = (1.8 - mu_next) / (1.8 - 1.0)
    assert duration == pytest.approx(40 * 2 * math.pi / (20.0 * ratio**0.5), rel=1e-12)


def test_overdamped_grows_by_the_slow_rate_at_most_four_times() -> None:
    last = _m(1.0, 5.0, "overdamped", duration=10.0, dt=1e-3)
    pred = SimpleNamespace(mu_star=1.8, a=0.25)
    duration, dt = next_record_sampling(last, 1.4, pred)
    assert duration == pytest.approx(10.0 * 0.5 ** (-0.5), rel=1e-14)
    assert dt == 1e-3
    assert next_record_sampling(last, 1.79999, pred).duration == pytest.approx(40.0)
    assert next_record_sampling(last, 1.4, None).duration == pytest.approx(20.0)


def test_warn_and_live_share_the_policy() -> None:
    # warn, the batch sweep and the live sweep all advise through the one sweep policy
    assert sweep_policy.next_record_sampling is sampling.next_record_sampling
    recs = []
    for mu in (0.0, 0.3, 0.6, 0.9, 1.2):
        _, w = record(mu)
        u = live.update(recs, w, dt=DT, control=mu, plan=live.LivePlan(step=0.3))
        recs.append(u.record)
    ref = next_record_sampling(u.record.measurement, u.next_control, u.prediction)
    assert (u.record_duration, u.record_dt) == ref
    assert np.isfinite(ref).all() and u.next_control < MU_STAR
