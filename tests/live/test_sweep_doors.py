"""Batch, live, warn and watch: the same records give the same alarm, advice and answer
(issue 29, "Done when"), also after the sweep said ``converged`` and with records set aside.

References: the batch door (:func:`service.analysis.pipeline.sweep_from_signals`, ``snapwarn
sweep``) is the definition: it sees all the records at once and carries no state between
them. Every other door (a live sweep fed record by record, in process, over HTTP and by
``snapwarn watch``; ``warn``, which feeds its own records) must give, after each record, what
the batch door gives for the records so far. The records: closed-form ones (exact sigma^2,
``_records``) and a lab session of the independent generator (``_doors``: a lab that follows
the advice and goes on after ``converged``, with a missed hammer and a record cut short).
"""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
from dataclasses import replace
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest
from _records import DT, MU_STAR, record
from test_sweep_policy import point

from service import convert
from service.analysis import live, live_store
from service.analysis.pipeline import sweep_from_signals
from service.analysis.sweep_policy import SweepPlan, SweepPolicy, SweepRecord

ROOT = Path(__file__).resolve().parents[2]


def _policy_key(u: Any) -> str:
    """What a lab reads of a policy update: the answer, the alarm, the advice, the records
    set aside."""
    p = u.prediction
    return repr((None if p is None else (p.transition, p.mu_star, tuple(p.mu_star_interval)),
                 u.alarm, u.next_control, u.converged, u.set_aside,
                 tuple(f.code for f in u.flags)))  # fmt: skip (repr: NaN equals NaN)


def _batch(records: list[SweepRecord], plan: SweepPlan) -> Any:
    """The batch door's policy: every record at once, no state carried between them."""
    pol = SweepPolicy(plan)
    for r in records:
        pol.append(r)
    return pol.result()


# ------------------------------------------------------------------- closed-form records
def test_a_sweep_that_goes_on_after_converged_answers_as_a_batch() -> None:
    """After a converged update whose interval was joined with the one without its newest
    record (``converged_hull``), a live sweep kept that joined interval for its next trust
    test while a batch compares with the records' own: on these records (the eighth reads
    sigma^2 six standard errors soft) the tenth update was not converged live, converged as a
    batch, with another interval. Now every record keeps its records' own interval; the live
    sweep (and one read back from the store after each record) answers as the batch."""
    controls = [0.0, 0.3, 0.6, 0.9, 1.2, 1.5, 1.65, 1.72, 1.75, 1.77, 1.78, 1.785]
    plan = SweepPlan(step=0.3, target_width=0.1)
    recs = []
    for k, c in enumerate(controls):
        m = point(c)
        if k == 7:
            m = replace(m, sigma2=m.sigma2 + 6 * m.sigma2_std)
        recs.append(SweepRecord(0, c, m, name=f"rec_{k:02d}.csv"))
    pol = SweepPolicy(plan)
    stored: list[SweepRecord] = []
    hull_then_more = False
    for n, r in enumerate(recs, 1):
        u = pol.add(r)
        # a live sweep read back from the store before every record (another worker)
        again = SweepPolicy(plan, [live_store.record_from_dict(live_store.record_to_dict(x))
                                   for x in stored])  # fmt: skip
        back = again.add(r)
        stored = again.records
        b = _batch(recs[:n], plan)
        assert _policy_key(u) == _policy_key(b), n
        assert _policy_key(back) == _policy_key(b), n
        if "converged_hull" in [f.code for f in u.flags] and n < len(recs):
            hull_then_more = True
    assert hull_then_more  # the case this test is about: records after a joined interval
    lo, hi = u.interval
    assert u.converged and lo <= MU_STAR <= hi


