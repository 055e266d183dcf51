"""Blind trials: put a blind campaign through a product door and judge the answer.

The generators (``_blind_structures``, ``_blind_recorder``, ``_blind_sweeps``) never import the
product; this module drives the product only through its doors: the CLI in a subprocess
(``snapwarn sweep MANIFEST --json``) and, for the HTTP door, the SDK against a real ``snapwarn
serve`` (the caller passes its URL).

Judgement (:func:`judge`), per campaign:

* type: ``right`` (in the truth's ``right`` set), ``withheld`` (``undetermined``, or
  ``pitchfork`` where sub/supercritical is the question), ``early`` (a correct name on a sweep
  that stops at ``T/T0 < 2``, where the type must be withheld) or ``wrong``;
* ``covered``: the 95 % interval holds the true mu*; ``err_widths``: (mu* - truth) / width;
* ``confident``: a wrong type named, or an interval that misses the truth with no flag that
  says the interval may be off (:data:`CAUTION`): the product's worst failure; ``late``: the
  whole interval lies beyond the truth (a lab told to go on would snap);
* records: every record that cannot be trusted (snapped branch, growing) set aside by name or
  flagged as past the transition; every record set aside named by its file;
* detector: records whose fundamental's ``sigma2`` is off the truth by more than 10 % and not
  set aside (the detector or reconcile picked another line).
"""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[2]

#: prediction flags that say the interval may not hold the truth (a miss with one is honest)
CAUTION = frozenset({
    "interval_huge", "interval_unbounded", "mu_star_far", "slowdown_not_reached",
    "few_points_near", "exponent_undecided", "fold_indistinct", "imperfection_possible",
    "imperfection_undecided", "a_unbounded", "law_misfit", "growth_unconfirmed",
    "predictor_failed", "too_few_records",
})  # fmt: skip


@dataclass
class Answer:
    door: str
    ok: bool  # the door answered (no crash, no 5xx)
    transition: str | None = None
    mu_star: float | None = None
    interval: tuple[float, float] | None = None
    flags: tuple[str, ...] = ()
    set_aside: tuple[str, ...] = ()  # messages
    measurements: list = field(default_factory=list)
    error: str = ""
    seconds: float = float("nan")


@dataclass
class Verdict:
    type: str  # right | withheld | early | wrong | no-answer
    covered: bool
    err_widths: float
    confident: bool
    problems: list[str]
    bad_records: list[str]  # detector: records read off the critical mode, not set aside
    late: bool = False  # the whole interval lies beyond the truth (the dangerous side)


def _set_aside_messages(doc: Any) -> list[str]:
    out: list[str] = []
    if isinstance(doc, dict):
        if doc.get("code") == "record_set_aside":
            out.append(str(doc.get("message", "")))
        for v in doc.values():
            out += _set_aside_messages(v)
    elif isinstance(doc, list):
        for v in doc:
            out += _set_aside_messages(v)
    return out


def _from_sweep_doc(door: str, doc: dict) -> Answer:
    p = doc.get("prediction") or {}
    iv = p.get("mu_star_interval")
    flags = tuple(f["code"] for f in (p.get("flags") or [])) + tuple(
        f["code"] for f in (doc.get("flags") or []))
    sa = tuple(_set_aside_messages(doc)) + tuple(
        f"{a.get('name', '')}: {a.get('reason', '')}" for a in (doc.get("set_aside") or []))
    return Answer(door, True, p.get("transition"), p.get("mu_star"),
                  None if iv is None or iv[0] is None else (float(iv[0]), float(iv[1])),
                  tuple(dict.fromkeys(flags)), sa, doc.get("measurements") or [])  # fmt: skip


def cli_command(manifest: Path, *extra: str) -> list[str]:
    return [str(ROOT / ".venv/bin/snapwarn"), "sweep", str(manifest), "--json", "--no-progress",
            *extra]  # fmt: skip


