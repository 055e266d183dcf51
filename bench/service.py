"""Service benchmark: POST /v1/detections with a 1e4-sample inline signal, over loopback,
against the core-bound throughput of the same work measured in-process, in one run.

    python bench/service.py                 # 1, 8 and 32 concurrent clients, 8 s each
    python bench/service.py --seconds 3     # quicker
    python bench/service.py --clients 1 4   # other levels
    python bench/service.py --http-workers 2
    python bench/service.py --client httpx  # the previous load generator (~8x its CPU)

Core-bound throughput: the request's whole work without HTTP -- parse and validate the same
body, detect, serialise the answer (``inline_detection``, exactly what a server's analysis
worker runs per request) -- looped in one process per core for ``--core-seconds``, in windows:
one before the first level and one after each level (the same processes, warmed once). On a
shared machine the load changes: each level is compared with the mean of the two windows next
to it; every window is printed.

The service: a real server (`snapwarn serve`, uvicorn, SQLite file in a temporary folder) on
127.0.0.1, warmed up; for each level of concurrency that many client tasks, one keep-alive
connection each, run back to back for a bounded time. The load generator runs in this process
on the same cores, so its CPU is the test's own cost: ``--client raw`` (default) is a small
asyncio HTTP/1.1 client (a prepared request; the status and the whole body of every response
checked byte for byte against the reference answer, itself validated as a ``Detection``),
about 0.15 ms CPU per request; ``--client httpx`` (httpx2.AsyncClient) costs ~1.2 ms.
Reported per level:

- latency p50 / p95 / p99 / max (ms), throughput (requests per second), errors (any non-200
  answer or transport error), the slowest and fastest client's request counts (starvation);
- the throughput as a fraction of the core-bound throughput; and of the core-bound throughput
  on the part of the cores the load generator left (it runs in this process, on the same
  cores: ``core-bound x (1 - client CPU / (wall x cores))``);
- CPU per request (/proc): the server process (uvicorn's event loop and its threads), its
  analysis pool, the client; the in-process work's CPU per request; their ratio, the CPU
  ceiling: the fraction the service could reach if every core were busy with this test;
- the share of the cores the server and the client got (on a shared machine the rest went to
  other processes), and the 1-minute load average before and after.

Then the live sweeps' latency (``--live-trials``, default 5; 0 skips): the time from one
1e4-sample record's upload to its answer in a 20-record live sweep, with its Server-Timing split
(``bench/live_latency.py``, run from here; target 50 ms of server time).

Writes bench/results/service.json and bench/results/service.csv.
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

from bench._proc import children as _children  # noqa: E402
from bench._proc import free_port as _free_port  # noqa: E402
from bench._proc import proc_cpu as _proc_cpu  # noqa: E402
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


class _Http1(asyncio.Protocol):
    """One keep-alive HTTP/1.1 connection of the raw load generator: it writes a prepared
    request and reads one whole response (status line, headers, ``Content-Length`` body)."""

    def __init__(self) -> None:
        self.transport: asyncio.Transport | None = None
        self.buf = bytearray()
        self.head: bytes | None = None
        self.need = -1
        self.waiter: asyncio.Future[None] | None = None
        self.closed: BaseException | None = None

    def connection_made(self, transport: asyncio.BaseTransport) -> None:
        self.transport = transport  # type: ignore[assignment]

    def data_received(self, data: bytes) -> None:
        self.buf += data
        if self.head is None:
            end = self.buf.find(b"\r\n\r\n")
            if end < 0:
                return
            self.head = bytes(self.buf[:end])
            del self.buf[: end + 4]
            for line in self.head.split(b"\r\n")[1:]:
                name, _, value = line.partition(b":")
                if name.strip().lower() == b"content-length":
                    self.need = int(value)
            if self.need < 0:  # chunked or unframed: not what this server sends
                self._done(ConnectionError(f"no content-length: {self.head[:200]!r}"))
                return
        if len(self.buf) >= self.need:
            self._done(None)

    def _done(self, exc: BaseException | None) -> None:
        if self.waiter is not None and not self.waiter.done():
            if exc is None:
                self.waiter.set_result(None)
            else:
                self.waiter.set_exception(exc)

    def connection_lost(self, exc: Exception | None) -> None:
        self.closed = exc or ConnectionError("connection closed by the server")
        self._done(self.closed)

    async def request(self, raw: bytes) -> tuple[bytes, bytes]:
        """Send ``raw`` (a whole request); the response's head and body."""
        if self.closed is not None or self.transport is None:
            raise ConnectionError("connection closed")
        self.waiter = asyncio.get_running_loop().create_future()
        self.head, self.need = None, -1
        self.buf.clear()
        self.transport.write(raw)
        await self.waiter
        assert self.head is not None
        return self.head, bytes(self.buf[: self.need])


