"""Fuzz the API with schemathesis against a real uvicorn on loopback; count the answers.

Used by ``test_svc_fuzz.py`` (slow) and by CI directly::

    python tests/service/_svc_fuzz.py --db sqlite --examples 40
    python tests/service/_svc_fuzz.py --db "$SNAPWARN_TEST_PG_URL" --examples 40

Every generated request is checked for: no 5xx (``not_a_server_error``), a response that
matches its documented schema, status code and content type. The counts come from the HAR
report (every request and answer the run made).
"""

from __future__ import annotations

import argparse
import collections
import json
import os
import subprocess
import sys
import tempfile
import uuid
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from _svc_helpers import _create_pg_database, start_server  # noqa: E402

SCHEMATHESIS = [sys.executable, "-m", "schemathesis.cli"]
CHECKS = (
    "not_a_server_error",
    "response_schema_conformance",
    "status_code_conformance",
    "content_type_conformance",
)
PHASES = "examples,coverage,fuzzing,stateful"
#: Server settings of the fuzz run: short job time limits, so that generated jobs end quickly.
SERVER_ENV = {
    "SNAPWARN_JOB_TIME_LIMIT_S": "20",
    "SNAPWARN_MAX_ACTIVE_JOBS_PER_OWNER": "32",
    "SNAPWARN_WARM_POOL": "false",
}


def _statuses(har: Path) -> collections.Counter:
    doc = json.loads(har.read_text())
    counts: collections.Counter = collections.Counter()
    for e in doc.get("log", {}).get("entries", []):
        counts[int(e["response"]["status"])] += 1
    return counts


def run_fuzz(
    url: str,
    out: Path,
    *,
    examples: int = 40,
    seed: int = 1,
    workers: int = 2,
    max_time: float | None = None,
    phases: str = PHASES,
) -> dict:
    """Run schemathesis on the server at ``url``; a summary of what it sent and found."""
    out.mkdir(parents=True, exist_ok=True)
    har = out / "fuzz.har"
    cmd = [
        *SCHEMATHESIS,
        "run",
        f"{url}/openapi.json",
        "--checks",
        ",".join(CHECKS),
        "--phases",
        phases,
        "--max-examples",
        str(examples),
        "--seed",
        str(seed),
        "--workers",
        str(workers),
        "--request-timeout",
        "60",
        "--exclude-path-regex",
        "/events$",  # a server-sent event stream never ends: not a request/response operation
        "--generation-database",
        "none",
        "--suppress-health-check",
        "all",
        "--no-color",
        "--report",
        "har,junit",
        "--report-har-path",
        str(har),
        "--report-dir",
        str(out),
    ]
    if max_time:
        cmd += ["--max-time", str(int(max_time))]
    proc = subprocess.run(cmd, capture_output=True, text=True, cwd=out)
    text = proc.stdout + proc.stderr
    (out / "schemathesis.txt").write_text(text)
    counts = _statuses(har) if har.exists() else collections.Counter()
    failures = [ln.strip() for ln in text.splitlines() if ln.strip().startswith("❌ ST")]
    generated = None
    for ln in text.splitlines():
        if " generated" in ln and ln.strip()[0].isdigit():
            generated = int(ln.strip().split()[0])
    return {
        "returncode": proc.returncode,
        "requests": sum(counts.values()),
        "generated": generated,
        "status_counts": dict(sorted(counts.items())),
        "server_errors": sum(v for k, v in counts.items() if k >= 500),
        "failures": failures,
        "output": str(out / "schemathesis.txt"),
    }


def fuzz_database(db: str, tmp: Path, **kw: object) -> dict:
    """Start `snapwarn serve` on ``db`` ('sqlite' or a PostgreSQL server URL) and fuzz it."""
    if db == "sqlite":
        db_url = f"sqlite:///{tmp / 'fuzz.db'}"
    else:
        db_url = _create_pg_database(db, f"snapwarn_fuzz_{uuid.uuid4().hex[:8]}")
    server = start_server(db_url, tmp, extra_env=SERVER_ENV, timeout=180)
    try:
        summary = run_fuzz(server.url, tmp / "report", **kw)  # type: ignore[arg-type]
    finally:
        server.stop()
    log = server.output()
    summary["server_log_tracebacks"] = log.count("Traceback (most recent call last)")
    summary["database"] = "sqlite" if db == "sqlite" else "postgresql"
    return summary


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--db", default="sqlite", help="'sqlite' or a PostgreSQL URL")
    p.add_argument("--examples", type=int, default=40, help="cases per operation and phase")
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--workers", type=int, default=2)
    p.add_argument("--max-time", type=float, default=None)
    p.add_argument("--keep", default=None, help="folder for the reports (default: temporary)")
    a = p.parse_args(argv)
    tmp = Path(a.keep) if a.keep else Path(tempfile.mkdtemp(prefix="snapwarn-fuzz-"))
    tmp.mkdir(parents=True, exist_ok=True)
    s = fuzz_database(
        os.path.expandvars(a.db),
        tmp,
        examples=a.examples,
        seed=a.seed,
        workers=a.workers,
        max_time=a.max_time,
    )
    print(json.dumps(s, indent=2))
    ok = s["server_errors"] == 0 and not s["failures"] and s["requests"] > 0
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