def _snapwarn(*args: str) -> list[str]:
    """The command line of ``snapwarn ARGS``: the checkout's ``.venv`` script, else this Python
    importing the checkout's ``service.cli`` (``PYTHONPATH`` = the checkout)."""
    exe = ROOT / ".venv/bin/snapwarn"
    if exe.exists():
        return [str(exe), *args]
    return [sys.executable, "-c", "import sys; from service.cli import main; sys.exit(main())",
            *args]  # fmt: skip


def cli_sweep(manifest: Path, *extra: str, timeout: float = 900) -> Answer:
    """``snapwarn sweep MANIFEST --json`` in a subprocess."""
    import time

    exe = ROOT / ".venv/bin/snapwarn"
    cmd = cli_command(manifest, *extra)
    if not exe.exists():
        cmd = [sys.executable, "-c", "import sys; from service.cli import main; sys.exit(main())",
               *cmd[1:]]  # fmt: skip
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    t0 = time.perf_counter()
    r = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout, env=env)
    dt = time.perf_counter() - t0
    try:
        doc = json.loads(r.stdout)
    except json.JSONDecodeError:
        doc = None
    if r.returncode != 0 or not isinstance(doc, dict):
        err = (r.stderr.strip() or r.stdout.strip())[-400:]
        # a refusal with a clear message (exit 2, an error naming a field) is a door answer;
        # a traceback is a crash
        ok = "Traceback" not in r.stderr
        return Answer("cli", ok, error=f"exit {r.returncode}: {err}", seconds=dt)
    a = _from_sweep_doc("cli", doc)
    a.seconds = dt
    return a


def cli_predict(table: Path, *extra: str, timeout: float = 600) -> Answer:
    """``snapwarn predict TABLE --json`` in a subprocess (the predictor alone)."""
    import time

    cmd = _snapwarn("predict", str(table), "--json", *extra)
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    t0 = time.perf_counter()
    r = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout, env=env)
    dt = time.perf_counter() - t0
    try:
        doc = json.loads(r.stdout)
    except json.JSONDecodeError:
        doc = None
    if r.returncode != 0 or not isinstance(doc, dict):
        ok = "Traceback" not in r.stderr
        return Answer("predict", ok, error=f"exit {r.returncode}: {r.stderr.strip()[-400:]}",
                      seconds=dt)  # fmt: skip
    p = doc.get("prediction", doc)
    iv = p.get("mu_star_interval")
    return Answer("predict", True, p.get("transition"), p.get("mu_star"),
                  None if iv is None or iv[0] is None else (float(iv[0]), float(iv[1])),
                  tuple(f["code"] for f in (p.get("flags") or [])), (), [], seconds=dt)  # fmt: skip


def cli_detect(path: Path, *extra: str, expect_error: bool = False, timeout: float = 600,
               ) -> Any:  # fmt: skip
    """``snapwarn detect FILE --json``: its document, or (``expect_error``) the refusal's text
    (exit 2, no traceback)."""
    cmd = _snapwarn("detect", str(path), "--json", *extra)
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    r = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout, env=env)
    assert "Traceback" not in r.stderr, r.stderr[-2000:]
    if expect_error:
        assert r.returncode == 2, (r.returncode, r.stdout[:500])
        return r.stderr
    assert r.returncode == 0, r.stderr[-1000:]
    return json.loads(r.stdout)


def assert_live_gives(url: str, truth: Any, cli: Answer, title: str) -> None:
    """Feed ``truth``'s records one by one to a live sweep (SDK) and assert it ends on the
    CLI's answer ``cli`` (type, mu* and interval to 1e-9)."""
    import numpy as np

    from service.client import Client

    docs = []
    with Client(url, timeout=600.0) as sdk:
        live = sdk.live_sweep(title, control="P", unit=truth.control_unit)
        for name, c in zip(truth.names, truth.controls, strict=True):
            docs.append(live.add(file=truth.manifest.parent / name, control=c)
                        .model_dump(mode="json"))  # fmt: skip
        live.close()
    last = docs[-1]
    assert last["transition"] == cli.transition, (last["transition"], cli.transition)
    assert math.isclose(last["mu_star"], cli.mu_star, rel_tol=1e-9), (last["mu_star"], cli.mu_star)
    assert np.allclose(last["mu_star_interval"], cli.interval, rtol=1e-9)


