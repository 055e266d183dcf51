"""Service benchmark: POST /v1/detections with a 1e4-sample inline signal, over loopback.

    python bench/service.py                 # 1, 8 and 32 concurrent clients, 8 s each
    python bench/service.py --seconds 3     # quicker
    python bench/service.py --clients 1 4   # other levels

Starts a real server (`snapwarn serve`, uvicorn, SQLite file in a temporary folder) on
127.0.0.1, warms it up, then for each level of concurrency runs that many client tasks
(httpx2.AsyncClient, keep-alive) back to back for a bounded time and reports:

- latency p50 / p95 / p99 / max (ms) and throughput (requests per second),
- errors (any non-200 answer or transport error) and the slowest client's request count
  (starvation: a client that got far fewer answers than the others),
- the server's CPU time per request: user + system time of the server process and all its
  descendants (the analysis pool) from /proc, divided by the requests answered,
- the capacity the cores allow, cores / CPU time per request, and the throughput as a fraction
  of it; also with the load generator's own CPU per request counted (it shares the cores).

The client runs in this process on the same machine: its CPU competes with the server's, and
the cores are shared with whatever else runs (the load average is recorded). Writes
bench/results/service.json and bench/results/service.csv.
"""

from __future__ import annotations

import argparse
import asyncio
import csv
import json
import os
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


def _signal(n: int = 10_000, seed: int = 0) -> dict:
    """A noisy ringing record about a static level (what a probe records after a kick)."""
    dt = 0.01
    t = np.arange(n) * dt
    rng = np.random.default_rng(seed)
    w = 0.3 + np.exp(-0.02 * t) * np.sin(2 * np.pi * 1.3 * t) + 1e-3 * rng.standard_normal(n)
    return {"dt": dt, "w": w.tolist()}


def start_server(
    tmp: Path,
    http_workers: int,
    analysis_workers: int | None,
    http_impl: str = "auto",
    loop_impl: str = "auto",
) -> tuple:
    port = _free_port()
    env = dict(
        os.environ,
        SNAPWARN_LOG_LEVEL="warning",
        PYTHONUNBUFFERED="1",
        SNAPWARN_HTTP_IMPL=http_impl,
        SNAPWARN_LOOP_IMPL=loop_impl,
    )
    if analysis_workers:
        env["SNAPWARN_ANALYSIS_WORKERS"] = str(analysis_workers)
    cmd = [
        sys.executable,
        "-c",
        "import sys; from service.cli import main; sys.exit(main())",
        "serve",
        "--host",
        "127.0.0.1",
        "--port",
        str(port),
        "--workers",
        str(http_workers),
        "--db",
        f"sqlite:///{tmp / 'bench.db'}",
        "--no-jobs",
    ]
    log = open(tmp / "server.log", "wb")  # noqa: SIM115
    proc = subprocess.Popen(cmd, cwd=ROOT, env=env, stdout=log, stderr=subprocess.STDOUT)
    url = f"http://127.0.0.1:{port}"
    end = time.monotonic() + 120
    while time.monotonic() < end:
        if proc.poll() is not None:
            raise SystemExit(f"server exited: {(tmp / 'server.log').read_text()}")
        try:
            if httpx2.get(url + "/healthz", timeout=2).status_code == 200:
                return proc, url
        except httpx2.HTTPError:
            pass
        time.sleep(0.2)
    proc.kill()
    raise SystemExit("server did not start")


async def _level(url: str, body: bytes, clients: int, seconds: float) -> dict:
    lat: list[float] = []
    per_client = [0] * clients
    errors: list[str] = []
    limits = httpx2.Limits(max_connections=clients, max_keepalive_connections=clients)
    async with httpx2.AsyncClient(base_url=url, timeout=60, limits=limits) as c:
        stop_at = time.perf_counter() + seconds

        async def one(k: int) -> None:
            while time.perf_counter() < stop_at:
                t0 = time.perf_counter()
                try:
                    r = await c.post(
                        "/v1/detections", content=body, headers={"content-type": "application/json"}
                    )
                    ok = r.status_code == 200
                    if not ok:
                        errors.append(f"{r.status_code}: {r.text[:200]}")
                except httpx2.HTTPError as exc:
                    ok = False
                    errors.append(repr(exc))
                if ok:
                    lat.append(time.perf_counter() - t0)
                    per_client[k] += 1

        t0 = time.perf_counter()
        await asyncio.gather(*(one(k) for k in range(clients)))
        wall = time.perf_counter() - t0
    a = np.array(lat) * 1e3
    return {
        "clients": clients,
        "requests": int(a.size),
        "errors": len(errors),
        "error_samples": errors[:3],
        "wall_s": wall,
        "throughput_rps": a.size / wall,
        "p50_ms": float(np.percentile(a, 50)) if a.size else None,
        "p95_ms": float(np.percentile(a, 95)) if a.size else None,
        "p99_ms": float(np.percentile(a, 99)) if a.size else None,
        "max_ms": float(a.max()) if a.size else None,
        "min_requests_per_client": min(per_client),
        "max_requests_per_client": max(per_client),
    }


def _has(module: str) -> bool:
    import importlib.util

    return importlib.util.find_spec(module) is not None


