"""The FastAPI app factory: settings -> store, pools, job runner, routers, error mapping."""

from __future__ import annotations

import gc
import json
import logging
import sys
import threading
import time
from collections.abc import AsyncIterator
from contextlib import asynccontextmanager
from functools import partial
from pathlib import Path
from typing import Any

from anyio import to_thread
from fastapi import Depends, FastAPI
from fastapi.openapi.utils import get_openapi

from service.api import pages
from service.api.auth import get_caller, is_loopback
from service.api.errors import BodyLimitMiddleware, install_handlers
from service.api.executor import make_analysis_pool, make_pool, warm_pool
from service.api.hotpath import HotPathMiddleware
from service.api.idempotency import IdempotencyMiddleware
from service.api.jobs import JobRunner
from service.api.openapi_links import add_links
from service.api.routers import (
    detections,
    health,
    jobs,
    live,
    predictions,
    signals,
    simulations,
    sweeps,
)
from service.api.security import SecurityMiddleware, redact_logs
from service.api.settings import Settings
from service.api.state import AppState
from service.api.storage import Store
from service.schemas import DetectionRequest, PredictionRequest, Problem, SignalIn
from service.schemas.common import PROBLEM_MEDIA_TYPE
from sim.backends import preload as preload_backends

log = logging.getLogger("snapwarn.api")

DESCRIPTION = """\
Early warning of shape transitions of elastic strips, over HTTP.

Upload recorded impulse responses (JSON, CSV, NPY/NPZ, WAV, MATLAB), simulate scenes, detect
modes, run sweeps as persistent jobs (they survive restarts) and get the transition type and
mu* with its interval. Every error is an RFC 9457 problem (`application/problem+json`) that
names the field and the value.
"""


def _lifespan(settings: Settings) -> Any:
    @asynccontextmanager
    async def lifespan(app: FastAPI) -> AsyncIterator[None]:
        # The event loop shares the GIL with the threads of this process (the job runner's,
        # the storage's to_thread, a thread executor); at the default 5 ms switch interval
        # each hand-off to them waits up to 5 ms. 0.5 ms keeps them moving. (The analysis
        # pool, a LightPool, is fed by the event loop itself: no thread per call.)
        sys.setswitchinterval(settings.gil_switch_interval_s)
        # the simulators' packages, before any worker thread imports them lazily (see preload)
        preload_backends()
        store = Store(settings.db_url)
        await to_thread.run_sync(store.create_all)
        await to_thread.run_sync(store.recover_idempotent)  # keys of requests that died
        redact_logs()
        if settings.auth == "off" and not is_loopback(settings.host):
            logging.getLogger("snapwarn").warning(
                "WARNING: API keys are off (SNAPWARN_AUTH=off) on %s, beyond loopback: anyone "
                "who can reach this server acts as an admin", settings.host,
            )  # fmt: skip
        pool = make_analysis_pool(settings.executor, settings.analysis_workers)
        state = AppState(settings=settings, store=store, pool=pool)
        if settings.warm_pool:

            def ready(avail: dict[str, bool]) -> None:
                state.numerics_cache = (time.monotonic(), avail)

            def warm_all() -> None:  # the kernels load (or compile) before the app is ready
                try:
                    warm_pool(pool, settings.analysis_workers, ready)
                finally:
                    state.kernels_ready = True

            state.kernels_ready = False
            threading.Thread(target=warm_all, name="snapwarn-warm", daemon=True).start()
        runner = None
        if settings.run_jobs:
            runner = JobRunner(
                store,
                settings,
                partial(make_pool, settings.executor, settings.job_workers, "snapwarn-jobs"),
            )
            await to_thread.run_sync(runner.start)
        state.runner = runner
        app.state.snapwarn = state
        gc.freeze()  # start-up's objects live as long as the server: out of the collector's way
        try:
            yield
        finally:
            app.state.snapwarn = None
            if runner is not None:
                await to_thread.run_sync(runner.stop)
            state.pool.shutdown(wait=False, cancel_futures=True)
            store.dispose()

    return lifespan


def create_app(settings: Settings | None = None) -> FastAPI:
    """Build the app. Nothing is opened until its lifespan starts (uvicorn does that)."""
    settings = settings or Settings()
    app = FastAPI(
        title="snapwarn",
        version="0.1.0",
        description=DESCRIPTION,
        lifespan=_lifespan(settings),
        openapi_url="/openapi.json",
        docs_url=None,  # /docs is served by service.api.pages from local assets (no CDN)
        redoc_url=None,
    )
    app.state.settings = settings
    app.state.snapwarn = None
    install_handlers(app)
    if settings.hot_path:  # innermost of ours: the checks of those below still apply
        app.add_middleware(HotPathMiddleware)
    app.add_middleware(IdempotencyMiddleware)
    app.add_middleware(BodyLimitMiddleware, max_bytes=settings.max_body_bytes,
                       read_timeout_s=settings.body_read_timeout_s)  # fmt: skip
    app.add_middleware(SecurityMiddleware, settings=settings)
    if settings.cors_origins:  # CORS is closed unless origins are configured
        from starlette.middleware.cors import CORSMiddleware

        app.add_middleware(
            CORSMiddleware,
            allow_origins=settings.cors_origins,
            allow_methods=["GET", "POST", "DELETE"],
            allow_headers=["authorization", "x-api-key", "content-type", "idempotency-key"],
            expose_headers=["location", "idempotent-replayed"],
        )
    app.include_router(health.router)
    guarded = [Depends(get_caller)]
    for r in (
        signals.router,
        simulations.router,
        detections.router,
        predictions.router,
        sweeps.router,
        jobs.router,
    ):
        app.include_router(r, dependencies=guarded)
    app.include_router(live.router, dependencies=guarded)
    from service.api.routers import atlases

    app.include_router(atlases.router, dependencies=guarded)
    from service.api.routers import snaps

    app.include_router(snaps.router, dependencies=guarded)
    pages.install(app)
    app.openapi = partial(_openapi, app)  # type: ignore[method-assign]
    return app


