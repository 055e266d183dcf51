"""Sweeps of records as labs make them, through the CLI (in-process): files written in different
time units, a sweep run toward the transition from above, a record past the transition, a
sweep table from a spreadsheet in Hz. The truth is a fold law ``sigma^2 = -C sqrt(mu* - mu)``
written into damped sines, so the right answer is known."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).parent))
sys.path.insert(0, str(Path(__file__).parents[1] / "contract"))
from _contract_helpers import run_cli  # noqa: E402
from _foreign import beam_grid, table  # noqa: E402

from service import recordings as R  # noqa: E402

MU_STAR = 30.0  # degrees, say
C = 1e4  # sigma^2 = -C sqrt(mu* - mu) (1/s^2)
G = 0.5  # decay rate (1/s)
CONTROLS = np.array([0, 8, 15, 20, 24, 26.5, 28, 29, 29.5, 29.8])
DT = 5e-4  # s


def _record(x: float, seed: int) -> np.ndarray:
    """A kicked record at distance ``x`` below mu*: static level and a damped sine."""
    om = np.sqrt(C * np.sqrt(x) - G * G)
    t = DT * np.arange(8000)
    rng = np.random.default_rng(seed)
    return 2.0 - 0.3 * np.sqrt(x) + 0.2 * np.exp(-G * t) * np.sin(om * t) + (
        2e-3 * rng.standard_normal(t.size)
    )


def _write(d: Path, name: str, w: np.ndarray, unit: str | None) -> None:
    """A CSV with its time column in ``unit`` (``None``: a bare ``t``, seconds)."""
    scale = {"s": 1.0, "ms": 1e3, None: 1.0}[unit]
    head = "t,w [mm]" if unit is None else f"t [{unit}],w [mm]"
    t = DT * np.arange(w.size) * scale
    (d / name).write_text(table(head, [t, w], ["%.9g", "%.6g"]))


def _manifest(d: Path, rows: list[tuple[str, float]], name: str = "manifest.csv") -> Path:
    p = d / name
    p.write_text("path,control\n" + "".join(f"{f},{float(c)!r}\n" for f, c in rows))
    return p


def _sweep(path: Path) -> tuple[int, dict, str]:
    return run_cli("sweep", str(path), "--json", "--no-progress")


@pytest.fixture(scope="module")
def lab(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The same ten records written three ways: all in ms, half in ms and half in s, and half
    in ms and half without a unit."""
    d = tmp_path_factory.mktemp("lab")
    for k, c in enumerate(CONTROLS):
        w = _record(MU_STAR - c, k)
        _write(d, f"ms{k}.csv", w, "ms")
        _write(d, f"s{k}.csv", w, "s")
        _write(d, f"bare{k}.csv", w, None)
    return d


def test_records_in_different_time_units_are_brought_to_seconds(lab: Path) -> None:
    one = _manifest(lab, [(f"ms{k}.csv", c) for k, c in enumerate(CONTROLS)], "one.csv")
    mixed = _manifest(lab, [(f"{'ms' if k % 2 else 's'}{k}.csv", c)
                            for k, c in enumerate(CONTROLS)], "mixed.csv")  # fmt: skip
    rc1, a, err1 = _sweep(one)
    rc2, b, err2 = _sweep(mixed)
    assert rc1 == 0 and rc2 == 0, (err1, err2)
    pa, pb = a["prediction"], b["prediction"]
    assert pa["transition"] == pb["transition"] == "saddle-node"
    lo, hi = pb["mu_star_interval"]
    assert lo <= MU_STAR <= hi
    assert pb["mu_star"] == pytest.approx(pa["mu_star"], abs=1e-6)
    # the sweep's last alarm is the prediction's (it read the slowdown alone: 'none' by T/T0
    # where the prediction, a live sweep and warn said 'critical')
    for doc in (a, b):
        assert doc["alarm"][-1] == doc["prediction"]["alarm"]
    # sigma^2 per second^2 in both (the one-unit sweep in ms^-2 is 1e-6 of it)
    s_ms = [m["sigma2"] for m in a["measurements"]]
    s_s = [m["sigma2"] for m in b["measurements"]]
    assert s_s == pytest.approx([1e6 * v for v in s_ms], rel=1e-6)


def test_a_missing_time_unit_among_others_is_refused_by_name(lab: Path) -> None:
    rows = [(f"{'ms' if k < 5 else 'bare'}{k}.csv", c) for k, c in enumerate(CONTROLS)]
    rc, doc, err = _sweep(_manifest(lab, rows, "nounit.csv"))
    assert rc == 2 and doc["field"] == "records"
    assert "ms0.csv: ms" in err and "bare9.csv: none given" in err