def _detect_reference(body: bytes, n: int = 200) -> dict:
    """``detect`` on the same signal in this process: what the service adds is the rest."""
    from service.analysis.detect import detect

    d = json.loads(body)
    w = np.asarray(d["w"])
    detect(w, dt=d["dt"])
    times = []
    for _ in range(n):
        t0 = time.perf_counter()
        detect(w, dt=d["dt"])
        times.append(time.perf_counter() - t0)
    a = np.array(times) * 1e3
    return {
        "p50_ms": float(np.percentile(a, 50)),
        "p95_ms": float(np.percentile(a, 95)),
        "calls": n,
    }


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--clients", type=int, nargs="+", default=[1, 8, 32])
    ap.add_argument("--seconds", type=float, default=8.0, help="per level (bounded run)")
    ap.add_argument("--warmup", type=float, default=3.0)
    ap.add_argument("--http-workers", type=int, default=1)
    ap.add_argument(
        "--analysis-workers", type=int, default=None, help="default: the server's (min(4, cores))"
    )
    ap.add_argument("--samples", type=int, default=10_000)
    ap.add_argument("--http", default="auto", help="uvicorn HTTP parser: auto, httptools, h11")
    ap.add_argument("--loop", default="auto", help="uvicorn event loop: auto, uvloop, asyncio")
    ap.add_argument("--out", type=Path, default=RESULTS / "service")
    args = ap.parse_args(argv)

    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    body = json.dumps(_signal(args.samples)).encode()
    rows = []
    with tempfile.TemporaryDirectory() as d:
        proc, url = start_server(
            Path(d), args.http_workers, args.analysis_workers, args.http, args.loop
        )
        try:
            health = httpx2.get(url + "/healthz").json()
            asyncio.run(_level(url, body, max(args.clients), args.warmup))  # warm every worker
            for c in args.clients:
                cpu0 = _tree_cpu(proc.pid)
                me0 = time.process_time()
                load0 = os.getloadavg()[0]
                res = asyncio.run(_level(url, body, c, args.seconds))
                cpu = _tree_cpu(proc.pid) - cpu0
                res["client_cpu_ms_per_request"] = (
                    1e3 * (time.process_time() - me0) / max(1, res["requests"])
                )
                res["server_cpu_ms_per_request"] = 1e3 * cpu / max(1, res["requests"])
                cap = cores / (cpu / max(1, res["requests"])) if cpu > 0 else None
                res["capacity_rps"] = cap
                res["fraction_of_capacity"] = res["throughput_rps"] / cap if cap else None
                # the load generator shares the cores: what they allow with it counted
                both = (cpu / max(1, res["requests"])) + res["client_cpu_ms_per_request"] / 1e3
                res["capacity_with_client_rps"] = cores / both if both > 0 else None
                res["fraction_of_capacity_with_client"] = (
                    res["throughput_rps"] / res["capacity_with_client_rps"]
                    if res["capacity_with_client_rps"]
                    else None
                )
                res["loadavg_1min_before"] = load0
                res["loadavg_1min_after"] = os.getloadavg()[0]
                # the share of the cores the server (and the client) got: on a shared machine
                # a throughput below capacity with a share below 1 is other processes' doing
                res["server_cpu_share"] = cpu / (res["wall_s"] * cores)
                res["server_and_client_cpu_share"] = (
                    cpu + (time.process_time() - me0)
                ) / (res["wall_s"] * cores)
                rows.append(res)
                if not res["requests"]:
                    print(f"{c:3d} clients: no answer; errors: {res['error_samples']}")
                    continue
                frac = 100 * (res["fraction_of_capacity"] or 0)
                frac2 = 100 * (res["fraction_of_capacity_with_client"] or 0)
                print(
                    f"{c:3d} clients: p50 {res['p50_ms']:.1f} ms  p95 {res['p95_ms']:.1f} ms  "
                    f"p99 {res['p99_ms']:.1f} ms  {res['throughput_rps']:.1f} req/s  "
                    f"cpu {res['server_cpu_ms_per_request']:.2f} ms/req (client "
                    f"{res['client_cpu_ms_per_request']:.2f})  capacity "
                    f"{cap or float('nan'):.1f} req/s ({frac:.0f}%, {frac2:.0f}"
                    f"% counting the client)  errors {res['errors']}  per-client "
                    f"{res['min_requests_per_client']}..{res['max_requests_per_client']}  "
                    f"cores used {100 * res['server_and_client_cpu_share']:.0f}% "
                    f"(load {load0:.1f})",
                    flush=True,
                )
        finally:
            proc.send_signal(signal.SIGTERM)
            try:
                proc.wait(20)
            except subprocess.TimeoutExpired:
                proc.kill()
    ref = _detect_reference(body)
    print(
        f"reference: detect() alone in one process: p50 {ref['p50_ms']:.2f} ms, "
        f"p95 {ref['p95_ms']:.2f} ms"
    )
    doc = {
        "benchmark": "POST /v1/detections, inline signal",
        "detect_in_process": ref,
        "samples": args.samples,
        "seconds_per_level": args.seconds,
        "http_workers": args.http_workers,
        "uvicorn": {
            "http": args.http,
            "loop": args.loop,
            "httptools_installed": _has("httptools"),
            "uvloop_installed": _has("uvloop"),
        },
        "server_health": health,
        "cores": cores,
        "machine": platform.platform(),
        "python": platform.python_version(),
        "date_utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
        "command": "python bench/service.py " + " ".join(argv or sys.argv[1:]),
        "levels": rows,
    }
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.with_suffix(".json").write_text(json.dumps(doc, indent=2) + "\n")
    keys = [k for k in rows[0] if k != "error_samples"]
    with open(args.out.with_suffix(".csv"), "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=keys, extrasaction="ignore")
        w.writeheader()
        w.writerows(rows)
    print(f"wrote {args.out.with_suffix('.json')} and .csv")
    return 0 if all(r["errors"] == 0 for r in rows) else 1


if __name__ == "__main__":
    sys.exit(main())