async def _raw_level(url: str, body: bytes, clients: int, seconds: float) -> dict:
    """A level of ``clients`` keep-alive connections driven by :class:`_Http1` (a small client:
    about a tenth of httpx's CPU per request). Every response is checked: status 200 and a
    body byte-identical to the reference answer (fetched first with httpx and validated as a
    ``Detection`` document; the service is deterministic, so any other body is an error)."""
    from service.schemas import Detection

    ref = httpx2.post(url + "/v1/detections", content=body, timeout=60,
                      headers={"content-type": "application/json"})  # fmt: skip
    if ref.status_code != 200:
        raise SystemExit(f"reference request: {ref.status_code} {ref.text[:300]}")
    Detection.model_validate_json(ref.content)
    expected = ref.content
    host, port = url.split("//", 1)[1].rsplit(":", 1)
    raw = (
        f"POST /v1/detections HTTP/1.1\r\nhost: {host}:{port}\r\n"
        f"content-type: application/json\r\ncontent-length: {len(body)}\r\n\r\n"
    ).encode() + body
    loop = asyncio.get_running_loop()
    lat: list[float] = []
    per_client = [0] * clients
    errors: list[str] = []

    async def connect() -> _Http1:
        return (await loop.create_connection(_Http1, host, int(port)))[1]

    conns = [await connect() for _ in range(clients)]
    stop_at = time.perf_counter() + seconds

    async def one(k: int) -> None:
        conn = conns[k]
        while time.perf_counter() < stop_at:
            t0 = time.perf_counter()
            try:
                head, got = await conn.request(raw)
            except (OSError, ConnectionError) as exc:
                errors.append(repr(exc))
                conn = conns[k] = await connect()
                continue
            if not head.startswith(b"HTTP/1.1 200 ") or got != expected:
                errors.append(f"{head[:60]!r}: {got[:200]!r}")
            else:
                lat.append(time.perf_counter() - t0)
                per_client[k] += 1
            if b"connection: close" in head.lower():
                conn.transport.close()  # type: ignore[union-attr]
                conn = conns[k] = await connect()

    t0 = time.perf_counter()
    await asyncio.gather(*(one(k) for k in range(clients)))
    wall = time.perf_counter() - t0
    for c in conns:
        if c.transport is not None:
            c.transport.close()
    return _summary(clients, lat, per_client, errors, wall)


async def _level(url: str, body: bytes, clients: int, seconds: float, client: str = "raw") -> dict:
    """One level of concurrency: ``client`` "raw" (:func:`_raw_level`) or "httpx"."""
    if client == "raw":
        return await _raw_level(url, body, clients, seconds)
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
    return _summary(clients, lat, per_client, errors, wall)


def _summary(
    clients: int, lat: list[float], per_client: list[int], errors: list[str], wall: float
) -> dict:
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


_ONE_THREAD = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS")


def _core_loop(body: bytes, start: float, seconds: float) -> tuple[int, float]:
    """One core's share of the core-bound measurement (a spawned process): the request's work
    back to back from ``start`` (wall clock) for ``seconds``; (requests done, CPU seconds)."""
    from service.api import warm
    from service.api.routers.detections import inline_detection
    from service.api.settings import Settings

    warm.warm()  # started as the server's analysis workers are (imports, then gc.freeze)
    s = Settings()
    for _ in range(20):  # imports, JIT, caches
        kind, _out = inline_detection(body, s.max_samples, s.uniform_rtol)
        assert kind == "json", kind
    while time.time() < start:
        time.sleep(0.001)
    n, c0, end = 0, time.process_time(), start + seconds
    while time.time() < end:
        inline_detection(body, s.max_samples, s.uniform_rtol)
        n += 1
    return n, time.process_time() - c0


