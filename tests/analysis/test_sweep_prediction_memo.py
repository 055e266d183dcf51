"""The sweep policy's memo of predictions (``sweep_policy._PREDICTIONS``): the same answers, to
the last bit, with and without it, and the prediction of the records but the newest (the
converged hull's) is not computed twice."""

from __future__ import annotations

import math
from dataclasses import replace

import pytest

from service.analysis import sweep_policy
from service.analysis.measurement import Measurement
from service.analysis.sweep_policy import SweepPlan, SweepPolicy, SweepRecord

MU_STAR = 1.8
DT = 2e-3


def _point(mu: float) -> Measurement:
    s2 = -400.0 * math.sqrt(MU_STAR - mu)  # a saddle-node's law
    return Measurement(mu, math.sqrt(abs(s2)), s2, 1e-3 * abs(s2), 0.05 * (MU_STAR - mu) ** 0.5,
                       1e-6, "underdamped", 8.0, DT)  # fmt: skip


def _sweep(
    monkeypatch: pytest.MonkeyPatch, size: int, soft: float = 6.0, clear: bool = True
) -> tuple[list[str], int]:
    """The repr of every update of a sweep that converges (its newest record read ``soft``
    standard errors soft: at 6 the converged hull is taken), and how many predictions ran."""
    monkeypatch.setattr(sweep_policy, "_PREDICTIONS_MAX", size)
    if clear:
        sweep_policy._PREDICTIONS.clear()
    calls = []
    real = sweep_policy.predict

    def counted(*a, **k):  # noqa: ANN002, ANN003, ANN202
        calls.append(1)
        return real(*a, **k)

    monkeypatch.setattr(sweep_policy, "predict", counted)
    controls = [0.0, 0.3, 0.6, 0.9, 1.2, 1.5, 1.65, 1.72]
    pol = SweepPolicy(SweepPlan(step=0.3, target_width=0.2))
    out = []
    for k, c in enumerate(controls):
        m = _point(c)
        if k == len(controls) - 1:
            m = replace(m, sigma2=m.sigma2 + soft * m.sigma2_std)
        u = pol.add(SweepRecord(0, c, m, name=f"rec_{k:02d}.csv"))
        cls = u.prediction.classification if u.prediction is not None else None
        out.append(repr((u, cls)))  # repr: exact floats, and NaN equals NaN
    assert u.converged
    batch = SweepPolicy(SweepPlan(step=0.3, target_width=0.2))
    for r in pol.records:
        batch.append(replace(r, interval=None))
    res = batch.result()
    out.append(repr((res, res.prediction.classification)))
    return out, len(calls)


def test_the_memo_changes_no_answer_and_saves_the_repeated_predictions(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    plain, n_plain = _sweep(monkeypatch, 0)
    assert "converged_hull" in plain[-2]
    plain2, _ = _sweep(monkeypatch, 0, soft=2.0)
    assert plain2[-1] != plain[-1]
    memo, n_memo = _sweep(monkeypatch, 16)
    assert memo == plain
    # the hull's prediction (the records but the newest) and the batch's were computed before
    assert n_memo < n_plain
    # the same controls, the newest record read otherwise: the memo keeps the answers apart
    memo2, _ = _sweep(monkeypatch, 16, soft=2.0, clear=False)
    assert memo2 == plain2
    sweep_policy._PREDICTIONS.clear()


def test_the_memo_is_bounded(monkeypatch: pytest.MonkeyPatch) -> None:
    _sweep(monkeypatch, 2)
    monkeypatch.setattr(sweep_policy, "_PREDICTIONS_MAX", 2)
    pol = SweepPolicy(SweepPlan(step=0.3))
    for c in (0.0, 0.3, 0.6, 0.9, 1.2):
        pol.add(SweepRecord(0, c, _point(c)))
    assert len(sweep_policy._PREDICTIONS) == 2
    sweep_policy._PREDICTIONS.clear()