def test_a_sweep_toward_the_transition_from_above_is_refused(lab: Path) -> None:
    """Records at 60 - theta: the transition (at 30) lies below them. Before, mu* came out at
    954, far above every record, with the alarm `none`."""
    rows = [(f"ms{k}.csv", 2 * MU_STAR - c) for k, c in enumerate(CONTROLS)]
    rc, doc, err = _sweep(_manifest(lab, rows, "above.csv"))
    assert rc == 2 and doc["field"] == "mu", err
    assert "from above" in err and "-mu" in err
    # negated, it is the ordinary sweep: mu* = -30
    rows = [(f"ms{k}.csv", -(2 * MU_STAR - c)) for k, c in enumerate(CONTROLS)]
    rc, doc, err = _sweep(_manifest(lab, rows, "negated.csv"))
    assert rc == 0, err
    lo, hi = doc["prediction"]["mu_star_interval"]
    assert lo <= -MU_STAR <= hi


def test_a_sweep_table_that_slows_down_toward_its_first_row_is_refused(tmp_path: Path) -> None:
    """predict's table in increasing rows, the transition below them."""
    ms, mu, s2, sd = beam_grid("asymmetric", 0.05, 0.01)
    p = tmp_path / "above.csv"
    p.write_text(table("mu,sigma2,sigma2_std", [2 * ms - mu[::-1], s2[::-1], sd[::-1]],
                       ["%.17g"] * 3))  # fmt: skip
    rc, doc, err = run_cli("predict", str(p), "--json")
    assert rc == 2 and doc["field"] == "mu" and "from above" in err


def test_omega_std_without_a_unit_is_in_the_unit_of_omega(tmp_path: Path) -> None:
    """`omega [Hz],omega_std`: the std is in Hz too (it was read as rad/s: a noise 2 pi times
    too small, flagged noise_underestimated, another mu* and interval)."""
    ms, mu, s2, sd = beam_grid("asymmetric", 0.05, 0.01)
    om = np.sqrt(-s2)
    om_sd = sd / (2 * om)
    a, b = tmp_path / "rad.csv", tmp_path / "hz.csv"
    a.write_text(table("mu,omega,omega_std", [mu, om, om_sd], ["%.17g"] * 3))
    b.write_text(table("mu,omega [Hz],omega_std", [mu, om / (2 * np.pi), om_sd / (2 * np.pi)],
                       ["%.17g"] * 3))  # fmt: skip
    ra = run_cli("predict", str(a), "--json")[1]
    rb = run_cli("predict", str(b), "--json")[1]
    assert rb["mu_star"] == pytest.approx(ra["mu_star"], rel=1e-9)
    assert rb["mu_star_interval"] == pytest.approx(ra["mu_star_interval"], rel=1e-9)
    assert [f["code"] for f in rb["flags"]] == [f["code"] for f in ra["flags"]]


def test_a_decimal_comma_first_row_is_data_not_units() -> None:
    """`t;w` then `0,000000;0,003456`: the first row was read as a row of units (one sample
    lost, the time unit '0,000000' on the charts)."""
    t = DT * np.arange(400)
    w = np.exp(-G * t) * np.sin(60.0 * t)
    rows = "\n".join(f"{a:.6f};{b:.6f}".replace(".", ",") for a, b in zip(t, w))
    rec = R.read_bytes(("t;w\n" + rows + "\n").encode(), "csv")
    assert rec.n == 400 and rec.unit is None and rec.value_unit is None
    assert rec.w[0] == 0.0 and rec.dt == pytest.approx(DT, rel=1e-9)
    # a real units row under a ';' header still is one
    rec = R.read_bytes(("t;w\n(ms);(mm)\n" + rows + "\n").encode(), "csv")
    assert rec.n == 400 and rec.unit == "ms" and rec.value_unit == "mm"


def test_a_time_column_named_by_its_unit_carries_it() -> None:
    rec = R.read_bytes(b"ms,w\n0,1\n1,2\n2,0\n3,1\n", "csv")
    assert rec.unit == "ms"
    assert R.seconds_per("ms") == 1e-3 and R.seconds_per("\u00b5s") == 1e-6
    assert R.seconds_per("furlongs") is None and R.seconds_per(None) is None