class CoreBound:
    """The request's work alone, one process per core (no HTTP, no hand-off), in windows.

    The processes are spawned and warmed once; :meth:`measure` runs one window on all of them
    at once. Windows are taken next to each service level (before it and after it), so that on
    a shared machine each level is compared with what the same cores gave the in-process work
    around the same time.
    """

    def __init__(self, body: bytes, cores: int) -> None:
        import multiprocessing as mp

        self.body, self.cores, self.first = body, cores, True
        saved = {k: os.environ.get(k) for k in _ONE_THREAD}
        os.environ.update({k: "1" for k in _ONE_THREAD})  # as the server's analysis workers
        try:
            self.pool = mp.get_context("spawn").Pool(cores)
        finally:
            for k, v in saved.items():
                if v is None:
                    os.environ.pop(k, None)
                else:
                    os.environ[k] = v

    def measure(self, seconds: float) -> dict:
        """One window of ``seconds``: requests per second, CPU per request, share of cores."""
        start = time.time() + (20.0 if self.first else 2.0)  # every process warm by then
        self.first = False
        load0 = os.getloadavg()[0]
        got = self.pool.starmap(_core_loop, [(self.body, start, seconds)] * self.cores)
        n = sum(g[0] for g in got)
        return {
            "processes": self.cores,
            "seconds": seconds,
            "requests": n,
            "throughput_rps": n / seconds,
            "cpu_ms_per_request": 1e3 * sum(g[1] for g in got) / max(1, n),
            "cpu_share": sum(g[1] for g in got) / (seconds * self.cores),
            "loadavg_1min_before": load0,
            "loadavg_1min_after": os.getloadavg()[0],
        }

    def close(self) -> None:
        self.pool.terminate()
        self.pool.join()


def _mean_windows(windows: list[dict]) -> dict:
    """The reference of a level: the mean of the core-bound windows around it."""
    return {
        "throughput_rps": float(np.mean([w["throughput_rps"] for w in windows])),
        "cpu_ms_per_request": float(np.mean([w["cpu_ms_per_request"] for w in windows])),
        "cpu_share": float(np.mean([w["cpu_share"] for w in windows])),
    }


def _loop_processes(pid: int, http_workers: int) -> list[int]:
    """The processes running event loops: the server itself, or with several HTTP workers its
    uvicorn worker processes (its children; their analysis pools are their children)."""
    return [pid] + (_children(pid) if http_workers > 1 else [])


def _measure(
    proc: subprocess.Popen,
    url: str,
    body: bytes,
    clients: int,
    seconds: float,
    cores: int,
    http_workers: int = 1,
    client: str = "raw",
) -> dict:
    """One level of concurrency, with the CPU of the server (event loops, pools), the client."""
    loops = _loop_processes(proc.pid, http_workers)
    tree0, me0 = _tree_cpu(proc.pid), time.process_time()
    main0 = sum(_proc_cpu(p) for p in loops)
    load0 = os.getloadavg()[0]
    res = asyncio.run(_level(url, body, clients, seconds, client))
    tree = _tree_cpu(proc.pid) - tree0
    main = sum(_proc_cpu(p) for p in loops) - main0
    me = time.process_time() - me0
    n, wall = max(1, res["requests"]), res["wall_s"]
    res["server_cpu_ms_per_request"] = 1e3 * tree / n
    res["server_main_cpu_ms_per_request"] = 1e3 * main / n
    res["server_pool_cpu_ms_per_request"] = 1e3 * (tree - main) / n
    res["client_cpu_ms_per_request"] = 1e3 * me / n
    res["client_cpu_share"] = me / (wall * cores)
    res["http_workers"] = http_workers
    res["client"] = client
    res["server_cpu_share"] = tree / (wall * cores)
    res["server_and_client_cpu_share"] = (tree + me) / (wall * cores)
    res["loadavg_1min_before"] = load0
    res["loadavg_1min_after"] = os.getloadavg()[0]
    return res