def http_sweep(url: str, manifest: Path, control_unit: str) -> Answer:
    """Upload each record with the SDK, create a sweep over HTTP, wait for it."""
    from service.client import Client
    from service.client.errors import ApiError

    rows = [ln.split(",") for ln in manifest.read_text().splitlines()[1:] if ln.strip()]
    files = [(manifest.parent / n, float(c)) for n, c in rows]
    try:
        with Client(url, timeout=600.0) as sdk:
            sigs = [(sdk.upload_file(p, control_value=c, control_unit=control_unit), c)
                    for p, c in files]  # fmt: skip
            job = sdk.create_sweep([(s.id, c) for s, c in sigs], control="P", unit=control_unit)
            done = sdk.wait(job, timeout=900)
    except ApiError as exc:
        status = getattr(exc, "status", None) or getattr(exc, "status_code", None)
        ok = status is None or int(status) < 500
        return Answer("http", ok, error=f"ApiError {status}: {str(exc)[:300]}")
    doc = done.model_dump(mode="json")
    res = doc.get("result") or {}
    if not res:
        return Answer("http", True, error=f"no result: {str(doc)[:300]}")
    return _from_sweep_doc("http", res)


def judge(ans: Answer, truth: Any) -> Verdict:
    """The verdict on one door's answer for one campaign (module docstring)."""
    problems: list[str] = []
    if not ans.ok:
        return Verdict("no-answer", False, math.nan, False, [f"door failed: {ans.error}"], [])
    if ans.transition is None:
        return Verdict("withheld", False, math.nan, False,
                       [f"no prediction: {ans.error or ans.flags}"], [])  # fmt: skip
    far = truth.plan in ("far", "veryfar")  # _blind_sweeps.FAR_PLANS: no type may be named
    t = ans.transition
    if t in truth.right:
        vt = "right"
    elif t == "undetermined" or (t == "pitchfork" and not far and "pitchfork" in truth.kind):
        vt = "withheld"
    elif far and _family_ok(t, truth):
        vt = "early"
    else:
        vt = "wrong"
    covered, err = False, math.nan
    if ans.interval is not None:
        lo, hi = ans.interval
        covered = lo <= truth.mu_star <= hi
        width = hi - lo
        if ans.mu_star is not None and width > 0 and math.isfinite(width):
            err = (ans.mu_star - truth.mu_star) / width
    caution = set(ans.flags) & CAUTION
    confident = vt == "wrong" or (ans.interval is not None and not covered and not caution)
    if vt == "wrong":
        problems.append(f"type {t} (truth {truth.kind})")
    if vt == "early":
        problems.append(f"type {t} named at T/T0 = {truth.t_ratio_last:.2f} < 2")
    late = ans.interval is not None and ans.interval[0] > truth.mu_star
    if ans.interval is not None and not covered:
        problems.append(f"interval {ans.interval} misses mu* = {truth.mu_star!r}"
                        + (" LATE (wholly beyond the truth)" if late else " (early)")
                        + (f" (flags {sorted(caution)})" if caution else " with no caution flag"))
    # untrusted records: set aside by name, or the sweep says it is past the transition (or,
    # for one growing record below the stable records' interval, that the growth awaits a
    # second record: growth_unconfirmed, the interval spanning both readings)
    text = " ".join(ans.set_aside)
    grew = {"past_transition", "growth_unconfirmed"}
    for name, why in truth.untrusted.items():
        stem = Path(name).stem
        if stem not in text and not (grew & set(ans.flags)):
            problems.append(f"{name} ({why}) neither set aside by name nor past_transition")
    for m in ans.set_aside:
        if not any(Path(n).stem in m for n in truth.names):
            problems.append(f"a record set aside without its file's name: {m[:100]!r}")
    bad = []
    # measurements are per usable control (sorted, repeats averaged): match by control
    by_c: dict[float, list[float]] = {}
    for c, s2, name in zip(truth.controls, truth.sigma2, truth.names, strict=False):
        if name in truth.untrusted:
            continue
        by_c.setdefault(round(c, 9), []).append(s2)
    for m in ans.measurements:
        c = round(float(m.get("mu", math.nan)), 9)
        s2 = m.get("sigma2")
        if c in by_c and s2 is not None:
            s2t = sum(by_c[c]) / len(by_c[c])
            if abs(s2 - s2t) > 0.1 * abs(s2t):
                bad.append(f"control {c:g}: sigma2 {s2:.5g} vs truth {s2t:.5g}")
    return Verdict(vt, covered, err, confident, problems, bad, late)


