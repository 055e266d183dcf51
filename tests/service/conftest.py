"""Fixtures of the service tests: real SQLite files, a real PostgreSQL (when
SNAPWARN_TEST_PG_URL is set, see .ci/postgres.sh), the app in-process (ASGI, lifespan run) and
a real uvicorn on 127.0.0.1 started through ``snapwarn serve`` in a subprocess."""

from __future__ import annotations

import os
import signal
from collections.abc import AsyncIterator, Iterator

import httpx2
import pytest
from _svc_helpers import PG_ENV, DbFactory, Server, start_server, test_settings

from service.api import create_app


@pytest.fixture(scope="session")
def anyio_backend() -> str:
    return "asyncio"


@pytest.fixture(scope="session")
def pg_url() -> str:
    url = os.environ.get(PG_ENV)
    if not url:
        pytest.skip(f"{PG_ENV} is not set (start a server with .ci/postgres.sh)")
    return url


@pytest.fixture(
    scope="session",
    params=["sqlite", pytest.param("postgres", marks=pytest.mark.postgres)],
)
def new_db(request: pytest.FixtureRequest, tmp_path_factory: pytest.TempPathFactory) -> DbFactory:
    """Tests using it run on SQLite files and (if SNAPWARN_TEST_PG_URL is set) PostgreSQL."""
    pg = request.getfixturevalue("pg_url") if request.param == "postgres" else None
    return DbFactory(request.param, tmp_path_factory.mktemp(f"db-{request.param}"), pg)


@pytest.fixture(scope="session")
def db_url(new_db: DbFactory) -> str:
    """One fresh database per kind, shared by the in-process app of the session."""
    return new_db("app")


@pytest.fixture(scope="session")
async def asgi(db_url: str) -> AsyncIterator[tuple[object, httpx2.AsyncClient]]:
    """The real app in-process (lifespan run: store, process pool, job runner)."""
    app = create_app(test_settings(db_url))
    async with app.router.lifespan_context(app):
        transport = httpx2.ASGITransport(app=app)
        async with httpx2.AsyncClient(transport=transport, base_url="http://asgi") as client:
            yield app, client


@pytest.fixture(scope="session")
def live_server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Server]:
    """One real uvicorn (through `snapwarn serve`) on a SQLite file, for the whole session."""
    tmp = tmp_path_factory.mktemp("live")
    server = start_server(f"sqlite:///{tmp / 'live.db'}", tmp)
    yield server
    rc = server.stop()
    # uvicorn shuts down gracefully on SIGTERM, then re-raises it: -15 (not -9: no kill needed)
    assert rc in (0, -signal.SIGTERM), f"server did not stop cleanly ({rc}):\n{server.output()}"