def test_the_live_door_sets_aside_a_record_it_cannot_analyse() -> None:
    """A record the detector refuses (10 samples; a NaN in the samples) is set aside by its
    name with the reason, as the batch door sets it aside, and the sweep goes on; a request
    the detector refuses for another reason (its dt) is still an error naming the field."""
    from service.analysis.errors import ParameterError

    controls = [0.0, 0.3, 0.6, 0.9, 1.2, 1.5]
    ws = [record(mu)[1] for mu in controls]
    ws[2] = ws[2][:10]
    ws[4] = ws[4].copy()
    ws[4][100] = np.nan
    names = [f"rec_{k:02d}.csv" for k in range(len(controls))]
    plan = live.LivePlan(step=0.3)
    recs: list = []
    for w, mu, name in zip(ws, controls, names, strict=True):
        u = live.update(recs, w, dt=DT, control=mu, plan=plan, name=name)
        recs.append(u.record)
    assert [a.name for a in u.set_aside] == ["rec_02.csv", "rec_04.csv"]
    assert "too short" in u.set_aside[0].reason and "non-finite" in u.set_aside[1].reason
    assert u.prediction is not None and u.n_used == 4 and math.isfinite(u.next_control)
    doc = convert.live_update(u).model_dump(mode="json")  # the wire document holds it
    assert [a["name"] for a in doc["set_aside"]] == ["rec_02.csv", "rec_04.csv"]
    bad = live.update(recs[:4], ws[4], dt=DT, control=1.2, plan=plan, name="rec_04.csv")
    wire = convert.live_update(bad).model_dump(mode="json")
    assert wire["detection"]["modes"] == [] and wire["detection"]["method"] == live.NOT_ANALYSED
    assert [f["code"] for f in wire["record_flags"]] == ["record_set_aside"]
    assert not wire["used_in_fit"]
    b = sweep_from_signals([(w, DT, mu) for w, mu in zip(ws, controls, strict=True)],
                           names=names, plan=plan)  # fmt: skip
    assert b.set_aside == u.set_aside
    assert b.prediction.mu_star_interval == u.prediction.mu_star_interval
    assert b.alarm[-1] == u.alarm and b.next_control == u.next_control
    with pytest.raises(ParameterError) as err:
        live.update(recs, ws[0], dt=-1.0, control=1.6, plan=plan)
    assert err.value.parameter == "dt"


# ---------------------------------------------------------------------- the lab's records
@pytest.fixture(scope="module")
def lab(tmp_path_factory: pytest.TempPathFactory) -> SimpleNamespace:
    """A saddle-node lab session (seed 3), its files, and the live sweep in process fed the
    files one by one (the reference every door is compared with, after each record)."""
    import _doors as D

    from service.recordings import read_file

    records, mu_star = D.session("saddle-node", 3)
    folder = tmp_path_factory.mktemp("lab")
    manifest = D.write(records, folder)
    plan = live.LivePlan(step=D.STEP)
    recs, ups, files = [], [], []
    for r in records:
        f = read_file(folder / r.name)
        files.append((f.w, f.dt, r.control))
        u = live.update(recs, f.w, dt=f.dt, control=r.control, plan=plan, name=r.name,
                        time_unit=f.unit)  # fmt: skip
        recs.append(u.record)
        ups.append(u)
    return SimpleNamespace(records=records, mu_star=mu_star, folder=folder, manifest=manifest,
                           plan=plan, updates=ups, live_records=recs, files=files)  # fmt: skip


def _wire(doc: dict) -> tuple:
    """The answer, alarm, advice and records set aside of a wire document (a live update or
    a sweep result)."""
    p = doc.get("prediction") or {}
    alarm = doc["alarm"][-1] if isinstance(doc["alarm"], list) else doc["alarm"]
    nxt = doc["next_control"]
    aside = [(a["name"], a["reason"]) for a in doc["set_aside"]]
    return (p.get("transition"), p.get("mu_star"), p.get("mu_star_interval"), alarm, nxt, aside)


@pytest.mark.slow
def test_lab_records_give_one_answer_through_live_and_batch(lab: SimpleNamespace) -> None:
    """After each record the live sweep answers as the batch of the records so far (the
    policy on the same detections), and the batch door on the files (``sweep_from_signals``
    right after ``converged`` and at the end; ``snapwarn sweep --json`` at the end) answers as
    the live door; the missed hammer and the record cut short are set aside by name."""
    from service.cli import main

    ups, recs = lab.updates, lab.live_records
    first = next(k for k, u in enumerate(ups) if u.converged)
    assert first < len(ups) - 1  # records after converged
    for n, u in enumerate(ups, 1):
        assert _policy_key(u.policy) == _policy_key(_batch(recs[:n], lab.plan)), n
    names = [a.name[:6] for a in ups[-1].set_aside]
    assert {"rec_04", "rec_06"} <= set(names), names
    last = ups[-1]
    lo, hi = last.prediction.mu_star_interval
    assert lo <= lab.mu_star <= hi
    for n in (first + 2, len(ups)):
        b = sweep_from_signals(lab.files[:n], names=[r.name for r in lab.records[:n]],
                               plan=lab.plan)  # fmt: skip
        u = ups[n - 1]
        assert _wire(convert.sweep_result(b).model_dump(mode="json")) == _wire(
            convert.live_update(u).model_dump(mode="json")), n
    args = ["sweep", str(lab.manifest), "--no-progress", "--json", "--step", str(lab.plan.step)]
    import contextlib
    import io

    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        assert main(args) == 0
    doc = json.loads(out.getvalue())
    assert _wire(doc) == _wire(convert.live_update(last).model_dump(mode="json"))