def failures(ans: Answer, truth: Any) -> list[str]:
    """What makes a door's answer fail a blind trial: the judge's problems (a miss, an untrusted
    record neither set aside nor reported), a type neither right nor honestly withheld, no
    interval where the plan reaches close enough for one."""
    v = judge(ans, truth)
    bad = list(v.problems)
    if v.type not in ("right", "withheld"):
        bad.append(f"type verdict {v.type}")
    if ans.interval is None and truth.plan not in ("far", "veryfar"):
        bad.append("no interval")
    return bad


def _family_ok(t: str, truth: Any) -> bool:
    """A name of the right family (exponent) on a far sweep."""
    if truth.kind == "saddle-node":
        return t == "saddle-node"
    return "pitchfork" in t and (t == "pitchfork" or t == truth.kind or truth.kind == "pitchfork")


def describe(truth: Any, ans: Answer, v: Verdict) -> str:
    return (f"{truth.family}/{truth.plan} {truth.params}: {ans.door} said {ans.transition} "
            f"mu*={ans.mu_star} {ans.interval} flags={list(ans.flags)}; truth {truth.kind} "
            f"{truth.mu_star!r}; verdict {v.type}, covered={v.covered}, confident={v.confident}; "
            f"{v.problems}; detector: {v.bad_records}")


#: detector rows: the blind lab's impairments one at a time (``Recording`` overrides); every
#: row's record starts from a 10 % pre-trigger at rest unless it says ``start``; a laser in mm
#: at 2 kHz without hum unless the row says otherwise
DETECTOR_ROWS: dict[str, dict] = {
    "clean_45dB": dict(snr_db=45.0),
    "noise_30dB": dict(snr_db=30.0),
    "noise_25dB": dict(snr_db=25.0),
    "midring_30dB": dict(snr_db=30.0, start="midring"),
    "hum_2pct_45dB": dict(snr_db=45.0, hum_rel=0.02),
    "hum_10pct_45dB": dict(snr_db=45.0, hum_rel=0.10),
    "rate_500Hz": dict(snr_db=45.0, rate_hz=500.0),
    "rate_20kHz": dict(snr_db=45.0, rate_hz=20000.0),
    "geophone": dict(snr_db=45.0, sensor="geophone", unit="in/s"),
    "accel_g": dict(snr_db=45.0, sensor="accel", unit="g"),
    "adc_12bit": dict(snr_db=60.0, adc_bits=12),
    "bounce": dict(snr_db=45.0, second_hit=(0.3, 0.5)),
    "rig_mode": dict(snr_db=45.0, rig=(0.6, 0.02, 0.5)),
}
#: families whose critical mode is the lowest line at every control (the detector's
#: fundamental is then the critical mode)
DETECTOR_FAMILIES = ("arch_fold", "arch_pitchfork", "arch_imperfect", "threelink")