def _print_level(r: dict) -> None:
    if not r["requests"]:
        print(f"{r['clients']:3d} clients: no answer; errors: {r['error_samples']}")
        return
    print(
        f"{r['clients']:3d} clients: p50 {r['p50_ms']:.1f} ms  p95 {r['p95_ms']:.1f} ms  "
        f"p99 {r['p99_ms']:.1f} ms  {r['throughput_rps']:.1f} req/s = "
        f"{100 * r['fraction_of_core_bound']:.0f}% of core-bound {r['core_bound_rps']:.1f} "
        f"({100 * r['fraction_of_core_bound_client_left']:.0f}% of it on the cores the client "
        f"left)  errors {r['errors']}  per-client {r['min_requests_per_client']}.."
        f"{r['max_requests_per_client']}\n"
        f"             cpu ms/req: server {r['server_cpu_ms_per_request']:.2f} (event "
        f"loop{'s' if r.get('http_workers', 1) > 1 else ''} "
        f"{r['server_main_cpu_ms_per_request']:.2f}, pool "
        f"{r['server_pool_cpu_ms_per_request']:.2f}), client "
        f"{r['client_cpu_ms_per_request']:.2f}; cpu ceiling {100 * r['cpu_ceiling']:.0f}%; "
        f"cores used {100 * r['server_and_client_cpu_share']:.0f}% "
        f"(load {r['loadavg_1min_before']:.1f} -> {r['loadavg_1min_after']:.1f})",
        flush=True,
    )


def _print_core(label: str, c: dict) -> None:
    print(
        f"core-bound ({label}): {c['throughput_rps']:.1f} req/s, {c['processes']} processes "
        f"x {c['seconds']:g} s, cpu {c['cpu_ms_per_request']:.2f} ms/req, cores used "
        f"{100 * c['cpu_share']:.0f}% (load {c['loadavg_1min_before']:.1f} -> "
        f"{c['loadavg_1min_after']:.1f})",
        flush=True,
    )


