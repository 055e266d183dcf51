"""CLI commands of the service: ``serve``, ``worker``, ``keys``, ``db``, ``openapi``.

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
    p.add_argument(
        "--auth",
        choices=("auto", "on", "off"),
        default=None,
        help="API keys on /v1: 'auto' (default) requires them beyond loopback, "
        "'off' is an explicit opt-out (beyond loopback only with --i-know)",
    )
    p.add_argument(
        "--i-know",
        action="store_true",
        help="serve without API keys (--auth off) on an address beyond loopback: anyone who "
        "can reach it is an admin",
    )
    p.set_defaults(func=_serve)

    k = sub.add_parser(
        "keys",
        help="create, list and revoke API keys",
        description="API keys are stored hashed in the service database; a new key is shown "
        "once. Every resource belongs to the owner of the key that made it.",
    )
    ksub = k.add_subparsers(dest="keys_cmd", required=True, metavar="{create,list,revoke}")
    kc = ksub.add_parser("create", help="create a key (printed once)")
    kc.add_argument("--owner", default=None, help="owner name (default: one per key)")
    kc.add_argument("--admin", action="store_true", help="sees and manages every owner's data")
    kc.add_argument("--note", default=None, help="a free text note")
    kl = ksub.add_parser("list", help="the keys (never their secrets)")
    kl.add_argument("--all", action="store_true", help="include revoked keys")
    kr = ksub.add_parser("revoke", help="revoke a key by its id")
    kr.add_argument("key_id", help="the id (the part after 'sw_' up to the next '_')")
    for q in (kc, kl, kr):
        q.add_argument("--db", default=None, metavar="URL", help="database URL")
        add_json_flag(q)
    k.set_defaults(func=_keys)

    d = sub.add_parser(
        "db",
        help="database migrations (upgrade, current)",
        description="The server upgrades its database at startup; this does it by hand.",
    )
    dsub = d.add_subparsers(dest="db_cmd", required=True, metavar="{upgrade,current}")
    for name, text in (("upgrade", "upgrade to the newest schema"), ("current", "the revision")):
        q = dsub.add_parser(name, help=text)
        q.add_argument("--db", default=None, metavar="URL", help="database URL")
        add_json_flag(q)
    d.set_defaults(func=_db)

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
        auth=args.auth,
    )
    settings = _settings()
    import uvicorn

    from service.api.auth import is_loopback, keys_required

    open_beyond = settings.auth == "off" and not is_loopback(settings.host)
    if open_beyond and not args.i_know:
        raise bad("--auth", "off", f"on {settings.host} (beyond loopback) lets anyone who can "
                  "reach the server act as an admin: add --i-know to do so anyway, or create "
                  "keys ('snapwarn keys create') and keep --auth auto")  # fmt: skip
    if open_beyond:
        keys = "NO API KEYS (--auth off) on an address beyond loopback: anyone who can reach it "
        keys += "is an admin"
        sys.stderr.write(f"snapwarn: WARNING: {keys}\n")
    elif keys_required(settings):
        keys = "API keys required"
    elif settings.auth == "off":
        keys = "API keys off (--auth off)"
    else:
        keys = "no API key needed from this machine (loopback; proxied requests need one)"
    sys.stderr.write(
        f"snapwarn: serving on http://{settings.host}:{settings.port} (db {settings.db_url}; "
        f"{keys})\n"
    )
    from service.api.header_guard import protocol_for

    uvicorn.run(
        "service.api.app:app_from_env",
        factory=True,
        host=settings.host,
        port=settings.port,
        workers=settings.http_workers,
        log_level=settings.log_level,
        http=protocol_for(settings.http_impl),  # uvicorn's, with a bound on the headers
        loop=settings.loop_impl,
        proxy_headers=bool(settings.forwarded_allow_ips),
        forwarded_allow_ips=",".join(settings.forwarded_allow_ips) or None,
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


def _store(db: str | None):  # noqa: ANN202 - imported lazily
    _apply_env(db)
    settings = _settings()
    from service.api.storage import Store

    store = Store(settings.db_url)
    store.migrate()
    return store


def _key_doc(info) -> dict:  # noqa: ANN001
    return {
        "id": info.id,
        "owner": info.owner,
        "admin": info.admin,
        "note": info.note,
        "created_at": info.created_at.isoformat() + "Z",
        "revoked_at": info.revoked_at.isoformat() + "Z" if info.revoked_at else None,
    }


def _keys(args: argparse.Namespace) -> int:
    store = _store(args.db)
    try:
        if args.keys_cmd == "create":
            key, info = store.create_key(args.owner, admin=args.admin, note=args.note)
            emit(
                {"key": key, **_key_doc(info)},
                json_mode=args.json,
                text=f"{key}\n(owner {info.owner}{', admin' if info.admin else ''}; "
                "shown once: only its hash is stored)",
            )
        elif args.keys_cmd == "list":
            infos = store.list_keys(include_revoked=args.all)
            lines = [
                f"{i.id}  {i.owner}{'  admin' if i.admin else ''}"
                f"{'  revoked' if i.revoked_at else ''}{'  ' + i.note if i.note else ''}"
                for i in infos
            ]
            emit(
                {"keys": [_key_doc(i) for i in infos]},
                json_mode=args.json,
                text="\n".join(lines) or "no keys",
            )
        else:
            if not store.revoke_key(args.key_id):
                raise bad("key_id", args.key_id, "is not a live key (see `snapwarn keys list`)")
            emit(
                {"id": args.key_id, "revoked": True},
                json_mode=args.json,
                text=f"revoked {args.key_id}",
            )
    finally:
        store.dispose()
    return 0


def _db(args: argparse.Namespace) -> int:
    from service.api import migrations

    _apply_env(args.db)
    settings = _settings()
    from service.api.storage import Store

    store = Store(settings.db_url)
    try:
        rev = store.migrate() if args.db_cmd == "upgrade" else migrations.current(store.engine)
    finally:
        store.dispose()
    emit(
        {"revision": rev, "head": migrations.head()},
        json_mode=args.json,
        text=f"revision {rev} (head {migrations.head()})",
    )
    return 0