def detect_one(row: str, i: int) -> dict:
    """One record: family and control drawn from ``i``, the row's recording; the detector's
    fundamental against the critical mode (1 %)."""
    from dataclasses import replace

    import _blind_sweeps as S
    import numpy as np
    from _blind_recorder import record

    from service.analysis.detect import WARNING_FLAGS, detect

    fam = DETECTOR_FAMILIES[i % len(DETECTOR_FAMILIES)]
    over = dict(hum_rel=0.0, rate_hz=2000.0, sensor="laser", unit="mm", adc_bits=None,
                start="pretrigger", duration_s=3.0)  # fmt: skip
    over.update(DETECTOR_ROWS[row])
    camp = S.campaign(fam, "lab", 100 + i, **over)
    rng = np.random.default_rng(i)
    j = int(rng.integers(0, len(camp.controls)))
    p = camp.controls[j]
    rec = replace(camp.rec, seed=1000 + i, duration_s=camp._duration(p, False))
    r = record(camp.state(p), camp.omega_scale(), camp.gamma(), rec, camp.force(),
               camp.static_mm_per_unit)  # fmt: skip
    s2 = -float(camp.state(p).omega2[camp.state(p).critical]) * camp.omega_scale() ** 2
    out = {"row": row, "i": i, "family": fam, "control": p, "f_true_hz":
           math.sqrt(-s2) / (2 * math.pi), "samples": len(r.y)}  # fmt: skip
    try:
        det = detect(r.y, dt=1.0 / rec.rate_hz)
    except Exception as exc:  # noqa: BLE001 - an exception is an outcome here
        return out | {"outcome": "error", "flags": f"{type(exc).__name__}: {exc}"[:120]}
    codes = det.flag_codes
    fund = det.fundamental
    if fund is None:
        return out | {"outcome": "withheld", "flags": " ".join(codes)}
    rel = math.sqrt(abs(fund.sigma2) / -s2) - 1
    if abs(rel) <= 0.01:
        outcome = "right"
    else:
        outcome = "flagged" if any(c in WARNING_FLAGS for c in codes) else "silent"
    return out | {"outcome": outcome, "rel_err": rel, "flags": " ".join(codes),
                  "f_det_hz": math.sqrt(abs(fund.sigma2)) / (2 * math.pi)}  # fmt: skip


class Server:
    """A real ``snapwarn serve`` on a free loopback port (SQLite in ``folder``)."""

    def __init__(self, folder: Path, timeout: float = 120.0) -> None:
        import socket
        import time
        import urllib.request

        with socket.socket() as s:
            s.bind(("127.0.0.1", 0))
            port = s.getsockname()[1]
        self.url = f"http://127.0.0.1:{port}"
        env = dict(os.environ, PYTHONPATH=str(ROOT), PYTHONUNBUFFERED="1",
                   SNAPWARN_LOG_LEVEL="warning")  # fmt: skip
        env.pop("SNAPWARN_API_KEY", None)
        # answers are judged here, not latency: a live add on a loaded machine (CI, 2 cores
        # shared) may pass the default 60 s request limit (a 422 telling to run it as a job)
        env.setdefault("SNAPWARN_REQUEST_TIME_LIMIT_S", "600")
        exe = ROOT / ".venv/bin/snapwarn"
        cmd = ([str(exe)] if exe.exists() else
               [sys.executable, "-c", "import sys; from service.cli import main; sys.exit(main())"])
        self.log = Path(folder) / f"serve-{port}.log"
        self._fh = open(self.log, "wb")  # noqa: SIM115 - closed in stop()
        self.proc = subprocess.Popen(
            [*cmd, "serve", "--port", str(port), "--db", f"sqlite:///{Path(folder) / 'api.db'}"],
            cwd=folder, env=env, stdout=self._fh, stderr=subprocess.STDOUT)
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            if self.proc.poll() is not None:
                raise RuntimeError(f"snapwarn serve exited: {self.log.read_text()[-2000:]}")
            try:
                with urllib.request.urlopen(self.url + "/healthz", timeout=1.0) as r:
                    if r.status == 200:
                        return
            except OSError:
                time.sleep(0.2)
        self.stop()
        raise RuntimeError(f"snapwarn serve did not answer: {self.log.read_text()[-2000:]}")

    def server_errors(self) -> list[str]:
        """Lines of the server's log that report a 5xx or a traceback."""
        text = self.log.read_text(errors="replace")
        return [ln for ln in text.splitlines()
                if "Traceback" in ln or " 500 " in ln or " 502 " in ln or " 503 " in ln]

    def stop(self) -> None:
        self.proc.terminate()
        try:
            self.proc.wait(20)
        except subprocess.TimeoutExpired:
            self.proc.kill()
        self._fh.close()