@pytest.mark.slow
def test_watch_answers_as_the_live_door_after_each_record(lab: SimpleNamespace, tmp_path) -> None:  # noqa: ANN001
    """``snapwarn watch DIR --json`` (a process following the folder, in process): after each
    record, the live door's update."""
    folder = tmp_path / "watched"
    folder.mkdir()
    for r in lab.records:
        (folder / r.name).write_text((lab.folder / r.name).read_text())
    env = dict(os.environ, PYTHONPATH=str(ROOT), PYTHONUNBUFFERED="1")
    cmd = [sys.executable, "-c", "import sys; from service.cli import main; sys.exit(main())",
           "watch", str(folder), "--control", r"_theta_(?P<control>[-+0-9.eE]+)\.csv$",
           "--json", "--step", str(lab.plan.step), "--budget", str(len(lab.records)),
           "--idle", "60"]  # fmt: skip
    r = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=1200)
    assert r.returncode == 0, r.stderr[-2000:]
    docs = [json.loads(x) for x in r.stdout.splitlines() if x.strip().startswith("{")]
    assert len(docs) == len(lab.updates)
    for k, (d, u) in enumerate(zip(docs, lab.updates, strict=True)):
        ref = convert.live_update(u).model_dump(mode="json")
        assert _wire(d) == _wire(ref), k
        assert (d["converged"], d["record_duration"]) == (ref["converged"],
                                                           ref["record_duration"]), k


@pytest.mark.slow
def test_http_live_and_batch_answer_as_in_process(lab: SimpleNamespace, server) -> None:  # noqa: ANN001
    """Over HTTP with the SDK (a real uvicorn): the live sweep fed the files answers after
    each record as in process (the record cut short set aside by name, not refused)."""
    from service.client import Client

    with Client(server.url, timeout=600.0) as sdk:
        sweep = sdk.live_sweep("doors", control="theta", unit="deg", step=lab.plan.step)
        for r, u in zip(lab.records, lab.updates, strict=True):
            got = sweep.add(file=lab.folder / r.name, control=r.control).model_dump(mode="json")
            ref = convert.live_update(u).model_dump(mode="json")
            assert _wire(got) == _wire(ref), r.name
        sweep.close()


# ---------------------------------------------------------------------------- warn's door
def test_warn_answers_as_the_batch_and_the_live_door(monkeypatch: pytest.MonkeyPatch) -> None:
    """``warn`` measures its own records; here its simulator is the lab's generator (record 6
    a missed hammer). The records it measured, given to the live door one by one and to the
    batch door at once with warn's plan, give warn's alarm after each record and its final
    answer and advice."""
    import _lab_loop as LL

    import sim
    from service.analysis.pipeline import SIMULATED_RESOLUTION, warn

    camp = LL.campaign("subcritical-pitchfork", 2)
    seen: list[tuple[np.ndarray, float, float]] = []

    def simulate(scene: Any, model: str) -> Any:
        k = len(seen)
        rec = camp.record(scene.mu, k, duration=scene.duration, dt=scene.dt)
        y = LL.missed_hammer(rec, k) if k == 6 else rec.y
        seen.append((y, rec.dt, float(scene.mu)))
        return SimpleNamespace(w=y, dt=rec.dt, t=rec.t, model=model)

    monkeypatch.setattr(sim, "simulate", simulate)
    res = warn("symmetric", model="lab", first_step=LL.STEP, first_dt=rec_dt(camp),
               first_duration=4.0, rel_width=0.05, max_measurements=30)  # fmt: skip
    assert res.stopped == "converged"
    # the missed hammer is set aside and warn records again at its control (the advice)
    assert [a.seq for a in res.set_aside] == [7] and seen[7][2] == seen[6][2]
    plan = SweepPlan(step=LL.STEP, target_width=0.05, control_resolution=SIMULATED_RESOLUTION)
    recs: list = []
    for k, (y, dt, mu) in enumerate(seen):
        u = live.update(recs, y, dt=dt, control=mu, plan=plan)
        recs.append(u.record)
        assert repr(u.alarm) == repr(res.alarm[k]), k  # (repr: NaN equals NaN)
    b = sweep_from_signals(seen, plan=plan)
    for door in (u, b):
        assert door.prediction.mu_star == res.prediction.mu_star
        assert door.prediction.mu_star_interval == res.prediction.mu_star_interval
        assert door.next_control == res.next_control
        assert door.set_aside == res.set_aside
    assert repr(b.alarm[-1]) == repr(res.alarm[-1])
    assert res.prediction.mu_star_interval[0] <= camp.mu_star <= res.prediction.mu_star_interval[1]


def rec_dt(camp: Any) -> float:
    return 1.0 / camp.lab.fs
