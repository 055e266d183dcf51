"""The one sweep policy (``service.analysis.sweep_policy``) and the alarm scale.

References: the closed-form records of ``_records`` (exact sigma^2, saddle-node at mu* = 1.8),
hand-computed alarm cases (gap in the lab's steps and in widths), and the other doors of the
same records (batch ``sweep_from_signals``, the live ``update``).
"""

from __future__ import annotations

import json
import math
from dataclasses import replace

import numpy as np
import pytest
from _records import DT, MU_STAR, record, sigma2_of

from service.analysis import live
from service.analysis.alarm import ALARM_LEVELS, alarm_for
from service.analysis.measurement import Measurement
from service.analysis.pipeline import sweep_from_signals
from service.analysis.sweep_policy import SweepPlan, SweepRecord, evaluate

GROW = None


def growing(n: int = 4000) -> np.ndarray:
    t = np.arange(n) * DT
    return 0.01 + 1e-3 * np.exp(0.5 * t) * np.sin(15.0 * t)


def point(mu: float, sigma2: float | None = None) -> Measurement:
    s2 = sigma2_of(mu) if sigma2 is None else sigma2
    return Measurement(mu, math.sqrt(abs(s2)), s2, 1e-3 * abs(s2), 0.05 * (MU_STAR - mu) ** 0.5,
                       1e-6, "underdamped", 8.0, DT)  # fmt: skip


# ------------------------------------------------------------------------------ the scale
def test_the_scale_counts_danger_in_lab_steps_and_evidence_in_widths() -> None:
    a = alarm_for(10.0, 1.2)
    assert (a.level, a.rank) == ("insufficient", 0)
    # [23, 600] from 22.5 with steps of 2.5: wider than the 22.5 travelled; its lower end 0.2
    # steps ahead is still a bound: warning, never the top level because the interval is wide
    # (before: critical); a wide interval whose lower end is far gives no judgement
    a = alarm_for(22.5, 1.5, 50.0, (23.0, 600.0), step=2.5, span=22.5)
    assert a.level == "warning" and "never critical" in a.reason
    assert alarm_for(22.5, 1.5, 50.0, (30.0, 600.0), step=2.5, span=22.5).level == "watch"
    assert alarm_for(22.5, 1.5, 50.0, (33.0, 600.0), step=2.5, span=22.5).level == "insufficient"
    assert alarm_for(22.5, 1.5, 50.0, (23.0, 600.0), span=22.5).level == "insufficient"
    # one that reaches down to the last record bounds nothing the records do not show
    assert alarm_for(22.5, 1.5, 50.0, (22.5, 600.0), step=2.5, span=22.5).level == "insufficient"
    for lo, level in ((40.0, "clear"), (30.5, "watch"), (27.0, "warning"), (24.0, "critical")):
        a = alarm_for(22.5, 1.5, lo + 1.0, (lo, lo + 2.0), step=2.5, span=22.5)
        assert a.level == level, (lo, a)
        assert a.steps_left == pytest.approx((lo - 22.5) / 2.5)
        assert a.widths_left == pytest.approx((lo - 22.5) / 2.0)
        assert a.rank == ALARM_LEVELS.index(level)
    # a transition without loss of stability is never a snap alarm
    assert alarm_for(22.5, 1.5, 25.0, (24.0, 26.0), step=2.5, span=22.5,
                     transition="none").level == "clear"  # fmt: skip
    # a record that grew: the top level, at that record
    a = alarm_for(22.5, 1.5, 25.0, (24.0, 26.0), step=2.5, span=22.5, past=23.0)
    assert (a.level, a.rank, a.mu) == ("critical", 4, 23.0)


# ----------------------------------------------------------------------------- the records
def test_a_record_whose_fundamental_cannot_enter_is_set_aside_by_name() -> None:
    """sigma2 = +5.03 on one record in the middle (before: 'sigma2[17]=5.03' ended the sweep)."""
    controls = [0.0, 0.3, 0.6, 0.9, 1.2, 1.5, 1.65]
    recs = [SweepRecord(k + 1, c, point(c), name=f"rec_{k:02d}.csv")
            for k, c in enumerate(controls)]  # fmt: skip
    recs[3] = SweepRecord(4, 0.9, point(0.9, 5.03), name="rec_03.csv")
    u = evaluate(recs, SweepPlan())
    assert u.n_set_aside == 1 and u.set_aside[0].name == "rec_03.csv"
    assert "5.03" in u.set_aside[0].reason and "rec_03.csv" in u.set_aside[0].reason
    assert u.n_used == 6 and u.prediction is not None
    lo, hi = u.prediction.mu_star_interval
    assert lo <= MU_STAR <= hi
    assert "record_set_aside" in [f.code for f in u.flags]
    # three usable controls still answer; two do not (and say why)
    few = [SweepRecord(k + 1, c, point(c)) for k, c in enumerate((0.0, 0.6, 1.2))]
    assert evaluate(few).prediction is not None
    u2 = evaluate([*few[:2], SweepRecord(3, 1.2, point(1.2, 5.03))])
    assert u2.prediction is None and "too_few_records" in [f.code for f in u2.flags]
    assert u2.alarm.level == "insufficient"