def _live_record(trials: int) -> dict | None:
    """Time from a live record's upload to its answer (``bench/live_latency.py``: a real
    server, a 1e4-sample record added to a 20-record live sweep, Server-Timing split), run here
    so that this benchmark reports it with the rest; None when skipped."""
    if trials <= 0:
        return None
    sys.path.insert(0, str(ROOT / "bench"))
    import live_latency  # noqa: PLC0415 (a sibling script, imported only when run)

    print("\nlive sweeps: one record added to an open sweep (bench/live_latency.py)")
    live_latency.main(["--trials", str(trials)])
    res = json.loads((RESULTS / "live_latency.json").read_text())
    print(
        f"live record ({res['samples']} samples, {res['records_before']}-record sweep): server "
        f"{res['server_ms_median']:.0f} ms median (target {res['target_server_ms']:.0f} ms), "
        f"round trip {res['round_trip_ms_median']:.0f} ms"
    )
    return res


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--clients", type=int, nargs="+", default=[1, 8, 32])
    ap.add_argument("--seconds", type=float, default=8.0, help="per level (bounded run)")
    ap.add_argument("--core-seconds", type=float, default=6.0, help="per core-bound run")
    ap.add_argument("--warmup", type=float, default=3.0)
    ap.add_argument("--http-workers", type=int, default=1)
    ap.add_argument(
        "--client",
        choices=("raw", "httpx"),
        default="raw",
        help="load generator: raw (asyncio protocol, ~0.15 ms CPU/request) or httpx (~1.2 ms)",
    )
    ap.add_argument(
        "--analysis-workers", type=int, default=None, help="default: the server's (min(4, cores))"
    )
    ap.add_argument("--samples", type=int, default=10_000)
    ap.add_argument("--http", default="auto", help="uvicorn HTTP parser: auto, httptools, h11")
    ap.add_argument("--loop", default="auto", help="uvicorn event loop: auto, uvloop, asyncio")
    ap.add_argument("--out", type=Path, default=RESULTS / "service")
    ap.add_argument(
        "--live-trials", type=int, default=5,
        help="live sweeps: trials of one 1e4-sample record added to a 20-record sweep (0: skip)",
    )  # fmt: skip
    args = ap.parse_args(argv)

    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    body = json.dumps(_signal(args.samples)).encode()
    print(
        f"load {' '.join(f'{x:.2f}' for x in os.getloadavg())} (uptime), {cores} cores; server: "
        f"{args.http_workers} HTTP worker(s), analysis workers "
        f"{args.analysis_workers or 'default'}; client: {args.client}",
        flush=True,
    )
    cb = CoreBound(body, cores)
    rows = []
    try:
        windows = [cb.measure(args.core_seconds)]
        _print_core("before the levels", windows[0])
        with tempfile.TemporaryDirectory() as d:
            proc, url = start_server(
                Path(d), args.http_workers, args.analysis_workers, args.http, args.loop
            )
            try:
                health = httpx2.get(url + "/healthz").json()
                warm = _level(url, body, max(args.clients), args.warmup, args.client)
                asyncio.run(warm)  # warm every worker
                for c in args.clients:
                    row = _measure(
                        proc, url, body, c, args.seconds, cores, args.http_workers, args.client
                    )
                    windows.append(cb.measure(args.core_seconds))
                    _print_core(f"after {c} clients", windows[-1])
                    row["core_bound_windows"] = windows[-2:]
                    rows.append(row)
            finally:
                proc.send_signal(signal.SIGTERM)
                try:
                    proc.wait(20)
                except subprocess.TimeoutExpired:
                    proc.kill()
    finally:
        cb.close()
    before, after, ref = windows[0], windows[-1], _mean_windows(windows)
    print(f"core-bound, mean of the {len(windows)} windows: {ref['throughput_rps']:.1f} req/s")
    if min(w["cpu_share"] for w in windows) < 0.9:
        print(
            "note: core-bound windows got less than 90% of the cores (a shared machine): each "
            "level is compared with the mean of the windows just before and after it; the cpu "
            "ceiling (in-process CPU / server+client CPU per request) depends less on it"
        )
    for r in rows:  # against the windows next to it
        r.update(_relative(r, _mean_windows(r["core_bound_windows"])))
        _print_level(r)
    det = _detect_reference(body)
    print(
        f"reference: detect() alone in one process: p50 {det['p50_ms']:.2f} ms, "
        f"p95 {det['p95_ms']:.2f} ms"
    )
    live = _live_record(args.live_trials)
    doc = {
        "benchmark": "POST /v1/detections, inline signal",
        "live_record": live,
        "core_bound": {"before": before, "after": after, "reference": ref, "windows": windows},
        "detect_in_process": det,
        "samples": args.samples,
        "seconds_per_level": args.seconds,
        "http_workers": args.http_workers,
        "client": args.client,
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
    keys = [k for k in rows[0] if k not in ("error_samples", "core_bound_windows")]
    with open(args.out.with_suffix(".csv"), "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=keys, extrasaction="ignore")
        w.writeheader()
        w.writerows(rows)
    print(f"wrote {args.out.with_suffix('.json')} and .csv")
    return 0 if all(r["errors"] == 0 for r in rows) else 1


def _relative(r: dict, ref: dict) -> dict:
    """The level's figures against the core-bound reference ``ref``."""
    frac = r["throughput_rps"] / ref["throughput_rps"]
    return {
        "core_bound_rps": ref["throughput_rps"],
        "fraction_of_core_bound": frac,
        "fraction_of_core_bound_client_left": frac / max(1e-9, 1.0 - r["client_cpu_share"]),
        "cpu_ceiling": ref["cpu_ms_per_request"]
        / (r["server_cpu_ms_per_request"] + r["client_cpu_ms_per_request"]),
    }


if __name__ == "__main__":
    sys.exit(main())
