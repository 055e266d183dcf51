"""The numerics of a live sweep (``service.analysis.live``) and its storage invariant.

References: the closed-form records of ``_records`` (exact sigma^2, saddle-node at mu* = 1.8),
the policy of ``service.analysis.alarm.next_measurement`` (an independent call on the same
points), and, for storage, many writers racing on one database.
"""

from __future__ import annotations

import math
import os
import threading

import numpy as np
import pytest
from _records import DT, MU_STAR, record, sigma2_of

from service.analysis import live, live_store
from service.analysis.alarm import next_measurement
from service.analysis.errors import ParameterError


def sweep(controls, plan=None):  # noqa: ANN001, ANN201
    recs, ups = [], []
    for mu in controls:
        _, w = record(mu)
        u = live.update(recs, w, dt=DT, control=mu, plan=plan or live.LivePlan(step=0.3))
        recs.append(u.record)
        ups.append(u)
    return recs, ups


def test_plan_validation_names_the_parameter() -> None:
    for kw, name in ((dict(step=0.0), "step"), (dict(margin=-1.0), "margin"),
                     (dict(target_width=math.inf), "target_width"),
                     (dict(step_fraction=1.0), "step_fraction")):  # fmt: skip
        with pytest.raises(ParameterError) as err:
            live.LivePlan(**kw)
        assert err.value.parameter == name
    with pytest.raises(ParameterError) as err:
        live.measure(np.zeros(100), dt=1.0, control=math.nan)
    assert err.value.parameter == "control"


def test_update_matches_closed_form_and_the_policy() -> None:
    # T/T0 = 2.9 at the last: past classify.MIN_T_RATIO, where a type may be named
    controls = [0.0, 0.3, 0.6, 0.9, 1.2, 1.5, 1.65, 1.72, 1.775]
    recs, ups = sweep(controls, live.LivePlan(step=0.3, margin=0.01))
    for u, mu in zip(ups, controls):
        assert u.record.measurement.sigma2 == pytest.approx(sigma2_of(mu), rel=1e-6)
    assert ups[0].next_control == pytest.approx(0.3)  # one record: the step
    # the sweep answers from three usable controls (the policy's MIN_RECORDS)
    assert ups[1].prediction is None and ups[2].prediction is not None
    last = ups[-1]
    lo, hi = last.prediction.mu_star_interval
    assert lo <= MU_STAR <= hi
    assert last.prediction.transition == "saddle-node"
    # the advice is next_measurement on the same points (an independent call)
    ms = [r.measurement for r in recs]
    # (the interval bounds the step: alone once trusted, with the sigma^4 bound before)
    ref = next_measurement(
        [m.mu for m in ms], [abs(m.sigma2) for m in ms],
        trusted_bound=lo if last.trusted else None, lower_bound=None if last.trusted else lo,
        margin=0.01, max_step=0.3, max_step_growth=math.inf,
        min_t_ratio=live.SIGMA4_MIN_T_RATIO, sigma4_when_trusted=False,
    )  # fmt: skip
    assert last.next_control == pytest.approx(ref.mu, rel=0, abs=1e-15)
    # below the safe bound minus the margin, hence below mu* minus the margin
    assert last.next_control < last.next.bound - 0.01
    assert last.next_control < MU_STAR - 0.01


def test_flags_and_fit_set() -> None:
    recs, ups = sweep([0.0, 0.6, 0.3, 0.6])
    codes = [[f.code for f in u.record.flags] for u in ups]
    assert codes[0] == [] and "past_safe_value" in codes[1]
    assert "out_of_order" in codes[2] and "repeated_control" in codes[3]
    # the repeated control is averaged into its point (as a batch sweep does): 4 records used
    assert ups[3].n_used == 4 and ups[3].used_in_fit and ups[2].used_in_fit


def test_no_mode_is_a_flag_not_an_error() -> None:
    rng = np.random.default_rng(0)
    u = live.update([], np.full(500, 0.1) + 1e-12 * rng.standard_normal(500), dt=1e-3,
                    control=0.0, plan=live.LivePlan(step=0.1))  # fmt: skip
    assert u.record.measurement is None
    assert "no_mode" in [f.code for f in u.record.flags]
    assert u.n_used == 0 and u.next is None


def test_record_roundtrip_and_finish() -> None:
    recs, ups = sweep([0.0, 0.3, 0.6, 0.9, 1.2])
    back = [live_store.record_from_dict(live_store.record_to_dict(r)) for r in recs]
    assert back == recs
    res = live.finish(back, stopped="closed")
    assert res.stopped == "closed" and len(res.measurements) == 5
    assert res.prediction.mu_star == pytest.approx(ups[-1].prediction.mu_star, abs=1e-14)
    # the last update's prediction, kept (a budget-spending record): the same final document
    kept = live.finish(back, stopped="budget", update=ups[-1])
    fitted = live.finish(back, stopped="budget")
    assert kept.prediction.mu_star == fitted.prediction.mu_star
    assert kept.prediction.mu_star_interval == fitted.prediction.mu_star_interval
    assert kept.prediction.probabilities == fitted.prediction.probabilities
    assert kept.measurements == fitted.measurements and kept.flags == fitted.flags


