"""CLI commands of the service: ``serve``, ``worker``, ``openapi`` (see service/cli/__init__.py).

The web stack is imported only when one of these commands runs.
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

from service.cli._common import add_json_flag, bad, emit

DEFAULT_OPENAPI = Path("openapi") / "openapi.json"


def register(sub: argparse._SubParsersAction) -> None:
    """Add this area's sub-commands to ``sub``."""
    p = sub.add_parser(
        "serve",
        help="run the REST API (uvicorn)",
        description="Run the REST API. Settings come from SNAPWARN_* variables; "
        "the options override them.",
    )
    p.add_argument("--host", default=None, help="bind address (default 127.0.0.1)")
    p.add_argument("--port", default=None, help="port (default 8000)")
    p.add_argument(
        "--db",
        default=None,
        metavar="URL",
        help="database URL (default sqlite:///./var/snapwarn.db)",
    )
    p.add_argument("--workers", default=None, help="uvicorn worker processes (default 1)")
    p.add_argument(
        "--no-jobs",
        action="store_true",
        help="do not run jobs in the server (run `snapwarn worker` instead)",
    )
    p.set_defaults(func=_serve)

    w = sub.add_parser(
        "worker",
        help="run persistent jobs from the database",
        description="Claim and run queued jobs (sweeps, long simulations) until "
        "stopped; restarted workers resume interrupted jobs.",
    )
    w.add_argument("--db", default=None, metavar="URL", help="database URL")
    w.add_argument("--jobs", default=None, help="jobs run at once (default 1)")
    add_json_flag(w)
    w.set_defaults(func=_worker)

    o = sub.add_parser(
        "openapi",
        help="write the OpenAPI document of the REST API",
        description="Export the OpenAPI document exactly as the app serves it.",
    )
    o.add_argument(
        "--out",
        default=str(DEFAULT_OPENAPI),
        metavar="PATH",
        help=f"output file, '-' for stdout (default {DEFAULT_OPENAPI})",
    )
    add_json_flag(o)
    o.set_defaults(func=_openapi)


def _int(option: str, value: str | None, lo: int, hi: int) -> int | None:
    if value is None:
        return None
    try:
        v = int(value)
    except ValueError:
        raise bad(option, value, "is not an integer") from None
    if not lo <= v <= hi:
        raise bad(option, value, f"must be in [{lo}, {hi}]")
    return v


def _apply_env(db: str | None, **more: object) -> None:
    """Options become SNAPWARN_* variables, so uvicorn's worker processes see them too."""
    if db is not None:
        if "://" not in db:
            raise bad("--db", db, "is not a database URL (e.g. sqlite:///./var/snapwarn.db)")
        os.environ["SNAPWARN_DB_URL"] = db
    for key, value in more.items():
        if value is not None:
            os.environ[f"SNAPWARN_{key.upper()}"] = str(value)


def _settings():  # noqa: ANN202 - imported lazily
    from pydantic import ValidationError

    from service.api.settings import Settings

    try:
        return Settings()
    except ValidationError as exc:
        e = exc.errors()[0]
        raise bad("SNAPWARN_" + str(e["loc"][0]).upper(), e.get("input"), e["msg"]) from None


def _serve(args: argparse.Namespace) -> int:
    port = _int("--port", args.port, 0, 65535)
    workers = _int("--workers", args.workers, 1, 64)
    _apply_env(
        args.db,
        host=args.host,
        port=port,
        http_workers=workers,
        run_jobs="false" if args.no_jobs else None,
    )
    settings = _settings()
    import uvicorn

    sys.stderr.write(
        f"snapwarn: serving on http://{settings.host}:{settings.port} (db {settings.db_url})\n"
    )
    uvicorn.run(
        "service.api.app:app_from_env",
        factory=True,
        host=settings.host,
        port=settings.port,
        workers=settings.http_workers,
        log_level=settings.log_level,
        http=settings.http_impl,
        loop=settings.loop_impl,
        timeout_graceful_shutdown=5,
    )
    return 0


def _worker(args: argparse.Namespace) -> int:
    import signal
    import threading
    from functools import partial

    jobs = _int("--jobs", args.jobs, 1, 64)
    _apply_env(args.db, job_workers=jobs)
    settings = _settings()
    from service.api.executor import make_pool
    from service.api.jobs import JobRunner
    from service.api.storage import Store

    store = Store(settings.db_url)
    store.create_all()
    runner = JobRunner(
        store,
        settings,
        partial(make_pool, settings.executor, settings.job_workers, "snapwarn-jobs"),
    )
    stop = threading.Event()
    for sig in (signal.SIGTERM, signal.SIGINT):
        signal.signal(sig, lambda *_: stop.set())
    runner.start()
    sys.stderr.write(f"snapwarn: worker {runner.owner} running jobs from {settings.db_url}\n")
    while not stop.wait(0.5):
        pass
    runner.stop()
    store.dispose()
    emit({"worker": runner.owner, "stopped": True}, json_mode=args.json, text="worker stopped")
    return 0


def _openapi(args: argparse.Namespace) -> int:
    from service.api.app import export_openapi, openapi_document, render_openapi

    if args.out == "-":
        sys.stdout.write(render_openapi(openapi_document()))
        return 0
    path = export_openapi(args.out)
    doc = openapi_document()
    emit(
        {"path": str(path), "paths": len(doc["paths"]), "openapi": doc["openapi"]},
        json_mode=args.json,
        text=f"wrote {path} ({len(doc['paths'])} paths)",
    )
    return 0