def test_a_record_past_the_transition_raises_the_alarm(lab: Path) -> None:
    """A record at 30.5 (beyond mu* = 30) grows: before, it was dropped as `no_mode` (or read as
    a stable mode) and the alarm stayed `watch`."""
    t = DT * np.arange(8000)
    grow = 2.0 + 0.02 * np.exp(0.8 * t) * np.sin(40.0 * t)
    grow += 2e-3 * np.random.default_rng(99).standard_normal(t.size)
    _write(lab, "past.csv", grow, "ms")
    rows = [(f"ms{k}.csv", c) for k, c in enumerate(CONTROLS)] + [("past.csv", 30.5)]
    rc, doc, err = _sweep(_manifest(lab, rows, "past.csv.manifest"))
    assert rc == 0, err
    codes = [f["code"] for f in doc["flags"]]
    assert "past_transition" in codes
    assert doc["alarm"][-1]["level"] == "critical" and doc["alarm"][-1]["mu"] == 30.5
    assert len(doc["measurements"]) == CONTROLS.size  # the growing record is not one of them
    lo, hi = doc["prediction"]["mu_star_interval"]
    assert lo <= MU_STAR <= hi and doc["prediction"]["transition"] == "saddle-node"


def test_too_few_stable_records_say_so(lab: Path) -> None:
    t = DT * np.arange(8000)
    _write(lab, "flat.csv", 2.0 + 1e-3 * np.random.default_rng(5).standard_normal(t.size), "ms")
    rows = [("ms0.csv", 0.0), ("ms1.csv", 8.0), ("flat.csv", 15.0)]
    rc, doc, err = _sweep(_manifest(lab, rows, "few.csv"))
    assert rc == 0, err
    assert doc["prediction"] is None
    assert {"no_mode", "too_few_records"} <= {f["code"] for f in doc["flags"]}


def test_the_manifest_control_column_is_named_like_predicts(lab: Path) -> None:
    p = lab / "theta.csv"
    p.write_text("path,theta [rad]\n" + "".join(
        f"ms{k}.csv,{float(np.radians(c))!r}\n" for k, c in enumerate(CONTROLS)))  # fmt: skip
    rc, doc, err = _sweep(p)
    assert rc == 2 and "--control-column" in err
    rc, doc, err = run_cli("sweep", str(p), "--json", "--no-progress", "--control-column", "theta")
    assert rc == 0, err
    lo, hi = doc["prediction"]["mu_star_interval"]
    assert lo <= np.radians(MU_STAR) <= hi


def test_times_written_with_too_few_digits_say_so() -> None:
    """`%.6g` of times near 1000 s with a 1 ms step repeat: the error says why."""
    t = 1000.0 + DT * np.arange(400)
    w = np.sin(60.0 * t)
    text = "t,w\n" + "".join(f"{a:.6g},{b:.6f}\n" for a, b in zip(t, w))
    with pytest.raises(R.RecordingError) as ei:
        R.read_bytes(text.encode(), "csv")
    assert "too few digits" in str(ei.value) and ei.value.field == "t[1]"


def test_a_table_whose_last_rows_are_past_the_transition(tmp_path: Path) -> None:
    """sigma2 >= 0 on the last rows (stepped past mu*): those rows are left out, flagged, and
    the alarm is critical there (before: the whole table was refused). A positive row inside
    the table is still an error naming it."""
    ms, mu, s2, sd = beam_grid("asymmetric", 0.05, 0.01)
    mu2 = np.append(mu, [ms + 0.02, ms + 0.05])
    s22 = np.append(s2, [40.0, 90.0])
    sd2 = np.append(sd, [1.0, 1.0])
    p = tmp_path / "past.csv"
    p.write_text(table("mu,sigma2,sigma2_std", [mu2, s22, sd2], ["%.17g"] * 3))
    ref = tmp_path / "ref.csv"
    ref.write_text(table("mu,sigma2,sigma2_std", [mu, s2, sd], ["%.17g"] * 3))
    rc, doc, err = run_cli("predict", str(p), "--json")
    assert rc == 0, err
    base = run_cli("predict", str(ref), "--json")[1]
    assert doc["mu_star"] == base["mu_star"]
    assert "past_transition" in [f["code"] for f in doc["flags"]]
    assert doc["alarm"]["level"] == "critical" and doc["alarm"]["mu"] == pytest.approx(ms + 0.02)
    lo, hi = doc["mu_star_interval"]
    assert lo <= ms <= hi <= ms + 0.02
    s2[3] = 5.0  # inside the table: an error
    ref.write_text(table("mu,sigma2,sigma2_std", [mu, s2, sd], ["%.17g"] * 3))
    rc, doc, err = run_cli("predict", str(ref), "--json")
    assert rc == 2 and doc["field"] == "sigma2"