def test_stored_records_keep_their_detection() -> None:
    """Read back from the store (strict JSON: non-finite numbers as null), a record keeps its
    detection, so the sweep-wide choice of the fundamental still sees every record (before: a
    sweep read back from the store had no detections, and reconcile was skipped); a record
    stored without one reads back without."""
    import json

    from service.analysis.sweep_policy import _reconciled
    from service.api.storage.models import sanitize

    recs, _ = sweep([0.0, 0.3, 0.6, 0.9, 1.2])
    stored = [json.loads(json.dumps(sanitize(live_store.record_to_dict(r)))) for r in recs]
    back = [live_store.record_from_dict(d) for d in stored]
    for r, b in zip(recs, back, strict=True):
        assert b.detection is not None
        assert json.dumps(sanitize(live_store.detection_to_dict(b.detection))) == json.dumps(
            sanitize(live_store.detection_to_dict(r.detection)))  # fmt: skip
        assert b.detection.fundamental == r.detection.fundamental
    assert [r.detection for r in _reconciled(back)] == [r.detection for r in back]
    old = {k: v for k, v in stored[0].items() if k != "detection"}
    assert live_store.record_from_dict(old).detection is None


@pytest.mark.parametrize(
    "db", ["sqlite", pytest.param("postgres", marks=pytest.mark.postgres)]
)
def test_optimistic_append_serialises_writers(tmp_path, db: str) -> None:  # noqa: ANN001
    """Eight threads append five records each with the route's read-compute-append loop: all
    40 are stored with seq 1..40, and each saw exactly the records before it."""
    from service.api.storage import Store
    from service.api.storage import live as store_live

    if db == "postgres":
        url = os.environ.get("SNAPWARN_TEST_PG_URL")
        if not url:
            pytest.skip("SNAPWARN_TEST_PG_URL is not set")
    else:
        url = f"sqlite:///{tmp_path / 'race.db'}"
    store = Store(url)
    store.migrate()
    _, _, row = store_live.create_live_sweep(store, name="race", request={}, control_name="mu",
                                             control_unit=None, options={})  # fmt: skip
    errors: list[BaseException] = []

    def writer(k: int) -> None:
        try:
            for j in range(5):
                while True:
                    st = store_live.live_state(store, row.id)
                    n = len(st.records)
                    rec = {"seq": n + 1, "control": float(k + 10 * j), "seen": n}
                    if store_live.append_record(store, row.id, st.sweep.version, signal_id=None,
                                                control=rec["control"], record=rec,
                                                doc={"seen": n}) is not None:  # fmt: skip
                        break
        except BaseException as exc:  # noqa: BLE001
            errors.append(exc)

    threads = [threading.Thread(target=writer, args=(k,)) for k in range(8)]
    for th in threads:
        th.start()
    for th in threads:
        th.join(120)
    assert not errors
    _, recs = store_live.records_after(store, row.id, 0)
    assert [r.seq for r in recs] == list(range(1, 41))
    assert all(r.doc["seen"] == r.seq - 1 for r in recs)
    assert sorted(r.control for r in recs) == sorted(float(k + 10 * j) for k in range(8)
                                                     for j in range(5))  # fmt: skip
    store.dispose()


def test_a_record_that_grows_is_past_the_transition() -> None:
    """A record beyond mu* grows: it is no point of the fit (before, a growing record was read
    as a stable mode or dropped as no_mode, and the alarm followed the slowdown alone)."""
    controls = [0.0, 0.3, 0.6, 0.9, 1.2, 1.5, 1.65]
    recs, ups = sweep(controls, live.LivePlan(step=0.3, margin=0.01))
    assert ups[-1].alarm.level != "critical" or ups[-1].alarm.steps_left <= 1
    t = np.arange(4000) * DT
    grow = 0.01 + 1e-3 * np.exp(0.5 * t) * np.sin(15.0 * t)
    det, m, flags = live.measure(grow, dt=DT, control=1.9)
    assert m is None and [f.code for f in flags] == ["past_transition"]
    assert "unstable" in det.flag_codes
    u = live.update(recs, grow, dt=DT, control=1.9, plan=live.LivePlan(step=0.3, margin=0.01))
    assert u.alarm.level == "critical" and u.alarm.mu == 1.9
    assert u.n_used == len(controls)  # the fit is the records below it
    assert "past_transition" in [f.code for f in u.record.flags]
    lo, hi = u.prediction.mu_star_interval
    assert lo <= MU_STAR <= hi


def test_repeated_controls_are_averaged_as_a_batch_sweep_averages_them() -> None:
    """Two kicks at each control (different noise): the live sweep fits one point per control,
    the average a batch sweep of the same records makes (the predictor's inverse-variance
    mean), so both doors give the same mu*; before, the live fit kept the first record."""
    from service.analysis.pipeline import sweep_from_signals

    controls = [0.0, 0.3, 0.6, 0.9, 1.2, 1.5, 1.65, 1.72]
    rng = np.random.default_rng(11)
    recs, ups, batch = [], [], []
    for mu in controls:
        for _ in range(2):
            _, w = record(mu)
            w = w + 1e-4 * rng.standard_normal(w.size)
            u = live.update(recs, w, dt=DT, control=mu, plan=live.LivePlan(step=0.3))
            recs.append(u.record)
            ups.append(u)
            batch.append((w, DT, mu))
    last = ups[-1]
    assert last.n_used == 16 and last.used_in_fit
    ref = sweep_from_signals(batch)
    assert last.prediction.transition == ref.prediction.transition
    assert last.prediction.mu_star == pytest.approx(ref.prediction.mu_star, rel=1e-9)
    assert "repeated_points_averaged" in [f.code for f in ref.flags]
    assert "repeated_points_averaged" in [f.code for f in last.flags]
