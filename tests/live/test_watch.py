"""``snapwarn watch``: a real process follows a folder while files appear in it.

Files are written the way loggers write them (a header, a time column in milliseconds, rounded
values, written in two parts), one at a time while the watcher runs. The same files give the
same warning in process and through a server (one scene through every door).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import threading
import time
from pathlib import Path

import httpx2
import numpy as np
import pytest
from _records import MU_STAR, record, sigma2_of

ROOT = Path(__file__).resolve().parents[2]
SNAPWARN = [sys.executable, "-c", "import sys; from service.cli import main; sys.exit(main())"]
CONTROLS = [0.0, 0.3, 0.6, 0.9, 1.2]


def write_record(folder: Path, mu: float) -> None:
    """``mu_<value>.csv`` written in two parts (a logger still writing), then renamed in."""
    t, w = record(mu, n=3000)
    lines = ["time [ms],deflection"] + [f"{1e3 * a:.6g},{b:.9g}" for a, b in zip(t, w)]
    text = "\n".join(lines) + "\n"
    path = folder / f"mu_{mu:.3f}.csv"
    with open(path, "w") as fh:
        fh.write(text[: len(text) // 2])
        fh.flush()
        time.sleep(0.05)
        fh.write(text[len(text) // 2 :])


def start_watch(folder: Path, *extra: str) -> subprocess.Popen:
    env = dict(os.environ, PYTHONPATH=str(ROOT), PYTHONUNBUFFERED="1")
    cmd = [*SNAPWARN, "watch", str(folder),
           "--control", r"mu_([-+0-9.]+)\.csv", "--json", "--step", "0.3",
           "--budget", str(len(CONTROLS)), "--idle", "120", *extra]  # fmt: skip
    return subprocess.Popen(cmd, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True)  # fmt: skip


def feed(folder: Path, proc: subprocess.Popen) -> list[dict]:
    """Write the first file before the watcher starts, the others while it runs; collect its
    JSON lines."""
    out: list[dict] = []

    def read() -> None:
        for ln in proc.stdout:
            out.append(json.loads(ln))

    reader = threading.Thread(target=read)
    reader.start()
    (folder / "notes.txt").write_text("not a record\n")
    for mu in CONTROLS[1:]:
        deadline = time.monotonic() + 120
        while len(out) < CONTROLS.index(mu) and time.monotonic() < deadline:
            time.sleep(0.05)  # the lab measures where it is told, after the answer
        write_record(folder, mu)
    proc.wait(180)
    reader.join(10)
    return out


def check(out: list[dict]) -> dict:
    assert [d["seq"] for d in out] == [1, 2, 3, 4, 5]
    assert [d["control"] for d in out] == CONTROLS
    for d in out:
        s2 = d["detection"]["fundamental"]["sigma2"]
        assert s2 == pytest.approx(sigma2_of(d["control"]) * 1e-6, rel=1e-4)  # 1/ms^2
        assert not d["record_flags"]
    last = out[-1]
    lo, hi = last["mu_star_interval"]
    assert lo <= MU_STAR <= hi and abs(last["mu_star"] - MU_STAR) < 1e-3
    # (T/T0 = 1.3 after these five: the transition is not named before the slowdown shows)
    assert 1.2 < last["next_control"] < MU_STAR
    return last


def watch_local(tmp_path: Path) -> dict:
    here = tmp_path / "local"
    here.mkdir()
    write_record(here, CONTROLS[0])  # already there when the watch starts
    proc = start_watch(here)
    local = check(feed(here, proc))
    assert proc.returncode == 0, proc.stderr.read()
    return local


def test_watch_in_process(tmp_path: Path) -> None:
    watch_local(tmp_path)


@pytest.mark.slow
def test_watch_through_a_server_agrees_with_in_process(tmp_path: Path, server) -> None:  # noqa: ANN001
    local = watch_local(tmp_path)
    there = tmp_path / "remote"
    there.mkdir()
    write_record(there, CONTROLS[0])
    proc = start_watch(there, "--server", server.url, "--name", "watched")
    remote = check(feed(there, proc))
    err = proc.stderr.read()
    assert proc.returncode == 0, err
    # one scene through every door: the same numbers
    assert remote["mu_star"] == pytest.approx(local["mu_star"], rel=0, abs=1e-12)
    assert remote["next_control"] == pytest.approx(local["next_control"], rel=0, abs=1e-12)
    # the server's sweep spent its budget: an ordinary finished sweep
    sweep = httpx2.get(f"{server.url}/v1/sweeps/{remote['sweep_id']}").json()
    assert sweep["status"] == "succeeded"
    assert len(sweep["result"]["measurements"]) == len(CONTROLS)
    assert np.isclose(sweep["result"]["prediction"]["mu_star"], remote["mu_star"], atol=1e-12)


def test_watch_refuses_a_regex_without_group(tmp_path: Path) -> None:
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    r = subprocess.run([*SNAPWARN, "watch", str(tmp_path),
                        "--control", r"mu_.*\.csv", "--json"],
                       env=env, capture_output=True, text=True, timeout=120)  # fmt: skip
    assert r.returncode == 2
    doc = json.loads(r.stdout)
    assert doc["field"] == "--control"


def test_text_line_of_each_stage() -> None:
    """The human line: no prediction yet, then mu* with its interval, the alarm, the advice."""
    import math
    import re

    from service import convert, numfmt
    from service.analysis import live
    from service.cli.watch_cmds import control_of, line

    assert control_of("mu_0.300.csv", re.compile(r"mu_([-+0-9.]+)\.csv")) == 0.3
    assert control_of("run-7_load=1.5N.csv", re.compile(r"load=(?P<control>[0-9.]+)N")) == 1.5
    assert control_of("notes.txt", re.compile(r"mu_([-+0-9.]+)\.csv")) is None
    recs, lines = [], []
    for mu in CONTROLS:
        _, w = record(mu, n=2000)
        u = live.update(recs, w, dt=2e-3, control=mu, plan=live.LivePlan(step=0.3))
        recs.append(u.record)
        lines.append(line(convert.live_update(u), f"mu_{mu}.csv"))
    assert lines[0].startswith("#1 mu_0.0.csv control=0 | sigma2=")
    assert "mu*" not in lines[1] and "next<=0.6" in lines[1]
    # three records answer: [1.79, 3.33] is wider than the 0.6 travelled, but its lower end is
    # 4 steps ahead: watch (a wide interval is never critical)
    assert "mu*=1.8" in lines[2] and "alarm=watch" in lines[2]
    # [1.62, 2.32] is evidence (no wider than the 1.2 travelled): its lower end bounds the step
    assert "mu*=1.8" in lines[4] and "(interval)" in lines[4] and "alarm=warning" in lines[4]
    # numbers as a scientist writes them: sigma2 to its standard error (in Hz too when the time
    # unit is known), mu*, its interval and the advice to the interval's precision, with units
    u = convert.live_update(u)
    text = line(u, "mu_1.2.csv", "deg", "s")
    f = u.detection.fundamental
    lo, hi = u.mu_star_interval
    a, b = numfmt.fmt_interval(lo, hi)
    assert f"control=1.2 deg | sigma2={numfmt.fmt_pm(f.sigma2, f.sigma2_std)} 1/s^2 (" in text
    assert f"{f.omega / (2 * math.pi):.4g} Hz)" in text
    assert f"mu*={numfmt.fmt(u.mu_star, 0.5 * (hi - lo))} deg [{a}, {b}] deg" in text
    assert f"next<={numfmt.fmt_below(u.next_control, 0.5 * (hi - lo))} deg (interval)" in text


def test_watch_takes_the_users_hand(tmp_path: Path) -> None:
    """``--quantity``, ``--notch`` and ``--band`` reach every record (each update says what its
    record was read with and names it by its file); a band with no mode of the records in it
    sets each aside by its file, with the band in the reason."""
    for mu in CONTROLS[:3]:
        write_record(tmp_path, mu)
    env = dict(os.environ, PYTHONPATH=str(ROOT), PYTHONUNBUFFERED="1")
    cmd = [*SNAPWARN, "watch", str(tmp_path), "--control", r"mu_([-+0-9.]+)\.csv", "--json",
           "--budget", "3", "--idle", "60", "--quantity", "displacement", "--notch", "0.1",
           "--band", "1,2"]  # fmt: skip
    r = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr
    out = [json.loads(x) for x in r.stdout.splitlines()]
    names = [f"mu_{mu:.3f}.csv" for mu in CONTROLS[:3]]
    assert [d["record_name"] for d in out] == names
    for d in out:
        assert d["record_options"] == {"quantity": "displacement", "start": None,
                                       "notch": [0.1], "exclude": False}  # fmt: skip
    last = out[-1]
    assert [a["name"] for a in last["set_aside"]] == names
    assert all("band [1, 2]" in a["reason"] for a in last["set_aside"])
    assert last["mu_star"] is None


def test_watch_in_process_brings_records_to_the_first_ones_time_unit(tmp_path: Path) -> None:
    """A file in seconds after one in milliseconds is read in the sweep's unit (ms), as the
    service's live door does; one without a known unit is skipped with the reason."""
    import argparse

    from service.cli._common import CliError
    from service.cli.watch_cmds import InProcess

    write_record(tmp_path, 0.0)  # time [ms]
    t, w = record(0.3, n=3000)
    rows = "".join(f"{float(a)!r},{float(b)!r}\n" for a, b in zip(t, w))
    (tmp_path / "mu_0.300.csv").write_text("time [s],deflection\n" + rows)
    (tmp_path / "mu_0.600.csv").write_text("time [fortnights],deflection\n" + rows)
    args = argparse.Namespace(step=0.3, margin=0.0, band=None, target_width=None, dt=None,
                              control_resolution=None, quantity=None, notch=None)  # fmt: skip
    src = InProcess(args)
    first = src.add(tmp_path / "mu_0.000.csv", 0.0)
    second = src.add(tmp_path / "mu_0.300.csv", 0.3)
    assert src.records[1].time_unit == "ms" and second.detection.time_unit is None
    s2 = second.detection.fundamental.sigma2
    assert s2 == pytest.approx(sigma2_of(0.3) * 1e-6, rel=1e-4)  # 1/ms^2, not 1/s^2
    assert first.detection.fundamental.sigma2 == pytest.approx(sigma2_of(0.0) * 1e-6, rel=1e-4)
    with pytest.raises(CliError, match="fortnights"):
        src.add(tmp_path / "mu_0.600.csv", 0.6)