def test_a_record_too_short_to_analyse_is_named(lab: Path) -> None:
    (lab / "short.csv").write_text("t [ms],w\n0,1\n1,2\n2,1\n")
    rows = [("ms0.csv", 0.0), ("ms1.csv", 8.0), ("short.csv", 15.0), ("ms3.csv", 20.0)]
    # in a sweep it is set aside by name with the detector's reason; the others answer
    rc, doc, err = _sweep(_manifest(lab, rows, "short.manifest"))
    assert rc == 0, err
    assert [a["name"] for a in doc["set_aside"]] == ["short.csv"]
    assert "too short" in doc["set_aside"][0]["reason"]
    assert len(doc["measurements"]) == 3
    rc, doc, err = run_cli("detect", str(lab / "short.csv"), "--json")
    assert rc == 2 and "short.csv" in err and doc["field"] == "w"


def test_mu_star_never_lies_beyond_a_row_past_the_transition(tmp_path: Path) -> None:
    """The rows below extrapolate to 27.5, the row at 25.5 is already unstable: mu* and its
    interval end there (mu* came out at 27.5, outside its own interval [24.0, 25.5])."""
    p = tmp_path / "t.csv"
    p.write_text("mu,sigma2\n0,-3\n10,-2\n18.5,-1\n23,-0.5\n25.5,0.2\n")
    rc, doc, err = run_cli("predict", str(p), "--json")
    assert rc == 0, err
    lo, hi = doc["mu_star_interval"]
    assert lo <= doc["mu_star"] <= hi <= 25.5
    assert doc["alarm"]["level"] == "critical"


def test_a_static_deflection_that_never_varies(tmp_path: Path) -> None:
    """w_static = 0 on every row (the trivial branch before a pitchfork, written as measured
    zero) without its std: no information on b, flagged, never a solver's NaN message."""
    p = tmp_path / "w0.csv"
    p.write_text("mu,sigma2,w_static\n0,-1968,0\n0.5,-1696,0\n1.0,-1193,0\n1.3,-827,0\n"
                 "1.5,-564,0\n1.6,-420,0\n")  # fmt: skip
    rc, doc, err = run_cli("predict", str(p), "--json")
    assert rc == 0, err
    q = tmp_path / "plain.csv"
    q.write_text("mu,sigma2\n0,-1968\n0.5,-1696\n1.0,-1193\n1.3,-827\n1.5,-564\n1.6,-420\n")
    assert doc == run_cli("predict", str(q), "--json")[1]


def test_a_scope_campaign_gives_the_answer_of_its_plain_records(lab: Path) -> None:
    """The same ten records as a scope campaign writes them: 15 % pre-trigger at rest before
    each kick, ISO 8601 timestamps, a manifest whose files' column is 'file' and whose control
    carries its unit, two records per control value. The prediction is that of the plain
    records (to the 1e-3 of a standard error the cut and the microsecond clock allow), with
    the flags that say what was read."""
    import datetime

    start = datetime.datetime(2026, 11, 27, 14, 0, 0)
    rows = []
    for k, c in enumerate(CONTROLS):
        w = _record(MU_STAR - c, k)
        rest = w[-1] + 2e-3 * np.random.default_rng(100 + k).standard_normal(1400)
        ww = np.r_[rest, w]
        for rep in (0, 1):
            stamps = [start + datetime.timedelta(seconds=DT * i) for i in range(ww.size)]
            body = "".join(f"{s.isoformat(timespec='microseconds')};{v:.6g}\n"
                           for s, v in zip(stamps, ww, strict=True))  # fmt: skip
            (lab / f"scope{k}_{rep}.csv").write_text("Timestamp;w [mm]\n" + body)
            rows.append(f"scope{k}_{rep}.csv,{float(c)!r}\n")
    (lab / "scope.csv").write_text("file,theta [deg]\n" + "".join(rows))
    plain = _manifest(lab, [(f"s{k}.csv", c) for k, c in enumerate(CONTROLS)], "plain.csv")
    rc, doc, err = run_cli("sweep", str(lab / "scope.csv"), "--control-column", "theta",
                           "--json", "--no-progress")  # fmt: skip
    rc0, ref, err0 = _sweep(plain)
    assert rc == 0 and rc0 == 0, (err, err0)
    p, p0 = doc["prediction"], ref["prediction"]
    assert p["transition"] == p0["transition"] == "saddle-node"
    assert abs(p["mu_star"] - p0["mu_star"]) < 0.1 * p0["mu_star_std"]
    assert "repeated_points_averaged" in [f["code"] for f in doc["flags"]]  # the policy's
    per_record = doc["detections"] if "detections" in doc else doc["measurements"]
    assert per_record and all("pretrigger" in [f["code"] for f in r["flags"]] for r in per_record)