def _openapi(app: FastAPI) -> dict[str, Any]:
    """The OpenAPI document, with the schemas only referenced by hand (problems, uploads)."""
    if app.openapi_schema:
        return app.openapi_schema
    doc = get_openapi(
        title=app.title, version=app.version, description=app.description, routes=app.routes
    )
    comps = doc.setdefault("components", {}).setdefault("schemas", {})
    for model in (Problem, SignalIn, DetectionRequest, PredictionRequest):
        schema = model.model_json_schema(ref_template="#/components/schemas/{model}")
        for name, sub in schema.pop("$defs", {}).items():
            comps.setdefault(name, sub)
        comps.setdefault(model.__name__, schema)
    _document_common_problems(doc)
    _add_links(doc)
    add_links(doc)  # the chains that need a body (service.api.openapi_links)
    app.openapi_schema = doc
    return doc


#: Answers any /v1 operation may give, from the middlewares and the framework (RFC 9457).
_COMMON = {
    "401": "Missing, wrong or revoked API key.",
    "403": "Cross-site request or foreign Host refused.",
    "422": "Invalid input: the field and the value are named.",
    "503": "The service is starting (its analysis workers load their kernels): retry after "
    "Retry-After seconds.",
}
_WITH_BODY = {
    "400": "The body could not be read (not UTF-8, malformed).",
    "409": "A request with the same Idempotency-Key is still running.",
    "413": "Payload over the limits (settings).",
    "415": "Unsupported media type (send JSON or multipart).",
}
_CREATES_JOBS = ("/v1/simulations", "/v1/sweeps", "/v1/atlases")


def _add_links(doc: dict[str, Any]) -> None:
    """OpenAPI links from each creating POST to the operations on what it created (the id in
    its answer), for clients and for stateful testing: ``POST /v1/x`` -> ``/v1/x/{x_id}...``."""
    paths = doc.get("paths", {})
    for base, ops in paths.items():
        post = ops.get("post")
        if not isinstance(post, dict) or "{" in base:
            continue
        for path, sub in paths.items():
            if not path.startswith(base + "/{"):
                continue
            param = path[len(base) + 2 :].split("}", 1)[0]
            if "{" in path[len(base) + 2 + len(param) + 1 :]:
                continue  # a second parameter: not known from the answer alone
            pointer = path.replace("~", "~0").replace("/", "~1")
            for method in sub:
                if method not in ("get", "post", "delete"):
                    continue
                tail = path[len(base) + len(param) + 3 :].strip("/")
                name = method + ("_" + tail if tail else "_created")
                name = "".join(ch if ch.isalnum() else "_" for ch in name)
                for code in ("201", "202"):
                    if code in post.get("responses", {}):
                        post["responses"][code].setdefault("links", {})[name] = {
                            "operationRef": f"#/paths/{pointer}/{method}",
                            "parameters": {param: "$response.body#/id"},
                        }


def _document_common_problems(doc: dict[str, Any]) -> None:
    """Every operation documents the problems the layers around it may answer; the framework's
    own 422 schema is replaced by the problem document that is really sent."""
    problem = {PROBLEM_MEDIA_TYPE: {"schema": {"$ref": "#/components/schemas/Problem"}}}
    for path, ops in doc.get("paths", {}).items():
        for method, op in ops.items():
            if not isinstance(op, dict) or "responses" not in op:
                continue
            responses = op["responses"]
            for code, resp in responses.items():
                if code.startswith(("4", "5")):
                    resp["content"] = problem
            if not path.startswith("/v1/"):
                continue
            extra = dict(_COMMON)
            if method in ("post", "put", "patch"):
                extra.update(_WITH_BODY)
                if path in _CREATES_JOBS or "202" in responses:  # may queue a job
                    extra["429"] = "Too many queued or running jobs of this owner; retry later."
            for code, text in extra.items():
                responses.setdefault(code, {"description": text, "content": problem})


def openapi_document() -> dict[str, Any]:
    """The OpenAPI document of an app on default settings (what /openapi.json serves)."""
    return create_app(Settings(api_key=None)).openapi()


def export_openapi(path: str | Path) -> Path:
    """Write the OpenAPI document (sorted keys, 2-space indent, final newline) to ``path``."""
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    p.write_text(render_openapi(openapi_document()))
    return p


def render_openapi(doc: dict[str, Any]) -> str:
    return json.dumps(doc, indent=2, sort_keys=True, ensure_ascii=False) + "\n"


def app_from_env() -> FastAPI:
    """Factory for ``uvicorn --factory service.api.app:app_from_env`` (settings from env)."""
    return create_app(Settings())