def slow_damped(n: int = 4000) -> np.ndarray:
    """A record that rings only in a slow, heavily damped mode (sigma^2 = -101: 10 rad/s,
    decay rate 1): what a detector reads as the fundamental of a record whose hammer excited
    the damped mode 1 and not the mode that goes soft."""
    t = np.arange(n) * DT
    return 1e-2 * np.exp(-1.0 * t) * np.sin(10.0 * t)


def test_one_odd_first_record_does_not_turn_the_sweep_round(tmp_path, capsys) -> None:  # noqa: ANN001
    """Audit (h), second part: a first record slower than every other (a heavily damped mode
    picked) made the records 'slow down toward the lowest mu': the batch door refused the whole
    sweep (CLI exit 2) with "approaches its transition from above: give -mu" (the lab stepped
    up), the live door answered predictor_failed. Now that record is set aside by name with its
    reason and the others answer, in every door; a sweep whose records all slow down toward
    the lowest control is still refused with that advice (then true)."""
    from service.analysis.errors import ParameterError
    from service.cli import main

    controls = [0.0, 0.3, 0.6, 0.9]
    ws = [slow_damped(), *(record(mu)[1] for mu in controls[1:])]
    names = [f"rec_{k:02d}.csv" for k in range(len(controls))]
    plan = live.LivePlan(step=0.3)
    b = sweep_from_signals([(w, DT, mu) for w, mu in zip(ws, controls, strict=True)],
                           names=names, plan=plan)  # fmt: skip
    assert [a.name for a in b.set_aside] == ["rec_00.csv"]
    why = b.set_aside[0].reason
    assert "rec_00.csv" in why and "slower than every record" in why and "direction" in why
    p = b.prediction
    assert p is not None and p.mu_star_interval[0] <= MU_STAR <= p.mu_star_interval[1]
    assert "give -mu" not in json.dumps([f.message for f in b.flags])
    recs: list = []
    for w, mu, name in zip(ws, controls, names, strict=True):
        u = live.update(recs, w, dt=DT, control=mu, plan=plan, name=name)
        recs.append(u.record)
    assert u.set_aside == b.set_aside and u.prediction.mu_star_interval == p.mu_star_interval
    assert u.next_control == b.next_control and "predictor_failed" not in [f.code for f in u.flags]
    # with three records the two others cannot answer: set aside all the same, too few
    u3 = evaluate(recs[:3], plan)
    assert [a.name for a in u3.set_aside] == ["rec_00.csv"]
    assert "too_few_records" in [f.code for f in u3.flags]
    # the CLI door (exit 0, the file named)
    for name, w in zip(names, ws, strict=True):
        t = np.arange(w.size) * DT
        body = "".join(f"{float(a)!r},{float(v)!r}\n" for a, v in zip(t, w, strict=True))
        (tmp_path / name).write_text("t [s],w\n" + body)
    manifest = tmp_path / "manifest.csv"
    manifest.write_text("path,control\n" + "".join(f"{n},{c!r}\n"
                                                    for n, c in zip(names, controls)))  # fmt: skip
    assert main(["sweep", str(manifest), "--no-progress", "--json", "--step", "0.3"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert [a["name"] for a in doc["set_aside"]] == ["rec_00.csv"]
    # a sweep stepped the other way (every record slower than the one above it): refused,
    # and the advice to give -mu is then true
    down = [SweepRecord(k + 1, c, point(c)) for k, c in enumerate((0.0, 0.6, 1.2, 1.5, 1.65))]
    rev = [SweepRecord(r.seq, -r.control, replace(r.measurement, mu=-r.control))
           for r in down]  # fmt: skip
    with pytest.raises(ParameterError, match="give -mu"):
        evaluate(rev, SweepPlan(), strict=True)
    assert evaluate(rev, SweepPlan()).n_set_aside == 0


def test_an_overdamped_pick_beside_a_stronger_ringing_mode_is_in_doubt() -> None:
    """A slow relaxation (two real poles, sigma^2 = -143) in the record at 0.9 beside the
    strip's ringing mode 7x stronger: the detector takes the relaxation as the fundamental and
    its ambiguity rule looks at ringing fundamentals only (before: no flag). The policy flags
    it fundamental_ambiguous (the reason names the ringing mode), in the batch door and the
    live door alike; the sweep-wide choice takes the ringing line there. A ringing mode less
    than 3x stronger puts no overdamped fundamental in doubt."""
    from service.analysis.sweep_records import OVERDAMPED_DOUBT, doubt_overdamped

    controls = [0.0, 0.3, 0.6, 0.9, 1.2, 1.5]
    t = np.arange(4000) * DT
    ws = [record(mu)[1] for mu in controls]
    ws[3] = ws[3] + 1.4e-3 * (np.exp(-0.5 * t) - np.exp(-286.0 * t))
    names = [f"rec_{k:02d}.csv" for k in range(len(controls))]
    b = sweep_from_signals([(w, DT, mu) for w, mu in zip(ws, controls, strict=True)],
                           names=names)  # fmt: skip
    det = next(d for d, _, name in b.detections if name == "rec_03.csv")
    assert det.fundamental.mode.regime == "overdamped"
    doubt = [f.message for f in det.flags if f.code == "fundamental_ambiguous"]
    assert len(doubt) == 1 and "overdamped" in doubt[0] and "7.1" in doubt[0]
    assert sum("fundamental_ambiguous" in [f.code for f in d.flags]
               for d, _, _ in b.detections) == 1  # fmt: skip
    m = next(m for m in b.measurements if m.mu == 0.9)
    assert m.sigma2 == pytest.approx(sigma2_of(0.9), rel=1e-6)  # the ringing line
    lo, hi = b.prediction.mu_star_interval
    assert lo <= MU_STAR <= hi
    recs: list = []
    for w, mu, name in zip(ws, controls, names, strict=True):
        u = live.update(recs, w, dt=DT, control=mu, name=name)
        recs.append(u.record)
        if name == "rec_03.csv":
            assert [f.message for f in u.detection.flags
                    if f.code == "fundamental_ambiguous"] == doubt  # fmt: skip
    assert u.prediction.mu_star_interval == b.prediction.mu_star_interval
    # the same relaxation 2x weaker than the ringing mode (5e-3 against 1e-2): no doubt
    weak = detect_of(record(0.9)[1] + 5e-3 * (np.exp(-0.5 * t) - np.exp(-286.0 * t)))
    assert weak.fundamental.mode.regime == "overdamped"
    assert "fundamental_ambiguous" not in [f.code for f in doubt_overdamped(weak).flags]
    assert OVERDAMPED_DOUBT == 3.0


def detect_of(w: np.ndarray) -> object:
    from service.analysis.detect import detect

    return detect(w, dt=DT)


def test_the_advice_stays_below_every_bound() -> None:
    """Below the point estimate always, below the lower end of an interval that is evidence,
    below a record that grew; a live sweep recovers at the next good record."""
    plan = live.LivePlan(step=0.3)
    recs, ups = [], []
    for mu in (0.0, 0.3, 0.6, 0.9, 1.2, 1.4):
        u = live.update(recs, record(mu)[1], dt=DT, control=mu, plan=plan)
        recs.append(u.record)
        ups.append(u)
    for u in ups[2:]:
        p = u.prediction
        lo, hi = p.mu_star_interval
        assert u.next_control < p.mu_star
        last = max(m.mu for m in u.policy.measurements)
        if u.trusted or hi - lo <= last:
            assert u.next_control < lo
    # a record that grows at 1.55, below the interval the six stable records give: one record
    # is not enough (a detector can read a spurious growing pole): critical, the advice repeats
    # that control (never above it) and the interval spans both readings
    g = live.update(recs, growing(), dt=DT, control=1.55, plan=plan)
    assert g.alarm.level == "critical" and g.next_control == 1.55
    assert "growth_unconfirmed" in [f.code for f in g.flags] and "again" in g.alarm.reason
    assert g.prediction.mu_star_interval[0] == 1.4 and not g.converged
    # a second record that grows there confirms it: the interval is the bracket the records
    # give, from the last stable record to 1.55 (not the point 1.55), so no step is safe
    g2 = live.update([*recs, g.record], growing(), dt=DT, control=1.55, plan=plan)
    assert g2.alarm.level == "critical" and not math.isfinite(g2.next_control)
    assert {"past_transition", "no_safe_step"} <= {f.code for f in g2.flags}
    assert g2.prediction.mu_star_interval == (1.4, 1.55)
    # ... then a stable record above it: the growing one was not past the transition; it is set
    # aside with its reason and the sweep goes on from the stable record
    recs.append(g.record)
    u = live.update(recs, record(1.6)[1], dt=DT, control=1.6, plan=plan)
    assert u.n_set_aside == 1 and "stable record" in u.set_aside[0].reason
    assert math.isfinite(u.next_control) and 1.6 < u.next_control < MU_STAR
    assert u.alarm.level != "insufficient" and u.used_in_fit


# ------------------------------------------------------------------------------- the doors
def test_batch_and_live_give_one_answer() -> None:
    """The same records through the batch door and the live door (fed in control order): the
    same mu*, interval, alarm and next safe control (one policy, not two copies of it)."""
    controls = [0.0, 0.3, 0.6, 0.9, 1.2, 1.5, 1.65, 1.72]
    rng = np.random.default_rng(3)
    batch, recs = [], []
    for mu in controls:
        w = record(mu)[1] + 1e-4 * rng.standard_normal(4000)
        batch.append((w, DT, mu))
        u = live.update(recs, w, dt=DT, control=mu)
        recs.append(u.record)
    b = sweep_from_signals(batch[::-1])  # any order: the batch sorts by control
    assert b.prediction.mu_star == u.prediction.mu_star
    assert b.prediction.mu_star_interval == u.prediction.mu_star_interval
    assert b.alarm[-1] == u.alarm and b.prediction.alarm == u.alarm
    assert b.next_control == u.next_control
    closed = live.finish(recs)
    assert closed.next_control == u.next_control and closed.alarm[-1] == u.alarm


def test_the_cli_door_answers_as_the_live_door(tmp_path, capsys) -> None:  # noqa: ANN001
    """``snapwarn sweep`` on files (plain and --json) and a live sweep fed the same records read
    back from those files: one mu*, interval, alarm and next safe value; the plain output names
    the type, mu* with its interval and unit (to the interval's precision), alarm and advice."""
    from service.cli import main
    from service.numfmt import fmt, fmt_interval
    from service.recordings import read_file

    controls = [0.0, 0.3, 0.6, 0.9, 1.2, 1.5, 1.65, 1.72]
    rng = np.random.default_rng(5)
    rows = []
    for k, mu in enumerate(controls):
        t, w = record(mu)
        w = w + 1e-4 * rng.standard_normal(w.size)
        name = f"rec_{k:02d}.csv"
        body = "".join(f"{float(a)!r},{float(b)!r}\n" for a, b in zip(t, w, strict=True))
        (tmp_path / name).write_text("t [s],w\n" + body)
        rows.append(f"{name},{mu!r}\n")
    manifest = tmp_path / "manifest.csv"
    manifest.write_text("path,control\n" + "".join(rows))
    args = ["sweep", str(manifest), "--no-progress", "--control-name", "theta",
            "--control-unit", "deg"]  # fmt: skip
    assert main([*args, "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    recs = []
    for k, mu in enumerate(controls):
        r = read_file(tmp_path / f"rec_{k:02d}.csv")
        u = live.update(recs, r.w, dt=r.dt, control=mu)
        recs.append(u.record)
    p = doc["prediction"]
    assert p["mu_star"] == u.prediction.mu_star
    assert tuple(p["mu_star_interval"]) == u.prediction.mu_star_interval
    assert doc["alarm"][-1]["level"] == u.alarm.level and doc["alarm"][-1]["rank"] == u.alarm.rank
    assert doc["next_control"] == u.next_control and p["next_safe_mu"] == u.next_control
    assert p["classification"]["mu_star"] == p["mu_star"]  # one mu* per document
    assert main(args) == 0
    text = capsys.readouterr().out.splitlines()
    lo, hi = p["mu_star_interval"]
    a, b = fmt_interval(lo, hi)
    assert text[0] == f"type: {p['transition']}" or text[0].startswith("type: undetermined (")
    assert text[1].startswith(f"theta* = {fmt(p['mu_star'], 0.5 * (hi - lo))} deg, "
                              f"95 % interval [{a}, {b}] deg")  # fmt: skip
    # the alarm's reason counts in controls: the line says in which unit
    assert text[2].startswith(f"alarm: {u.alarm.level} (rank {u.alarm.rank}; controls in deg): ")
    assert text[3].startswith("next safe theta: ") and text[3].endswith(" deg")
    assert float(text[3].split()[-2]) <= u.next_control


def test_a_converged_interval_does_not_rest_on_the_newest_record() -> None:
    """The sweep stops on its answer, and the nearest record decides an extrapolated mu* almost
    alone: the converged interval joins the interval of the records without the newest one
    (flag converged_hull); before convergence the interval is the records' own."""
    from dataclasses import replace

    from service.analysis.sweep_policy import SweepPolicy

    controls = [0.0, 0.3, 0.6, 0.9, 1.2, 1.5, 1.65, 1.72]
    plan = SweepPlan(step=0.3, target_width=0.2)
    pol = SweepPolicy(plan)
    for k, c in enumerate(controls):
        m = point(c)
        if k == len(controls) - 1:  # the newest record reads sigma^2 six standard errors soft
            m = replace(m, sigma2=m.sigma2 + 6 * m.sigma2_std)
        u = pol.add(SweepRecord(0, c, m, name=f"rec_{k:02d}.csv"))
        if not u.converged:
            assert "converged_hull" not in [f.code for f in u.flags]
    assert u.converged and "converged_hull" in [f.code for f in u.flags]
    own = evaluate(pol.records, plan).interval  # not converged without the previous interval
    without = evaluate(pol.records[:-1], plan).interval
    lo, hi = u.interval
    assert own != (lo, hi)
    assert lo == min(own[0], without[0]) and hi == max(own[1], without[1])
    assert u.prediction.alarm.mu_star_interval == (lo, hi)  # one interval per document
    assert lo <= MU_STAR <= hi


def test_no_side_of_the_interval_is_finer_than_the_control_resolution() -> None:
    """A lab that sets its control to 0.2 knows each control only to half of that: no side of
    the interval is narrower than 0.1 (never below the last stable control, 1.76); with a
    resolution finer than the interval the interval is the records' own."""
    controls = [0.0, 0.3, 0.6, 0.9, 1.2, 1.5, 1.65, 1.72, 1.76]
    recs = [SweepRecord(k + 1, c, point(c)) for k, c in enumerate(controls)]
    own = evaluate(recs, SweepPlan(step=0.3, control_resolution=1e-9)).prediction
    got = evaluate(recs, SweepPlan(step=0.3, control_resolution=0.2)).prediction
    assert got.mu_star == own.mu_star
    (lo0, hi0), (lo, hi) = own.mu_star_interval, got.mu_star_interval
    assert hi0 - own.mu_star < 0.1 and hi == pytest.approx(own.mu_star + 0.1)
    assert lo0 > 1.76 and lo == 1.76


def test_the_default_control_resolution_is_the_grid_and_floors_the_interval() -> None:
    """Without a resolution given, the controls' grid is the lab's: written to 0.01 (1.76),
    each is known to 0.005, and so no side of the interval is nearer mu* than that (flag
    resolution_floor says so), exactly as when the lab gives 0.01; controls written to full
    precision (a lab following the advice) give 1e-4 of the lab's step. A session that follows
    the advice converges on an interval no side of which is finer than that, covering mu*."""
    from service.analysis.sweep_policy import SweepPolicy, resolution

    controls = [0.0, 0.3, 0.6, 0.9, 1.2, 1.5, 1.65, 1.72, 1.76]
    recs = [SweepRecord(k + 1, c, point(c)) for k, c in enumerate(controls)]
    own = evaluate(recs, SweepPlan(step=0.3, control_resolution=1e-9))
    grid = evaluate(recs, SweepPlan(step=0.3))
    given = evaluate(recs, SweepPlan(step=0.3, control_resolution=0.01))
    assert "resolution_floor" not in [f.code for f in own.flags]
    assert own.interval[0] > MU_STAR - 0.005  # finer than the grid allows ...
    assert grid.interval == given.interval == (MU_STAR - 0.005, own.interval[1])  # ... floored
    assert "resolution_floor" in [f.code for f in grid.flags]
    assert grid.prediction.mu_star == own.prediction.mu_star
    # a lab that can set its control to 0.001 follows the advice rounded down to that: its
    # controls' grid is its resolution; it converges (the next step would be finer than it
    # can set) on an interval no side of which is nearer mu* than half of it
    plan = SweepPlan(step=0.3)
    pol, mu = SweepPolicy(plan), 0.0
    for _ in range(40):
        u = pol.add(SweepRecord(0, mu, point(mu)))
        if u.converged or not math.isfinite(u.next_control):
            break
        mu = math.floor(u.next_control * 1000) / 1000
    assert u.converged and mu < MU_STAR
    assert resolution(u.measurements, plan, 0.3) == pytest.approx(1e-3)
    lo, hi = u.interval
    m = u.prediction.mu_star
    assert lo <= MU_STAR <= hi
    assert m - lo >= 5e-4 - 1e-12 or lo == mu
    assert hi - m >= 5e-4 - 1e-12 and "resolution_floor" in [f.code for f in u.flags]
    # written to full precision (the advice as given), the controls give 1e-4 of the step
    assert resolution([point(0.0), point(0.3), point(0.3 + 1.234567e-7)], plan,
                      0.3) == pytest.approx(3e-5)  # fmt: skip


def test_the_plain_sweep_without_a_prediction_says_why_and_what_is_set_aside() -> None:
    """Plain ``snapwarn sweep`` without a prediction (before: one line, 'no prediction (...)'):
    why (too few records), the alarm, the advice, the next record's length and each record set
    aside, with the unit."""
    from service import convert
    from service.cli.analysis_cmds import sweep_text

    controls = [0.0, 0.3, 0.6, 0.9]
    names = [f"rec_{k:02d}.csv" for k in range(len(controls))]
    opts = [{"exclude": True}, {"exclude": True}, {}, {}]
    b = sweep_from_signals([(record(mu)[1], DT, mu) for mu in controls], names=names,
                           options=opts, plan=SweepPlan(step=0.3))  # fmt: skip
    text = sweep_text(convert.sweep_result(b), "theta", "deg").splitlines()
    assert text[0].startswith("no prediction (2 control(s) in the fit, 2 record(s) set aside): ")
    assert "a prediction needs at least 3" in text[0]
    assert text[1].startswith("alarm: insufficient (rank 0; controls in deg): ")
    # nothing bounds theta* yet: the advised step is the trust region's, never called safe
    assert text[2] == (f"next theta (not known safe: no prediction bounds theta* yet): "
                       f"{b.next_control:.6g} deg")  # fmt: skip
    assert text[3].startswith(f"next record: {b.record_duration:.3g} long, sample step ")
    assert text[4:] == [f"set aside: record {n} set aside: excluded by the user" for n in names[:2]]


def test_after_a_repeat_that_did_not_lift_the_interval_the_advice_fills_in_below() -> None:
    """No step up is safe when the interval reaches down to the last record: the record is
    repeated there; when the repeat leaves the interval there too, the next record fills in
    halfway between the last two controls (stable ground, below the last record): repeats
    narrow one point's noise, not the law's shape (imperfect ten-lab seeds 6 and 7 repeated
    10-16 times and ended 2.0 % and 1.0 % wide). A live sweep that follows it flags no
    out_of_order; a fill-in finer than the control resolution is a repeat again."""
    controls = [0.0, 0.3, 0.6, 0.9, 1.2, 1.5, 1.65, 1.72]
    plan = SweepPlan(step=0.3)

    def rec(c: float) -> SweepRecord:  # the record at 1.72 reads sigma^2 2 % soft
        m = point(c)
        return SweepRecord(0, c, replace(m, sigma2=m.sigma2 * 0.98) if c == 1.72 else m)

    from service.analysis.sweep_policy import SweepPolicy

    pol = SweepPolicy(plan)
    for c in controls:
        u = pol.add(rec(c))
    last = u.next_control
    assert u.next.limited_by == "bound" and 1.72 < last < MU_STAR
    u = pol.add(rec(last))
    assert u.next.limited_by == "repeat" and u.next_control == last
    assert u.interval[0] == last  # the interval reaches down to the last record
    u = pol.add(rec(last))
    assert u.next.limited_by == "fill_in" and u.interval[0] == last
    assert u.next_control == 0.5 * (1.72 + last) < last
    # a live sweep: the advised fill-in below the largest control is no out_of_order, another
    # control below it is
    fill = u.next_control
    assert "out_of_order" not in [f.code for f in live._record_flags(pol.records, fill, None, ())]
    assert "out_of_order" in [f.code for f in live._record_flags(pol.records, 1.7, None, ())]
    # halfway finer than the lab can set its control: a repeat again
    coarse = evaluate(pol.records, SweepPlan(step=0.3, control_resolution=0.01),
                      previous_interval=pol.records[-2].interval)  # fmt: skip
    assert coarse.next.limited_by == "repeat" and coarse.next_control == last
