"""Live-sweep latency: a 1e4-sample record added to a 20-record live sweep, over loopback.

    python bench/live_latency.py                 # 5 timed trials (+1 warm-up)
    python bench/live_latency.py --trials 10 --records 20 --samples 10000

The records are a lab loop on the Euler beam (asymmetric, xi = 2e-4, 40 dB): the first
``--records`` at the controls the live sweep itself advised, then one more record of
``--samples`` samples at the next advised control. For each trial a fresh live sweep on a real
server (uvicorn, SQLite file, one analysis worker process) receives the prior records (not
timed) and then the timed one (``POST /v1/sweeps/{id}/records``, inline JSON). Reported:

- the server time from the upload's arrival to its answer, and the client's round trip;
- its split, from the ``Server-Timing`` header the route writes (medians over the trials):
  detection of the new record, classification + prediction over all records, the policy
  (alarm, next safe value, sampling advice), storage (reading the sweep's state: only records
  this server process has not seen; appending the update; the record's own samples are stored
  while the numerics run), serialisation (the wire document and the JSON answer), parsing the
  body, and the hand-off to the analysis worker. The worker's stages come with their CPU
  time (``time.process_time`` in the worker: the work itself, whatever the load);
- the CPU time the server's process tree (uvicorn and its analysis worker) spent on it
  (/proc, 10 ms ticks): on a loaded machine the honest measure of the work;
- the same numerics in this process, split: the detection of the new record and the
  assessment (classification + prediction + policy over all records), medians of 5 runs, wall
  and CPU time; and the assessment again with the sweep policy's memo of predictions emptied
  (every prediction computed: the cost before the memo), both sides in this one run.

Each timed record carries its own tiny noise (:func:`fresh`), so that no timing reuses a
prediction of an earlier trial; the prior records' predictions are reused, as in a real sweep.

``--baseline REV`` compares the in-process numerics with those of git revision ``REV`` in
one run: two worker processes, one importing this tree and one ``REV``'s (``git archive`` of
its ``service``, ``sim`` and ``bench`` in a temporary directory, whose numba cache fills on
first use: minutes), each build the same prior records' sweep and then take the same fresh
records in turn (the order alternating), timing ``live.measure`` and ``live.assess`` in CPU
time. It prints both medians, the paired median ratio, and whether the two trees' answers
(the repr of the detection and of the update) are identical record by record; the server is
not started.

Target (issue 13): under 50 ms of server time. The cores are shared with whatever else runs
(the load average is printed). Writes bench/results/live_latency.json.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import math
import os
import pickle
import platform
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "bench" / "results"
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

import httpx2  # noqa: E402

from bench._proc import free_port as _free_port  # noqa: E402
from bench._proc import tree_cpu as _tree_cpu  # noqa: E402

Record = tuple[np.ndarray, float, float]  # (w, dt, control)


def lab_records(n_prior: int, n_samples: int, actuation: str) -> list[Record]:
    """``n_prior`` records at the advised controls, then one of ``n_samples`` samples."""
    from service.analysis import live
    from service.analysis.pipeline import KICK_POWER
    from service.analysis.sampling import PERIODS
    from sim import simulate
    from sim.scene import Scene

    plan = live.LivePlan(step=0.2)
    recs: list[live.LiveRecord] = []
    out = []
    mu, duration, dt, omega0 = 0.0, 2.0, 1e-3, None
    for k in range(n_prior + 1):
        if k == n_prior:  # the timed record: same length, n_samples samples
            dt = duration / (n_samples - 1)
        kick = 1e-2  # as warn's experimenter: scaled with the expected rate ** KICK_POWER
        if omega0 is not None:
            kick *= min(1.0, (2 * math.pi / duration * PERIODS) / omega0) ** KICK_POWER
        sig = simulate(Scene(actuation=actuation, mu=mu, damping=2e-4, kick=kick, snr_db=40.0,
                             duration=duration, dt=dt, seed=1 + k), "euler-beam")  # fmt: skip
        w = np.asarray(sig.w)[:n_samples] if k == n_prior else np.asarray(sig.w)
        out.append((w, float(sig.dt), float(mu)))
        if k == n_prior:
            break
        u = live.update(recs, w, dt=sig.dt, control=mu, plan=plan)
        recs.append(u.record)
        omega0 = omega0 or u.record.measurement.omega
        if not math.isfinite(u.next_control):
            raise SystemExit(f"no safe step after {k + 1} records: use fewer --records")
        mu, duration, dt = u.next_control, u.record_duration, u.record_dt
    return out


def fresh(record: Record, k: int) -> Record:
    """The timed record with its own tiny noise (1e-7 of its spread, seed ``k``): every
    timing sees a record its process has not assessed before (the sweep policy keeps its last
    predictions by their exact inputs; the prior records' are reused, as in a real sweep)."""
    w, dt, mu = record
    noise = np.random.default_rng(1000 + k).standard_normal(w.size)
    return w + 1e-7 * float(np.std(w)) * noise, dt, mu


def in_process(records: list[Record]) -> dict[str, float]:
    """Median times (ms) of the detection of the last record and of the assessment; the
    assessment also with the sweep policy's memo of predictions emptied first (``cold``: what
    every record cost before the memo; measured right after the other, same record)."""
    from service.analysis import live, sweep_policy

    plan = live.LivePlan(step=0.2)
    prior: list[live.LiveRecord] = []
    for w, dt, mu in records[:-1]:
        prior.append(live.update(prior, w, dt=dt, control=mu, plan=plan).record)
    det_t, ass_t, det_c, ass_c, cold_t, cold_c = [], [], [], [], [], []
    for k in range(5):
        w, dt, mu = fresh(records[-1], k)
        t0, c0 = time.perf_counter(), time.process_time()
        det, m, fl = live.measure(w, dt=dt, control=mu)
        t1, c1 = time.perf_counter(), time.process_time()
        live.assess(prior, det, m, mu, plan=plan, detection_flags=fl)
        t2, c2 = time.perf_counter(), time.process_time()
        sweep_policy._PREDICTIONS.clear()  # cold: every prediction computed again
        live.assess(prior, det, m, mu, plan=plan, detection_flags=fl)
        t3, c3 = time.perf_counter(), time.process_time()
        det_t.append(t1 - t0)
        ass_t.append(t2 - t1)
        cold_t.append(t3 - t2)
        det_c.append(c1 - c0)
        ass_c.append(c2 - c1)
        cold_c.append(c3 - c2)
    med = lambda v: 1e3 * float(np.median(v))  # noqa: E731
    return {"detect_ms": med(det_t), "assess_ms": med(ass_t), "detect_cpu_ms": med(det_c),
            "assess_cpu_ms": med(ass_c), "assess_cold_ms": med(cold_t),
            "assess_cold_cpu_ms": med(cold_c)}  # fmt: skip


def worker(records_path: str, tree: str) -> int:
    """``--worker``: with the numerics of the source tree ``tree``, build the prior records'
    sweep of ``records_path`` (a pickle of :func:`lab_records`), then for each line ``k`` of
    stdin time the detection and the assessment of ``fresh(last record, k)`` and answer
    ``detect_cpu_ms assess_cpu_ms hash`` (the hash of both answers' repr)."""
    sys.path.insert(0, tree)
    from service.analysis import live

    if not Path(live.__file__).resolve().is_relative_to(Path(tree).resolve()):
        raise SystemExit(f"imported {live.__file__}, not the tree {tree}")

    with open(records_path, "rb") as fh:
        records = pickle.load(fh)
    plan = live.LivePlan(step=0.2)
    prior: list[live.LiveRecord] = []
    for w, dt, mu in records[:-1]:
        prior.append(live.update(prior, w, dt=dt, control=mu, plan=plan).record)
    print("ready", flush=True)
    for line in sys.stdin:
        w, dt, mu = fresh(records[-1], int(line))
        c0 = time.process_time()
        det, m, fl = live.measure(w, dt=dt, control=mu)
        c1 = time.process_time()
        u = live.assess(prior, det, m, mu, plan=plan, detection_flags=fl)
        c2 = time.process_time()
        h = hashlib.sha256(repr((det, u)).encode()).hexdigest()[:16]
        print(f"{1e3 * (c1 - c0):.4f} {1e3 * (c2 - c1):.4f} {h}", flush=True)
    return 0


def compare(records: list[Record], rev: str, n: int) -> int:
    """``--baseline``: this tree against revision ``rev``, interleaved (see the module notes)."""
    tmp = Path(tempfile.mkdtemp(prefix="snapwarn-live-baseline-"))
    blob = subprocess.run(["git", "-C", str(ROOT), "archive", rev, "service", "sim", "bench"],
                          check=True, capture_output=True).stdout  # fmt: skip
    subprocess.run(["tar", "-x", "-C", str(tmp)], input=blob, check=True)
    rec_path = tmp / "records.pkl"
    rec_path.write_bytes(pickle.dumps(records))
    trees = {"this tree": ROOT, rev: tmp}
    env = dict(os.environ, OPENBLAS_NUM_THREADS="1", OMP_NUM_THREADS="1")
    procs = {}
    for name, root in trees.items():
        # this script in both workers (REV's may predate --worker), importing root's numerics
        cmd = [sys.executable, __file__, "--worker", str(rec_path), "--tree", str(root)]
        procs[name] = subprocess.Popen(cmd, cwd=root, env=env, stdin=subprocess.PIPE,
                                       stdout=subprocess.PIPE, text=True)  # fmt: skip
    for name, p in procs.items():
        if p.stdout.readline().strip() != "ready":
            raise SystemExit(f"the worker of {name} did not start")
    det = {k: [] for k in trees}
    ass = {k: [] for k in trees}
    same = 0
    load0 = os.getloadavg()[0]
    for k in range(-1, n):  # one record each first, untimed (first calls)
        order = list(procs) if k % 2 == 0 else list(procs)[::-1]
        hashes = []
        for name in order:
            p = procs[name]
            p.stdin.write(f"{2000 + k}\n")
            p.stdin.flush()
            d, a, h = p.stdout.readline().split()
            hashes.append(h)
            if k >= 0:
                det[name].append(float(d))
                ass[name].append(float(a))
        same += k >= 0 and hashes[0] == hashes[1]
    for p in procs.values():
        p.stdin.close()
        p.wait(60)
    print(f"in process, {n} fresh records, the two trees in turn (load average "
          f"{load0:.2f} -> {os.getloadavg()[0]:.2f} on {os.cpu_count()} cpus); answers "
          f"identical on {same} of {n}")
    base, this = rev, "this tree"
    for label, v in (("detection", det), ("assessment", ass)):
        b, t = np.array(v[base]), np.array(v[this])
        print(f"  {label:10s} CPU median: {rev} {np.median(b):7.2f} ms, this tree "
              f"{np.median(t):7.2f} ms; paired median ratio {np.median(t / b):.3f}")
    return 0 if same == n else 1


def start_server(tmp: Path) -> tuple[subprocess.Popen, str]:
    port = _free_port()
    env = dict(os.environ, SNAPWARN_DB_URL=f"sqlite:///{tmp / 'bench.db'}",
               SNAPWARN_ANALYSIS_WORKERS="1", SNAPWARN_LOG_LEVEL="warning",
               PYTHONPATH=str(ROOT))  # fmt: skip
    env.pop("SNAPWARN_API_KEY", None)
    cmd = [sys.executable, "-m", "uvicorn", "--factory", "service.api.app:app_from_env",
           "--host", "127.0.0.1", "--port", str(port), "--log-level", "warning"]  # fmt: skip
    proc = subprocess.Popen(cmd, cwd=tmp, env=env, stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL)  # fmt: skip
    url = f"http://127.0.0.1:{port}"
    deadline = time.monotonic() + 600  # ready: its analysis worker has loaded its kernels
    while time.monotonic() < deadline:
        try:
            r = httpx2.get(url + "/healthz", timeout=1.0)
            if r.status_code == 200 and r.json().get("ready", True):
                return proc, url
        except httpx2.HTTPError:
            pass
        time.sleep(0.2)
    proc.kill()
    raise SystemExit("the server did not start")


def server_timing(header: str) -> dict[str, tuple[float, float]]:
    """``{name: (ms, cpu ms or NaN)}`` from a ``Server-Timing`` header (``desc="cpu X"``)."""
    out = {}
    for part in header.split(","):
        name, *params = (p.strip() for p in part.split(";"))
        kv = dict(p.split("=", 1) for p in params)
        desc = kv.get("desc", "").strip('"')
        cpu = float(desc.split()[1]) if desc.startswith("cpu ") else math.nan
        out[name] = (float(kv["dur"]), cpu)
    return out


#: The split printed (and its Server-Timing entries): what the route measures, stage by stage.
STAGES = {
    "detect": ("detect",),
    "classify+predict": ("classify_predict",),
    "policy (alarm, advice, sampling)": ("policy",),
    "storage (sweep state read, append)": ("state", "store"),
    "serialisation (wire document, JSON)": ("serialise",),
    "body parsing": ("read",),
    "hand-off to the analysis worker": ("pool",),
}


def stage_split(timings: list[dict[str, tuple[float, float]]]) -> dict[str, tuple[float, float]]:
    """Median (ms, CPU ms) of each stage of :data:`STAGES` over the trials."""
    out = {}
    for label, names in STAGES.items():
        ms = [sum(t[n][0] for n in names if n in t) for t in timings]
        cpus = [sum(t[n][1] for n in names if n in t) for t in timings]
        out[label] = (float(np.median(ms)), float(np.median(cpus)))
    return out


def trial(
    client: httpx2.Client, records: list, pid: int, k: int
) -> tuple[float, float, dict, float]:
    r = client.post("/v1/sweeps", json={"mode": "live", "name": "bench", "live": {"step": 0.2}})
    r.raise_for_status()
    sid = r.json()["id"]
    for w, dt, mu in records[:-1]:
        client.post(f"/v1/sweeps/{sid}/records",
                    json={"w": w.tolist(), "dt": dt, "control": mu}).raise_for_status()  # fmt: skip
    w, dt, mu = fresh(records[-1], k)
    body = json.dumps({"w": w.tolist(), "dt": dt, "control": mu}).encode()
    cpu0 = _tree_cpu(pid)
    t0 = time.perf_counter()
    r = client.post(f"/v1/sweeps/{sid}/records", content=body,
                    headers={"content-type": "application/json"})  # fmt: skip
    wall = time.perf_counter() - t0
    cpu = _tree_cpu(pid) - cpu0
    r.raise_for_status()
    timing = server_timing(r.headers["server-timing"])
    server = timing.pop("app")[0]
    doc = r.json()
    client.post(f"/v1/sweeps/{sid}/close").raise_for_status()
    doc["_timing"] = timing
    return server, 1e3 * wall, doc, 1e3 * cpu


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--trials", type=int, default=5)
    ap.add_argument("--records", type=int, default=20, help="records already in the sweep")
    ap.add_argument("--samples", type=int, default=10_000, help="samples of the timed record")
    ap.add_argument("--actuation", default="asymmetric")
    ap.add_argument("--baseline", metavar="REV", default=None,
                    help="compare the in-process numerics with revision REV (no server)")
    ap.add_argument("--worker", metavar="RECORDS", default=None, help=argparse.SUPPRESS)
    ap.add_argument("--tree", default=str(ROOT), help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.worker:
        return worker(args.worker, args.tree)
    print(f"building {args.records} + 1 beam records ({args.actuation}) ...", file=sys.stderr)
    records = lab_records(args.records, args.samples, args.actuation)
    if args.baseline:
        return compare(records, args.baseline, max(args.trials, 2) * 4)
    local = in_process(records)
    with tempfile.TemporaryDirectory() as tmp:
        proc, url = start_server(Path(tmp))
        try:
            with httpx2.Client(base_url=url, timeout=300.0) as c:
                trial(c, records, proc.pid, 0)  # warm-up (pool, caches)
                res = [trial(c, records, proc.pid, k + 1) for k in range(args.trials)]
        finally:
            proc.send_signal(signal.SIGTERM)
            proc.wait(30)
    server = np.array([r[0] for r in res])
    wall = np.array([r[1] for r in res])
    cpu = np.array([r[3] for r in res])
    split = stage_split([r[2]["_timing"] for r in res])
    last = res[-1][2]
    load = os.getloadavg()
    doc = {
        "records_before": args.records,
        "samples": int(records[-1][0].size),
        "trials": args.trials,
        "server_ms_median": float(np.median(server)),
        "server_ms_max": float(server.max()),
        "round_trip_ms_median": float(np.median(wall)),
        "server_cpu_ms_median": float(np.median(cpu)),
        "server_split_ms_median": {k: v[0] for k, v in split.items()},
        "server_timing_entries_ms_median": {
            k: float(np.median([r[2]["_timing"].get(k, (0.0,))[0] for r in res]))
            for k in res[0][2]["_timing"]
        },
        "server_split_cpu_ms_median": {k: v[1] for k, v in split.items() if math.isfinite(v[1])},
        "in_process_detect_cpu_ms": local["detect_cpu_ms"],
        "in_process_assess_cpu_ms": local["assess_cpu_ms"],
        "in_process_detect_ms": local["detect_ms"],
        "in_process_assess_ms": local["assess_ms"],
        "in_process_assess_cold_cpu_ms": local["assess_cold_cpu_ms"],
        "in_process_assess_cold_ms": local["assess_cold_ms"],
        "target_server_ms": 50.0,
        "mu_star": last["mu_star"],
        "transition": last["transition"],
        "n_used": last["n_used"],
        "load_average": list(load),
        "cpus": os.cpu_count(),
        "python": platform.python_version(),
    }
    RESULTS.mkdir(parents=True, exist_ok=True)
    (RESULTS / "live_latency.json").write_text(json.dumps(doc, indent=2) + "\n")
    print(f"live sweep: a {doc['samples']}-sample record added to a {args.records}-record sweep "
          f"({args.trials} trials; load average {load[0]:.2f} on {os.cpu_count()} cpus)")
    print(f"  server time (upload -> answer)  median {doc['server_ms_median']:8.1f} ms   "
          f"max {doc['server_ms_max']:8.1f} ms   target < 50 ms")
    print(f"  client round trip               median {doc['round_trip_ms_median']:8.1f} ms")
    print("  server split (Server-Timing, medians; CPU where the analysis worker measured it):")
    for k, (ms, cpu_ms) in split.items():
        extra = f"   CPU {cpu_ms:7.1f} ms" if math.isfinite(cpu_ms) else ""
        print(f"    {k:38s} {ms:7.1f} ms{extra}")
    print(f"  server CPU (process tree)       median {doc['server_cpu_ms_median']:8.1f} ms "
          "(1/100 s ticks)")
    print(f"  in process: detection {local['detect_ms']:.1f} ms (CPU {local['detect_cpu_ms']:.1f}),"
          f" classification + prediction + policy over {args.records + 1} records "
          f"{local['assess_ms']:.1f} ms (CPU {local['assess_cpu_ms']:.1f}); the same with the "
          f"memo of predictions emptied first {local['assess_cold_ms']:.1f} ms "
          f"(CPU {local['assess_cold_cpu_ms']:.1f})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
